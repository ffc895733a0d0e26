//! Simulated CT of a plaster cast: the CT-like reference surface of a synthetic subject.
//!
//! A CT does not see the triangles of the cast's surface; it sees the material's density
//! averaged over each voxel (the partial-volume effect), and the surface a segmentation tool
//! gives back is an isosurface of that density at half the material's value. This module does
//! the same to a closed [`TriMesh`]:
//!
//! 1. [`occupancy`]: the fraction of every voxel that lies inside the surface, computed exactly
//!    along z and by a k x k midpoint rule across x and y (k x k parallel rays per voxel column,
//!    each clipped against the surface with a watertight, winding-number ray cast);
//! 2. [`isosurface`]: the 0.5 level set of the trilinearly sampled field, by marching tetrahedra
//!    on the Kuhn (Freudenthal) triangulation of the grid, which makes it closed and 2-manifold.
//!
//! [`ct_surface`] chains the two. No smoothing is applied: a CT does not smooth either, and the
//! reference must share neither vertices nor connectivity with the mesh it was scanned from.

use crate::error::{Error, Result};
pub use crate::geometry::marching_tetrahedra::{isosurface, Grid, FULL};
use crate::geometry::{Point, TriMesh};
use rayon::prelude::*;

/// Rays per voxel column along x and along y used by [`ct_surface`]. Even, so that a face lying
/// exactly on a grid plane through voxel centres covers exactly half of each sub-ray set.
pub(crate) const DEFAULT_SUB_RAYS: usize = 4;

/// Empty voxel layers added around the surface's bounding box on every side; two keep every
/// voxel that can touch the surface away from the grid boundary, so the isosurface is closed.
pub const PADDING: i64 = 2;

/// Largest grid [`occupancy`] will allocate (2^28 nodes, 512 MiB of occupancy values). A hand
/// of 190 x 100 x 90 mm needs 1.5e7 nodes at 0.5 mm and 1.1e8 at 0.25 mm.
pub(crate) const MAX_NODES: usize = 1 << 28;

/// Sub-ray retries with a different jitter when a ray's winding number does not return to zero
/// (which, for a watertight mesh, only floating-point rounding at a vertex can cause).
const RAY_ATTEMPTS: usize = 4;

/// Simulated CT of a closed surface: partial-volume occupancy on a regular grid of `voxel_mm`
/// voxels ([`occupancy`] with [`DEFAULT_SUB_RAYS`]), then its 0.5 isosurface ([`isosurface`]).
///
/// Input: a closed, consistently oriented mesh in mm (self-overlapping parts count once, as in a
/// cast; see [`occupancy`]). Output: a closed, 2-manifold, outward-oriented mesh in mm whose
/// vertices lie on the grid's edges, so it shares nothing with the input but its shape.
/// Errors: a non-positive voxel, an open surface, a grid larger than [`MAX_NODES`], or a surface
/// too thin to fill half of any voxel.
///
/// What to expect, as from a real CT: smooth parts come back within about 0.4 voxel (linear
/// interpolation of the voxel-averaged density along the grid's diagonals is not exact), the
/// enclosed volume within a few hundredths of a percent (errors of either sign cancel), sharp
/// convex edges rounded by up to a voxel, and about 8 triangles per voxel face's worth of area
/// (marching tetrahedra makes many small, some sliver-shaped, triangles): 1.5 million for a hand
/// at 0.5 mm.
pub fn ct_surface(mesh: &TriMesh, voxel_mm: f64) -> Result<TriMesh> {
    let grid = occupancy(mesh, voxel_mm, DEFAULT_SUB_RAYS)?;
    let surface = isosurface(&grid, 0.5)?;
    if surface.faces.is_empty() {
        return Err(Error::invalid(format!(
            "CT scan: the surface fills no voxel of {voxel_mm} mm to half; use smaller voxels"
        )));
    }
    Ok(surface)
}

/// Partial-volume occupancy of the solid bounded by `mesh` on a grid of `voxel_mm` voxels.
///
/// Method: for every voxel column (x, y) cast `sub_rays` x `sub_rays` rays along +z at the
/// midpoints of a regular sub-grid of the column's cross-section (the midpoint rule across x and
/// y), each shifted by an irrational ~1e-3 voxel so that rays rarely pass exactly through a
/// vertex or along an edge. Each ray is intersected with every triangle whose xy bounding box it
/// may cross (triangles bucketed by column); the point-in-triangle test evaluates each edge's
/// orientation predicate once per edge, with the endpoints in index order, and breaks exact
/// zeros by a symbolic perturbation of the ray (Edelsbrunner & Mücke 1990, "Simulation of
/// Simplicity"), so a ray through an edge or vertex crosses exactly one of the faces there (or
/// an entering and a leaving one), which makes the cast watertight (cf. Woop, Benthin & Wald
/// 2013, "Watertight ray/triangle intersection"). Crossings are sorted along the ray and summed
/// into a winding number; the ray is inside where it is non-zero (so overlapping parts of a
/// self-intersecting surface count once, and an inward-oriented mesh gives the same result).
/// A voxel's value is the mean over its column's rays of the fraction of its z extent inside,
/// exact along z. The grid covers the mesh's bounding box plus [`PADDING`] empty voxels.
///
/// Requires a closed mesh: every edge must be traversed as often in one direction as in the
/// other (2-manifoldness is not needed). `sub_rays` must be in 1..=16; even values are best.
/// Deterministic: columns are independent and written in place, in parallel.
pub fn occupancy(mesh: &TriMesh, voxel_mm: f64, sub_rays: usize) -> Result<Grid> {
    if !(voxel_mm.is_finite() && voxel_mm > 0.0) {
        return Err(Error::invalid(format!(
            "CT scan: voxel size {voxel_mm} mm is not a positive number"
        )));
    }
    if !(1..=16).contains(&sub_rays) {
        return Err(Error::invalid(format!(
            "CT scan: {sub_rays} sub-rays per voxel side is outside 1..=16"
        )));
    }
    if mesh.faces.is_empty() {
        return Err(Error::invalid("CT scan: the surface has no faces"));
    }
    if let Some(v) = mesh
        .vertices
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(format!(
            "CT scan: vertex {v} has a non-finite coordinate"
        )));
    }
    check_watertight(mesh)?;
    let h = voxel_mm;
    let (lo, hi) = face_bounds(mesh);
    let mut first = [0i64; 3];
    let mut dims = [0usize; 3];
    for a in 0..3 {
        let (l, u) = (lo[a] / h, hi[a] / h);
        if !(l.abs() < 1e15 && u.abs() < 1e15) {
            return Err(Error::invalid(format!(
                "CT scan: the surface spans {} to {} mm along {}, too far for {h} mm voxels",
                lo[a],
                hi[a],
                ["x", "y", "z"][a]
            )));
        }
        first[a] = l.floor() as i64 - PADDING;
        let last = u.ceil() as i64 + PADDING;
        dims[a] = usize::try_from(last - first[a] + 1).unwrap_or(usize::MAX);
    }
    let nodes = dims[0]
        .checked_mul(dims[1])
        .and_then(|n| n.checked_mul(dims[2]))
        .filter(|&n| n <= MAX_NODES)
        .ok_or_else(|| {
            Error::invalid(format!(
                "CT scan: a grid of {} x {} x {} voxels of {h} mm over a {:.1} x {:.1} x {:.1} mm \
                 surface exceeds the limit of {MAX_NODES} voxels; use larger voxels",
                dims[0],
                dims[1],
                dims[2],
                hi[0] - lo[0],
                hi[1] - lo[1],
                hi[2] - lo[2]
            ))
        })?;
    let [nx, ny, nz] = dims;

    // Bucket triangles by the voxel columns whose rays their xy bounding box may meet. A column
    // spans [(c - 1/2) h, (c + 1/2) h); its rays lie strictly inside (at least h/32 from the
    // border, jitter included), so a margin of h/100 keeps every candidate.
    let margin = 0.01 * h;
    let col_of = |x: f64, axis: usize| -> usize {
        let c = (x / h + 0.5).floor() as i64 - first[axis];
        c.clamp(0, dims[axis] as i64 - 1) as usize
    };
    let face_cols: Vec<[usize; 4]> = mesh
        .faces
        .iter()
        .map(|f| {
            let p = f.map(|v| mesh.vertices[v]);
            let (x0, x1) = (
                p[0].x.min(p[1].x).min(p[2].x),
                p[0].x.max(p[1].x).max(p[2].x),
            );
            let (y0, y1) = (
                p[0].y.min(p[1].y).min(p[2].y),
                p[0].y.max(p[1].y).max(p[2].y),
            );
            [
                col_of(x0 - margin, 0),
                col_of(x1 + margin, 0),
                col_of(y0 - margin, 1),
                col_of(y1 + margin, 1),
            ]
        })
        .collect();
    let mut start = vec![0usize; nx * ny + 1];
    for &[i0, i1, j0, j1] in &face_cols {
        for i in i0..=i1 {
            for j in j0..=j1 {
                start[i * ny + j + 1] += 1;
            }
        }
    }
    for c in 0..nx * ny {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut bucket = vec![0u32; start[nx * ny]];
    for (f, &[i0, i1, j0, j1]) in face_cols.iter().enumerate() {
        for i in i0..=i1 {
            for j in j0..=j1 {
                bucket[fill[i * ny + j]] = f as u32;
                fill[i * ny + j] += 1;
            }
        }
    }
    drop(face_cols);
    drop(fill);

    let mut values = vec![0u16; nodes];
    let failures: Vec<Option<(f64, f64)>> = values
        .par_chunks_mut(nz)
        .enumerate()
        .map_init(
            || ColumnScratch::new(nz),
            |scratch, (c, column)| {
                let (i, j) = (c / ny, c % ny);
                let candidates = &bucket[start[c]..start[c + 1]];
                if candidates.is_empty() {
                    return None;
                }
                let gx = (first[0] + i as i64) as f64;
                let gy = (first[1] + j as i64) as f64;
                scan_column(
                    mesh,
                    candidates,
                    [gx, gy],
                    first[2],
                    h,
                    sub_rays,
                    scratch,
                    column,
                )
            },
        )
        .collect();
    if let Some((x, y)) = failures.into_iter().flatten().next() {
        return Err(Error::invalid(format!(
            "CT scan: the ray along z at x = {x:.4} mm, y = {y:.4} mm leaves the surface more \
             often than it enters it; the surface is not watertight there"
        )));
    }
    Ok(Grid {
        voxel_mm: h,
        first,
        dims,
        values,
    })
}

/// Reusable buffers of one worker: coverage accumulators of a column and the crossings of a ray.
struct ColumnScratch {
    /// Partial coverage added to single voxels.
    partial: Vec<f64>,
    /// Difference array of whole-voxel coverage (prefix sums give the coverage).
    steps: Vec<f64>,
    /// Crossings of the current ray: height and winding change.
    hits: Vec<(f64, i32)>,
}

impl ColumnScratch {
    fn new(nz: usize) -> Self {
        ColumnScratch {
            partial: vec![0.0; nz + 1],
            steps: vec![0.0; nz + 1],
            hits: Vec::new(),
        }
    }
}

/// Fill one voxel column (lattice x, y = `g`) with the mean inside fraction of its
/// `sub_rays`² rays; returns the position of a ray that could not be closed, if any.
#[allow(clippy::too_many_arguments)]
fn scan_column(
    mesh: &TriMesh,
    candidates: &[u32],
    g: [f64; 2],
    first_z: i64,
    h: f64,
    sub_rays: usize,
    s: &mut ColumnScratch,
    column: &mut [u16],
) -> Option<(f64, f64)> {
    let nz = column.len();
    let k = sub_rays as f64;
    let weight = 1.0 / (k * k);
    let mut failure = None;
    for a in 0..sub_rays {
        for b in 0..sub_rays {
            let mut closed = false;
            let (mut x, mut y) = (0.0, 0.0);
            for attempt in 0..RAY_ATTEMPTS {
                let (jx, jy) = jitter(attempt);
                x = (g[0] - 0.5 + (a as f64 + 0.5) / k + jx) * h;
                y = (g[1] - 0.5 + (b as f64 + 0.5) / k + jy) * h;
                s.hits.clear();
                for &f in candidates {
                    if let Some(hit) = ray_crossing(mesh, mesh.faces[f as usize], x, y) {
                        s.hits.push(hit);
                    }
                }
                s.hits
                    .sort_unstable_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
                if s.hits.iter().map(|hit| hit.1).sum::<i32>() == 0 {
                    closed = true;
                    break;
                }
            }
            if !closed {
                failure.get_or_insert((x, y));
                continue;
            }
            // Sweep the crossings: the ray is inside where the winding number is non-zero.
            let mut winding = 0;
            let mut enter = 0.0;
            for &(z, dw) in &s.hits {
                let before = winding;
                winding += dw;
                if before == 0 && winding != 0 {
                    enter = z;
                } else if before != 0 && winding == 0 {
                    // Voxel k spans [k, k+1) in these coordinates.
                    let u0 = (enter / h - first_z as f64 + 0.5).clamp(0.0, nz as f64);
                    let u1 = (z / h - first_z as f64 + 0.5).clamp(0.0, nz as f64);
                    add_coverage(&mut s.partial, &mut s.steps, u0, u1, weight);
                }
            }
        }
    }
    let mut whole = 0.0;
    for (kz, v) in column.iter_mut().enumerate() {
        whole += s.steps[kz];
        let fraction = (s.partial[kz] + whole).clamp(0.0, 1.0);
        *v = (fraction * FULL as f64).round() as u16;
    }
    s.partial.fill(0.0);
    s.steps.fill(0.0);
    failure
}

/// Sub-ray offset of retry `attempt`, in voxels: small irrational fractions (multiples of
/// sqrt 2 - 1, sqrt 3 - 1, sqrt 5 - 2, pi - 3, all below 2e-3) so rays avoid the rational
/// coordinates of modelled geometry, and a retried ray moves off whatever it grazed.
fn jitter(attempt: usize) -> (f64, f64) {
    let r = attempt as f64;
    (
        1e-3 * (std::f64::consts::SQRT_2 - 1.0 + r * (5f64.sqrt() - 2.0)),
        1e-3 * (3f64.sqrt() - 1.0 + r * (std::f64::consts::PI - 3.0)),
    )
}

/// Add `weight` times the covered part of `[u0, u1]` (in voxel units, voxel k = `[k, k+1)`) to a
/// column: end voxels into `partial`, the run of whole voxels as two steps in `steps`.
fn add_coverage(partial: &mut [f64], steps: &mut [f64], u0: f64, u1: f64, weight: f64) {
    if u1 <= u0 {
        return;
    }
    let last = partial.len() - 1;
    let k0 = (u0.floor() as usize).min(last);
    let k1 = (u1.floor() as usize).min(last);
    if k0 == k1 {
        partial[k0] += (u1 - u0) * weight;
    } else {
        partial[k0] += (k0 as f64 + 1.0 - u0) * weight;
        steps[k0 + 1] += weight;
        steps[k1] -= weight;
        partial[k1] += (u1 - k1 as f64) * weight;
    }
}

/// Orientation of ray point `(x, y)` relative to the xy projection of edge `u -> v` (twice the
/// signed area of `u, v, p`), and its sign with exact zeros broken by the perturbation
/// `p + (e, e²)` (Simulation of Simplicity); sign 0 only for an edge that projects to a point.
#[inline]
fn edge_orientation(u: &Point, v: &Point, x: f64, y: f64) -> (f64, i32) {
    let (dx, dy) = (v.x - u.x, v.y - u.y);
    let e = dx * (y - u.y) - dy * (x - u.x);
    let sign = if e > 0.0 {
        1
    } else if e < 0.0 {
        -1
    } else if dy != 0.0 {
        if dy > 0.0 {
            -1
        } else {
            1
        }
    } else if dx > 0.0 {
        1
    } else if dx < 0.0 {
        -1
    } else {
        0
    };
    (e, sign)
}

/// The crossing of the +z ray through `(x, y)` with triangle `face`: its height and the change
/// of winding number (-1 leaving through a face whose normal points up, +1 entering), or
/// `None`. Each edge is evaluated with its endpoints in index order, so the faces on either side
/// of an edge see the very same predicate value and a ray never slips between them.
#[inline]
fn ray_crossing(mesh: &TriMesh, face: [usize; 3], x: f64, y: f64) -> Option<(f64, i32)> {
    let p = &mesh.vertices;
    let oriented = |a: usize, b: usize| {
        if a < b {
            edge_orientation(&p[a], &p[b], x, y)
        } else {
            let (e, s) = edge_orientation(&p[b], &p[a], x, y);
            (-e, -s)
        }
    };
    let [a, b, c] = face;
    let (w_c, s_ab) = oriented(a, b);
    if s_ab == 0 {
        return None;
    }
    let (w_a, s_bc) = oriented(b, c);
    if s_bc != s_ab {
        return None;
    }
    let (w_b, s_ca) = oriented(c, a);
    if s_ca != s_ab {
        return None;
    }
    let (za, zb, zc) = (p[a].z, p[b].z, p[c].z);
    let (z_lo, z_hi) = (za.min(zb).min(zc), za.max(zb).max(zc));
    let total = w_a + w_b + w_c;
    let z = (w_a * za + w_b * zb + w_c * zc) / total;
    // A sliver seen edge-on can make the weights vanish; the crossing still counts, at a height
    // inside the triangle.
    let z = if z.is_finite() {
        z.clamp(z_lo, z_hi)
    } else {
        (za + zb + zc) / 3.0
    };
    // Counter-clockwise seen from +z means an upward normal: the ray leaves the solid there.
    Some((z, -s_ab))
}

/// Bounding box of the vertices used by faces.
fn face_bounds(mesh: &TriMesh) -> (Point, Point) {
    let first = mesh.vertices[mesh.faces[0][0]];
    mesh.faces
        .iter()
        .flatten()
        .fold((first, first), |(lo, hi), &v| {
            (lo.inf(&mesh.vertices[v]), hi.sup(&mesh.vertices[v]))
        })
}

/// Error unless every edge is traversed as often from a to b as from b to a, the condition
/// under which the winding number of a closed oriented surface is well defined.
fn check_watertight(mesh: &TriMesh) -> Result<()> {
    let n = mesh.vertices.len();
    let mut directed: Vec<(usize, usize, i32)> = Vec::with_capacity(mesh.faces.len() * 3);
    for (fi, f) in mesh.faces.iter().enumerate() {
        if let Some(&v) = f.iter().find(|&&v| v >= n) {
            return Err(Error::invalid(format!(
                "CT scan: face {fi} names vertex {v}, but the surface has {n} vertices"
            )));
        }
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            directed.push(if a < b { (a, b, 1) } else { (b, a, -1) });
        }
    }
    directed.sort_unstable();
    for run in directed.chunk_by(|p, q| p.0 == q.0 && p.1 == q.1) {
        let forward = run.iter().filter(|e| e.2 > 0).count();
        let backward = run.len() - forward;
        if forward != backward {
            let (a, b) = (run[0].0, run[0].1);
            return Err(Error::invalid(format!(
                "CT scan: the surface is not closed: edge ({a}, {b}) is used {forward} time(s) \
                 from {a} to {b} but {backward} time(s) from {b} to {a}; weld and close the mesh first"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;
    use crate::geometry::Vec3;

    use crate::geometry::mesh::tests::{icosphere, torus};

    fn translated(mesh: &TriMesh, d: Vec3) -> TriMesh {
        TriMesh::new(
            mesh.vertices.iter().map(|p| p + d).collect(),
            mesh.faces.clone(),
        )
        .unwrap()
    }

    fn union(a: &TriMesh, b: &TriMesh) -> TriMesh {
        let n = a.n_vertices();
        let mut v = a.vertices.clone();
        v.extend(&b.vertices);
        let mut f = a.faces.clone();
        f.extend(b.faces.iter().map(|t| t.map(|x| x + n)));
        TriMesh::new(v, f).unwrap()
    }

    fn relative_error(got: f64, want: f64) -> f64 {
        (got - want).abs() / want.abs()
    }

    #[test]
    fn rays_through_edges_and_vertices_cross_once() {
        // Octahedron with vertices on the axes: rays along z exactly through its top and bottom
        // vertices, through its edges, and along its silhouette.
        let p = |x: f64, y: f64, z: f64| Point::new(x, y, z);
        let octa = TriMesh::new(
            vec![
                p(1., 0., 0.),
                p(0., 1., 0.),
                p(-1., 0., 0.),
                p(0., -1., 0.),
                p(0., 0., 1.),
                p(0., 0., -1.),
            ],
            vec![
                [0, 1, 4],
                [1, 2, 4],
                [2, 3, 4],
                [3, 0, 4],
                [1, 0, 5],
                [2, 1, 5],
                [3, 2, 5],
                [0, 3, 5],
            ],
        )
        .unwrap();
        assert!(octa.signed_volume() > 0.0);
        for (x, y) in [
            (0.0, 0.0),
            (0.5, 0.0),
            (0.0, -0.5),
            (-0.25, 0.0),
            (0.25, 0.25),
            (0.3, 0.2),
        ] {
            let hits: Vec<(f64, i32)> = octa
                .faces
                .iter()
                .filter_map(|&f| ray_crossing(&octa, f, x, y))
                .collect();
            let entering = hits.iter().filter(|h| h.1 == 1).count();
            let leaving = hits.iter().filter(|h| h.1 == -1).count();
            assert_eq!((entering, leaving), (1, 1), "ray at ({x}, {y}): {hits:?}");
            let depth = 1.0 - x.abs() - y.abs();
            for (z, dw) in hits {
                assert!(
                    (z - depth * -(dw as f64)).abs() < 1e-12,
                    "ray at ({x}, {y}) crosses at {z}"
                );
            }
        }
        // Grazing the equator at a vertex or along an edge: no crossing, or an enter-leave pair.
        for (x, y) in [
            (1.0, 0.0),
            (0.0, 1.0),
            (0.5, 0.5),
            (0.5, -0.5),
            (-0.75, 0.25),
        ] {
            let hits: Vec<i32> = octa
                .faces
                .iter()
                .filter_map(|&f| ray_crossing(&octa, f, x, y))
                .map(|h| h.1)
                .collect();
            assert_eq!(hits.iter().sum::<i32>(), 0, "ray at ({x}, {y}): {hits:?}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

        /// Any placement of a sphere in the grid: closed, genus 0, and the volume kept.
        #[test]
        fn any_placement_scans_closed(
            dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0,
            ax in -3.2f64..3.2, ay in -3.2f64..3.2, az in -3.2f64..3.2,
        ) {
            let rot = nalgebra::Rotation3::from_euler_angles(ax, ay, az);
            let base = icosphere(5.0, 2);
            let sphere = TriMesh::new(
                base.vertices.iter().map(|p| rot * p + Vec3::new(dx, dy, dz)).collect(),
                base.faces.clone(),
            ).unwrap();
            let want = sphere.signed_volume();
            let grid = occupancy(&sphere, 0.5, DEFAULT_SUB_RAYS).unwrap();
            proptest::prop_assert!(relative_error(grid.volume(), want) < 1e-3);
            let scan = isosurface(&grid, 0.5).unwrap();
            proptest::prop_assert!(scan.check_closed_manifold().is_ok());
            proptest::prop_assert_eq!(scan.topology().euler_characteristic(), 2);
            proptest::prop_assert!(relative_error(scan.signed_volume(), want) < 0.01);
        }
    }

    #[test]
    fn sphere_scan_is_closed_accurate_and_near_the_surface() {
        let sphere = icosphere(20.0, 4);
        let h = 0.5;
        let grid = occupancy(&sphere, h, DEFAULT_SUB_RAYS).unwrap();
        let want = sphere.signed_volume();
        // The partial volumes alone measure the enclosed volume (quadrature only across x, y).
        assert!(
            relative_error(grid.volume(), want) < 1e-4,
            "grid {} vs {want}",
            grid.volume()
        );
        let scan = isosurface(&grid, 0.5).unwrap();
        scan.check_closed_manifold().unwrap();
        let topo = scan.topology();
        assert_eq!(topo.euler_characteristic(), 2);
        assert_eq!(topo.face_components().1, 1);
        let got = scan.signed_volume();
        assert!(relative_error(got, want) < 0.005, "volume {got} vs {want}");
        // Every vertex between the polyhedron's inscribed and circumscribed spheres, widened by
        // the tolerance; the inscribed radius is the smallest distance to a face plane.
        let r_in = (0..sphere.n_faces())
            .map(|f| {
                let n = sphere.face_cross(f).normalize();
                sphere.corners(f)[0].coords.dot(&n)
            })
            .fold(f64::INFINITY, f64::min);
        let tol = 0.1 + h / 4.0;
        for (i, p) in scan.vertices.iter().enumerate() {
            let r = p.coords.norm();
            assert!(r > r_in - tol && r < 20.0 + tol, "vertex {i} at radius {r}");
        }
        // Nothing shared with the input: no output vertex coincides with an input vertex.
        let input_radius_vertices = scan
            .vertices
            .iter()
            .filter(|p| sphere.vertices.iter().any(|q| (*p - q).norm() < 1e-9))
            .count();
        assert_eq!(input_radius_vertices, 0);
    }

    #[test]
    fn torus_scan_has_genus_one() {
        let t = torus(12.0, 4.0, 64, 24);
        let scan = ct_surface(&t, 0.5).unwrap();
        scan.check_closed_manifold().unwrap();
        let topo = scan.topology();
        assert_eq!(topo.euler_characteristic(), 0);
        assert_eq!(topo.face_components().1, 1);
        assert!(relative_error(scan.signed_volume(), t.signed_volume()) < 0.01);
    }

    #[test]
    fn box_on_grid_planes_keeps_its_volume() {
        // Faces exactly on node planes (the value there is exactly one half), then exactly on
        // voxel boundaries (half-way between nodes): both degenerate for rays and for the level.
        let h = 0.5;
        let (a, b, c) = (40.0, 30.0, 20.0);
        let (volume, edge_length) = (a * b * c, 4.0 * (a + b + c));
        for shift in [0.0, h / 2.0] {
            let cube = translated(
                &cuboid(a, b, c),
                Vec3::new(-3.0 + shift, 2.0 + shift, 5.0 + shift),
            );
            let grid = occupancy(&cube, h, DEFAULT_SUB_RAYS).unwrap();
            // Exact but for quantisation: at most half a step per partially filled voxel.
            let partial = grid.values.iter().filter(|&&v| v != 0 && v != FULL).count();
            let quantisation = partial as f64 * 0.5 / FULL as f64 * h.powi(3);
            assert!(
                (grid.volume() - volume).abs() <= quantisation + 1e-9,
                "grid volume {}",
                grid.volume()
            );
            let scan = isosurface(&grid, 0.5).unwrap();
            scan.check_closed_manifold().unwrap();
            assert_eq!(scan.topology().euler_characteristic(), 2);
            // The faces come back where they were...
            let (lo, hi) = scan.bounds().unwrap();
            let (blo, bhi) = cube.bounds().unwrap();
            assert!(
                (lo - blo).norm() < 1e-3 && (hi - bhi).norm() < 1e-3,
                "bounds {lo} {hi}"
            );
            // ...but, as in a real CT, partial volume rounds the sharp edges: the level cuts off
            // at most a right triangle with legs of one voxel along each edge (h²/2 per mm), and
            // never adds volume.
            let loss = volume - scan.signed_volume();
            assert!(
                loss > -1e-3 && loss <= edge_length * h * h / 2.0,
                "shift {shift}: volume lost {loss}"
            );
            assert!(loss / volume < 0.003, "volume lost {loss}");
        }
    }

    #[test]
    fn two_spheres_give_two_components() {
        let a = icosphere(5.0, 2);
        let b = translated(&a, Vec3::new(12.0, 3.0, -2.0));
        let scan = ct_surface(&union(&a, &b), 0.5).unwrap();
        scan.check_closed_manifold().unwrap();
        let topo = scan.topology();
        assert_eq!(topo.face_components().1, 2);
        assert_eq!(topo.euler_characteristic(), 4);
    }

    #[test]
    fn overlapping_parts_count_once_and_orientation_does_not_matter() {
        // Two interpenetrating spheres: the union (winding number non-zero), one component.
        let a = icosphere(6.0, 3);
        let b = translated(&a, Vec3::new(6.0, 0.0, 0.0));
        let grid = occupancy(&union(&a, &b), 0.5, DEFAULT_SUB_RAYS).unwrap();
        // Volume of the union of two balls of radius r with centres d apart, for the polyhedra
        // approximated by the inscribed/circumscribed balls: check against the exact formula
        // with the mesh-volume-equivalent radius.
        let r = (a.signed_volume() * 3.0 / (4.0 * std::f64::consts::PI)).cbrt();
        let d = 6.0;
        let lens = std::f64::consts::PI * (4.0 * r + d) * (2.0 * r - d).powi(2) / 12.0;
        let want = 2.0 * a.signed_volume() - lens;
        assert!(
            relative_error(grid.volume(), want) < 0.01,
            "{} vs {want}",
            grid.volume()
        );
        let scan = isosurface(&grid, 0.5).unwrap();
        scan.check_closed_manifold().unwrap();
        assert_eq!(scan.topology().face_components().1, 1);
        // The same sphere inward-oriented scans to the same surface.
        let inward = TriMesh::new(
            a.vertices.clone(),
            a.faces.iter().map(|&[p, q, s]| [p, s, q]).collect(),
        )
        .unwrap();
        assert_eq!(
            ct_surface(&inward, 0.5).unwrap(),
            ct_surface(&a, 0.5).unwrap()
        );
    }

    #[test]
    fn scan_is_deterministic() {
        let t = translated(&torus(8.0, 3.0, 40, 16), Vec3::new(0.3, -0.2, 0.1));
        let first = ct_surface(&t, 0.5).unwrap();
        let second = ct_surface(&t, 0.5).unwrap();
        assert_eq!(first.vertices, second.vertices);
        assert_eq!(first.faces, second.faces);
        // Nor does the number of worker threads change anything.
        let single = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| ct_surface(&t, 0.5).unwrap());
        assert_eq!(first, single);
    }

    #[test]
    fn bad_input_is_an_error() {
        let s = icosphere(5.0, 1);
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = ct_surface(&s, h).unwrap_err().to_string();
            assert!(e.contains("voxel size"), "{e}");
        }
        // An open surface names the edge.
        let open = TriMesh::new(s.vertices.clone(), s.faces[1..].to_vec()).unwrap();
        let e = ct_surface(&open, 0.5).unwrap_err().to_string();
        assert!(e.contains("not closed") && e.contains("edge ("), "{e}");
        // A grid far too big is refused before anything is allocated.
        let e = ct_surface(&s, 1e-4).unwrap_err().to_string();
        assert!(e.contains("exceeds the limit"), "{e}");
        let e = ct_surface(&TriMesh::new(vec![], vec![]).unwrap(), 0.5).unwrap_err();
        assert!(e.to_string().contains("no faces"));
        // A closed surface thinner than half a voxel: nothing to extract.
        let flat = cuboid(10.0, 10.0, 0.01);
        let e = ct_surface(&flat, 1.0).unwrap_err().to_string();
        assert!(e.contains("use smaller voxels"), "{e}");
        assert!(occupancy(&s, 0.5, 0).is_err());
        let mut grid = occupancy(&s, 1.0, 2).unwrap();
        assert!(isosurface(&grid, 0.0).is_err() && isosurface(&grid, 1.0).is_err());
        grid.values[0] = FULL;
        assert!(isosurface(&grid, 0.5)
            .unwrap_err()
            .to_string()
            .contains("boundary node (0, 0, 0)"));
        grid.values.pop();
        assert!(isosurface(&grid, 0.5).is_err());
    }
}
