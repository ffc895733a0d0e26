//! Wavefront OBJ: geometric vertices (`v`) and polygonal faces (`f`), nothing else.
//!
//! Format reference: Wavefront "Object Files (.obj)", Appendix B1 of the Advanced Visualizer
//! manual (statements `v`, `vn`, `f`, 1-based and negative relative indices, `\` line
//! continuation). Texture coordinates, normals, groups, objects, materials, lines, points and
//! free-form statements are skipped: every model of the file is merged into one mesh that keeps
//! the file's vertex order, so a homologous mesh keeps its vertex correspondence.
//!
//! The parser is our own rather than `tobj`'s: `tobj` renumbers vertices per model in order of
//! first use (breaking correspondence and duplicating vertices shared between `o`/`g` groups),
//! stores `f32` unless its `use_f64` feature is on, and reports errors without a line. `tobj`
//! still serves as the peer reader in the tests.

use super::atomic::{read_bytes, write_atomic};
use super::Units;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use std::path::Path;

/// Read an OBJ file whose coordinates are in `units` (unless it was written by [`write_obj`],
/// whose header states its unit, which then wins); returns the mesh in millimetres.
pub fn read_obj(path: &Path, units: Units) -> Result<TriMesh> {
    let bytes = read_bytes(path)?;
    read_obj_bytes(&bytes, units, path)
}

/// Parse OBJ text (see the module doc for what is read); `label` names the source in errors.
///
/// Polygons are fan-triangulated `(0, i, i+1)`, keeping their winding. Positive indices may
/// refer to vertices defined later in the file (they are checked once the whole file is read);
/// negative indices count back from the last vertex defined so far (OBJ spec, "Referencing
/// vertex data"). A `v` statement's optional `w` or colour values are ignored. Errors name the
/// line and the face or vertex: a bad number, a non-finite coordinate, index 0, an index out
/// of range, a face with fewer than three vertices or one that repeats a vertex, a file with no
/// face.
pub(crate) fn read_obj_bytes(bytes: &[u8], units: Units, label: &Path) -> Result<TriMesh> {
    let err = |line: usize, msg: String| Error::input(label, format!("line {line}: {msg}"));
    let units = match written_units(bytes) {
        Some(u) if u != units => {
            log::debug!(
                "{}: read in {u}, as its ergohand header says (not {units})",
                label.display()
            );
            u
        }
        _ => units,
    };
    let scale = units.to_mm();
    let mut vertices: Vec<Point> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    // Source line and face ordinal of every triangle, for the deferred range check.
    let mut origin: Vec<(usize, usize)> = Vec::new();
    let mut n_face_statements = 0usize;

    for (line_no, stmt) in Statements::new(bytes) {
        let body = match stmt.iter().position(|&b| b == b'#') {
            Some(i) => &stmt[..i],
            None => &stmt[..],
        };
        let mut words = body
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(b"v") => {
                let vi = vertices.len() + 1;
                let mut c = [0.0f64; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let w = words.next().ok_or_else(|| {
                        err(
                            line_no,
                            format!("vertex {vi} has {k} coordinates; a 'v' needs x y z"),
                        )
                    })?;
                    let x = parse_f64(w).ok_or_else(|| {
                        err(
                            line_no,
                            format!("vertex {vi}: '{}' is not a number", show(w)),
                        )
                    })?;
                    if !x.is_finite() {
                        return Err(err(
                            line_no,
                            format!("vertex {vi}: coordinate '{}' is not finite", show(w)),
                        ));
                    }
                    *slot = x * scale;
                }
                vertices.push(Point::new(c[0], c[1], c[2]));
            }
            Some(b"f") => {
                n_face_statements += 1;
                let fi = n_face_statements;
                let mut poly: Vec<usize> = Vec::new();
                for w in words {
                    let first = w.split(|&b| b == b'/').next().unwrap_or(w);
                    let idx: i64 = std::str::from_utf8(first)
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            err(
                                line_no,
                                format!("face {fi}: '{}' is not a vertex index", show(w)),
                            )
                        })?;
                    let resolved = if idx > 0 {
                        (idx - 1) as u64
                    } else if idx < 0 {
                        let back = idx.unsigned_abs();
                        if back > vertices.len() as u64 {
                            return Err(err(
                                line_no,
                                format!(
                                    "face {fi}: relative index {idx} reaches before the first \
                                     vertex ({} defined so far)",
                                    vertices.len()
                                ),
                            ));
                        }
                        vertices.len() as u64 - back
                    } else {
                        return Err(err(
                            line_no,
                            format!("face {fi}: index 0 is invalid (OBJ indices start at 1)"),
                        ));
                    };
                    // Anything beyond usize cannot be a vertex; keep it out of range.
                    poly.push(usize::try_from(resolved).unwrap_or(usize::MAX));
                }
                if poly.len() < 3 {
                    return Err(err(
                        line_no,
                        format!(
                            "face {fi} has {} vertices; a face needs at least 3",
                            poly.len()
                        ),
                    ));
                }
                for i in 1..poly.len() - 1 {
                    let t = [poly[0], poly[i], poly[i + 1]];
                    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                        return Err(err(
                            line_no,
                            format!(
                                "face {fi} repeats vertex {}; remove degenerate faces",
                                one_based(if t[1] == t[2] { t[1] } else { t[0] })
                            ),
                        ));
                    }
                    faces.push(t);
                    origin.push((line_no, fi));
                }
            }
            _ => {}
        }
    }

    let n = vertices.len();
    for (t, &(line_no, fi)) in faces.iter().zip(&origin) {
        if let Some(&v) = t.iter().find(|&&v| v >= n) {
            return Err(err(
                line_no,
                format!(
                    "face {fi} names vertex {}, but the file has {n}",
                    one_based(v)
                ),
            ));
        }
    }
    if faces.is_empty() {
        return Err(Error::input(
            label,
            format!("no faces ('f' statements) among {n} vertices; a triangle mesh is needed"),
        ));
    }
    TriMesh::new(vertices, faces).map_err(|e| e.in_file(label))
}

/// The unit an OBJ written by [`write_obj`] states: its first line is `# ergohand OBJ mesh` and
/// its second `# units: U ...`. OBJ has no unit of its own, so only a file that says it was
/// written this way is trusted; any other file is read in the unit the caller names.
fn written_units(bytes: &[u8]) -> Option<Units> {
    let head = &bytes[..bytes.len().min(200)];
    let text = std::str::from_utf8(head)
        .or_else(|e| std::str::from_utf8(&head[..e.valid_up_to()]))
        .ok()?;
    let mut lines = text.lines();
    if lines.next()?.trim_end() != "# ergohand OBJ mesh" {
        return None;
    }
    let rest = lines.next()?.strip_prefix("# units: ")?;
    rest.split_whitespace().next()?.parse().ok()
}

/// Write `mesh` (mm) as OBJ with coordinates in `units`, optionally with one unit normal per
/// vertex (`vn`, referenced as `f a//a ...`). The header states the unit (`# units: mm`), which
/// [`read_obj`] honours over the unit it is given.
///
/// A model folder's OBJs are millimetres (the subject-format spec); metres suit a viewer that
/// takes OBJ lengths as metres, as Blender's importer does (a millimetre hand would be about
/// 200 m wide there).
///
/// Numbers are printed with Rust's shortest round-trip `f64` formatting, so reading the file
/// back in the same unit restores every millimetre coordinate exactly when `units` is
/// millimetres (and to within the rounding of one division and multiplication otherwise).
pub fn write_obj(
    path: &Path,
    mesh: &TriMesh,
    units: Units,
    normals: Option<&[Vec3]>,
) -> Result<()> {
    check_mesh(mesh).map_err(|e| e.in_file(path))?;
    if let Some(n) = normals {
        if n.len() != mesh.n_vertices() {
            return Err(Error::input(
                path,
                format!(
                    "{} normals given for {} vertices; give one normal per vertex",
                    n.len(),
                    mesh.n_vertices()
                ),
            ));
        }
        if let Some(i) = n.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(Error::input(path, format!("normal {i} is not finite")));
        }
    }
    let s = 1.0 / units.to_mm();
    write_atomic(path, |w| {
        writeln!(w, "# ergohand OBJ mesh")?;
        writeln!(w, "# units: {units} (lengths below are in {units})")?;
        writeln!(
            w,
            "# {} vertices, {} triangles",
            mesh.n_vertices(),
            mesh.n_faces()
        )?;
        for p in &mesh.vertices {
            let q = p * s;
            writeln!(w, "v {} {} {}", q.x, q.y, q.z)?;
        }
        if let Some(ns) = normals {
            for v in ns {
                writeln!(w, "vn {} {} {}", v.x, v.y, v.z)?;
            }
        }
        for f in &mesh.faces {
            let [a, b, c] = f.map(|i| i + 1);
            if normals.is_some() {
                writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
            } else {
                writeln!(w, "f {a} {b} {c}")?;
            }
        }
        Ok(())
    })
}

/// Error unless every coordinate is finite and every face names three distinct existing
/// vertices; `TriMesh`'s fields are public, so a writer cannot assume [`TriMesh::new`] ran.
pub(crate) fn check_mesh(mesh: &TriMesh) -> Result<()> {
    let n = mesh.n_vertices();
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(format!(
            "vertex {i} has a non-finite coordinate"
        )));
    }
    for (fi, f) in mesh.faces.iter().enumerate() {
        if let Some(&v) = f.iter().find(|&&v| v >= n) {
            return Err(Error::invalid(format!(
                "face {fi} names vertex {v}, but the mesh has {n} vertices"
            )));
        }
    }
    Ok(())
}

/// 1-based number of a 0-based index, saturating (an out-of-range index is usize::MAX).
fn one_based(i: usize) -> String {
    if i == usize::MAX {
        "beyond any count".into()
    } else {
        (i as u128 + 1).to_string()
    }
}

/// `f64` from an ASCII token; `None` for anything `str::parse` refuses.
fn parse_f64(w: &[u8]) -> Option<f64> {
    std::str::from_utf8(w).ok()?.parse().ok()
}

/// A token for an error message: lossy UTF-8, cut to 40 characters.
fn show(w: &[u8]) -> String {
    let s = String::from_utf8_lossy(w);
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// Logical lines of an OBJ file with the 1-based number of their first physical line:
/// `\r\n` and `\n` both end a line, and a `\` at the end of a line joins the next one
/// (OBJ spec, "Line continuation").
struct Statements<'a> {
    /// The bytes not yet split; `None` once the last line has been returned.
    rest: Option<&'a [u8]>,
    /// Number of physical lines returned so far.
    line_no: usize,
}

impl<'a> Statements<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Statements {
            rest: Some(bytes),
            line_no: 0,
        }
    }

    /// The next physical line, without its `\n`.
    fn physical(&mut self) -> Option<&'a [u8]> {
        let rest = self.rest?;
        self.line_no += 1;
        match rest.iter().position(|&b| b == b'\n') {
            Some(i) => {
                self.rest = Some(&rest[i + 1..]);
                Some(&rest[..i])
            }
            None => {
                self.rest = None;
                Some(rest)
            }
        }
    }
}

impl Iterator for Statements<'_> {
    type Item = (usize, Vec<u8>);

    fn next(&mut self) -> Option<Self::Item> {
        let first = self.physical()?;
        let start = self.line_no;
        let mut out = Vec::new();
        let mut line = first;
        loop {
            let trimmed = trim_end(line);
            match trimmed.strip_suffix(b"\\") {
                Some(head) => {
                    out.extend_from_slice(head);
                    out.push(b' ');
                    match self.physical() {
                        Some(next) => line = next,
                        None => break,
                    }
                }
                None => {
                    out.extend_from_slice(trimmed);
                    break;
                }
            }
        }
        Some((start, out))
    }
}

fn trim_end(mut s: &[u8]) -> &[u8] {
    while let [rest @ .., last] = s {
        if last.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;
    use proptest::prelude::*;

    fn label() -> &'static Path {
        Path::new("test.obj")
    }

    fn msg(r: Result<TriMesh>) -> String {
        let e = r.expect_err("expected an error");
        let s = e.to_string();
        assert!(
            s.starts_with("test.obj: "),
            "error does not name the file: {s}"
        );
        assert!(!s.contains('\n'), "error is not one line: {s}");
        s
    }

    /// A box with irrational-looking coordinates, so exactness is actually exercised.
    fn odd_box() -> TriMesh {
        let m = cuboid(0.1, 1.0 / 3.0, std::f64::consts::PI);
        TriMesh::new(
            m.vertices
                .iter()
                .map(|p| p + Vec3::new(-12.345678901234567, 1e-9, 7.0e5))
                .collect(),
            m.faces,
        )
        .unwrap()
    }

    #[test]
    fn round_trip_is_exact_in_mm() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("box.obj");
        let m = odd_box();
        write_obj(&p, &m, Units::Millimetres, None).unwrap();
        let back = read_obj(&p, Units::Millimetres).unwrap();
        assert_eq!(back, m);
        // With normals the faces reference them (`a//a`), positions and faces unchanged.
        let n = m.vertex_normals();
        write_obj(&p, &m, Units::Millimetres, Some(&n)).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text.lines().filter(|l| l.starts_with("vn ")).count(), 8);
        assert!(text.contains("units: mm"));
        assert_eq!(read_obj(&p, Units::Millimetres).unwrap(), m);
    }

    #[test]
    fn metres_are_read_as_millimetres() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("box_m.obj");
        let m = cuboid(20.0, 30.0, 40.0);
        write_obj(&p, &m, Units::Metres, None).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("v 0.02 0.03 0.04"), "{text}");
        let back = read_obj(&p, Units::Metres).unwrap();
        assert_eq!(back.faces, m.faces);
        for (a, b) in back.vertices.iter().zip(&m.vertices) {
            assert!((a - b).norm() <= 1e-12 * 40.0);
        }
        // Its header says metres, so it is read in metres whatever the caller says; without the
        // header the same numbers read as millimetres are a thousand times smaller.
        let told_mm = read_obj(&p, Units::Millimetres).unwrap();
        assert_eq!(told_mm, back);
        assert!(
            text.starts_with("# ergohand OBJ mesh\n# units: m "),
            "{text}"
        );
        let headless = text.replacen("# ergohand OBJ mesh", "# another writer", 1);
        let small = read_obj_bytes(headless.as_bytes(), Units::Millimetres, label()).unwrap();
        assert!((small.signed_volume() * 1e9 - m.signed_volume()).abs() < 1e-6);
        // And the other way: a millimetre file read by a caller who says metres.
        write_obj(&p, &m, Units::Millimetres, None).unwrap();
        assert_eq!(read_obj(&p, Units::Metres).unwrap(), m);
    }

    const MULTI: &str = "# two objects sharing vertices, a quad, negative indices, continuation\n\
        mtllib none.mtl\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
        vt 0 0\nvn 0 0 1\n\
        o first\n\
        f 1/1/1 2/1/1 3/1/1 4/1/1\n\
        v 0.5 0.5 1.0 1.0\n\
        o second\n\
        g side\n\
        f -5 -4 \\\n -1\n\
        l 1 2\n\
        f 2//1 3//1 5//1\r\n\
        f 3 4 5 # trailing comment\n";

    #[test]
    fn merges_objects_and_triangulates() {
        let m = read_obj_bytes(MULTI.as_bytes(), Units::Millimetres, label()).unwrap();
        assert_eq!(m.n_vertices(), 5);
        assert_eq!(
            m.faces,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 2, 4], [2, 3, 4]]
        );
        assert_eq!(m.vertices[4], Point::new(0.5, 0.5, 1.0));
    }

    /// Peer check: tobj reads the same file to the same triangles (as coordinates, since tobj
    /// renumbers vertices per object), to its f32 precision.
    #[test]
    fn agrees_with_tobj() {
        let opts = tobj::LoadOptions {
            triangulate: true,
            ignore_lines: true,
            ignore_points: true,
            ..Default::default()
        };
        // tobj neither joins `\` continuation lines nor strips trailing comments; give it the
        // text without them.
        let text = MULTI
            .replace(" \\\n", " ")
            .replace(" # trailing comment", "");
        let mut reader = std::io::BufReader::new(text.as_bytes());
        let (models, _) =
            tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
                .unwrap();
        let ours = read_obj_bytes(MULTI.as_bytes(), Units::Millimetres, label()).unwrap();
        let mut theirs = Vec::new();
        for model in &models {
            let pos = &model.mesh.positions;
            for t in model.mesh.indices.chunks(3) {
                theirs.push([t[0], t[1], t[2]].map(|i| {
                    let i = i as usize * 3;
                    Point::new(pos[i] as f64, pos[i + 1] as f64, pos[i + 2] as f64)
                }));
            }
        }
        assert_eq!(theirs.len(), ours.n_faces());
        for (f, a) in theirs.iter().enumerate() {
            let b = ours.corners(f);
            for k in 0..3 {
                assert!((a[k] - b[k]).norm() < 1e-6, "face {f} corner {k}");
            }
        }
    }

    #[test]
    fn bad_input_names_line_and_item() {
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
        let case = |body: &str| {
            msg(read_obj_bytes(
                format!("{v}{body}").as_bytes(),
                Units::Millimetres,
                label(),
            ))
        };
        let s = case("f 1 2 3\nf 1 2 4\nf 1 3 17\n");
        assert!(
            s.contains("line 7") && s.contains("face 3 names vertex 17, but the file has 4"),
            "{s}"
        );
        let s = case("f 1 2 0\n");
        assert!(s.contains("line 5") && s.contains("index 0"), "{s}");
        let s = case("f 1 -9 2\n");
        assert!(s.contains("relative index -9"), "{s}");
        let s = case("f 1 2\n");
        assert!(s.contains("face 1 has 2 vertices"), "{s}");
        let s = case("f 1 2 2\n");
        assert!(s.contains("face 1 repeats vertex 2"), "{s}");
        let s = case("f 1 2 x\n");
        assert!(s.contains("'x' is not a vertex index"), "{s}");
        let s = case("v 1 nan 3\nf 1 2 3\n");
        assert!(
            s.contains("line 5") && s.contains("vertex 5") && s.contains("not finite"),
            "{s}"
        );
        let s = case("v 1 2\n");
        assert!(s.contains("vertex 5 has 2 coordinates"), "{s}");
        let s = case("v 1 2 3e\n");
        assert!(s.contains("'3e' is not a number"), "{s}");
        let s = case("");
        assert!(s.contains("no faces"), "{s}");
        let s = case("f 1 2 99999999999999999999999\n");
        assert!(s.contains("not a vertex index"), "{s}");
    }

    #[test]
    fn writer_rejects_bad_meshes_and_normals() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.obj");
        let m = cuboid(1.0, 1.0, 1.0);
        let e = write_obj(&p, &m, Units::Millimetres, Some(&[Vec3::z()])).unwrap_err();
        assert!(e.to_string().contains("1 normals given for 8 vertices"));
        let mut bad = m.clone();
        bad.faces[3][1] = 8;
        let e = write_obj(&p, &bad, Units::Millimetres, None).unwrap_err();
        assert!(
            e.to_string().contains("bad.obj") && e.to_string().contains("face 3 names vertex 8")
        );
        assert!(!p.exists());
    }

    fn valid_bytes() -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.obj");
        let m = cuboid(1.5, 2.0, 2.5);
        write_obj(&p, &m, Units::Millimetres, Some(&m.vertex_normals())).unwrap();
        std::fs::read(&p).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_never_panics(cut in 0usize..2000) {
            let b = valid_bytes();
            let cut = cut.min(b.len());
            if let Ok(m) = read_obj_bytes(&b[..cut], Units::Millimetres, label()) {
                prop_assert!(m.n_faces() <= 12);
            }
        }

        #[test]
        fn mutated_never_panics(edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
            let mut b = valid_bytes();
            for (i, x) in edits {
                let i = i.index(b.len());
                b[i] = x;
            }
            if let Ok(m) = read_obj_bytes(&b, Units::Millimetres, label()) {
                prop_assert!(m.faces.iter().flatten().all(|&v| v < m.n_vertices()));
            }
        }
    }
}
