//! The point of a convex hull nearest the origin: Wolfe's algorithm (P. Wolfe 1976, "Finding
//! the nearest point in a polytope", Mathematical Programming 11, 128-149).
//!
//! The hull is never built: the algorithm keeps a corral of at most `N + 1` affinely
//! independent points whose affine hull's nearest point is a convex combination of them, adds
//! the input point most opposed to the current nearest point (a major cycle) and, when the
//! affine minimum leaves the corral's simplex, walks back to its boundary and drops the points
//! whose weight vanished (minor cycles). It ends when no input point lies beyond the
//! hyperplane through the current point normal to it. The cost is a few linear scans of the
//! input and small linear solves, against the tens of thousands of facets of a 6-D hull of a
//! few hundred points.

use nalgebra::{DMatrix, DVector, SVector};

/// The point of the convex hull of `points` nearest the origin and its convex weights (one per
/// input point, summing to 1; zero for points outside the final corral); `None` for an empty
/// input or a non-finite coordinate. `tol` is relative to the largest squared norm of the
/// input: the answer's squared norm is within `tol` of the optimum's scale.
pub fn min_norm_point<const N: usize>(
    points: &[SVector<f64, N>],
    tol: f64,
) -> Option<(SVector<f64, N>, Vec<f64>)> {
    if points.is_empty() || points.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
        return None;
    }
    let scale = points.iter().map(|p| p.norm_squared()).fold(0.0, f64::max);
    if scale == 0.0 {
        let mut w = vec![0.0; points.len()];
        w[0] = 1.0;
        return Some((SVector::zeros(), w));
    }
    let tol = tol.max(f64::EPSILON) * scale;
    // The corral: input indices and their weights.
    let start = (0..points.len())
        .min_by(|&a, &b| {
            points[a]
                .norm_squared()
                .total_cmp(&points[b].norm_squared())
        })
        .expect("non-empty");
    let mut corral: Vec<usize> = vec![start];
    let mut lambda: Vec<f64> = vec![1.0];
    let mut x = points[start];
    // Wolfe's algorithm is finite; the cap guards the round-off cycles it can fall into.
    for _ in 0..(50 * (N + 1) + points.len()) {
        // Major cycle: the point most opposed to x.
        let (j, pj) = points
            .iter()
            .enumerate()
            .map(|(j, p)| (j, p.dot(&x)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("non-empty");
        let xx = x.norm_squared();
        if xx - pj <= tol || corral.contains(&j) || corral.len() > N {
            break;
        }
        corral.push(j);
        lambda.push(0.0);
        // Minor cycles: the affine minimum of the corral, walked back into its simplex.
        loop {
            let Some(alpha) = affine_minimum(points, &corral) else {
                // Affinely dependent after all: drop the newcomer and stop here.
                corral.pop();
                lambda.pop();
                return Some((x, weights(points.len(), &corral, &lambda)));
            };
            if alpha.iter().all(|&a| a > 1e-12) {
                lambda = alpha;
                break;
            }
            // The largest step from lambda toward alpha that keeps every weight >= 0.
            let theta = lambda
                .iter()
                .zip(&alpha)
                .filter(|(_, a)| **a <= 1e-12)
                .map(|(l, a)| l / (l - a))
                .fold(1.0, f64::min)
                .clamp(0.0, 1.0);
            for (l, a) in lambda.iter_mut().zip(&alpha) {
                *l = theta * a + (1.0 - theta) * *l;
            }
            // Drop the points whose weight vanished (at least the one that set theta), decided
            // on the positions before any is removed.
            let min_k = (0..lambda.len())
                .min_by(|&a, &b| lambda[a].total_cmp(&lambda[b]))
                .expect("non-empty");
            let keep: Vec<bool> = lambda
                .iter()
                .enumerate()
                .map(|(k, &l)| !(l <= 1e-12 || k == min_k && l <= 1e-9))
                .collect();
            let mut kept = keep.iter();
            corral.retain(|_| *kept.next().expect("one mark per point"));
            let mut kept = keep.iter();
            lambda.retain(|_| *kept.next().expect("one mark per point"));
            if corral.is_empty() {
                return None;
            }
            let s: f64 = lambda.iter().sum();
            lambda.iter_mut().for_each(|l| *l /= s);
        }
        let y: SVector<f64, N> = corral
            .iter()
            .zip(&lambda)
            .map(|(&i, &l)| points[i] * l)
            .sum();
        // A step that does not bring x nearer ends the search (round-off).
        if y.norm_squared() >= xx {
            break;
        }
        x = y;
    }
    Some((x, weights(points.len(), &corral, &lambda)))
}

/// Weights of the corral spread over every input point.
fn weights(n: usize, corral: &[usize], lambda: &[f64]) -> Vec<f64> {
    let mut w = vec![0.0; n];
    for (&i, &l) in corral.iter().zip(lambda) {
        w[i] = l;
    }
    w
}

/// Weights (summing to 1) of the point of the affine hull of `points[corral]` nearest the
/// origin, from the bordered system `[G 1; 1ᵀ 0] [a; mu] = [0; 1]` with `G` the corral's Gram
/// matrix; `None` when the corral is affinely dependent.
fn affine_minimum<const N: usize>(
    points: &[SVector<f64, N>],
    corral: &[usize],
) -> Option<Vec<f64>> {
    let m = corral.len();
    let mut a = DMatrix::zeros(m + 1, m + 1);
    for (r, &i) in corral.iter().enumerate() {
        for (c, &j) in corral.iter().enumerate() {
            a[(r, c)] = points[i].dot(&points[j]);
        }
        a[(r, m)] = 1.0;
        a[(m, r)] = 1.0;
    }
    let mut b = DVector::zeros(m + 1);
    b[m] = 1.0;
    // An affinely dependent corral makes the system singular (no solution) or, with round-off,
    // nearly so (huge or non-finite weights).
    let sol = a.full_piv_lu().solve(&b)?;
    let alpha: Vec<f64> = sol.iter().take(m).copied().collect();
    if alpha.iter().any(|x| !x.is_finite()) || alpha.iter().map(|x| x.abs()).sum::<f64>() > 1e9 {
        return None;
    }
    Some(alpha)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Vector2, Vector3, Vector6};

    /// A segment away from the origin: the nearest point is the foot of the perpendicular
    /// (closed form), with the weights that give it.
    #[test]
    fn segment_foot_of_the_perpendicular() {
        let p = [Vector2::new(-1.0, 2.0), Vector2::new(3.0, 2.0)];
        let (x, w) = min_norm_point(&p, 1e-12).unwrap();
        assert!((x - Vector2::new(0.0, 2.0)).norm() < 1e-12, "{x}");
        assert!(
            (w[0] - 0.75).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12,
            "{w:?}"
        );
        // Beyond the end: the nearer endpoint.
        let p = [Vector2::new(1.0, 2.0), Vector2::new(3.0, 2.0)];
        let (x, _) = min_norm_point(&p, 1e-12).unwrap();
        assert!((x - Vector2::new(1.0, 2.0)).norm() < 1e-12, "{x}");
    }

    /// A triangle in a plane at height 5 over a triangle holding the foot: distance 5; with
    /// the origin inside a tetrahedron: 0.
    #[test]
    fn plane_distance_and_inside() {
        let p = [
            Vector3::new(-1.0, -1.0, 5.0),
            Vector3::new(2.0, -1.0, 5.0),
            Vector3::new(0.0, 3.0, 5.0),
        ];
        let (x, w) = min_norm_point(&p, 1e-12).unwrap();
        assert!((x - Vector3::new(0.0, 0.0, 5.0)).norm() < 1e-9, "{x}");
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let t = [
            Vector3::new(1.0, 1.0, 1.0),
            Vector3::new(1.0, -1.0, -1.0),
            Vector3::new(-1.0, 1.0, -1.0),
            Vector3::new(-1.0, -1.0, 1.0),
        ];
        let (x, _) = min_norm_point(&t, 1e-12).unwrap();
        assert!(x.norm() < 1e-9, "{x}");
    }

    /// Random 6-D clouds shifted off the origin: the answer is the optimum of the convex
    /// program, checked by its optimality condition (no input point beyond the hyperplane
    /// through x normal to x: p·x >= |x|² for every p) and by the weights reproducing x.
    #[test]
    fn optimality_on_random_clouds() {
        let mut rng = Rng::new(5);
        let mut outside = 0;
        for trial in 0..60 {
            let n = 8 + trial * 5;
            let shift = Vector6::from_fn(|_, _| rng.range(-1.0, 1.0)) * (trial % 4) as f64;
            let p: Vec<Vector6<f64>> = (0..n)
                .map(|_| Vector6::from_fn(|_, _| rng.range(-1.0, 1.0)) + shift)
                .collect();
            let (x, w) = min_norm_point(&p, 1e-14).unwrap();
            let xx = x.norm_squared();
            for q in &p {
                assert!(
                    q.dot(&x) >= xx - 1e-9,
                    "trial {trial}: {} < {xx}",
                    q.dot(&x)
                );
            }
            assert!(w.iter().all(|&l| l >= 0.0));
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            let y: Vector6<f64> = p.iter().zip(&w).map(|(q, l)| q * *l).sum();
            assert!((y - x).norm() < 1e-9, "trial {trial}");
            if xx > 1e-6 {
                outside += 1;
            }
        }
        assert!(outside >= 20, "{outside}");
    }
}
