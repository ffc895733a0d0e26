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
//! The hull is the 6-D Quickhull of [`crate::geometry::convex_hull_6d`] (its input joggled by
//! [`JOGGLE`], which moves epsilon and volume by about 1e-7 relative). Epsilon alone
//! ([`epsilon`], what a grasp evaluation needs) does not need the whole hull: the nearest-facet
//! search ([`Hull::nearest_offset`]) refines only the facets near the origin and gives the whole
//! hull's epsilon on the same joggled points. The volume quality needs every facet. A grasp
//! without force closure has epsilon 0; how far it is from closure, the distance from the
//! origin to the hull ([`closure_distance`]), needs no hull at all (Wolfe's nearest point).

use super::contact::Contact;
pub use crate::geometry::convex_hull_6d::{Hull, JOGGLE};
use crate::geometry::min_norm_point::min_norm_point;
use crate::geometry::{Point, Vec3};
use nalgebra::Vector6;
use serde::Serialize;

/// Number of friction cone edges per contact.
pub const CONE_EDGES: usize = 8;

/// A 6-D wrench `[fx, fy, fz, τx/ρ, τy/ρ, τz/ρ]`.
pub(crate) type Wrench = Vector6<f64>;

/// The wrenches of the linearised friction cones ([`CONE_EDGES`] edges) of `contacts` on a
/// part with centre of mass `com` and torque scale `rho` (mm).
pub(crate) fn contact_wrenches(
    contacts: &[Contact],
    mu: f64,
    com: &Point,
    rho: f64,
) -> Vec<Wrench> {
    cone_wrenches(contacts, mu, com, rho, CONE_EDGES)
}

/// [`contact_wrenches`] with `edges` edges per friction cone (an inscribed pyramid: fewer
/// edges give a smaller, cheaper grasp wrench space whose epsilon is a lower bound of the
/// finer cone's, used to rank candidates before the full evaluation).
pub fn cone_wrenches(
    contacts: &[Contact],
    mu: f64,
    com: &Point,
    rho: f64,
    edges: usize,
) -> Vec<Wrench> {
    let mut out = Vec::with_capacity(contacts.len() * edges);
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
        for k in 0..edges {
            let th = 2.0 * std::f64::consts::PI * k as f64 / edges as f64;
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
                force_closure: eps > FORCE_CLOSURE_MIN,
                epsilon: eps.max(0.0),
                volume: h.volume(),
            }
        }
    }
}

/// The volume quality of `contacts` with friction `mu` on a part (`com`, `rho`), as
/// [`grasp_quality`] gives it, unless `stop` is set while the hull is built (`None` then).
pub fn grasp_volume_unless(
    contacts: &[Contact],
    mu: f64,
    com: &Point,
    rho: f64,
    stop: &std::sync::atomic::AtomicBool,
) -> Option<f64> {
    let w = contact_wrenches(contacts, mu, com, rho);
    match Hull::new_unless(&w, stop) {
        Some(h) => Some(h.volume()),
        None if stop.load(std::sync::atomic::Ordering::Relaxed) => None,
        None => Some(0.0),
    }
}

/// Quality of `contacts` with friction `mu` on a part (`com`, `rho`).
pub fn grasp_quality(contacts: &[Contact], mu: f64, com: &Point, rho: f64) -> Quality {
    quality(&contact_wrenches(contacts, mu, com, rho))
}

/// Force closure and the Ferrari-Canny epsilon without the volume quality: what the
/// evaluation of a grasp needs, computed without building the whole hull
/// ([`Hull::nearest_offset`]; the same numbers as [`quality`]'s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Epsilon {
    /// Origin strictly inside the grasp wrench space.
    pub force_closure: bool,
    /// Ferrari-Canny epsilon (0 without force closure).
    pub epsilon: f64,
}

/// Force closure and epsilon of a wrench set (see [`Epsilon`]).
pub fn epsilon(wrenches: &[Wrench]) -> Epsilon {
    let eps = Hull::nearest_offset(wrenches).unwrap_or(0.0);
    Epsilon {
        force_closure: eps > FORCE_CLOSURE_MIN,
        epsilon: eps.max(0.0),
    }
}

/// Force closure and epsilon of `contacts` with friction `mu` on a part (`com`, `rho`).
pub fn grasp_epsilon(contacts: &[Contact], mu: f64, com: &Point, rho: f64) -> Epsilon {
    epsilon(&contact_wrenches(contacts, mu, com, rho))
}

/// How far a grasp without force closure is from it: the distance from the origin to the
/// convex hull of its `wrenches` (0 when the hull holds the origin), by Wolfe's nearest point
/// ([`min_norm_point`]), in the units of epsilon. Where epsilon measures the largest
/// disturbance a force-closure grasp resists in every direction, this measures the smallest
/// wrench the grasp cannot resist in the worst direction: the nearer to 0, the less is missing.
/// `f64::INFINITY` for no wrenches.
pub fn closure_distance(wrenches: &[Wrench]) -> f64 {
    min_norm_point(wrenches, 1e-12)
        .map(|(x, _)| x.norm())
        .unwrap_or(f64::INFINITY)
}

/// Smallest epsilon counted as force closure: far above the joggle's effect ([`JOGGLE`]), far
/// below any grasp's.
const FORCE_CLOSURE_MIN: f64 = 1e-9;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::convex_hull_6d::{hyperplane, D};
    use crate::rng::Rng;
    use nalgebra::Matrix6;

    /// One contact at the centre of mass: its cone's edges (n + mu t_k, no torque) lie on the
    /// plane at distance |n| = 1 normal to n, around n, so the nearest point of their hull is
    /// n itself and the distance from force closure is 1 whatever mu (closed form). An opposing
    /// contact at the same point brings the origin into the hull: distance 0, though a pair
    /// pressing along one line is not force closure (no torque about that line; epsilon says
    /// so, the distance cannot). Grasps with force closure are at distance 0, those without
    /// farther.
    #[test]
    fn closure_distance_closed_forms() {
        let com = Point::origin();
        for mu in [0.2, 0.5, 1.0] {
            let one = [contact([0.0; 3], [0.0, 0.0, 1.0])];
            let w = cone_wrenches(&one, mu, &com, 20.0, CONE_EDGES);
            assert!(
                (closure_distance(&w) - 1.0).abs() < 1e-9,
                "{}",
                closure_distance(&w)
            );
            let pair = [one[0].clone(), contact([0.0; 3], [0.0, 0.0, -1.0])];
            let w = cone_wrenches(&pair, mu, &com, 20.0, CONE_EDGES);
            assert!(closure_distance(&w) < 1e-9, "{}", closure_distance(&w));
            assert!(!epsilon(&w).force_closure);
        }
        let mut rng = Rng::new(3);
        let (mut closed, mut open) = (0, 0);
        for n in [2, 3, 4, 6, 10, 20] {
            for mu in [0.2, 0.5] {
                let w = contact_wrenches(&scattered_contacts(&mut rng, n), mu, &com, 20.0);
                let d = closure_distance(&w);
                if epsilon(&w).force_closure {
                    assert!(d < 1e-9, "{n} contacts: {d}");
                    closed += 1;
                } else {
                    open += 1;
                }
            }
        }
        assert!(closed >= 3 && open >= 1, "{closed} / {open}");
    }

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
        let e = epsilon(&w);
        assert!(e.force_closure && (e.epsilon - 1.0 / 6f64.sqrt()).abs() < 1e-5);
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
        assert!((epsilon(&w).epsilon - 1.0).abs() < 2e-3);
    }

    /// The volume built beside other work is the whole hull's, and a hull asked to stop gives
    /// none (the stop is read before the first point is added).
    #[test]
    fn a_volume_given_up_is_none_and_one_not_given_up_is_the_whole_hulls() {
        use std::sync::atomic::AtomicBool;
        let mut rng = Rng::new(5);
        let com = Point::origin();
        let contacts = scattered_contacts(&mut rng, 10);
        let whole = grasp_quality(&contacts, 0.5, &com, 20.0).volume;
        assert!(whole > 0.0);
        let go_on = AtomicBool::new(false);
        assert_eq!(
            grasp_volume_unless(&contacts, 0.5, &com, 20.0, &go_on),
            Some(whole)
        );
        let stop = AtomicBool::new(true);
        assert_eq!(grasp_volume_unless(&contacts, 0.5, &com, 20.0, &stop), None);
        // Points that do not span 6-D have no hull: volume 0, as the whole quality says.
        let one = [contacts[0].clone()];
        assert_eq!(grasp_quality(&one, 0.5, &com, 20.0).volume, 0.0);
        assert_eq!(
            grasp_volume_unless(&one, 0.5, &com, 20.0, &go_on),
            Some(0.0)
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
        assert_eq!(
            epsilon(&w),
            Epsilon {
                force_closure: false,
                epsilon: 0.0
            }
        );
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
        let e = epsilon(&w);
        assert!(
            e.force_closure && (e.epsilon - closed).abs() < 1e-6,
            "{e:?}"
        );
    }

    /// Point contacts scattered over a sphere of radius 20 mm around the centre of mass,
    /// pushing roughly inward (normals tilted by up to 0.3 rad), as a grasp's patches are.
    pub(crate) fn scattered_contacts(rng: &mut Rng, n: usize) -> Vec<Contact> {
        (0..n)
            .map(|_| {
                let d = rng.unit_vector();
                let tilt = Vec3::from_fn(|_, _| rng.range(-0.3, 0.3));
                let nrm = (-d + tilt).normalize();
                contact((d * 20.0).into(), nrm.into())
            })
            .collect()
    }

    /// The nearest-facet search ([`Hull::nearest_offset`]) against the whole hull's nearest
    /// facet ([`Hull::min_offset`]): equal when the origin is inside, both negative when it is
    /// outside; for grasps of 3 to 40 contacts (24 to 320 wrenches, force closure or not) and
    /// point clouds with the origin inside, near the boundary and far outside.
    #[test]
    fn nearest_facet_search_equals_whole_hull() {
        let mut rng = Rng::new(11);
        let mut sets: Vec<Vec<Wrench>> = Vec::new();
        for n in [3, 4, 6, 10, 20, 31, 40] {
            for mu in [0.2, 0.5, 1.0] {
                let cs = scattered_contacts(&mut rng, n);
                sets.push(contact_wrenches(&cs, mu, &Point::origin(), 20.0));
            }
        }
        for shift in [0.0, 0.5, 3.0] {
            for _ in 0..3 {
                sets.push(
                    (0..150)
                        .map(|_| Vector6::from_fn(|_, _| rng.range(-1.0, 1.0) + shift))
                        .collect(),
                );
            }
        }
        let (mut inside, mut outside) = (0, 0);
        for w in &sets {
            // Both on the same joggled points: the first joggle the whole hull builds with
            // (a larger joggle moves epsilon by up to 0.3 % on these near-degenerate sets,
            // whose facets hold several edges of one cone).
            let (whole, nearest) = [1.0, 1e2, 1e4]
                .into_iter()
                .find_map(|m| {
                    let h = Hull::build(w, JOGGLE * m, None)?;
                    Some((Some(h.min_offset()), Hull::expand_nearest(w, JOGGLE * m)))
                })
                .unwrap_or((None, Hull::nearest_offset(w)));
            match (whole, nearest) {
                (Some(a), Some(b)) if a > 0.0 => {
                    assert!((a - b).abs() <= 1e-9 * (1.0 + a), "{a} vs {b}");
                    inside += 1;
                }
                (Some(a), Some(b)) => {
                    assert!(b <= 0.0 && b >= a - 1e-9, "{a} vs {b}");
                    outside += 1;
                }
                (a, b) => assert_eq!(a.is_some(), b.is_some()),
            }
            assert_eq!(epsilon(w).force_closure, quality(w).force_closure);
        }
        // Both branches are exercised.
        assert!(inside >= 5 && outside >= 5, "{inside} / {outside}");
    }
}
