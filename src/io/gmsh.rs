//! Gmsh MSH 4.1 ASCII tetrahedral meshes (for FEM users).
//!
//! Format reference: Gmsh reference manual, section 10.1 "MSH file format" (version 4.1):
//! `$MeshFormat` (`4.1 0 8`), `$Entities` (one volume entity, tag 1, with its bounding box),
//! `$Nodes` (one block on that volume: tags 1..n, then coordinates), `$Elements` (one block of
//! element type 4, the 4-node tetrahedron, tags 1..t, 1-based node tags). Gmsh's tetrahedron
//! has positive volume with the node order of [`TetMesh`]. An `$ElementData` view "signed_volume"
//! (the file's unit cubed, negative for an inverted element) follows, as Gmsh reads it for viewing.
//! With [`TetGroups`], physical groups per group (volumes) and per group's boundary (surfaces),
//! see [`write_msh`].

use super::atomic::write_atomic;
use super::Units;
use crate::error::Result;
use crate::geometry::tet_mesh::{TetGroups, TetMesh};
use std::path::Path;

/// Gmsh's element type of the 4-node tetrahedron.
pub(crate) const GMSH_TETRAHEDRON: u32 = 4;

/// Gmsh's element type of the 3-node triangle.
pub(crate) const GMSH_TRIANGLE: u32 = 2;

/// Bounding box of `points` scaled by `s`; zeros when empty.
fn bbox<'a>(points: impl Iterator<Item = &'a crate::geometry::Point>, s: f64) -> [f64; 6] {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] * s);
            hi[k] = hi[k].max(p[k] * s);
        }
    }
    if lo[0] > hi[0] {
        return [0.0; 6];
    }
    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
}

/// Write `mesh` (mm) as Gmsh MSH 4.1 ASCII with coordinates in `units`.
///
/// Without `groups`: one volume entity (tag 1) holding every tetrahedron, element tag `t + 1`
/// for tetrahedron `t`. With `groups`, as a finite-element user meets them in Gmsh: a
/// `$PhysicalNames` section with one 3-D physical group per group that has tetrahedra (tag
/// `id + 1`, named as the group, e.g. `I_PROX`) and one 2-D group per group that has boundary
/// faces (tag `names.len() + id + 1`, named `skin I_PROX`); each is one entity of its own (a
/// volume or a surface, entity tag `id + 1`), its elements in one block. Surface groups per
/// link rather than one `skin`: a load or contact goes on a part of the hand (a finger pad),
/// and a solver unites groups more easily than it splits one. Tetrahedra keep the element
/// tag `t + 1` (the blocks list them by group, so tags are not in file order); the boundary
/// triangles (wound counter-clockwise from outside) follow with tags from `n_tets + 1`. The
/// nodes are one block on the first volume entity. The `signed_volume` view gives every
/// element by tag, 0 for the triangles (they have no volume; meshio refuses a view that
/// leaves elements out).
pub fn write_msh(
    path: &Path,
    mesh: &TetMesh,
    units: Units,
    groups: Option<&TetGroups>,
) -> Result<()> {
    if let Some(g) = groups {
        g.check(mesh).map_err(|e| e.in_file(path))?;
    }
    let s = 1.0 / units.to_mm();
    let (n, t) = (mesh.n_nodes(), mesh.n_tets());
    // Per entity: (tag, bounding box, physical tag, element indices).
    type Entity = (usize, [f64; 6], Option<usize>, Vec<usize>);
    // Per physical group: (dimension, tag, name).
    type Named = (u8, usize, String);
    let (volumes, surfaces, names): (Vec<Entity>, Vec<Entity>, Vec<Named>) = match groups {
        None => (
            vec![(1, bbox(mesh.nodes.iter(), s), None, (0..t).collect())],
            Vec::new(),
            Vec::new(),
        ),
        Some(g) => {
            let ng = g.names.len();
            let mut by_tets = vec![Vec::new(); ng];
            for (e, &id) in g.tet_group.iter().enumerate() {
                by_tets[id as usize].push(e);
            }
            let mut by_faces = vec![Vec::new(); ng];
            for (k, (_, id)) in g.boundary.iter().enumerate() {
                by_faces[*id as usize].push(k);
            }
            let mut names = Vec::new();
            let mut vols = Vec::new();
            let mut surfs = Vec::new();
            for (id, tets) in by_tets.into_iter().enumerate() {
                if tets.is_empty() {
                    continue;
                }
                let b = bbox(
                    tets.iter()
                        .flat_map(|&e| mesh.tets[e].iter().map(|&v| &mesh.nodes[v])),
                    s,
                );
                names.push((3, id + 1, g.names[id].clone()));
                vols.push((id + 1, b, Some(id + 1), tets));
            }
            for (id, faces) in by_faces.into_iter().enumerate() {
                if faces.is_empty() {
                    continue;
                }
                let b = bbox(
                    faces
                        .iter()
                        .flat_map(|&k| g.boundary[k].0.iter().map(|&v| &mesh.nodes[v])),
                    s,
                );
                names.push((2, ng + id + 1, format!("skin {}", g.names[id])));
                surfs.push((id + 1, b, Some(ng + id + 1), faces));
            }
            (vols, surfs, names)
        }
    };
    let boundary: &[([usize; 3], u32)] = groups.map_or(&[], |g| &g.boundary);
    let b = boundary.len();
    let first_volume = volumes.first().map_or(1, |v| v.0);
    write_atomic(path, |w| {
        writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
        if !names.is_empty() {
            writeln!(w, "$PhysicalNames\n{}", names.len())?;
            for (dim, tag, name) in &names {
                writeln!(w, "{dim} {tag} \"{}\"", name.replace('"', "'"))?;
            }
            writeln!(w, "$EndPhysicalNames")?;
        }
        writeln!(w, "$Entities\n0 0 {} {}", surfaces.len(), volumes.len())?;
        for (tag, bb, phys, _) in surfaces.iter().chain(&volumes) {
            write!(
                w,
                "{tag} {:?} {:?} {:?} {:?} {:?} {:?} ",
                bb[0], bb[1], bb[2], bb[3], bb[4], bb[5]
            )?;
            match phys {
                Some(p) => writeln!(w, "1 {p} 0")?,
                None => writeln!(w, "0 0")?,
            }
        }
        writeln!(w, "$EndEntities")?;
        writeln!(w, "$Nodes\n1 {n} 1 {n}\n3 {first_volume} 0 {n}")?;
        for i in 1..=n {
            writeln!(w, "{i}")?;
        }
        for p in &mesh.nodes {
            writeln!(w, "{:?} {:?} {:?}", p.x * s, p.y * s, p.z * s)?;
        }
        writeln!(w, "$EndNodes")?;
        writeln!(
            w,
            "$Elements\n{} {} 1 {}",
            volumes.len() + surfaces.len(),
            t + b,
            t + b
        )?;
        for (tag, _, _, tets) in &volumes {
            writeln!(w, "3 {tag} {GMSH_TETRAHEDRON} {}", tets.len())?;
            for &e in tets {
                let q = mesh.tets[e];
                writeln!(
                    w,
                    "{} {} {} {} {}",
                    e + 1,
                    q[0] + 1,
                    q[1] + 1,
                    q[2] + 1,
                    q[3] + 1
                )?;
            }
        }
        for (tag, _, _, faces) in &surfaces {
            writeln!(w, "2 {tag} {GMSH_TRIANGLE} {}", faces.len())?;
            for &k in faces {
                let f = boundary[k].0;
                writeln!(w, "{} {} {} {}", t + k + 1, f[0] + 1, f[1] + 1, f[2] + 1)?;
            }
        }
        writeln!(w, "$EndElements")?;
        // Signed, so that an inverted element shows (negative); in the file's unit cubed.
        // Triangles get 0 (they hold no volume): meshio refuses element data that covers only
        // some of the elements.
        writeln!(
            w,
            "$ElementData\n1\n\"signed_volume\"\n1\n0.0\n3\n0\n1\n{}",
            t + b
        )?;
        for e in 0..t {
            writeln!(w, "{} {:e}", e + 1, mesh.tet_volume(e) * s * s * s)?;
        }
        for k in 0..b {
            writeln!(w, "{} 0", t + k + 1)?;
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
        write_msh(&p, &m, Units::Centimetres, None).unwrap();
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

    /// With groups, read back by the format's grammar: the physical names (3-D per group, 2-D
    /// `skin` per group), one entity per physical group, every tetrahedron once under its
    /// tag `t + 1` in its group's block, the 12 boundary triangles after them, and the volume
    /// view still indexing the tetrahedra.
    #[test]
    fn groups_become_physical_groups() {
        let (m, g) = crate::io::vtk::tests::grouped_cube();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.msh");
        write_msh(&p, &m, Units::Millimetres, Some(&g)).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let at = |s: &str| lines.iter().position(|l| *l == s).unwrap();
        let pn = at("$PhysicalNames");
        assert_eq!(
            &lines[pn + 1..pn + 6],
            &[
                "4",
                "3 1 \"A\"",
                "3 2 \"B\"",
                "2 3 \"skin A\"",
                "2 4 \"skin B\""
            ]
        );
        let ent = at("$Entities");
        assert_eq!(lines[ent + 1], "0 0 2 2");
        let phys: Vec<(usize, usize)> = lines[ent + 2..ent + 6]
            .iter()
            .map(|l| {
                let v: Vec<&str> = l.split(' ').collect();
                (v[0].parse().unwrap(), v[8].parse().unwrap())
            })
            .collect();
        assert_eq!(phys, vec![(1, 3), (2, 4), (1, 1), (2, 2)]);
        let el = at("$Elements");
        assert_eq!(lines[el + 1], "4 18 1 18");
        let mut seen = [0usize; 18];
        let mut k = el + 2;
        let mut faces = 0;
        while lines[k] != "$EndElements" {
            let h: Vec<usize> = lines[k].split(' ').map(|x| x.parse().unwrap()).collect();
            let (dim, entity, ty, count) = (h[0], h[1], h[2], h[3]);
            for line in &lines[k + 1..k + 1 + count] {
                let v: Vec<usize> = line.split(' ').map(|x| x.parse().unwrap()).collect();
                seen[v[0] - 1] += 1;
                if dim == 3 {
                    assert_eq!(ty, 4);
                    let e = v[0] - 1;
                    assert_eq!(g.tet_group[e] as usize + 1, entity);
                    assert_eq!(&v[1..], &m.tets[e].map(|i| i + 1));
                } else {
                    assert_eq!((dim, ty), (2, 2));
                    let (f, id) = g.boundary[v[0] - 7];
                    assert_eq!(id as usize + 1, entity);
                    assert_eq!(&v[1..], &f.map(|i| i + 1));
                    faces += 1;
                }
            }
            k += count + 1;
        }
        assert_eq!(faces, 12);
        assert!(seen.iter().all(|&n| n == 1));
        let data = at("$ElementData");
        assert_eq!(lines[data + 8], "18");
        assert!(lines[data + 9].starts_with("1 "));
        assert_eq!(
            lines[data + 15..data + 27],
            (7..=18).map(|e| format!("{e} 0")).collect::<Vec<_>>()
        );
    }
}
