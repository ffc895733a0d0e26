//! Deformation transfer from a low-resolution mesh to a high-resolution one: seed paper section
//! 3.5, equation 3, `ṽ = ᵂT_f̃ (ᵂT_f)⁻¹ v` (and section 3.7 step 2, where the same transfer
//! carries the fitted skin over to the surface of the tetrahedral mesh).
//!
//! Each high-resolution vertex `v` is bound once ([`bind`]) to the low-resolution face `f`
//! nearest to it; its coordinates in a frame attached to `f` are then re-read in the frame of
//! the same face `f̃` of any deformed copy of the low mesh ([`transfer`]). `ᵂT_f` is read as the
//! pose of `f`'s frame in the world (local to world), so `(ᵂT_f)⁻¹ v` are the local coordinates.
//!
//! Choices, and why:
//! * **Affine frame.** The paper's frame has "the normal and one edge of f as its axes", i.e. a
//!   rigid frame. A rigid frame keeps local coordinates in millimetres, so when landmark fitting
//!   scales a finger the high-resolution vertices would not scale with it. We use the frame of
//!   deformation transfer (Sumner & Popović 2004, "Deformation transfer for triangle meshes",
//!   section 3): origin at corner `a`, axes the two edges `b - a`, `c - a` and the normal scaled
//!   by the square root of twice the area, `n = (e1 × e2) / sqrt(|e1 × e2|)` (see
//!   [`affine_frame`]). Its axes transform exactly under any similarity (rotation, translation,
//!   uniform scale `s`: edges ×s, `|e1 × e2|` ×s², so `n` ×s), so a rigidly moved or uniformly
//!   scaled low mesh moves or scales the high one by exactly the same map. Under a general affine
//!   map the in-plane part is exact (points on the low surface follow it exactly) and the
//!   normal offset follows the deformed normal scaled by the square root of the area ratio: no
//!   frame built from a triangle alone can do better, since a triangle fixes only two columns of
//!   a 3D linear map.
//! * **Closest point plus offset.** `v = c + d`, with `c` the closest point of the low mesh
//!   (barycentric on `f`) and `d = v - c`. With one face, re-reading `c` by its barycentric
//!   coordinates and `d` in the affine frame is exactly equation 3 (`ã + F̃ F⁻¹ (v - a)`).
//! * **Blending against seams.** Equation 3 with a single face is discontinuous where the
//!   nearest face changes: two neighbouring faces deform by different linear maps `A_f ≠ A_g`,
//!   and the offset `d` jumps by `(A_f - A_g) d`. The closest point `c` itself is continuous (two
//!   faces agree on their shared edge), so only the offset is blended: `d̃ = Σ w_k F̃_k F_k⁻¹ d`
//!   over the faces `k` within `dist_min + r` of `v`, with weights `w_k = (1 - t²)²`,
//!   `t = (dist_k - dist_min) / r` (a C¹ bump that is 1 for the nearest face and 0 at the
//!   radius), normalised. The weights are continuous in `v`, so the transfer is continuous
//!   away from the medial axis of the low mesh; for any similarity all `F̃_k F_k⁻¹` are equal and
//!   the blend is still exact. `r = 0` is the paper's single-face equation 3. The default `r` is
//!   [`DEFAULT_BLEND_FRACTION`] of the mean edge length of the low mesh, which blends roughly
//!   over the one-ring of faces around the nearest one.
//! * **Degenerate faces** (area below `DEGENERATE_RATIO` times the squared longest edge) have
//!   no invertible frame; they are left out of the binding (their points lie on neighbouring
//!   faces' edges). A face that degenerates in the *deformed* mesh is harmless: only `F̃` is
//!   needed there, and its normal axis becomes zero.

use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh, Vec3};
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Default blend radius as a fraction of the low mesh's mean edge length.
pub(crate) const DEFAULT_BLEND_FRACTION: f64 = 0.5;

/// A face is degenerate when `|e1 × e2|` is below this times its longest squared edge
/// (aspect ratio about 1e-10), where its frame's inverse would amplify rounding beyond use.
const DEGENERATE_RATIO: f64 = 1e-10;

/// One face's share in a vertex's offset: weight and the offset's coordinates in its frame.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    face: u32,
    weight: f64,
    local: [f64; 3],
}

/// Precomputed binding of high-res vertices to low-res faces (equation 3): per high-res vertex,
/// the face holding its closest point on the low mesh with the point's barycentric coordinates,
/// and the local coordinates of the remaining offset in the affine frames of the nearby faces
/// it is blended over (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    n_low_vertices: usize,
    low_faces: Vec<[usize; 3]>,
    blend_radius: f64,
    anchor_face: Vec<u32>,
    anchor_bary: Vec<[f64; 3]>,
    anchor_distance: Vec<f64>,
    /// `entries[start[i]..start[i + 1]]` belong to point `i`.
    start: Vec<usize>,
    entries: Vec<Entry>,
}

impl Binding {
    /// Number of bound (high-resolution) points.
    pub fn len(&self) -> usize {
        self.anchor_face.len()
    }

    /// Whether no point is bound.
    pub fn is_empty(&self) -> bool {
        self.anchor_face.is_empty()
    }

    /// The blend radius used, mm (0: the paper's single nearest face).
    pub fn blend_radius(&self) -> f64 {
        self.blend_radius
    }

    /// For point `i`: the low face nearest to it, the barycentric coordinates of its closest
    /// point on that face, and its distance to the low mesh (mm).
    pub fn anchor(&self, i: usize) -> (usize, [f64; 3], f64) {
        (
            self.anchor_face[i] as usize,
            self.anchor_bary[i],
            self.anchor_distance[i],
        )
    }

    /// Number of faces point `i`'s offset is blended over (1 without blending).
    pub fn blend_count(&self, i: usize) -> usize {
        self.start[i + 1] - self.start[i]
    }
}

/// The affine frame of triangle `abc` (Sumner & Popović 2004, section 3): columns `b - a`,
/// `c - a` and `n = (e1 × e2) / sqrt(|e1 × e2|)`; the normal axis is zero for a zero-area
/// triangle. With origin `a` it is `ᵂT_f` of equation 3 in its affine form.
pub(crate) fn affine_frame(a: &Point, b: &Point, c: &Point) -> Matrix3<f64> {
    let (e1, e2) = (b - a, c - a);
    let x = e1.cross(&e2);
    let len = x.norm();
    let n = if len > 0.0 {
        x / len.sqrt()
    } else {
        Vec3::zeros()
    };
    Matrix3::from_columns(&[e1, e2, n])
}

/// Mean edge length of the faces listed (each edge counted once per face side).
fn mean_edge(mesh: &TriMesh, faces: &[[usize; 3]]) -> f64 {
    let total: f64 = faces
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (mesh.vertices[a], mesh.vertices[b], mesh.vertices[c]);
            (b - a).norm() + (c - b).norm() + (a - c).norm()
        })
        .sum();
    total / (3 * faces.len().max(1)) as f64
}

fn check_mesh(mesh: &TriMesh, what: &str) -> Result<()> {
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(format!(
            "{what}: vertex {i} has a non-finite coordinate"
        )));
    }
    let n = mesh.n_vertices();
    if let Some(f) = mesh.faces.iter().position(|f| f.iter().any(|&v| v >= n)) {
        return Err(Error::invalid(format!(
            "{what}: face {f} names a vertex beyond the {n} vertices"
        )));
    }
    Ok(())
}

/// Bind `high_points` to the low mesh with the default blend radius
/// ([`DEFAULT_BLEND_FRACTION`] of the low mesh's mean edge length); see [`bind_with_radius`].
pub fn bind(low: &TriMesh, high_points: &[Point]) -> Result<Binding> {
    bind_with_radius(low, high_points, None)
}

/// Bind every point of `high_points` to the low mesh (equation 3 of the seed paper, with the
/// affine frame and the offset blending of the module doc): closest point on the low mesh by an
/// AABB tree (Ericson 2005, 5.1.5), then the offset's coordinates in the affine frames
/// ([`affine_frame`]) of the faces within `dist_min + radius`.
///
/// `radius`: blend radius in mm; `Some(0.0)` is the paper's single nearest face, `None` the
/// default. Errors (one line, naming the item) when the low mesh has no usable face, a point or
/// low vertex is not finite, a face index is out of range, or the radius is negative or not
/// finite. Runs on rayon; the result does not depend on the thread count.
pub(crate) fn bind_with_radius(
    low: &TriMesh,
    high_points: &[Point],
    radius: Option<f64>,
) -> Result<Binding> {
    check_mesh(low, "low-resolution mesh")?;
    if let Some(i) = high_points
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(format!(
            "high-resolution point {i} has a non-finite coordinate"
        )));
    }
    // Usable faces: an invertible frame, with a margin against slivers.
    let mut good: Vec<usize> = Vec::with_capacity(low.n_faces());
    let mut inverse: Vec<Matrix3<f64>> = vec![Matrix3::zeros(); low.n_faces()];
    for (f, inv) in inverse.iter_mut().enumerate() {
        let [a, b, c] = low.corners(f);
        let longest = (b - a)
            .norm_squared()
            .max((c - b).norm_squared())
            .max((a - c).norm_squared());
        let cross = (b - a).cross(&(c - a)).norm();
        if cross > DEGENERATE_RATIO * longest {
            if let Some(m) = affine_frame(&a, &b, &c).try_inverse() {
                *inv = m;
                good.push(f);
            }
        }
    }
    if good.is_empty() {
        return Err(Error::invalid(format!(
            "low-resolution mesh has no face with a non-zero area ({} faces): nothing to bind to",
            low.n_faces()
        )));
    }
    let sub = TriMesh {
        vertices: low.vertices.clone(),
        faces: good.iter().map(|&f| low.faces[f]).collect(),
    };
    let radius = match radius {
        Some(r) if !(r.is_finite() && r >= 0.0) => {
            return Err(Error::invalid(format!(
                "blend radius {r} mm: must be finite and >= 0"
            )))
        }
        Some(r) => r,
        None => DEFAULT_BLEND_FRACTION * mean_edge(low, &sub.faces),
    };
    let tree = AabbTree::new(&sub);
    let bound: Vec<(u32, [f64; 3], f64, Vec<Entry>)> = high_points
        .par_iter()
        .map_init(Vec::new, |near, p| {
            // The tree is non-empty and `p` finite, so there is always an answer.
            let Some(c) = tree.closest_with_neighbours(p, radius, near) else {
                unreachable!("closest point on a non-empty mesh from a finite point")
            };
            let anchor = good[c.face];
            let d = p - c.point;
            let local = |f: usize| {
                let l = inverse[f] * d;
                [l.x, l.y, l.z]
            };
            let entries = if radius == 0.0 {
                vec![Entry {
                    face: anchor as u32,
                    weight: 1.0,
                    local: local(anchor),
                }]
            } else {
                // The nearest face has weight 1 by definition; others fade out at the radius.
                let mut e = vec![Entry {
                    face: anchor as u32,
                    weight: 1.0,
                    local: local(anchor),
                }];
                e.extend(near.iter().filter_map(|&(g, dist)| {
                    let t = ((dist - c.distance) / radius).clamp(0.0, 1.0);
                    let w = (1.0 - t * t).powi(2);
                    (good[g] != anchor && w > 0.0).then(|| Entry {
                        face: good[g] as u32,
                        weight: w,
                        local: local(good[g]),
                    })
                }));
                let sum: f64 = e.iter().map(|x| x.weight).sum();
                for x in &mut e {
                    x.weight /= sum;
                }
                e
            };
            (anchor as u32, c.barycentric, c.distance, entries)
        })
        .collect();
    let n = bound.len();
    let mut binding = Binding {
        n_low_vertices: low.n_vertices(),
        low_faces: low.faces.clone(),
        blend_radius: radius,
        anchor_face: Vec::with_capacity(n),
        anchor_bary: Vec::with_capacity(n),
        anchor_distance: Vec::with_capacity(n),
        start: Vec::with_capacity(n + 1),
        entries: Vec::new(),
    };
    binding.start.push(0);
    for (face, bary, dist, entries) in bound {
        binding.anchor_face.push(face);
        binding.anchor_bary.push(bary);
        binding.anchor_distance.push(dist);
        binding.entries.extend(entries);
        binding.start.push(binding.entries.len());
    }
    Ok(binding)
}

/// Carry the deformation `low -> low_deformed` over to the bound points (equation 3): each
/// point's closest point is re-read by its barycentric coordinates on the deformed face and its
/// offset by its local coordinates in the deformed affine frames, blended by the bound weights.
/// Returns one point per bound point, in the same order (the high-resolution mesh stays
/// homologous: same vertices, same faces).
///
/// Errors (one line) when `low_deformed` is not the bound mesh deformed: a different vertex
/// count, a different face list, or a non-finite vertex.
pub fn transfer(binding: &Binding, low_deformed: &TriMesh) -> Result<Vec<Point>> {
    if low_deformed.n_vertices() != binding.n_low_vertices {
        return Err(Error::invalid(format!(
            "deformed low-resolution mesh has {} vertices but the binding was made on {}: \
             transfer needs the same (homologous) mesh",
            low_deformed.n_vertices(),
            binding.n_low_vertices
        )));
    }
    if low_deformed.faces != binding.low_faces {
        let first = low_deformed
            .faces
            .iter()
            .zip(&binding.low_faces)
            .position(|(a, b)| a != b)
            .unwrap_or(binding.low_faces.len().min(low_deformed.n_faces()));
        return Err(Error::invalid(format!(
            "deformed low-resolution mesh differs from the bound one at face {first} \
             ({} faces vs {}): transfer needs the same (homologous) mesh",
            low_deformed.n_faces(),
            binding.low_faces.len()
        )));
    }
    check_mesh(low_deformed, "deformed low-resolution mesh")?;
    let frames: Vec<Matrix3<f64>> = (0..low_deformed.n_faces())
        .map(|f| {
            let [a, b, c] = low_deformed.corners(f);
            affine_frame(&a, &b, &c)
        })
        .collect();
    Ok((0..binding.len())
        .into_par_iter()
        .map(|i| {
            let [a, b, c] = low_deformed.corners(binding.anchor_face[i] as usize);
            let w = binding.anchor_bary[i];
            let base = a.coords * w[0] + b.coords * w[1] + c.coords * w[2];
            let offset: Vec3 = binding.entries[binding.start[i]..binding.start[i + 1]]
                .iter()
                .map(|e| frames[e.face as usize] * Vec3::from(e.local) * e.weight)
                .sum();
            Point::from(base + offset)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::rng::Rng;
    use nalgebra::{Isometry3, Matrix4, Translation3};
    use std::sync::OnceLock;

    /// Low mesh: the welded base hand (2314 faces); high points: the vertices of the template
    /// (two Loop subdivisions, 18.5k vertices), which lie off the base surface by up to a few mm.
    fn fixture() -> &'static (TriMesh, Vec<Point>) {
        static F: OnceLock<(TriMesh, Vec<Point>)> = OnceLock::new();
        F.get_or_init(|| {
            let t = crate::template::load_template(Side::Right).unwrap();
            (t.base.mesh, t.mesh.vertices)
        })
    }

    fn max_err(a: &[Point], b: &[Point]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max)
    }

    fn map(mesh: &TriMesh, f: impl Fn(&Point) -> Point) -> TriMesh {
        TriMesh {
            vertices: mesh.vertices.iter().map(&f).collect(),
            faces: mesh.faces.clone(),
        }
    }

    const RADII: [Option<f64>; 3] = [Some(0.0), None, Some(8.0)];

    #[test]
    fn identity_reproduces_points() {
        let (low, high) = fixture();
        for r in RADII {
            let b = bind_with_radius(low, high, r).unwrap();
            assert_eq!(b.len(), high.len());
            let out = transfer(&b, low).unwrap();
            assert!(max_err(&out, high) < 1e-9, "radius {r:?}");
        }
        // The high points really are off the low surface, so offsets are exercised.
        let b = bind(low, high).unwrap();
        let max_off = (0..b.len()).map(|i| b.anchor(i).2).fold(0.0, f64::max);
        assert!(max_off > 0.5, "max offset {max_off}");
        assert!((0..b.len()).any(|i| b.blend_count(i) > 1));
    }

    #[test]
    fn rigid_motion_carries_over() {
        let (low, high) = fixture();
        let mut rng = Rng::new(21);
        let iso = Isometry3::from_parts(Translation3::from(rng.gauss3(100.0)), rng.rotation());
        let moved = low.transformed(&iso);
        let expected: Vec<Point> = high.iter().map(|p| iso * p).collect();
        for r in RADII {
            let out = transfer(&bind_with_radius(low, high, r).unwrap(), &moved).unwrap();
            assert!(max_err(&out, &expected) < 1e-9, "radius {r:?}");
        }
    }

    #[test]
    fn similarity_carries_over() {
        let (low, high) = fixture();
        let mut rng = Rng::new(22);
        let (q, t, centre) = (rng.rotation(), rng.gauss3(50.0), low.vertex_centroid());
        for s in [1.37, 0.71] {
            let f = |p: &Point| Point::from(q * (p - centre) * s + centre.coords + t);
            let scaled = map(low, f);
            let expected: Vec<Point> = high.iter().map(f).collect();
            for r in RADII {
                let out = transfer(&bind_with_radius(low, high, r).unwrap(), &scaled).unwrap();
                assert!(max_err(&out, &expected) < 1e-9, "scale {s} radius {r:?}");
            }
        }
    }

    #[test]
    fn general_affine_map_is_exact_on_the_low_surface() {
        let (low, high) = fixture();
        let g = nalgebra::Matrix3::new(1.2, 0.1, -0.05, 0.02, 0.9, 0.1, 0.0, -0.08, 1.1);
        let t = Vec3::new(3.0, -4.0, 5.0);
        let f = |p: &Point| Point::from(g * p.coords + t);
        let deformed = map(low, f);
        // Points on the low surface: random barycentric points on random faces.
        let mut rng = Rng::new(23);
        let on: Vec<Point> = (0..3000)
            .map(|_| {
                let [a, b, c] = low.corners(rng.below(low.n_faces()));
                let (u, v) = (rng.uniform(), rng.uniform());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                a + (b - a) * u + (c - a) * v
            })
            .chain(low.vertices.iter().copied())
            .collect();
        let expected: Vec<Point> = on.iter().map(f).collect();
        for r in RADII {
            let out = transfer(&bind_with_radius(low, &on, r).unwrap(), &deformed).unwrap();
            assert!(max_err(&out, &expected) < 1e-9, "radius {r:?}");
        }
        // Off the surface only the offset is approximate: its error is a fraction of it.
        let b = bind(low, high).unwrap();
        let out = transfer(&b, &deformed).unwrap();
        let norm = g.norm(); // Frobenius, bounds the spectral norm
        for (i, (o, p)) in out.iter().zip(high).enumerate() {
            let off = b.anchor(i).2;
            assert!((o - f(p)).norm() <= 2.0 * norm * off + 1e-9, "point {i}");
        }
    }

    /// Equation 3 literally, with 4x4 homogeneous matrices ᵂT_f = [F a; 0 1] of the nearest
    /// face, against the single-face binding under a smooth non-linear deformation.
    #[test]
    fn single_face_binding_is_equation_3() {
        let (low, high) = fixture();
        let bend = |p: &Point| {
            Point::new(
                p.x + 0.002 * p.y * p.y,
                p.y + 5.0 * (p.z / 20.0).sin(),
                p.z * (1.0 + 0.001 * p.x),
            )
        };
        let deformed = map(low, bend);
        let b = bind_with_radius(low, high, Some(0.0)).unwrap();
        let out = transfer(&b, &deformed).unwrap();
        let pose = |m: &TriMesh, f: usize| {
            let [a, bb, c] = m.corners(f);
            let mut t = Matrix4::identity();
            t.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&affine_frame(&a, &bb, &c));
            t.fixed_view_mut::<3, 1>(0, 3).copy_from(&a.coords);
            t
        };
        let tree = AabbTree::new(low);
        for (i, v) in high.iter().enumerate().step_by(7) {
            let (f, _, dist) = b.anchor(i);
            // The bound face is a nearest face.
            assert!((dist - tree.distance(v).unwrap()).abs() < 1e-9);
            let m = pose(&deformed, f) * pose(low, f).try_inverse().unwrap();
            let expected = Point::from_homogeneous(m * v.to_homogeneous()).unwrap();
            assert!((out[i] - expected).norm() < 1e-9, "point {i}");
        }
    }

    /// A hinge of two triangles folded by 40 degrees, and a dense line of points 1 mm above it
    /// crossing the fold: the single-face transfer jumps where the nearest face changes, the
    /// blended one moves by steps proportional to the point spacing.
    #[test]
    fn blending_removes_the_seam() {
        let low = TriMesh::new(
            vec![
                Point::new(0.0, 0.0, 0.0),
                Point::new(0.0, 10.0, 0.0),
                Point::new(-10.0, 5.0, 0.0),
                Point::new(10.0, 5.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 3, 1]],
        )
        .unwrap();
        let angle = 40f64.to_radians();
        let mut folded = low.clone();
        folded.vertices[3] = Point::new(10.0 * angle.cos(), 5.0, 10.0 * angle.sin());
        let step = 1e-3;
        let line: Vec<Point> = (0..=16000)
            .map(|k| Point::new(-8.0 + k as f64 * step, 5.0, 1.0))
            .collect();
        let max_step = |pts: &[Point]| {
            pts.windows(2)
                .map(|w| (w[1] - w[0]).norm())
                .fold(0.0, f64::max)
        };
        let single = transfer(&bind_with_radius(&low, &line, Some(0.0)).unwrap(), &folded).unwrap();
        // The offset 1 mm turns by 40 degrees across the seam: a jump of 2 sin(20°) ≈ 0.68 mm.
        assert!(max_step(&single) > 0.5, "{}", max_step(&single));
        let b = bind(&low, &line).unwrap();
        assert!(b.blend_radius() > 1.0);
        let blended = transfer(&b, &folded).unwrap();
        assert!(max_step(&blended) < 10.0 * step, "{}", max_step(&blended));
        // Beyond the blend radius from the other face (sqrt(1 + 8²) - 1 > 7 mm) nothing changes.
        assert!(b.blend_radius() < 7.0);
        assert!((blended[0] - single[0]).norm() < 1e-12);
        assert!((blended[16000] - single[16000]).norm() < 1e-12);
    }

    #[test]
    fn degenerate_low_faces_are_skipped() {
        let (low, high) = fixture();
        // Add a zero-area face on an existing edge (a collapsed sliver).
        let mut bad = low.clone();
        let [a, b, _] = bad.faces[0];
        let mid = Point::from((bad.vertices[a].coords + bad.vertices[b].coords) / 2.0);
        bad.vertices.push(mid);
        let m = bad.n_vertices() - 1;
        bad.faces.push([a, b, m]);
        let binding = bind(&bad, high).unwrap();
        assert!((0..binding.len()).all(|i| binding.anchor(i).0 != bad.n_faces() - 1));
        let out = transfer(&binding, &bad).unwrap();
        assert!(max_err(&out, high) < 1e-9);
    }

    #[test]
    fn homology_and_determinism() {
        let (low, high) = fixture();
        let b1 = bind(low, high).unwrap();
        let b2 = bind(low, high).unwrap();
        assert_eq!(b1, b2);
        let jitter = map(low, |p| p + Vec3::new(0.0, 0.0, 0.5 * (p.x / 20.0).sin()));
        let out = transfer(&b1, &jitter).unwrap();
        assert_eq!(out.len(), high.len());
        // Each output stays with its own input: moved by the 0.5 mm displacement plus the
        // change of its offset under a deformation gradient of at most 0.025.
        let max_off = (0..b1.len()).map(|i| b1.anchor(i).2).fold(0.0, f64::max);
        assert!(max_err(&out, high) < 0.5 + 0.1 * max_off);
        assert_eq!(out, transfer(&b2, &jitter).unwrap());
    }

    #[test]
    fn mismatched_or_bad_input_is_an_error() {
        let (low, high) = fixture();
        let b = bind(low, high).unwrap();
        let mut fewer = low.clone();
        fewer.faces.pop();
        let e = transfer(&b, &fewer).unwrap_err().to_string();
        assert!(e.contains("face 2313") && e.contains("homologous"), "{e}");
        let mut swapped = low.clone();
        swapped.faces.swap(3, 4);
        assert!(transfer(&b, &swapped)
            .unwrap_err()
            .to_string()
            .contains("face 3"));
        let mut more = low.clone();
        more.vertices.push(Point::origin());
        assert!(transfer(&b, &more)
            .unwrap_err()
            .to_string()
            .contains("vertices"));
        let mut nan = low.clone();
        nan.vertices[5].y = f64::NAN;
        assert!(transfer(&b, &nan)
            .unwrap_err()
            .to_string()
            .contains("vertex 5"));

        let mut pts = high[..10].to_vec();
        pts[7].x = f64::INFINITY;
        assert!(bind(low, &pts).unwrap_err().to_string().contains("point 7"));
        assert!(bind_with_radius(low, high, Some(-1.0)).is_err());
        assert!(bind_with_radius(low, high, Some(f64::NAN)).is_err());
        let empty = TriMesh::new(low.vertices.clone(), vec![]).unwrap();
        assert!(bind(&empty, high)
            .unwrap_err()
            .to_string()
            .contains("no face"));
        let flat = TriMesh::new(
            vec![
                Point::origin(),
                Point::new(1.0, 0.0, 0.0),
                Point::new(2.0, 0.0, 0.0),
            ],
            vec![[0, 1, 2]],
        )
        .unwrap();
        assert!(bind(&flat, high).is_err());
        let out_of_range = TriMesh {
            vertices: vec![Point::origin(); 3],
            faces: vec![[0, 1, 9]],
        };
        assert!(bind(&out_of_range, high)
            .unwrap_err()
            .to_string()
            .contains("face 0"));
        // No points: an empty binding, an empty result.
        let b = bind(low, &[]).unwrap();
        assert!(b.is_empty() && transfer(&b, low).unwrap().is_empty());
    }
}
