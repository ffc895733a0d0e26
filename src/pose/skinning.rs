//! Skinning: the posed position of any point set (skin vertices, tetrahedral nodes) from
//! per-point link weights and the rigid motion of every link
//! ([`crate::skeleton::forward_kinematics::link_transforms`]).
//!
//! * Linear blend skinning (LBS; Magnenat-Thalmann et al. 1988): `p' = Σ_l w_l T_l p`.
//! * Dual-quaternion skinning (DQS; Kavan, Collins, Žára & O'Sullivan 2008, "Geometric skinning
//!   with approximate dual quaternion blending", ACM TOG 27(4)): the links' unit dual
//!   quaternions are blended (antipodality resolved against the point's dominant link),
//!   normalised, and applied as one rigid motion; it does not collapse a joint's volume the way
//!   LBS does ("candy wrapper").
//!
//! Both are written so that identity transforms reproduce the rest positions *bit for bit*
//! (the "zero angles reproduce the skin exactly"): LBS accumulates displacements
//! `Σ w_l ((R_l − I) p + t_l)`, which are exactly zero for identities, instead of a blended
//! matrix whose weights sum to 1 only up to round-off; DQS normalises a blended real part
//! `(Σw, 0, 0, 0)` to exactly `(1, 0, 0, 0)`.

use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::template::LinkWeights;
use nalgebra::{Isometry3, Quaternion, Vector3};

/// Which skinning to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Skinning {
    /// Linear blend skinning (what glTF viewers do).
    Linear,
    /// Dual-quaternion skinning (volume-preserving at bent joints; the default for files).
    #[default]
    DualQuaternion,
}

impl Skinning {
    /// `"lbs"` or `"dqs"`.
    pub fn name(self) -> &'static str {
        match self {
            Skinning::Linear => "lbs",
            Skinning::DualQuaternion => "dqs",
        }
    }
}

/// Per-point weights flattened to compressed rows (`offsets[i]..offsets[i + 1]` index `links`
/// and `weights`), the layout the LBS inner loop streams through.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseWeights {
    offsets: Vec<u32>,
    links: Vec<u32>,
    weights: Vec<f64>,
    n_links: usize,
}

impl SparseWeights {
    /// Flatten `weights` (one list per point of (link index, weight)). Errors (naming the point)
    /// on a link index `>= n_links`, a non-finite or negative weight, or a point whose weights
    /// do not sum to 1 within 1e-6 (every point must follow the links, or it would be left
    /// behind, scaled toward the origin).
    pub fn new(weights: &LinkWeights, n_links: usize) -> Result<Self> {
        let total: usize = weights.iter().map(Vec::len).sum();
        if total >= u32::MAX as usize {
            return Err(Error::invalid("skinning weights: too many entries"));
        }
        let mut offsets = Vec::with_capacity(weights.len() + 1);
        let mut links = Vec::with_capacity(total);
        let mut ws = Vec::with_capacity(total);
        offsets.push(0u32);
        for (i, w) in weights.iter().enumerate() {
            let mut sum = 0.0;
            for &(l, x) in w {
                if l >= n_links {
                    return Err(Error::invalid(format!(
                        "skinning weights: point {i} refers to link {l}, but there are {n_links} links"
                    )));
                }
                if !x.is_finite() || x < 0.0 {
                    return Err(Error::invalid(format!(
                        "skinning weights: point {i} has weight {x} for link {l}; weights must be finite and >= 0"
                    )));
                }
                sum += x;
                links.push(l as u32);
                ws.push(x);
            }
            if (sum - 1.0).abs() > 1e-6 {
                return Err(Error::invalid(format!(
                    "skinning weights: point {i}'s weights sum to {sum}, not 1; renormalise them"
                )));
            }
            offsets.push(links.len() as u32);
        }
        Ok(SparseWeights {
            offsets,
            links,
            weights: ws,
            n_links,
        })
    }

    /// Number of points.
    pub fn n_points(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Number of links the indices refer to.
    pub fn n_links(&self) -> usize {
        self.n_links
    }

    /// The (link, weight) pairs of point `i`.
    pub fn of(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.offsets[i] as usize..self.offsets[i + 1] as usize;
        self.links[r.clone()]
            .iter()
            .zip(&self.weights[r])
            .map(|(&l, &w)| (l as usize, w))
    }
}

/// A point set bound to links for repeated posing: rest positions and flattened weights.
#[derive(Clone, Debug)]
pub struct SkinBinding {
    rest: Vec<[f64; 3]>,
    weights: SparseWeights,
}

impl SkinBinding {
    /// Bind `rest` points with per-point `weights` over `n_links` links (see
    /// [`SparseWeights::new`] for the checks; the counts must agree).
    pub fn new(rest: &[Point], weights: &LinkWeights, n_links: usize) -> Result<Self> {
        if rest.len() != weights.len() {
            return Err(Error::invalid(format!(
                "skinning: {} points but {} weight lists",
                rest.len(),
                weights.len()
            )));
        }
        if let Some(i) = rest
            .iter()
            .position(|p| !p.coords.iter().all(|x| x.is_finite()))
        {
            return Err(Error::invalid(format!("skinning: point {i} is not finite")));
        }
        Ok(SkinBinding {
            rest: rest.iter().map(|p| [p.x, p.y, p.z]).collect(),
            weights: SparseWeights::new(weights, n_links)?,
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// True when no point is bound.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// The flattened weights.
    pub fn weights(&self) -> &SparseWeights {
        &self.weights
    }

    fn check(&self, transforms: &[Isometry3<f64>]) {
        assert!(
            transforms.len() >= self.weights.n_links,
            "skinning: {} transforms for {} links",
            transforms.len(),
            self.weights.n_links
        );
    }

    /// Linear blend skinning into `out` (resized to the point count), the fast path: per link a
    /// 3x4 `[R − I | t]`, per point at most a few fused multiply-adds per weight.
    ///
    /// Panics if `transforms` has fewer entries than the binding's links (a programming error:
    /// [`crate::skeleton::forward_kinematics::link_transforms`] always gives one per link).
    pub fn linear_into(&self, transforms: &[Isometry3<f64>], out: &mut Vec<Point>) {
        self.check(transforms);
        let mats: Vec<[f64; 12]> = transforms.iter().map(displacement_matrix).collect();
        let w = &self.weights;
        out.clear();
        out.resize(self.rest.len(), Point::origin());
        // Slices zipped rather than indexed: no bounds checks in the inner loop.
        for ((o, p), r) in out.iter_mut().zip(&self.rest).zip(w.offsets.windows(2)) {
            let [x, y, z] = *p;
            let (a, b) = (r[0] as usize, r[1] as usize);
            let (mut dx, mut dy, mut dz) = (0.0, 0.0, 0.0);
            for (&l, &a) in w.links[a..b].iter().zip(&w.weights[a..b]) {
                let m = &mats[l as usize];
                dx += a * (m[0] * x + m[1] * y + m[2] * z + m[3]);
                dy += a * (m[4] * x + m[5] * y + m[6] * z + m[7]);
                dz += a * (m[8] * x + m[9] * y + m[10] * z + m[11]);
            }
            *o = Point::new(x + dx, y + dy, z + dz);
        }
    }

    /// Linear blend skinning: the posed points.
    pub fn linear(&self, transforms: &[Isometry3<f64>]) -> Vec<Point> {
        let mut out = Vec::new();
        self.linear_into(transforms, &mut out);
        out
    }

    /// Dual-quaternion skinning (Kavan et al. 2008, algorithm 1 with the antipodality check
    /// against the point's dominant link): the posed points.
    pub fn dual_quaternion(&self, transforms: &[Isometry3<f64>]) -> Vec<Point> {
        self.check(transforms);
        let dqs: Vec<DualQuat> = transforms.iter().map(DualQuat::from_isometry).collect();
        let w = &self.weights;
        self.rest
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let p = Vector3::new(p[0], p[1], p[2]);
                let range = w.offsets[i] as usize..w.offsets[i + 1] as usize;
                // The antipodality pivot is the point's dominant link, whatever the order its
                // weights come in: a pivot on a small weight across a joint bent past 180°
                // (a fist's proximal link against the palm) would flip the blend.
                let Some(dominant) = range
                    .clone()
                    .max_by(|&a, &b| w.weights[a].total_cmp(&w.weights[b]))
                else {
                    return Point::from(p);
                };
                let first = range.start;
                let pivot = dqs[w.links[dominant] as usize].real;
                let mut real = Quaternion::new(0.0, 0.0, 0.0, 0.0);
                let mut dual = Quaternion::new(0.0, 0.0, 0.0, 0.0);
                for k in first..w.offsets[i + 1] as usize {
                    let d = &dqs[w.links[k] as usize];
                    let a = if d.real.dot(&pivot) < 0.0 {
                        -w.weights[k]
                    } else {
                        w.weights[k]
                    };
                    real += d.real * a;
                    dual += d.dual * a;
                }
                let n = real.norm();
                if n < 1e-12 {
                    return Point::from(p);
                }
                let (r, d) = (real / n, dual / n);
                let (w0, v0) = (r.w, r.imag());
                let (we, ve) = (d.w, d.imag());
                // Rotation by the unit quaternion (w0, v0), then the translation of the unit
                // dual quaternion: t = 2 (w0 ve − we v0 + v0 × ve).
                let rotated = p + (v0.cross(&p) * w0 + v0.cross(&v0.cross(&p))) * 2.0;
                let t = (ve * w0 - v0 * we + v0.cross(&ve)) * 2.0;
                Point::from(rotated + t)
            })
            .collect()
    }

    /// Pose with the chosen skinning.
    pub fn apply(&self, method: Skinning, transforms: &[Isometry3<f64>]) -> Vec<Point> {
        match method {
            Skinning::Linear => self.linear(transforms),
            Skinning::DualQuaternion => self.dual_quaternion(transforms),
        }
    }
}

/// `[R − I | t]` row-major: the displacement of a point under the isometry.
pub(crate) fn displacement_matrix(t: &Isometry3<f64>) -> [f64; 12] {
    let r = t.rotation.to_rotation_matrix();
    let m = r.matrix();
    let v = &t.translation.vector;
    [
        m[(0, 0)] - 1.0,
        m[(0, 1)],
        m[(0, 2)],
        v.x,
        m[(1, 0)],
        m[(1, 1)] - 1.0,
        m[(1, 2)],
        v.y,
        m[(2, 0)],
        m[(2, 1)],
        m[(2, 2)] - 1.0,
        v.z,
    ]
}

/// A unit dual quaternion `real + ε dual` (rotation `real`, then translation `t`, with
/// `dual = ½ t real`).
#[derive(Clone, Copy, Debug)]
struct DualQuat {
    real: Quaternion<f64>,
    dual: Quaternion<f64>,
}

impl DualQuat {
    fn from_isometry(t: &Isometry3<f64>) -> Self {
        let real = *t.rotation.quaternion();
        let v = t.translation.vector;
        let tq = Quaternion::new(0.0, v.x, v.y, v.z);
        DualQuat {
            real,
            dual: tq * real * 0.5,
        }
    }
}

/// Linear blend skinning of `points` with `weights` over `transforms.len()` links (one-shot
/// form of [`SkinBinding::linear`]).
pub fn linear_blend(
    points: &[Point],
    weights: &LinkWeights,
    transforms: &[Isometry3<f64>],
) -> Result<Vec<Point>> {
    Ok(SkinBinding::new(points, weights, transforms.len())?.linear(transforms))
}

/// Dual-quaternion skinning of `points` with `weights` over `transforms.len()` links
/// (one-shot form of [`SkinBinding::dual_quaternion`]).
pub fn dual_quaternion(
    points: &[Point],
    weights: &LinkWeights,
    transforms: &[Isometry3<f64>],
) -> Result<Vec<Point>> {
    Ok(SkinBinding::new(points, weights, transforms.len())?.dual_quaternion(transforms))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Translation3, Unit, UnitQuaternion};

    fn random_iso(rng: &mut Rng) -> Isometry3<f64> {
        let axis = Unit::new_normalize(Vector3::new(
            rng.normal(),
            rng.normal(),
            rng.normal() + 1e-3,
        ));
        Isometry3::from_parts(
            Translation3::new(
                rng.normal() * 20.0,
                rng.normal() * 20.0,
                rng.normal() * 20.0,
            ),
            UnitQuaternion::from_axis_angle(&axis, rng.normal() * 1.5),
        )
    }

    fn points(rng: &mut Rng, n: usize) -> Vec<Point> {
        (0..n)
            .map(|_| {
                Point::new(
                    rng.normal() * 50.0,
                    rng.normal() * 50.0,
                    rng.normal() * 50.0,
                )
            })
            .collect()
    }

    /// With one link per point both methods are that link's rigid motion.
    #[test]
    fn single_link_weights_are_rigid_for_both_methods() {
        let mut rng = Rng::new(5);
        let t: Vec<_> = (0..4).map(|_| random_iso(&mut rng)).collect();
        let p = points(&mut rng, 200);
        let w: LinkWeights = (0..p.len()).map(|i| vec![(i % 4, 1.0)]).collect();
        let b = SkinBinding::new(&p, &w, 4).unwrap();
        let (l, d) = (b.linear(&t), b.dual_quaternion(&t));
        for i in 0..p.len() {
            let want = t[i % 4] * p[i];
            assert!((l[i] - want).norm() < 1e-9);
            assert!((d[i] - want).norm() < 1e-9);
        }
    }

    /// Identity transforms give the rest points bit for bit, whatever the weights.
    #[test]
    fn identity_is_exact() {
        let mut rng = Rng::new(6);
        let p = points(&mut rng, 300);
        let w: LinkWeights = (0..p.len())
            .map(|i| {
                let a = rng.uniform();
                vec![(i % 3, a), (3, 1.0 - a)]
            })
            .collect();
        let t = vec![Isometry3::identity(); 4];
        let b = SkinBinding::new(&p, &w, 4).unwrap();
        assert_eq!(b.linear(&t), p);
        assert_eq!(b.dual_quaternion(&t), p);
    }

    /// Blending two rotations about one axis by half: LBS shrinks the point toward the axis
    /// (chord midpoint), DQS keeps its distance (the interpolated rotation), the classic
    /// contrast of Kavan et al. 2008, figure 2.
    #[test]
    fn dqs_keeps_the_radius_where_lbs_collapses() {
        let axis = Vector3::z_axis();
        let t = vec![
            Isometry3::identity(),
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&axis, std::f64::consts::FRAC_PI_2),
            ),
        ];
        let p = vec![Point::new(10.0, 0.0, 3.0)];
        let w = vec![vec![(0, 0.5), (1, 0.5)]];
        let b = SkinBinding::new(&p, &w, 2).unwrap();
        let l = b.linear(&t)[0];
        let d = b.dual_quaternion(&t)[0];
        assert!((l.xy().coords.norm() - 10.0 * (0.5f64).sqrt()).abs() < 1e-9);
        assert!((d.xy().coords.norm() - 10.0).abs() < 1e-9);
        let half = std::f64::consts::FRAC_PI_4;
        assert!((d - Point::new(10.0 * half.cos(), 10.0 * half.sin(), 3.0)).norm() < 1e-9);
    }

    #[test]
    fn bad_weights_name_the_point() {
        let p = vec![Point::origin(); 3];
        let e = SkinBinding::new(&p, &vec![vec![(0, 1.0)], vec![(5, 1.0)], vec![(0, 1.0)]], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("point 1"), "{e}");
        let e = SkinBinding::new(&p, &vec![vec![(0, 1.0)], vec![(0, 1.0)], vec![(0, 0.5)]], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("point 2"), "{e}");
        assert!(SkinBinding::new(&p, &vec![vec![(0, 1.0)]], 2).is_err());
    }
}
