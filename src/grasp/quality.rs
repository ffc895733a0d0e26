//! Grasp quality in the L1 grasp wrench space (Ferrari & Canny 1992, "Planning optimal grasps",
//! ICRA; as GraspIt computes it, Miller & Allen 2004).
//!
//! Each point contact with inward unit normal `n` and Coulomb coefficient `μ` contributes the
//! eight edges of its linearised friction cone, `f_k = n + μ (cos θ_k t₁ + sin θ_k t₂)` with unit
//! normal component, as the wrenches `(f_k, (p - c) × f_k / ρ)`, `c` the part's centre of mass
//! and `ρ` its largest radius from `c` (so torques and forces have the same unit). The grasp
//! wrench space is the convex hull of all of them (the L1 space: total normal force 1).
//! Force closure holds when the origin is strictly inside the hull; the epsilon quality is the
//! distance from the origin to the nearest hull facet (the largest ball around the origin in
//! the hull), the volume quality the hull's 6-D volume.
//!
//! The hull is our own Quickhull in six dimensions (Barber, Dobkin & Huhdanpaa 1996): no
//! permissively licensed Rust crate computes d > 3 hulls (qhull's bindings carry the qhull
//! licence and a C build). Input points are joggled by a deterministic [`JOGGLE`] relative
//! perturbation (qhull's `QJ`) so that the points are in general position and every facet is a
//! simplex; this moves epsilon and volume by about 1e-7 relative.

use super::contact::Contact;
use crate::geometry::{Point, Vec3};
use nalgebra::{Matrix5, Matrix6, Vector6};
use serde::Serialize;
use std::collections::HashMap;

/// Number of friction cone edges per contact.
pub const CONE_EDGES: usize = 8;

/// A 6-D wrench `[fx, fy, fz, τx/ρ, τy/ρ, τz/ρ]`.
pub type Wrench = Vector6<f64>;

/// The wrenches of the linearised friction cones of `contacts` on a part with centre of mass
/// `com` and torque scale `rho` (mm).
pub fn contact_wrenches(contacts: &[Contact], mu: f64, com: &Point, rho: f64) -> Vec<Wrench> {
    let mut out = Vec::with_capacity(contacts.len() * CONE_EDGES);
    for c in contacts {
        let n = Vec3::from(c.normal);
        let p = Point::from(c.point);
        let t1 = n
            .cross(&if n.x.abs() < 0.9 {
                Vec3::x()
            } else {
                Vec3::y()
            })
            .normalize();
        let t2 = n.cross(&t1);
        for k in 0..CONE_EDGES {
            let th = 2.0 * std::f64::consts::PI * k as f64 / CONE_EDGES as f64;
            let f = n + mu * (th.cos() * t1 + th.sin() * t2);
            let tau = (p - com).cross(&f) / rho;
            out.push(Wrench::new(f.x, f.y, f.z, tau.x, tau.y, tau.z));
        }
    }
    out
}

/// Grasp quality numbers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Quality {
    /// Origin strictly inside the grasp wrench space.
    pub force_closure: bool,
    /// Ferrari-Canny epsilon (0 without force closure).
    pub epsilon: f64,
    /// 6-D volume of the grasp wrench space (0 when it is not full-dimensional).
    pub volume: f64,
}

/// Quality of a wrench set (see the module documentation).
pub fn quality(wrenches: &[Wrench]) -> Quality {
    match Hull::new(wrenches) {
        None => Quality {
            force_closure: false,
            epsilon: 0.0,
            volume: 0.0,
        },
        Some(h) => {
            let eps = h.min_offset();
            Quality {
                force_closure: eps > 1e-9,
                epsilon: eps.max(0.0),
                volume: h.volume(),
            }
        }
    }
}

/// Quality of `contacts` with friction `mu` on a part (`com`, `rho`).
pub fn grasp_quality(contacts: &[Contact], mu: f64, com: &Point, rho: f64) -> Quality {
    quality(&contact_wrenches(contacts, mu, com, rho))
}

const D: usize = 6;

/// Relative size of the joggle (qhull `QJ`): large against round-off, small against the
/// precision epsilon is reported with.
pub const JOGGLE: f64 = 1e-7;

#[derive(Clone, Debug)]
struct Facet {
    verts: [usize; D],
    /// Across the ridge without `verts[k]`.
    neighbours: [usize; D],
    normal: Vector6<f64>,
    offset: f64,
    outside: Vec<usize>,
    alive: bool,
}

/// A full-dimensional convex hull in 6-D with simplicial facets.
#[derive(Clone, Debug)]
pub struct Hull {
    points: Vec<Vector6<f64>>,
    facets: Vec<Facet>,
    interior: Vector6<f64>,
}

/// Unit normal of the hyperplane through six points (generalised cross product of the five
/// edge vectors by cofactors), or `None` when they are affinely dependent.
fn hyperplane(p: &[Vector6<f64>; D]) -> Option<(Vector6<f64>, f64)> {
    let mut e = [[0.0; D]; D - 1];
    for i in 1..D {
        for k in 0..D {
            e[i - 1][k] = p[i][k] - p[0][k];
        }
    }
    let mut n = Vector6::zeros();
    for col in 0..D {
        let m = Matrix5::from_fn(|r, c| e[r][if c < col { c } else { c + 1 }]);
        let s = if col % 2 == 0 { 1.0 } else { -1.0 };
        n[col] = s * m.determinant();
    }
    let len = n.norm();
    let scale: f64 = e.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
    if len.is_nan() || len <= 1e-24 * scale.powi(5).max(1e-300) {
        return None;
    }
    let n = n / len;
    Some((n, n.dot(&p[0])))
}

impl Hull {
    /// Quickhull of `input`; `None` when the points do not span 6-D. Tries joggles of
    /// [`JOGGLE`] and 100 and 10,000 times larger (qhull retries `QJ` the same way) until the
    /// construction succeeds and every input point is inside every facet.
    pub fn new(input: &[Vector6<f64>]) -> Option<Hull> {
        // Rank test on the raw points: the joggle must not invent a sixth dimension.
        let scale = input.iter().map(|p| p.amax()).fold(0.0, f64::max);
        if input.len() < D + 1
            || scale.is_nan()
            || scale <= 0.0
            || initial_simplex(input, 1e-9 * scale).is_none()
        {
            return None;
        }
        [1.0, 1e2, 1e4]
            .into_iter()
            .find_map(|m| Hull::build(input, JOGGLE * m))
    }

    fn build(input: &[Vector6<f64>], joggle: f64) -> Option<Hull> {
        if input.len() < D + 1 || input.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
            return None;
        }
        let scale = input
            .iter()
            .map(|p| p.amax())
            .fold(0.0, f64::max)
            .max(1e-300);
        // Deterministic joggle (qhull QJ) from a fixed-seed generator: independent per
        // coordinate (an affine hash would preserve the very dependencies it must break).
        let mut rng = crate::rng::Rng::new(0x6A09_E667);
        let points: Vec<Vector6<f64>> = input
            .iter()
            .map(|p| Vector6::from_fn(|k, _| p[k] + rng.range(-1.0, 1.0) * joggle * scale))
            .collect();
        let eps = 1e-3 * joggle * scale;
        let simplex = initial_simplex(&points, eps)?;
        let interior = simplex.iter().map(|&i| points[i]).sum::<Vector6<f64>>() / (D + 1) as f64;
        let mut h = Hull {
            points,
            facets: Vec::new(),
            interior,
        };
        // Facet i omits simplex vertex i; facets i and j share the ridge omitting both.
        for i in 0..=D {
            let vs: Vec<usize> = (0..=D).filter(|&k| k != i).collect();
            let verts: [usize; D] = std::array::from_fn(|k| simplex[vs[k]]);
            let neighbours: [usize; D] = std::array::from_fn(|k| vs[k]);
            let (normal, offset) = h.oriented_plane(&verts)?;
            h.facets.push(Facet {
                verts,
                neighbours,
                normal,
                offset,
                outside: Vec::new(),
                alive: true,
            });
        }
        let all: Vec<usize> = (0..h.points.len())
            .filter(|i| !simplex.contains(i))
            .collect();
        h.assign(&all, &(0..=D).collect::<Vec<_>>(), eps);
        let mut guard = 0usize;
        // Facets that may have outside points (stale entries are skipped when popped).
        let mut pending: Vec<usize> = (0..=D).collect();
        // Visit marks of the visibility search: facet -> (round, visible).
        let mut mark: Vec<(usize, bool)> = Vec::new();
        loop {
            guard += 1;
            if guard > 200_000 {
                return None;
            }
            let Some(f0) = std::iter::from_fn(|| pending.pop())
                .find(|&f| h.facets[f].alive && !h.facets[f].outside.is_empty())
            else {
                break;
            };
            let fa = &h.facets[f0];
            let apex = *fa
                .outside
                .iter()
                .max_by(|&&a, &&b| h.dist(f0, a).total_cmp(&h.dist(f0, b)))
                .expect("non-empty");
            // Visible facets by BFS from f0.
            mark.resize(h.facets.len(), (0, false));
            let seen = |mark: &[(usize, bool)], g: usize| mark[g].0 == guard;
            let mut visible = vec![f0];
            mark[f0] = (guard, true);
            let mut qi = 0;
            while qi < visible.len() {
                let f = visible[qi];
                qi += 1;
                for k in 0..D {
                    let g = h.facets[f].neighbours[k];
                    if seen(&mark, g) {
                        continue;
                    }
                    let vis = h.dist(g, apex) > eps;
                    mark[g] = (guard, vis);
                    if vis {
                        visible.push(g);
                    }
                }
            }
            // Horizon ridges: (ridge vertices, the facet beyond).
            let mut new_ids = Vec::new();
            let mut ridge_map: HashMap<[usize; D - 1], (usize, usize)> = HashMap::new();
            let mut orphans = Vec::new();
            for &f in &visible {
                for k in 0..D {
                    let g = h.facets[f].neighbours[k];
                    if mark[g].1 {
                        continue;
                    }
                    let mut verts = h.facets[f].verts;
                    verts[k] = apex;
                    let (normal, offset) = h.oriented_plane(&verts)?;
                    let id = h.facets.len();
                    let mut neighbours = [usize::MAX; D];
                    neighbours[k] = g;
                    // Point g's link to f at the new facet.
                    let gk = h.facets[g]
                        .neighbours
                        .iter()
                        .position(|&x| x == f)
                        .expect("adjacency is symmetric");
                    h.facets[g].neighbours[gk] = id;
                    h.facets.push(Facet {
                        verts,
                        neighbours,
                        normal,
                        offset,
                        outside: Vec::new(),
                        alive: true,
                    });
                    new_ids.push(id);
                }
            }
            // Link the new facets to each other through their ridges containing the apex.
            for &id in &new_ids {
                let verts = h.facets[id].verts;
                for k in 0..D {
                    if verts[k] == apex {
                        continue;
                    }
                    let mut key = [0usize; D - 1];
                    for (slot, m) in key.iter_mut().zip((0..D).filter(|&m| m != k)) {
                        *slot = verts[m];
                    }
                    key.sort_unstable();
                    match ridge_map.remove(&key) {
                        Some((other, ok)) => {
                            h.facets[id].neighbours[k] = other;
                            h.facets[other].neighbours[ok] = id;
                        }
                        None => {
                            ridge_map.insert(key, (id, k));
                        }
                    }
                }
            }
            if !ridge_map.is_empty()
                || new_ids
                    .iter()
                    .any(|&id| h.facets[id].neighbours.contains(&usize::MAX))
            {
                return None;
            }
            for &f in &visible {
                h.facets[f].alive = false;
                orphans.append(&mut h.facets[f].outside);
            }
            orphans.retain(|&p| p != apex);
            h.assign(&orphans, &new_ids, eps);
            pending.extend(new_ids.iter().copied());
        }
        // Check: every point inside every facet (round-off may have broken convexity).
        let ok = h.facets.iter().filter(|f| f.alive).all(|f| {
            h.points
                .iter()
                .all(|p| f.normal.dot(p) - f.offset <= 1e3 * eps)
        });
        ok.then_some(h)
    }

    fn dist(&self, f: usize, p: usize) -> f64 {
        self.facets[f].normal.dot(&self.points[p]) - self.facets[f].offset
    }

    fn oriented_plane(&self, verts: &[usize; D]) -> Option<(Vector6<f64>, f64)> {
        let p: [Vector6<f64>; D] = std::array::from_fn(|k| self.points[verts[k]]);
        let (n, b) = hyperplane(&p)?;
        if n.dot(&self.interior) - b > 0.0 {
            Some((-n, -b))
        } else {
            Some((n, b))
        }
    }

    fn assign(&mut self, pts: &[usize], facets: &[usize], eps: f64) {
        for &p in pts {
            if let Some(&f) = facets.iter().find(|&&f| self.dist(f, p) > eps) {
                self.facets[f].outside.push(p);
            }
        }
    }

    /// Number of facets.
    pub fn n_facets(&self) -> usize {
        self.facets.iter().filter(|f| f.alive).count()
    }

    /// Smallest signed distance from the origin to a facet plane, positive when the origin is
    /// inside (the Ferrari-Canny epsilon).
    pub fn min_offset(&self) -> f64 {
        self.facets
            .iter()
            .filter(|f| f.alive)
            .map(|f| f.offset)
            .fold(f64::MAX, f64::min)
    }

    /// 6-D volume: the sum of the simplices from an interior point to every facet.
    pub fn volume(&self) -> f64 {
        let c = self.interior;
        let mut v = 0.0;
        for f in self.facets.iter().filter(|f| f.alive) {
            let m = Matrix6::from_fn(|r, k| self.points[f.verts[k]][r] - c[r]);
            v += m.determinant().abs();
        }
        v / 720.0
    }
}

/// Six affinely independent points spanning the largest simplex found greedily (the two
/// furthest apart along some axis, then repeatedly the point furthest from the affine hull so
/// far), or `None` when the input does not span 6-D.
fn initial_simplex(points: &[Vector6<f64>], eps: f64) -> Option<Vec<usize>> {
    let mut best = (0, 0, -1.0);
    for k in 0..D {
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in points.iter().enumerate() {
            if p[k] < points[lo][k] {
                lo = i;
            }
            if p[k] > points[hi][k] {
                hi = i;
            }
        }
        let ext = points[hi][k] - points[lo][k];
        if ext > best.2 {
            best = (lo, hi, ext);
        }
    }
    if best.2 <= eps {
        return None;
    }
    let mut chosen = vec![best.0, best.1];
    let mut basis: Vec<Vector6<f64>> = Vec::new();
    let o = points[best.0];
    let first = points[best.1] - o;
    basis.push(first.normalize());
    while chosen.len() < D + 1 {
        let mut far = (usize::MAX, 0.0);
        for (i, p) in points.iter().enumerate() {
            let mut r = p - o;
            for b in &basis {
                r -= b * b.dot(&r);
            }
            let d = r.norm();
            if d > far.1 {
                far = (i, d);
            }
        }
        if far.0 == usize::MAX || far.1 <= eps * 1e3 {
            return None;
        }
        let mut r = points[far.0] - o;
        for b in &basis {
            r -= b * b.dot(&r);
        }
        basis.push(r.normalize());
        chosen.push(far.0);
    }
    Some(chosen)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn cross_polytope_closed_form() {
        let mut w = Vec::new();
        for k in 0..D {
            let mut e = Vector6::zeros();
            e[k] = 1.0;
            w.push(e);
            w.push(-e);
        }
        let q = quality(&w);
        assert!(q.force_closure);
        assert!(
            (q.epsilon - 1.0 / 6f64.sqrt()).abs() < 1e-5,
            "{}",
            q.epsilon
        );
        assert!((q.volume - 64.0 / 720.0).abs() < 1e-5, "{}", q.volume);
    }

    #[test]
    fn hypercube_closed_form_with_interior_points() {
        let mut w = Vec::new();
        for m in 0..64u32 {
            w.push(Vector6::from_fn(
                |k, _| if m >> k & 1 == 1 { 1.0 } else { -1.0 },
            ));
        }
        let mut rng = Rng::new(3);
        for _ in 0..200 {
            w.push(Vector6::from_fn(|_, _| rng.range(-0.9, 0.9)));
        }
        assert!(Hull::new(&w).unwrap().n_facets() >= 12);
        let q = quality(&w);
        assert!(
            (q.epsilon - 1.0).abs() < 2e-3 && (q.volume - 64.0).abs() < 0.5,
            "{q:?}"
        );
    }

    #[test]
    fn origin_outside_or_flat_is_not_force_closure() {
        let mut rng = Rng::new(5);
        let w: Vec<Wrench> = (0..40)
            .map(|_| Vector6::from_fn(|_, _| rng.range(1.0, 2.0)))
            .collect();
        let q = quality(&w);
        assert!(!q.force_closure && q.epsilon == 0.0 && q.volume > 0.0);
        // A single contact: its wrenches span 3 dimensions only.
        let c = contact([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]);
        let q = grasp_quality(&[c], 0.5, &Point::origin(), 10.0);
        assert_eq!(
            q,
            Quality {
                force_closure: false,
                epsilon: 0.0,
                volume: 0.0
            }
        );
    }

    fn contact(p: [f64; 3], n: [f64; 3]) -> Contact {
        Contact {
            link: "x".into(),
            link_index: 0,
            point: p,
            normal: n,
            depth_mm: 0.0,
            area_mm2: 1.0,
        }
    }

    /// Two fingertip patches (three point contacts each, 2 mm apart) pressing on opposite
    /// poles of a 20 mm sphere.
    fn antipodal() -> Vec<Contact> {
        let mut c = Vec::new();
        for s in [-1.0, 1.0] {
            for k in 0..3 {
                let a = 2.0 * std::f64::consts::PI * k as f64 / 3.0;
                let (x, y) = (2.0 * a.cos(), 2.0 * a.sin());
                let z = s * (400.0f64 - x * x - y * y).sqrt();
                let n = -Vec3::new(x, y, z).normalize();
                c.push(contact([x, y, z], [n.x, n.y, n.z]));
            }
        }
        c
    }

    #[test]
    fn antipodal_needs_friction() {
        let q0 = grasp_quality(&antipodal(), 0.0, &Point::origin(), 20.0);
        assert!(!q0.force_closure, "{q0:?}");
        let q = grasp_quality(&antipodal(), 0.5, &Point::origin(), 20.0);
        assert!(q.force_closure && q.epsilon > 0.0, "{q:?}");
    }

    /// Epsilon of the symmetric three-contact grasp in closed form.
    ///
    /// Three contacts 120° apart on a circle of radius `R` in the plane z = 0, at
    /// `p_i = R (cos a_i, sin a_i, 0)`, `a_i = 0, 120°, 240°`, each pushing toward the centre
    /// (`n_i = -p_i / R`), friction `μ = 1/2`, centre of mass at the centre, torque scale
    /// `ρ = R`. [`contact_wrenches`] takes `t₁ = (n × x)/|n × x|` (`n × y` when `|n_x| ≥ 0.9`)
    /// and `t₂ = n × t₁`, which here are
    /// contact 0: `t₁ = (0, 0, -1)`, `t₂ = (0, -1, 0)`;
    /// contact 1: `t₁ = (0, 0, 1)`, `t₂ = (-√3/2, -1/2, 0)`;
    /// contact 2: `t₁ = (0, 0, -1)`, `t₂ = (-√3/2, 1/2, 0)`;
    /// edge `k` of contact `i` is `f = n_i + μ (cos θ_k t₁ + sin θ_k t₂)`, `θ_k = kπ/4`, with
    /// the wrench `w_ik = (f, p_i × f / ρ) = (f, -n_i × f)`.
    ///
    /// The eight edges of one contact lie in a 2-D affine plane of wrench space
    /// (`w(n_i) + μ span{w(t₁), w(t₂)}`), so a facet through three of them holds the whole
    /// octagon. The nearest facets form one orbit of the grasp's symmetry (D3h); one of them
    /// holds the octagon of contact 2, edges `θ = 0` and `θ = 7π/4` of contact 0 and edge
    /// `θ = 0` of contact 1. Six of these are affinely independent (`w_20, w_22, w_24, w_00,
    /// w_07, w_10`); the facet's hyperplane is `{w : u·w = 1}` with `u = A⁻¹ 1`, `A` the matrix
    /// of those six wrenches as rows, and `ε = 1/‖u‖`. In exact arithmetic (sympy, from the
    /// coordinates above) `ε(μ = 1/2) = 0.275925155686099053…`; it involves √2 (from the
    /// 45° edge) and √3 (from the 120° layout) and no simpler form.
    ///
    /// The test builds the six wrenches from the coordinates above (checking
    /// [`contact_wrenches`] against them), solves for `u`, checks that every one of the 24
    /// wrenches satisfies `u·w ≤ 1` (the hyperplane supports the grasp wrench space, so
    /// `ε ≤ 1/‖u‖`) and that no hyperplane through any six of the 24 wrenches supporting the
    /// space is nearer the origin (all C(24, 6) = 134,596 of them: the definition of epsilon
    /// evaluated without a hull, so `ε = 1/‖u‖`), then compares the Quickhull's epsilon, which
    /// carries the joggle ([`JOGGLE`], 1e-7 relative).
    #[test]
    fn symmetric_three_contact_epsilon_matches_closed_form() {
        let (r, mu) = (30.0, 0.5);
        let s3 = 3f64.sqrt() / 2.0;
        let mut cs = Vec::new();
        for k in 0..3 {
            let a = 2.0 * std::f64::consts::PI * k as f64 / 3.0;
            cs.push(contact(
                [r * a.cos(), r * a.sin(), 0.0],
                [-a.cos(), -a.sin(), 0.0],
            ));
        }
        let w = contact_wrenches(&cs, mu, &Point::origin(), r);
        assert_eq!(w.len(), 24);
        let frames = [
            (
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::new(0.0, -1.0, 0.0),
            ),
            (
                Vec3::new(0.5, -s3, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(-s3, -0.5, 0.0),
            ),
            (
                Vec3::new(0.5, s3, 0.0),
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::new(-s3, 0.5, 0.0),
            ),
        ];
        let edge = |i: usize, k: usize| {
            let (n, t1, t2) = frames[i];
            let th = std::f64::consts::FRAC_PI_4 * k as f64;
            let f = n + mu * (th.cos() * t1 + th.sin() * t2);
            let tau = -n.cross(&f);
            Wrench::new(f.x, f.y, f.z, tau.x, tau.y, tau.z)
        };
        for i in 0..3 {
            for k in 0..CONE_EDGES {
                assert!(
                    (w[i * CONE_EDGES + k] - edge(i, k)).norm() < 1e-12,
                    "{i} {k}"
                );
            }
        }
        let facet = [
            edge(2, 0),
            edge(2, 2),
            edge(2, 4),
            edge(0, 0),
            edge(0, 7),
            edge(1, 0),
        ];
        let a = Matrix6::from_fn(|row, col| facet[row][col]);
        let u = a.lu().solve(&Vector6::repeat(1.0)).unwrap();
        let closed = 1.0 / u.norm();
        assert!(
            (closed - 0.275_925_155_686_099_05).abs() < 1e-12,
            "{closed}"
        );
        // Supporting: every wrench on the origin's side of the facet's hyperplane.
        assert!(w.iter().all(|x| u.dot(x) <= 1.0 + 1e-12));
        // No supporting hyperplane through six wrenches is nearer the origin.
        let mut nearest = f64::MAX;
        let n = w.len();
        let mut idx = [0usize, 1, 2, 3, 4, 5];
        loop {
            let p: [Vector6<f64>; D] = std::array::from_fn(|k| w[idx[k]]);
            if let Some((nrm, off)) = hyperplane(&p) {
                let (nrm, off) = if off < 0.0 { (-nrm, -off) } else { (nrm, off) };
                if w.iter().all(|x| nrm.dot(x) <= off + 1e-12) {
                    nearest = nearest.min(off);
                }
            }
            // Next six-subset in lexicographic order.
            let Some(k) = (0..D).rev().find(|&k| idx[k] < n - D + k) else {
                break;
            };
            idx[k] += 1;
            for m in k + 1..D {
                idx[m] = idx[m - 1] + 1;
            }
        }
        assert!((nearest - closed).abs() < 1e-12, "{nearest} vs {closed}");
        let q = quality(&w);
        assert!(q.force_closure, "{q:?}");
        assert!(
            (q.epsilon - closed).abs() < 1e-6,
            "{} vs {closed}",
            q.epsilon
        );
    }
}
