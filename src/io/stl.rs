//! STL (stereolithography) triangle soup, binary and ASCII.
//!
//! Format reference: 3D Systems, "StereoLithography Interface Specification" (1988/1989),
//! section 6.5 (ASCII: `solid`/`facet normal`/`outer loop`/`vertex`/`endloop`/`endfacet`/
//! `endsolid`) and 6.6 (binary: 80-byte header, `u32` triangle count, then 50 bytes per
//! triangle: normal and three vertices as little-endian `f32`, and a `u16` attribute).
//!
//! STL repeats every corner per triangle; readers weld exact duplicates back into an indexed
//! mesh. Stored normals are ignored: the winding of the corners defines the outside.

use super::atomic::{read_bytes, write_atomic};
use super::obj::check_mesh;
use super::Units;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use std::collections::HashMap;
use std::path::Path;

const HEADER: usize = 80;
const RECORD: usize = 50;

/// Read a binary or ASCII STL file whose coordinates are in `units`; returns the welded mesh
/// in millimetres.
pub fn read_stl(path: &Path, units: Units) -> Result<TriMesh> {
    let bytes = read_bytes(path)?;
    read_stl_bytes(&bytes, units, path)
}

/// Parse STL bytes; `label` names the source in errors.
///
/// Binary or ASCII is decided by the binary size rule first, since many binary files start
/// with `solid` too: a file of exactly `84 + 50 n` bytes, `n` being the count at byte 80, is
/// binary. Otherwise a file starting with `solid` and free of NUL bytes is ASCII; anything else
/// is a binary file whose size disagrees with its count, reported as such before any
/// allocation. Exact duplicate corners are welded (as [`TriMesh::weld`] with `tol = 0`, first
/// occurrence kept) and triangles that collapse under welding are dropped.
pub(crate) fn read_stl_bytes(bytes: &[u8], units: Units, label: &Path) -> Result<TriMesh> {
    let soup = if binary_size_matches(bytes) {
        read_binary(bytes, label)?
    } else if looks_ascii(bytes) {
        read_ascii(bytes, label)?
    } else if bytes.len() >= HEADER + 4 {
        let n = triangle_count(bytes);
        return Err(Error::input(
            label,
            format!(
                "truncated or not an STL: binary header says {n} triangles ({} bytes), file \
                 holds {} ({} bytes) and it is not ASCII STL (no leading 'solid')",
                HEADER as u64 + 4 + RECORD as u64 * n as u64,
                (bytes.len() - HEADER - 4) / RECORD,
                bytes.len()
            ),
        ));
    } else {
        return Err(Error::input(
            label,
            format!(
                "not an STL: {} bytes is shorter than a binary STL header (84 bytes) and the \
                 file does not start with 'solid'",
                bytes.len()
            ),
        ));
    };
    if soup.is_empty() {
        return Err(Error::input(label, "holds no triangles"));
    }
    let mesh = weld_exact(&soup, units.to_mm());
    if mesh.faces.is_empty() {
        return Err(Error::input(
            label,
            format!(
                "all {} triangles are degenerate (corners coincide)",
                soup.len() / 3
            ),
        ));
    }
    Ok(mesh)
}

/// Write `mesh` (mm) as binary STL with coordinates in `units` as `f32` and unit face normals.
pub fn write_stl(path: &Path, mesh: &TriMesh, units: Units) -> Result<()> {
    check_mesh(mesh).map_err(|e| e.in_file(path))?;
    let n = u32::try_from(mesh.n_faces()).map_err(|_| {
        Error::input(
            path,
            format!(
                "{} triangles exceed binary STL's 32-bit count",
                mesh.n_faces()
            ),
        )
    })?;
    let s = 1.0 / units.to_mm();
    let mut coords = Vec::with_capacity(mesh.n_vertices());
    for (i, p) in mesh.vertices.iter().enumerate() {
        let q = (p * s).map(|c| c as f32);
        if !q.iter().all(|c| c.is_finite()) {
            return Err(Error::input(
                path,
                format!("vertex {i} does not fit a 32-bit float in {units}"),
            ));
        }
        coords.push(q);
    }
    let normals = mesh.face_normals();
    write_atomic(path, |w| {
        let mut header = [b' '; HEADER];
        let text = format!("ergohand binary STL, units: {units}");
        header[..text.len()].copy_from_slice(text.as_bytes());
        w.write_all(&header)?;
        w.write_all(&n.to_le_bytes())?;
        let mut rec = [0u8; RECORD];
        for (f, nrm) in mesh.faces.iter().zip(&normals) {
            let mut put =
                |k: usize, v: f32| rec[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
            for (k, c) in nrm.iter().enumerate() {
                put(k, *c as f32);
            }
            for (corner, &vi) in f.iter().enumerate() {
                for (k, c) in coords[vi].iter().enumerate() {
                    put(3 + 3 * corner + k, *c);
                }
            }
            w.write_all(&rec)?;
        }
        Ok(())
    })
}

/// Triangle corners in file units, three per triangle.
type Soup = Vec<[f64; 3]>;

fn triangle_count(bytes: &[u8]) -> u32 {
    u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]])
}

/// The binary size rule: `len == 84 + 50 n` (in u64, so no overflow on 32-bit targets).
fn binary_size_matches(bytes: &[u8]) -> bool {
    bytes.len() >= HEADER + 4
        && bytes.len() as u64 == (HEADER + 4) as u64 + RECORD as u64 * triangle_count(bytes) as u64
}

fn looks_ascii(bytes: &[u8]) -> bool {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    bytes[start..]
        .get(..5)
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"))
        && !bytes.contains(&0)
}

/// Corners of a binary STL whose size has been checked against its count.
fn read_binary(bytes: &[u8], label: &Path) -> Result<Soup> {
    let mut soup = Vec::with_capacity(3 * triangle_count(bytes) as usize);
    for (t, rec) in bytes[HEADER + 4..].chunks_exact(RECORD).enumerate() {
        for corner in 0..3 {
            let mut p = [0.0f64; 3];
            for (k, c) in p.iter_mut().enumerate() {
                let o = 12 + 12 * corner + 4 * k;
                *c = f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64;
            }
            check_finite(&p, t, label)?;
            soup.push(p);
        }
    }
    Ok(soup)
}

fn check_finite(p: &[f64; 3], t: usize, label: &Path) -> Result<()> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(Error::input(
            label,
            format!("triangle {t} has a non-finite coordinate {p:?}"),
        ))
    }
}

/// Where the ASCII parser is in the grammar of spec section 6.5.
#[derive(Clone, Copy, PartialEq, Debug)]
enum State {
    /// Before `solid` or after `endsolid`.
    Outside,
    /// Inside a solid, expecting `facet` or `endsolid`.
    Solid,
    /// After `facet normal ni nj nk`, expecting `outer loop`.
    Facet,
    /// Inside `outer loop`, after this many vertices.
    Loop(usize),
    /// After `endloop`, expecting `endfacet`.
    EndLoop,
}

/// Corners of an ASCII STL. Keywords are matched case-insensitively; several solids in one
/// file are accepted; the normal's three values are skipped unparsed (exporters write `nan`
/// there). Errors name the line and the facet.
fn read_ascii(bytes: &[u8], label: &Path) -> Result<Soup> {
    let mut soup = Vec::new();
    let mut state = State::Outside;
    let mut facet = 0usize;
    let mut last_line = 0usize;
    for (li, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = li + 1;
        last_line = line_no;
        let err = |msg: String| Error::input(label, format!("line {line_no}: {msg}"));
        let mut words = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        while let Some(w) = words.next() {
            let is = |k: &[u8]| w.eq_ignore_ascii_case(k);
            let mut expect = |k: &str| -> Result<()> {
                match words.next() {
                    Some(x) if x.eq_ignore_ascii_case(k.as_bytes()) => Ok(()),
                    other => Err(err(format!(
                        "facet {facet}: expected '{k}', found {}",
                        found(other)
                    ))),
                }
            };
            match state {
                State::Outside if is(b"solid") => {
                    state = State::Solid;
                    break; // the rest of the line is the solid's name
                }
                State::Solid if is(b"facet") => {
                    expect("normal")?;
                    for _ in 0..3 {
                        if words.next().is_none() {
                            return Err(err(format!(
                                "facet {facet}: normal has fewer than 3 values"
                            )));
                        }
                    }
                    state = State::Facet;
                }
                State::Solid if is(b"endsolid") => {
                    state = State::Outside;
                    break;
                }
                State::Facet if is(b"outer") => {
                    expect("loop")?;
                    state = State::Loop(0);
                }
                State::Loop(k) if is(b"vertex") => {
                    if k == 3 {
                        return Err(err(format!(
                            "facet {facet} has more than 3 vertices; STL facets are triangles"
                        )));
                    }
                    let mut p = [0.0f64; 3];
                    for c in p.iter_mut() {
                        let t = words.next();
                        *c = t
                            .and_then(|t| std::str::from_utf8(t).ok())
                            .and_then(|t| t.parse().ok())
                            .ok_or_else(|| {
                                err(format!(
                                    "facet {facet}, vertex {k}: expected a number, found {}",
                                    found(t)
                                ))
                            })?;
                    }
                    check_finite(&p, facet, label).map_err(|_| {
                        err(format!(
                            "facet {facet}, vertex {k}: non-finite coordinate {p:?}"
                        ))
                    })?;
                    soup.push(p);
                    state = State::Loop(k + 1);
                }
                State::Loop(k) if is(b"endloop") => {
                    if k != 3 {
                        return Err(err(format!(
                            "facet {facet} has {k} vertices; STL facets have 3"
                        )));
                    }
                    state = State::EndLoop;
                }
                State::EndLoop if is(b"endfacet") => {
                    facet += 1;
                    state = State::Solid;
                }
                _ => {
                    let wanted = match state {
                        State::Outside => "'solid'",
                        State::Solid => "'facet' or 'endsolid'",
                        State::Facet => "'outer loop'",
                        State::Loop(_) => "'vertex' or 'endloop'",
                        State::EndLoop => "'endfacet'",
                    };
                    return Err(err(format!(
                        "facet {facet}: expected {wanted}, found {}",
                        found(Some(w))
                    )));
                }
            }
        }
    }
    if state != State::Outside {
        return Err(Error::input(
            label,
            format!(
                "truncated: the file ends at line {last_line} inside {} without 'endsolid'",
                if state == State::Solid {
                    "a solid".to_string()
                } else {
                    format!("facet {facet}")
                }
            ),
        ));
    }
    Ok(soup)
}

fn found(w: Option<&[u8]>) -> String {
    match w {
        None => "the end of the line".into(),
        Some(w) => {
            let s = String::from_utf8_lossy(w);
            let s: String = s.chars().take(40).collect();
            format!("'{s}'")
        }
    }
}

/// Index a triangle soup (three corners per triangle, file units), scaling to mm by `scale`.
///
/// Exact-duplicate welding: corners with identical coordinates (`-0.0 == 0.0`) share a vertex,
/// the first occurrence in file order being kept, and triangles whose corners merge are
/// dropped. This is [`TriMesh::weld`] with `tol = 0`, done by hashing bit patterns so that no
/// grid arithmetic can overflow on extreme coordinates.
fn weld_exact(soup: &[[f64; 3]], scale: f64) -> TriMesh {
    let key = |p: &[f64; 3]| p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
    let mut index: HashMap<[u64; 3], usize> = HashMap::new();
    let mut vertices = Vec::new();
    let mut remap = Vec::with_capacity(soup.len());
    for p in soup {
        let q = p.map(|c| c * scale);
        let next = vertices.len();
        let i = *index.entry(key(&q)).or_insert(next);
        if i == next {
            vertices.push(Point::new(q[0], q[1], q[2]));
        }
        remap.push(i);
    }
    let faces = remap
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .filter(|f| f[0] != f[1] && f[1] != f[2] && f[0] != f[2])
        .collect();
    TriMesh { vertices, faces }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;
    use crate::geometry::Vec3;
    use proptest::prelude::*;
    use std::fmt::Write as _;

    fn label() -> &'static Path {
        Path::new("test.stl")
    }

    fn msg(r: Result<TriMesh>) -> String {
        let s = r.expect_err("expected an error").to_string();
        assert!(
            s.starts_with("test.stl: "),
            "error does not name the file: {s}"
        );
        assert!(!s.contains('\n'), "error is not one line: {s}");
        s
    }

    /// ASCII STL of `m` in mm written independently of the binary writer; `{:e}` keeps every
    /// f32 exact.
    fn ascii_of(m: &TriMesh) -> String {
        let mut s = String::from("solid test\n");
        for (f, n) in m.faces.iter().zip(m.face_normals()) {
            writeln!(
                s,
                "  facet normal {:e} {:e} {:e}\n    outer loop",
                n.x, n.y, n.z
            )
            .unwrap();
            for &v in f {
                let p = m.vertices[v].map(|c| c as f32);
                writeln!(s, "      vertex {:e} {:e} {:e}", p.x, p.y, p.z).unwrap();
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid test\n");
        s
    }

    /// A box whose coordinates are exact in f32, so binary round trips compare exactly.
    fn box_mm() -> TriMesh {
        cuboid(12.5, 30.25, 7.0).transformed(&nalgebra::Isometry3::translation(-3.0, 0.5, 100.0))
    }

    #[test]
    fn binary_round_trip_and_weld() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("box.stl");
        let m = box_mm();
        write_stl(&p, &m, Units::Millimetres).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(bytes.len(), 84 + 50 * 12);
        assert!(!bytes.starts_with(b"solid"));
        let back = read_stl(&p, Units::Millimetres).unwrap();
        // The soup's first-use order is the vertex order here, so the mesh comes back equal.
        assert_eq!(back.vertices.len(), 8);
        back.check_closed_manifold().unwrap();
        assert!((back.signed_volume() - m.signed_volume()).abs() < 1e-9);
        for f in 0..m.n_faces() {
            assert_eq!(back.corners(f), m.corners(f));
        }
        // The stored normal is the unit outward face normal.
        let n0 =
            Vec3::from_iterator((0..3).map(|k| {
                f32::from_le_bytes(bytes[84 + 4 * k..88 + 4 * k].try_into().unwrap()) as f64
            }));
        assert!((n0 - m.face_normals()[0]).norm() < 1e-7);
    }

    #[test]
    fn float_precision_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("odd.stl");
        let m = cuboid(0.1, 1.0 / 3.0, std::f64::consts::PI);
        write_stl(&p, &m, Units::Millimetres).unwrap();
        let back = read_stl(&p, Units::Millimetres).unwrap();
        for f in 0..m.n_faces() {
            for (a, b) in back.corners(f).iter().zip(m.corners(f)) {
                assert!((a - b).norm() <= 4.0 * f32::EPSILON as f64);
            }
        }
    }

    #[test]
    fn ascii_and_binary_agree() {
        let m = box_mm();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.stl");
        write_stl(&p, &m, Units::Millimetres).unwrap();
        let bin = read_stl(&p, Units::Millimetres).unwrap();
        let asc = read_stl_bytes(ascii_of(&m).as_bytes(), Units::Millimetres, label()).unwrap();
        assert_eq!(asc, bin);
        // Upper-case keywords, CRLF and odd spacing are still ASCII STL.
        let shouty = ascii_of(&m).to_uppercase().replace('\n', " \r\n");
        assert_eq!(
            read_stl_bytes(shouty.as_bytes(), Units::Millimetres, label()).unwrap(),
            bin
        );
    }

    #[test]
    fn binary_starting_with_solid_is_binary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.stl");
        let m = box_mm();
        write_stl(&p, &m, Units::Millimetres).unwrap();
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[..12].copy_from_slice(b"solid binary");
        let r = read_stl_bytes(&bytes, Units::Millimetres, label()).unwrap();
        assert_eq!(r, read_stl(&p, Units::Millimetres).unwrap());
    }

    #[test]
    fn weld_matches_trimesh_weld() {
        let m = box_mm();
        let soup: Vec<[f64; 3]> = m
            .faces
            .iter()
            .flatten()
            .map(|&v| m.vertices[v].coords.into())
            .collect();
        let split = TriMesh::new(
            soup.iter().map(|c| Point::from(*c)).collect(),
            (0..12).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
        )
        .unwrap();
        assert_eq!(weld_exact(&soup, 1.0), split.weld(0.0).0);
    }

    #[test]
    fn units_convert_to_mm() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.stl");
        let m = cuboid(100.0, 50.0, 20.0);
        write_stl(&p, &m, Units::Metres).unwrap();
        let back = read_stl(&p, Units::Metres).unwrap();
        assert!(
            (back.signed_volume() - 1e5).abs() < 1e-2,
            "{}",
            back.signed_volume()
        );
        let inches = read_stl(&p, Units::Inches).unwrap();
        let expect = 1e5 * (25.4f64 / 1000.0).powi(3);
        assert!((inches.signed_volume() - expect).abs() < 1e-6 * expect);
    }

    #[test]
    fn bad_input_names_the_item() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.stl");
        let m = box_mm();
        write_stl(&p, &m, Units::Millimetres).unwrap();
        let good = std::fs::read(&p).unwrap();

        let mut b = good.clone();
        b[80..84].copy_from_slice(&1000u32.to_le_bytes());
        let s = msg(read_stl_bytes(&b, Units::Millimetres, label()));
        assert!(
            s.contains("header says 1000 triangles") && s.contains("holds 12"),
            "{s}"
        );
        // A huge count must not be believed (no allocation): same error.
        b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(
            msg(read_stl_bytes(&b, Units::Millimetres, label())).contains("4294967295 triangles")
        );

        let mut b = good.clone();
        b[84 + 50 * 4 + 12 + 4..84 + 50 * 4 + 12 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        let s = msg(read_stl_bytes(&b, Units::Millimetres, label()));
        assert!(s.contains("triangle 4 has a non-finite"), "{s}");

        assert!(msg(read_stl_bytes(b"hello", Units::Millimetres, label())).contains("not an STL"));
        let s = msg(read_stl_bytes(&good[..84], Units::Millimetres, label()));
        assert!(
            s.contains("header says 12 triangles") && s.contains("holds 0"),
            "{s}"
        );
        let mut empty = good[..84].to_vec();
        empty[80..84].copy_from_slice(&0u32.to_le_bytes());
        assert!(msg(read_stl_bytes(&empty, Units::Millimetres, label())).contains("no triangles"));
        let flat = "solid x\nfacet normal 0 0 0\nouter loop\nvertex 1 2 3\nvertex 1 2 3\n\
                    vertex 4 5 6\nendloop\nendfacet\nendsolid x\n";
        let s = msg(read_stl_bytes(flat.as_bytes(), Units::Millimetres, label()));
        assert!(s.contains("all 1 triangles are degenerate"), "{s}");

        let a = ascii_of(&m);
        let s = msg(read_stl_bytes(
            a.replacen("endloop", "vertex 1 2 3\nendloop", 1).as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(
            s.contains("line 7") && s.contains("facet 0 has more than 3 vertices"),
            "{s}"
        );
        let s = msg(read_stl_bytes(
            a.replacen("vertex -3e0", "vertex -3x0", 1).as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("expected a number, found '-3x0'"), "{s}");
        let cut = &a[..a.match_indices("endloop").nth(6).unwrap().0];
        let s = msg(read_stl_bytes(cut.as_bytes(), Units::Millimetres, label()));
        assert!(s.contains("truncated") && s.contains("facet 6"), "{s}");
        let s = msg(read_stl_bytes(
            a.replacen("outer loop", "outer lop", 3).as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(
            s.contains("line 3") && s.contains("expected 'loop', found 'lop'"),
            "{s}"
        );
        let s = msg(read_stl_bytes(
            a.replacen("vertex -3e0", "vertex inf", 1).as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("non-finite"), "{s}");
    }

    fn valid(ascii: bool) -> Vec<u8> {
        let m = cuboid(1.5, 2.0, 2.5);
        if ascii {
            return ascii_of(&m).into_bytes();
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.stl");
        write_stl(&p, &m, Units::Millimetres).unwrap();
        std::fs::read(&p).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_never_panics(ascii in any::<bool>(), cut in 0usize..2000) {
            let b = valid(ascii);
            let cut = cut.min(b.len());
            if let Ok(m) = read_stl_bytes(&b[..cut], Units::Millimetres, label()) {
                prop_assert!(m.n_faces() <= 12);
            }
        }

        #[test]
        fn mutated_never_panics(ascii in any::<bool>(), edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
            let mut b = valid(ascii);
            for (i, x) in edits {
                let i = i.index(b.len());
                b[i] = x;
            }
            if let Ok(m) = read_stl_bytes(&b, Units::Millimetres, label()) {
                prop_assert!(TriMesh::new(m.vertices.clone(), m.faces.clone()).is_ok());
            }
        }
    }
}
