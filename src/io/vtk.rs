//! Legacy VTK unstructured grids of linear tetrahedra (ASCII).
//!
//! Format reference: Kitware, "VTK File Formats" (VTK User's Guide, 11th ed., chapter 19,
//! "Simple Legacy Formats"): header line `# vtk DataFile Version 3.0`, a title line, `ASCII`,
//! `DATASET UNSTRUCTURED_GRID`, then `POINTS n double`, `CELLS n size` (each cell: its point
//! count, then 0-based point indices), `CELL_TYPES n` (`VTK_TETRA = 10`). The tetrahedron's
//! points 0, 1, 2 wind counter-clockwise seen from point 3 (positive volume), as in
//! [`TetMesh`]. `CELL_DATA` of the minimum dihedral angle (degrees) and the signed volume (in the
//! file's unit cubed; negative for an inverted element) is written for viewing.

use super::atomic::{read_bytes, write_atomic};
use super::Units;
use crate::error::{Error, Result};
use crate::geometry::tet_mesh::{dihedral_angles, TetGroups, TetMesh};
use crate::geometry::Point;
use std::path::Path;

/// VTK's cell type id of the linear tetrahedron.
pub(crate) const VTK_TETRA: u32 = 10;

/// VTK's cell type id of the linear triangle.
pub(crate) const VTK_TRIANGLE: u32 = 5;

/// Write `mesh` (mm) as a legacy ASCII VTK unstructured grid with coordinates in `units`, with
/// cell scalars `min_dihedral_deg` (each tetrahedron's smallest dihedral angle) and
/// `signed_volume` (the file's unit cubed).
///
/// With `groups`, the boundary triangles follow the tetrahedra as `VTK_TRIANGLE` cells (wound
/// counter-clockwise from outside), and two integer cell scalars are added: `link` (the cell's
/// group id; for a triangle, its tetrahedron's) and `boundary` (1 for a triangle, 0 for a
/// tetrahedron). A triangle has 0 for `min_dihedral_deg` and `signed_volume` (it has neither;
/// 0 rather than NaN so every reader and colour map takes the field), so select `boundary == 0`
/// before reading those. The group names go into the title line as `groups: 0 ARM 1 PALM ...`
/// (legacy VTK has no place for names of integer values; left out if the line would pass the
/// format's 256 characters).
pub fn write_vtk(
    path: &Path,
    mesh: &TetMesh,
    units: Units,
    groups: Option<&TetGroups>,
) -> Result<()> {
    if let Some(g) = groups {
        g.check(mesh).map_err(|e| e.in_file(path))?;
    }
    let s = 1.0 / units.to_mm();
    let boundary: &[([usize; 3], u32)] = groups.map_or(&[], |g| &g.boundary);
    let (t, b) = (mesh.n_tets(), boundary.len());
    let mut title = format!("ergohand tetrahedral mesh (units: {units:?})");
    if let Some(g) = groups {
        let names: Vec<String> = g
            .names
            .iter()
            .enumerate()
            .map(|(i, n)| format!("{i} {n}"))
            .collect();
        let with = format!("{title}; groups: {}", names.join(" "));
        if with.len() < 256 && !with.contains('\n') {
            title = with;
        }
    }
    write_atomic(path, |w| {
        writeln!(w, "# vtk DataFile Version 3.0")?;
        writeln!(w, "{title}")?;
        writeln!(w, "ASCII")?;
        writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
        writeln!(w, "POINTS {} double", mesh.n_nodes())?;
        for p in &mesh.nodes {
            // `{:?}` prints the shortest text that reads back to the same f64.
            writeln!(w, "{:?} {:?} {:?}", p.x * s, p.y * s, p.z * s)?;
        }
        writeln!(w, "CELLS {} {}", t + b, 5 * t + 4 * b)?;
        for q in &mesh.tets {
            writeln!(w, "4 {} {} {} {}", q[0], q[1], q[2], q[3])?;
        }
        for (f, _) in boundary {
            writeln!(w, "3 {} {} {}", f[0], f[1], f[2])?;
        }
        writeln!(w, "CELL_TYPES {}", t + b)?;
        for _ in 0..t {
            writeln!(w, "{VTK_TETRA}")?;
        }
        for _ in 0..b {
            writeln!(w, "{VTK_TRIANGLE}")?;
        }
        writeln!(w, "CELL_DATA {}", t + b)?;
        writeln!(w, "SCALARS min_dihedral_deg double 1")?;
        writeln!(w, "LOOKUP_TABLE default")?;
        for q in 0..t {
            let a = dihedral_angles(mesh.corners(q))
                .into_iter()
                .fold(f64::INFINITY, f64::min);
            writeln!(w, "{:.4}", a.to_degrees())?;
        }
        for _ in 0..b {
            writeln!(w, "0")?;
        }
        // Signed, so that an inverted element shows (negative) where the angles cannot.
        writeln!(w, "SCALARS signed_volume double 1")?;
        writeln!(w, "LOOKUP_TABLE default")?;
        for q in 0..t {
            writeln!(w, "{:e}", mesh.tet_volume(q) * s * s * s)?;
        }
        for _ in 0..b {
            writeln!(w, "0")?;
        }
        if let Some(g) = groups {
            writeln!(w, "SCALARS link int 1")?;
            writeln!(w, "LOOKUP_TABLE default")?;
            for id in g.tet_group.iter().chain(boundary.iter().map(|x| &x.1)) {
                writeln!(w, "{id}")?;
            }
            writeln!(w, "SCALARS boundary int 1")?;
            writeln!(w, "LOOKUP_TABLE default")?;
            for k in 0..t + b {
                writeln!(w, "{}", u8::from(k >= t))?;
            }
        }
        Ok(())
    })
}

/// Read a legacy ASCII VTK unstructured grid of tetrahedra whose coordinates are in `units`;
/// returns the mesh in mm.
pub fn read_vtk(path: &Path, units: Units) -> Result<TetMesh> {
    let bytes = read_bytes(path)?;
    read_vtk_bytes(&bytes, units, path)
}

/// Parse legacy VTK bytes (see [`read_vtk`]); `label` names the source in errors. Only ASCII
/// files whose cells are `VTK_TETRA` or `VTK_TRIANGLE` are accepted; the triangles (boundary
/// faces written with groups) are skipped, and data sections after `CELL_TYPES` are ignored. Counts are checked against the file length before anything is allocated.
pub(crate) fn read_vtk_bytes(bytes: &[u8], units: Units, label: &Path) -> Result<TetMesh> {
    let err = |msg: String| Error::input(label, msg);
    let text = std::str::from_utf8(bytes).map_err(|e| {
        err(format!(
            "not a text file (invalid UTF-8 at byte {})",
            e.valid_up_to()
        ))
    })?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or("");
    if !header.starts_with("# vtk DataFile Version") {
        return Err(err(
            "not a legacy VTK file: line 1 must start with '# vtk DataFile Version'".into(),
        ));
    }
    let _title = lines
        .next()
        .ok_or_else(|| err("truncated: no title line (line 2)".into()))?;
    match lines.next().map(str::trim) {
        Some("ASCII") => {}
        Some("BINARY") => {
            return Err(err(
                "binary legacy VTK is not supported: write it as ASCII".into()
            ))
        }
        other => {
            return Err(err(format!(
                "line 3 must be ASCII or BINARY, found {:?}",
                other.unwrap_or("end of file")
            )))
        }
    }
    let rest: Vec<&str> = lines.collect();
    let mut tok = rest.iter().flat_map(|l| l.split_ascii_whitespace());
    let mut next = |what: &str| -> Result<&str> {
        tok.next()
            .ok_or_else(|| err(format!("truncated: end of file where {what} was expected")))
    };
    let (a, b) = (next("DATASET")?, next("the dataset type")?);
    if a != "DATASET" || b != "UNSTRUCTURED_GRID" {
        return Err(err(format!(
            "expected 'DATASET UNSTRUCTURED_GRID', found '{a} {b}'"
        )));
    }
    // Every number takes at least two bytes (digit and separator): a bound on any count.
    let limit = bytes.len() / 2;
    let count = |s: &str, what: &str| -> Result<usize> {
        let n: usize = s
            .parse()
            .map_err(|_| err(format!("{what}: '{s}' is not a count")))?;
        if n > limit {
            return Err(err(format!(
                "{what}: {n} is more than a {}-byte file can hold",
                bytes.len()
            )));
        }
        Ok(n)
    };
    let kw = next("POINTS")?;
    if kw != "POINTS" {
        return Err(err(format!("expected POINTS, found '{kw}'")));
    }
    let n_points = count(next("the point count")?, "POINTS")?;
    if n_points.saturating_mul(3) > limit {
        return Err(err(format!(
            "POINTS: {n_points} points are more than a {}-byte file can hold",
            bytes.len()
        )));
    }
    let ty = next("the point type")?;
    if !matches!(ty, "float" | "double") {
        return Err(err(format!(
            "POINTS type '{ty}' is not supported (float or double)"
        )));
    }
    let scale = units.to_mm();
    let mut nodes = Vec::with_capacity(n_points);
    for i in 0..n_points {
        let mut c = [0.0; 3];
        for (k, x) in c.iter_mut().enumerate() {
            let s = next("a point coordinate")?;
            *x = s
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    err(format!(
                        "point {i} coordinate {k}: '{s}' is not a finite number"
                    ))
                })?
                * scale;
        }
        nodes.push(Point::from(c));
    }
    let kw = next("CELLS")?;
    if kw != "CELLS" {
        return Err(err(format!("expected CELLS, found '{kw}'")));
    }
    let n_cells = count(next("the cell count")?, "CELLS")?;
    let size = count(next("the cell list size")?, "CELLS size")?;
    // Tetrahedra are kept; triangles (the boundary faces this crate writes with groups) are
    // read and skipped.
    let mut tets = Vec::with_capacity(n_cells);
    let mut is_tet = Vec::with_capacity(n_cells);
    let mut listed = 0usize;
    for c in 0..n_cells {
        let k = next("a cell's point count")?;
        let k = match k {
            "4" => 4,
            "3" => 3,
            _ => {
                return Err(err(format!(
                    "cell {c} has '{k}' points: only tetrahedra (4) and triangles (3) are supported"
                )))
            }
        };
        listed += k + 1;
        let mut t = [0usize; 4];
        for x in t.iter_mut().take(k) {
            let s = next("a cell's point index")?;
            *x = s
                .parse::<usize>()
                .ok()
                .filter(|&v| v < n_points)
                .ok_or_else(|| {
                    err(format!(
                        "cell {c}: point index '{s}' is not one of the {n_points} points"
                    ))
                })?;
        }
        is_tet.push(k == 4);
        if k == 4 {
            tets.push(t);
        }
    }
    if listed != size {
        return Err(err(format!(
            "CELLS: list size {size}, but the cells listed take {listed} numbers"
        )));
    }
    let kw = next("CELL_TYPES")?;
    if kw != "CELL_TYPES" {
        return Err(err(format!("expected CELL_TYPES, found '{kw}'")));
    }
    let n_types = count(next("the cell type count")?, "CELL_TYPES")?;
    if n_types != n_cells {
        return Err(err(format!(
            "CELL_TYPES: {n_types} types for {n_cells} cells"
        )));
    }
    for (c, &tet) in is_tet.iter().enumerate() {
        let s = next("a cell type")?;
        let want = if tet { "10" } else { "5" };
        if s != want {
            return Err(err(format!(
                "cell {c} has type '{s}' for {} points: only VTK_TETRA (10) and VTK_TRIANGLE (5) are supported",
                if tet { 4 } else { 3 }
            )));
        }
    }
    TetMesh::new(nodes, tets).map_err(|e| e.in_file(label))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample() -> TetMesh {
        TetMesh::new(
            vec![
                Point::new(0.0, 0.0, 0.0),
                Point::new(1.5, 0.0, 0.0),
                Point::new(0.0, 2.25, 0.0),
                Point::new(0.0, 0.0, 1.0 / 3.0),
                Point::new(0.1, 0.2, -1.7),
            ],
            vec![[0, 1, 2, 3], [0, 2, 1, 4]],
        )
        .unwrap()
    }

    fn valid() -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.vtk");
        write_vtk(&p, &sample(), Units::Millimetres, None).unwrap();
        std::fs::read(p).unwrap()
    }

    /// The signed volume field against the closed form: the right-angled corner tetrahedron
    /// with legs 1.5, 2.25 and 1/3 mm holds 1.5 · 2.25 · (1/3) / 6 = 0.1875 mm³, negative with
    /// two corners swapped; in metres, 1e-9 of it.
    #[test]
    fn signed_volume_shows_an_inverted_element() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.vtk");
        let mut m = sample();
        m.tets[0].swap(1, 2);
        let field = |units| {
            write_vtk(&p, &m, units, None).unwrap();
            let text = std::fs::read_to_string(&p).unwrap();
            let at = text
                .find("SCALARS signed_volume double 1\nLOOKUP_TABLE default\n")
                .unwrap();
            text[at..]
                .lines()
                .skip(2)
                .take(2)
                .map(|l| l.parse::<f64>().unwrap())
                .collect::<Vec<f64>>()
        };
        let mm = field(Units::Millimetres);
        assert!((mm[0] + 0.1875).abs() < 1e-12, "{mm:?}");
        assert!(mm[1] > 0.0);
        let metres = field(Units::Metres);
        assert!((metres[0] + 0.1875e-9).abs() < 1e-21, "{metres:?}");
    }

    #[test]
    fn round_trip_exact_and_in_units() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.vtk");
        let m = sample();
        write_vtk(&p, &m, Units::Millimetres, None).unwrap();
        assert_eq!(read_vtk(&p, Units::Millimetres).unwrap(), m);
        write_vtk(&p, &m, Units::Metres, None).unwrap();
        let back = read_vtk(&p, Units::Metres).unwrap();
        assert_eq!(back.tets, m.tets);
        for (a, b) in back.nodes.iter().zip(&m.nodes) {
            assert!((a - b).norm() < 1e-12);
        }
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("CELL_TYPES 2\n10\n10\n"));
    }

    /// A 10 mm cube cut into the six Kuhn tetrahedra, in two groups (alternating).
    pub(crate) fn grouped_cube() -> (TetMesh, TetGroups) {
        let corner = |c: u8| {
            Point::new(
                f64::from(c & 1) * 10.0,
                f64::from((c >> 1) & 1) * 10.0,
                f64::from((c >> 2) & 1) * 10.0,
            )
        };
        let m = TetMesh::new(
            (0..8).map(corner).collect(),
            crate::geometry::marching_tetrahedra::kuhn_tetrahedra()
                .map(|t| t.map(usize::from))
                .to_vec(),
        )
        .unwrap();
        let g = TetGroups::new(&m, vec!["A".into(), "B".into()], vec![0, 1, 0, 1, 0, 1]).unwrap();
        (m, g)
    }

    /// With groups: the boundary triangles follow the tetrahedra (each square face of the
    /// cube in two, 12), closed (each edge in two of them) and outward (their divergence
    /// volume is the cube's); the link and boundary fields, read from the text by the format's
    /// grammar, label them; and the reader gives back the same tetrahedral mesh.
    #[test]
    fn groups_add_boundary_triangles_and_fields() {
        let (m, g) = grouped_cube();
        assert_eq!(g.boundary.len(), 12);
        let mut edges = std::collections::HashMap::new();
        let mut vol = 0.0;
        for (f, group) in &g.boundary {
            assert!(*group < 2);
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
            let [a, b, c] = f.map(|v| m.nodes[v].coords);
            vol += a.dot(&b.cross(&c)) / 6.0;
        }
        assert!(edges.values().all(|&n| n == 2));
        assert!((vol - 1000.0).abs() < 1e-9, "{vol}");

        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.vtk");
        write_vtk(&p, &m, Units::Millimetres, Some(&g)).unwrap();
        assert_eq!(read_vtk(&p, Units::Millimetres).unwrap(), m);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.lines().nth(1).unwrap().ends_with("groups: 0 A 1 B"));
        assert!(text.contains("CELLS 18 78\n"));
        let field = |name: &str| -> Vec<f64> {
            let at = text.find(&format!("SCALARS {name} ")).unwrap();
            text[at..]
                .lines()
                .skip(2)
                .take(18)
                .map(|l| l.parse().unwrap())
                .collect()
        };
        let types: Vec<&str> = text[text.find("CELL_TYPES 18\n").unwrap()..]
            .lines()
            .skip(1)
            .take(18)
            .collect();
        assert_eq!(types[..6], ["10"; 6]);
        assert_eq!(types[6..], ["5"; 12]);
        let link = field("link");
        let want: Vec<f64> = g
            .tet_group
            .iter()
            .chain(g.boundary.iter().map(|b| &b.1))
            .map(|&x| f64::from(x))
            .collect();
        assert_eq!(link, want);
        let boundary = field("boundary");
        assert_eq!(boundary.iter().sum::<f64>(), 12.0);
        assert!(boundary[..6].iter().all(|&x| x == 0.0));
        let volume = field("signed_volume");
        assert!(volume[..6].iter().all(|&v| (v - 1000.0 / 6.0).abs() < 1e-9));
        assert!(volume[6..].iter().all(|&v| v == 0.0));

        // Groups that do not fit the mesh are refused before anything is written.
        let mut bad = g.clone();
        bad.tet_group.pop();
        let q = dir.path().join("bad.vtk");
        let e = write_vtk(&q, &m, Units::Millimetres, Some(&bad))
            .unwrap_err()
            .to_string();
        assert!(e.contains("5 group ids for 6 tetrahedra"), "{e}");
        assert!(!q.exists());
    }

    #[test]
    fn errors_name_file_and_item() {
        let good = String::from_utf8(valid()).unwrap();
        let cases = [
            (good.replace("ASCII", "BINARY"), "binary"),
            (good.replace("4 0 2 1 4", "4 0 2 1 9"), "cell 1"),
            (
                good.replace("CELL_TYPES 2\n10\n10", "CELL_TYPES 2\n10\n12"),
                "cell 1 has type",
            ),
            (good.replace("POINTS 5", "POINTS 999999999"), "POINTS"),
            ("hello".into(), "line 1"),
        ];
        for (text, want) in cases {
            let e = read_vtk_bytes(text.as_bytes(), Units::Millimetres, Path::new("x.vtk"))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("x.vtk: ") && e.contains(want), "{e}");
            assert!(!e.contains('\n'));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_never_panics(cut in 0usize..2000) {
            let b = valid();
            let cut = cut.min(b.len());
            if let Ok(m) = read_vtk_bytes(&b[..cut], Units::Millimetres, Path::new("t.vtk")) {
                prop_assert!(m.n_tets() <= 2);
            }
        }

        #[test]
        fn mutated_never_panics(edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
            let mut b = valid();
            for (i, x) in edits {
                let i = i.index(b.len());
                b[i] = x;
            }
            if let Ok(m) = read_vtk_bytes(&b, Units::Millimetres, Path::new("t.vtk")) {
                prop_assert!(m.n_tets() <= 2 && m.n_nodes() <= 5 * 10);
            }
        }
    }
}
