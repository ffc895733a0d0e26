//! Gmsh MSH 4.1 ASCII tetrahedral meshes (for FEM users).
//!
//! Format reference: Gmsh reference manual, section 10.1 "MSH file format" (version 4.1):
//! `$MeshFormat` (`4.1 0 8`), `$Entities` (one volume entity, tag 1, with its bounding box),
//! `$Nodes` (one block on that volume: tags 1..n, then coordinates), `$Elements` (one block of
//! element type 4, the 4-node tetrahedron, tags 1..t, 1-based node tags). Gmsh's tetrahedron
//! has positive volume with the node order of [`TetMesh`]. An `$ElementData` view "signed_volume"
//! (the file's unit cubed, negative for an inverted element) follows, as Gmsh reads it for viewing.

use super::atomic::write_atomic;
use super::Units;
use crate::error::Result;
use crate::geometry::tet_mesh::TetMesh;
use std::path::Path;

/// Gmsh's element type of the 4-node tetrahedron.
pub(crate) const GMSH_TETRAHEDRON: u32 = 4;

/// Write `mesh` (mm) as Gmsh MSH 4.1 ASCII with coordinates in `units`.
pub fn write_msh(path: &Path, mesh: &TetMesh, units: Units) -> Result<()> {
    let s = 1.0 / units.to_mm();
    let (n, t) = (mesh.n_nodes(), mesh.n_tets());
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &mesh.nodes {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] * s);
            hi[k] = hi[k].max(p[k] * s);
        }
    }
    if n == 0 {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    write_atomic(path, |w| {
        writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
        writeln!(w, "$Entities\n0 0 0 1")?;
        writeln!(
            w,
            "1 {:?} {:?} {:?} {:?} {:?} {:?} 0 0",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        )?;
        writeln!(w, "$EndEntities")?;
        writeln!(w, "$Nodes\n1 {n} 1 {n}\n3 1 0 {n}")?;
        for i in 1..=n {
            writeln!(w, "{i}")?;
        }
        for p in &mesh.nodes {
            writeln!(w, "{:?} {:?} {:?}", p.x * s, p.y * s, p.z * s)?;
        }
        writeln!(w, "$EndNodes")?;
        writeln!(w, "$Elements\n1 {t} 1 {t}\n3 1 {GMSH_TETRAHEDRON} {t}")?;
        for (e, tet) in mesh.tets.iter().enumerate() {
            writeln!(
                w,
                "{} {} {} {} {}",
                e + 1,
                tet[0] + 1,
                tet[1] + 1,
                tet[2] + 1,
                tet[3] + 1
            )?;
        }
        writeln!(w, "$EndElements")?;
        // Signed, so that an inverted element shows (negative); in the file's unit cubed.
        writeln!(
            w,
            "$ElementData\n1\n\"signed_volume\"\n1\n0.0\n3\n0\n1\n{t}"
        )?;
        for e in 0..t {
            writeln!(w, "{} {:e}", e + 1, mesh.tet_volume(e) * s * s * s)?;
        }
        writeln!(w, "$EndElementData")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;

    /// Parse the written file back by the format's grammar (an independent reading of the
    /// section layout) and compare.
    #[test]
    fn parses_back_by_the_spec() {
        let m = TetMesh::new(
            vec![
                Point::new(0.0, 0.0, 0.0),
                Point::new(10.0, 0.0, 0.0),
                Point::new(0.0, 10.0, 0.0),
                Point::new(0.0, 0.0, 10.0),
                Point::new(3.0, 3.0, -7.5),
            ],
            vec![[0, 1, 2, 3], [0, 2, 1, 4]],
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.msh");
        write_msh(&p, &m, Units::Centimetres).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let at = |s: &str| lines.iter().position(|l| *l == s).unwrap();
        assert_eq!(lines[at("$MeshFormat") + 1], "4.1 0 8");
        let ent: Vec<f64> = lines[at("$Entities") + 2]
            .split(' ')
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(ent, vec![1.0, 0.0, 0.0, -0.75, 1.0, 1.0, 1.0, 0.0, 0.0]);
        let nodes = at("$Nodes");
        let head: Vec<usize> = lines[nodes + 1]
            .split(' ')
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(head, vec![1, 5, 1, 5]);
        assert_eq!(lines[nodes + 2], "3 1 0 5");
        for i in 0..5 {
            assert_eq!(lines[nodes + 3 + i], (i + 1).to_string());
            let c: Vec<f64> = lines[nodes + 8 + i]
                .split(' ')
                .map(|x| x.parse().unwrap())
                .collect();
            for (k, x) in c.iter().enumerate() {
                assert!((x * 10.0 - m.nodes[i][k]).abs() < 1e-12);
            }
        }
        assert_eq!(lines[nodes + 13], "$EndNodes");
        let el = at("$Elements");
        assert_eq!(lines[el + 1], "1 2 1 2");
        assert_eq!(lines[el + 2], "3 1 4 2");
        for (e, t) in m.tets.iter().enumerate() {
            let v: Vec<usize> = lines[el + 3 + e]
                .split(' ')
                .map(|x| x.parse().unwrap())
                .collect();
            assert_eq!(v[0], e + 1);
            assert_eq!(&v[1..], &t.map(|i| i + 1));
        }
        assert_eq!(lines[el + 5], "$EndElements");
        // The signed volume view, in cm³: the first tetrahedron is the corner one with 10 mm
        // legs (1000/6 mm³), the second is 7.5 mm below its base (100 · 7.5 / 6 mm³).
        let data = at("$ElementData");
        assert_eq!(
            &lines[data + 1..data + 9],
            &["1", "\"signed_volume\"", "1", "0.0", "3", "0", "1", "2"]
        );
        for (e, want_mm3) in [1000.0 / 6.0, 750.0 / 6.0].iter().enumerate() {
            let v: Vec<&str> = lines[data + 9 + e].split(' ').collect();
            assert_eq!(v[0], (e + 1).to_string());
            let got: f64 = v[1].parse().unwrap();
            assert!((got - want_mm3 * 1e-3).abs() < 1e-12, "{got}");
        }
        assert_eq!(lines[data + 11], "$EndElementData");
    }
}
