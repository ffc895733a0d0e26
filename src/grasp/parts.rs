//! Procedural CAD parts of real size for the shipped grasp scenes (`scenes/*.stl`).
//!
//! Each part is a signed distance function (negative inside, mm; exact or a Lipschitz-1 bound
//! near the surface) sampled on a regular grid as a linear ramp of one voxel around the zero
//! level and meshed by marching tetrahedra ([`crate::geometry::marching_tetrahedra::isosurface`]), which
//! yields a closed, consistently oriented 2-manifold whenever the grid border is outside.
//! Smooth unions use the polynomial smooth minimum (Quilez 2013, "smooth minimum").
//!
//! Frames: every part stands on z = 0 with its long axis vertical where it has one.

use crate::error::{Error, Result};
use crate::geometry::marching_tetrahedra::{isosurface, Grid, FULL};
use crate::geometry::{Point, TriMesh};

/// The template's bottle grasp from the bottle's side, as a scene's `approach` (translation,
/// mm; rotation, degrees): the palm 12 mm from the side (radius 30), facing its axis, 35 mm
/// toward the wrist so that the axis lies under the distal palm and the fingers wrap
/// horizontally. `synth`'s grasp trials hold the bottle from here.
pub const BOTTLE_SIDE_APPROACH: ([f64; 3], [f64; 3]) = ([-35.0, -42.0, 90.0], [-90.0, -90.0, 0.0]);

/// The five shipped parts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// 60 mm diameter bottle, 200 mm tall, rounded shoulder, 26 mm neck.
    Bottle,
    /// 71 x 147 x 8 mm phone, 8 mm corner radius in plane, 3 mm edge rounding.
    Phone,
    /// 60 x 110 x 38 mm mouse: the upper half of an ellipsoid on a flat base.
    Mouse,
    /// Power drill: 45 x 60 mm elliptic grip 120 mm long, battery below, motor body above.
    Drill,
    /// 9 mm diameter pen, 140 mm long, conical tip.
    Pen,
}

impl Part {
    /// Every shipped part.
    pub const ALL: [Part; 5] = [
        Part::Bottle,
        Part::Phone,
        Part::Mouse,
        Part::Drill,
        Part::Pen,
    ];

    /// File stem of the part and its scene.
    pub fn name(self) -> &'static str {
        match self {
            Part::Bottle => "bottle",
            Part::Phone => "phone",
            Part::Mouse => "mouse",
            Part::Drill => "drill",
            Part::Pen => "pen",
        }
    }

    /// Stated bounding-box size (x, y, z), mm.
    pub(crate) fn size_mm(self) -> [f64; 3] {
        match self {
            Part::Bottle => [60.0, 60.0, 200.0],
            Part::Phone => [71.0, 147.0, 8.0],
            Part::Mouse => [60.0, 110.0, 38.0],
            Part::Drill => [60.0, 200.0, 210.0],
            Part::Pen => [9.0, 9.0, 140.0],
        }
    }

    /// Voxel size used to mesh the part, mm (a few ten thousand triangles each).
    pub fn voxel_mm(self) -> f64 {
        match self {
            Part::Bottle => 2.0,
            Part::Phone => 2.0,
            Part::Mouse => 2.0,
            Part::Drill => 3.5,
            Part::Pen => 1.0,
        }
    }

    /// Signed distance at `p`, mm (negative inside).
    pub fn sdf(self, p: &Point) -> f64 {
        match self {
            Part::Bottle => bottle(p),
            Part::Phone => phone(p),
            Part::Mouse => mouse(p),
            Part::Drill => drill(p),
            Part::Pen => pen(p),
        }
    }

    /// Mesh the part (closed 2-manifold, mm).
    pub fn mesh(self) -> Result<TriMesh> {
        let s = self.size_mm();
        let (lo, hi) = match self {
            Part::Drill => (
                Point::new(-30.0, -40.0, -30.0),
                Point::new(30.0, 160.0, 180.0),
            ),
            _ => (
                Point::new(-s[0] / 2.0, -s[1] / 2.0, 0.0),
                Point::new(s[0] / 2.0, s[1] / 2.0, s[2]),
            ),
        };
        mesh_sdf(|p| self.sdf(p), lo, hi, self.voxel_mm())
    }
}

/// Mesh the zero level of `sdf` inside the box `[lo, hi]` (which must contain the solid) with
/// voxels of `voxel_mm`: occupancy `0.5 - d / voxel` clamped to [0, 1], iso level 0.5.
pub fn mesh_sdf(
    sdf: impl Fn(&Point) -> f64,
    lo: Point,
    hi: Point,
    voxel_mm: f64,
) -> Result<TriMesh> {
    if voxel_mm.is_nan()
        || voxel_mm <= 0.0
        || (0..3).any(|a| hi[a].is_nan() || lo[a].is_nan() || hi[a] <= lo[a])
    {
        return Err(Error::invalid("mesh_sdf: empty box or non-positive voxel"));
    }
    let pad = 3;
    let first: [i64; 3] = std::array::from_fn(|a| (lo[a] / voxel_mm).floor() as i64 - pad);
    let dims: [usize; 3] =
        std::array::from_fn(|a| ((hi[a] / voxel_mm).ceil() as i64 + pad - first[a] + 1) as usize);
    let n = dims[0] * dims[1] * dims[2];
    if n > 50_000_000 {
        return Err(Error::invalid(format!(
            "mesh_sdf: {n} grid nodes is too many; use larger voxels"
        )));
    }
    let mut values = vec![0u16; n];
    for i in 0..dims[0] {
        for j in 0..dims[1] {
            for k in 0..dims[2] {
                let p = Point::new(
                    (first[0] + i as i64) as f64 * voxel_mm,
                    (first[1] + j as i64) as f64 * voxel_mm,
                    (first[2] + k as i64) as f64 * voxel_mm,
                );
                let occ = (0.5 - sdf(&p) / voxel_mm).clamp(0.0, 1.0);
                values[(i * dims[1] + j) * dims[2] + k] = (occ * FULL as f64).round() as u16;
            }
        }
    }
    isosurface(
        &Grid {
            voxel_mm,
            first,
            dims,
            values,
        },
        0.5,
    )
}

/// Polynomial smooth minimum of radius `k` mm.
fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Solid of revolution about z between `z0` and `z1` with radius profile `r(z)`: distance to the
/// side divided by the profile's slope factor (a Lipschitz bound), intersected with the caps.
fn revolved(p: &Point, z0: f64, z1: f64, r: impl Fn(f64) -> f64) -> f64 {
    let z = p.z.clamp(z0, z1);
    let h = 1e-3;
    let slope = (r(z + h) - r(z - h)) / (2.0 * h);
    let side = ((p.x * p.x + p.y * p.y).sqrt() - r(z)) / (1.0 + slope * slope).sqrt();
    side.max(z0 - p.z).max(p.z - z1)
}

fn bottle(p: &Point) -> f64 {
    revolved(p, 0.0, 200.0, |z| {
        if z < 150.0 {
            30.0
        } else if z < 185.0 {
            // Rounded shoulder: a quarter cosine from the body to the neck.
            let t = (z - 150.0) / 35.0;
            13.0 + 17.0 * (0.5 + 0.5 * (std::f64::consts::PI * t).cos())
        } else {
            13.0
        }
    })
}

/// 2-D rounded rectangle of half sizes `(bx, by)` and corner radius `r`.
fn round_rect(x: f64, y: f64, bx: f64, by: f64, r: f64) -> f64 {
    let qx = x.abs() - bx + r;
    let qy = y.abs() - by + r;
    (qx.max(0.0).hypot(qy.max(0.0))) + qx.max(qy).min(0.0) - r
}

/// Extrude a 2-D distance `d2` over `|z - zc| <= h` with edge rounding `r`.
fn extrude_round(d2: f64, z: f64, zc: f64, h: f64, r: f64) -> f64 {
    let wx = d2 + r;
    let wy = (z - zc).abs() - h + r;
    wx.max(0.0).hypot(wy.max(0.0)) + wx.max(wy).min(0.0) - r
}

fn phone(p: &Point) -> f64 {
    extrude_round(round_rect(p.x, p.y, 35.5, 73.5, 8.0), p.z, 4.0, 4.0, 3.0)
}

/// Ellipsoid distance bound (Quilez's k0 (k0 - 1) / k1 approximation).
fn ellipsoid(q: [f64; 3], r: [f64; 3]) -> f64 {
    let k0 = (0..3).map(|a| (q[a] / r[a]).powi(2)).sum::<f64>().sqrt();
    let k1 = (0..3)
        .map(|a| (q[a] / (r[a] * r[a])).powi(2))
        .sum::<f64>()
        .sqrt();
    if k1 < 1e-12 {
        -r.iter().cloned().fold(f64::MAX, f64::min)
    } else {
        k0 * (k0 - 1.0) / k1
    }
}

fn mouse(p: &Point) -> f64 {
    ellipsoid([p.x, p.y, p.z], [30.0, 55.0, 38.0]).max(-p.z)
}

fn drill(p: &Point) -> f64 {
    // Grip: elliptic section 45 (x) by 60 (y), from the battery (z = 0) to the body (z = 130).
    let grip = ellipsoid([p.x, p.y, 0.0], [22.5, 30.0, 1.0])
        .max(-p.z)
        .max(p.z - 130.0);
    // Battery pack below the grip.
    let battery = extrude_round(
        round_rect(p.x, p.y - 10.0, 30.0, 50.0, 8.0),
        p.z,
        -15.0,
        15.0,
        4.0,
    );
    // Motor body: a cylinder of 30 mm radius along y above the grip.
    let body = {
        let rho = p.x.hypot(p.z - 150.0);
        let dr = rho - 30.0;
        let dy = (p.y - 60.0).abs() - 100.0;
        dr.max(0.0).hypot(dy.max(0.0)) + dr.max(dy).min(0.0)
    };
    smin(smin(grip, battery, 6.0), body, 8.0)
}

fn pen(p: &Point) -> f64 {
    revolved(p, 0.0, 140.0, |z| {
        if z < 122.0 {
            4.5
        } else {
            4.5 - 3.5 * (z - 122.0) / 18.0
        }
    })
}

/// What [`clean_part`] removed from a part mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PartCleaning {
    /// Faces using one vertex twice (zero area whatever the coordinates).
    pub degenerate_faces: usize,
    /// Faces on the same three vertices as an earlier face (matched within the weld
    /// tolerance), in either orientation.
    pub repeated_faces: usize,
    /// Vertices no face uses (after the removals).
    pub unused_vertices: usize,
}

impl PartCleaning {
    /// Whether anything was removed.
    pub fn changed(&self) -> bool {
        *self != PartCleaning::default()
    }

    /// One line naming the counts, for the scene's warning.
    pub fn describe(&self) -> String {
        format!(
            "part cleaned before use: {} repeated and {} zero-area triangles and {} unused \
             vertices removed",
            self.repeated_faces, self.degenerate_faces, self.unused_vertices
        )
    }
}

/// Relative weld tolerance of [`clean_part`]: vertices within this fraction of the part's
/// bounding-box diagonal count as one when faces are compared (1e-6: 0.2 um on a 200 mm part,
/// far below any modelled feature, above the rounding of 32-bit STL coordinates).
pub(crate) const WELD_TOLERANCE: f64 = 1e-6;

/// A part mesh as the grasp checks need it: faces repeating an earlier face (the same three
/// vertices once welded within [`WELD_TOLERANCE`] x the diagonal, in either orientation: a
/// doubled or two-sided export) and faces using one vertex twice dropped, then unused vertices
/// removed; everything else kept as it is, in input order, so a clean part comes back
/// unchanged. Repeated triangles otherwise double the contact query's work and the contacts
/// themselves (each contact is found on both copies), which changes the wrench set and so the
/// grasp quality.
///
/// The weld only matches faces; it does not move vertices or drop thin slivers with three
/// distinct vertices: the marching-tetrahedra parts hold thousands of vertices closer than the
/// tolerance and near-zero-area faces, and collapsing those opened the bottle, phone and mouse
/// (they stopped being closed 2-manifolds, which turns the inside tests off).
pub fn clean_part(mesh: &TriMesh) -> (TriMesh, PartCleaning) {
    let tol = WELD_TOLERANCE * mesh.diagonal();
    let (_, remap) = mesh.weld(tol);
    let mut report = PartCleaning::default();
    let mut seen = std::collections::HashSet::new();
    let mut faces = Vec::with_capacity(mesh.faces.len());
    for f in &mesh.faces {
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            report.degenerate_faces += 1;
            continue;
        }
        let mut key = f.map(|i| remap[i]);
        key.sort_unstable();
        // A face that collapses in the weld is a sliver of a fine mesh, not a repeat.
        let collapsed = key[0] == key[1] || key[1] == key[2];
        if !collapsed && !seen.insert(key) {
            report.repeated_faces += 1;
            continue;
        }
        faces.push(*f);
    }
    let mut used = vec![false; mesh.n_vertices()];
    for f in &faces {
        for &i in f {
            used[i] = true;
        }
    }
    let mut index = vec![usize::MAX; mesh.n_vertices()];
    let mut vertices = Vec::with_capacity(mesh.n_vertices());
    for (i, p) in mesh.vertices.iter().enumerate() {
        if used[i] {
            index[i] = vertices.len();
            vertices.push(*p);
        }
    }
    report.unused_vertices = mesh.n_vertices() - vertices.len();
    let cleaned = TriMesh {
        vertices,
        faces: faces.iter().map(|f| f.map(|i| index[i])).collect(),
    };
    (cleaned, report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::stl::{read_stl, write_stl};
    use crate::io::Units;
    use std::path::PathBuf;

    fn scenes_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
    }

    /// Writes the shipped part files; run once with `--ignored` after changing a part.
    #[test]
    #[ignore]
    fn write_shipped_parts() {
        for part in Part::ALL {
            let m = part.mesh().unwrap();
            let path = scenes_dir().join(format!("{}.stl", part.name()));
            write_stl(&path, &m, Units::Millimetres).unwrap();
            eprintln!("{}: {} faces", part.name(), m.n_faces());
        }
    }

    #[test]
    fn shipped_parts_are_closed_manifolds_of_stated_size() {
        for part in Part::ALL {
            let path = scenes_dir().join(format!("{}.stl", part.name()));
            let m = read_stl(&path, Units::Millimetres).unwrap();
            m.check_closed_manifold()
                .unwrap_or_else(|e| panic!("{}: {e}", part.name()));
            assert!(m.signed_volume() > 0.0, "{} is inside out", part.name());
            assert!(
                (2_000..=120_000).contains(&m.n_faces()),
                "{}: {} faces",
                part.name(),
                m.n_faces()
            );
            let (lo, hi) = m.bounds().unwrap();
            let got = hi - lo;
            let tol = part.voxel_mm() + 0.5;
            for a in 0..3 {
                assert!(
                    (got[a] - part.size_mm()[a]).abs() <= tol,
                    "{} axis {a}: {:.1} mm, stated {:.1} mm",
                    part.name(),
                    got[a],
                    part.size_mm()[a]
                );
            }
        }
    }

    #[test]
    fn cleaning_removes_doubles_and_keeps_a_clean_part() {
        let cube = crate::geometry::mesh::tests::cuboid(60.0, 60.0, 200.0);
        let (same, r) = clean_part(&cube);
        assert!(!r.changed(), "{r:?}");
        assert_eq!(same.vertices, cube.vertices);
        assert_eq!(same.faces, cube.faces);
        // Every triangle twice (once flipped, as a two-sided export), a triangle repeated on a
        // copy of a vertex a fraction of a micrometre off, a face using a vertex twice and an
        // unused vertex.
        let mut dirty = cube.clone();
        let n = dirty.n_vertices();
        let [a, b, c] = cube.faces[0];
        dirty
            .vertices
            .push(cube.vertices[a] + nalgebra::Vector3::new(1e-5, 0.0, 0.0));
        dirty.vertices.push(Point::new(500.0, 0.0, 0.0));
        dirty
            .faces
            .extend(cube.faces.iter().map(|&[a, b, c]| [a, c, b]));
        dirty.faces.push([n, b, c]);
        dirty.faces.push([a, b, b]);
        let (clean, r) = clean_part(&dirty);
        assert_eq!(clean.vertices, cube.vertices);
        assert_eq!(clean.faces, cube.faces);
        assert_eq!(
            r,
            PartCleaning {
                degenerate_faces: 1,
                repeated_faces: 13,
                unused_vertices: 2,
            }
        );
        assert!(r.describe().contains("13 repeated"));
    }

    /// The shipped parts are clean: nothing removed, so their grasps are as before.
    #[test]
    fn shipped_parts_come_out_of_cleaning_unchanged() {
        for part in Part::ALL {
            let path = scenes_dir().join(format!("{}.stl", part.name()));
            let m = read_stl(&path, Units::Millimetres).unwrap();
            let (c, r) = clean_part(&m);
            assert!(!r.changed(), "{}: {r:?}", part.name());
            assert_eq!(c.faces, m.faces);
        }
    }

    #[test]
    fn bottle_volume_matches_its_profile() {
        // Independent: the body cylinder alone is pi r^2 h = 424 cm^3; with shoulder and neck a
        // little more; the mesh must enclose between the body and a 200 mm cylinder.
        let m = Part::Bottle.mesh().unwrap();
        let v = m.signed_volume();
        let body = std::f64::consts::PI * 900.0 * 150.0;
        let full = std::f64::consts::PI * 900.0 * 200.0;
        assert!(v > body && v < full, "volume {v}");
    }
}
