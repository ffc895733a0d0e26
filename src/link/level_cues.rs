//! A hinge's level along its axis from several cues (the dorsal landmark, the plates, the skin's
//! cross-section), each off the true level by its own error: the cues' error variances
//! estimated over the hinges of a hand from their pairwise differences (the three-cornered hat
//! of clock comparison, Gray & Allan 1974), and the inverse-variance weights they give.

/// Smallest error variance [`cue_weights`] gives a cue, mm²: (0.1 mm)², so that cues that
/// agree exactly (error-free data) keep finite weights.
const MIN_CUE_VARIANCE: f64 = 0.01;

/// [`cue_weights`] keeps every cue's variance at least their mean over this.
const MAX_CUE_WEIGHT_RATIO: f64 = 3.0;

/// Weights of N level cues measuring the same quantities (every row of `offsets` one hinge,
/// its N cues' levels, mm): each cue's error variance from the mean squares of the pairwise
/// differences, `m_ij = s_i² + s_j²` for independent errors, solved by least squares over the
/// pairs (exact for three cues: the "three-cornered hat" of Gray & Allan 1974, used to tell
/// apart the instabilities of three clocks compared only with each other), each kept at least
/// their mean over [`MAX_CUE_WEIGHT_RATIO`] and [`MIN_CUE_VARIANCE`]; the weights are the
/// inverse variances normalised to 1. Returns the
/// weights and the variances; `None` with fewer than two cues or three rows of N.
pub fn cue_weights(offsets: &[Vec<f64>]) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = offsets.first()?.len();
    let rows: Vec<&Vec<f64>> = offsets.iter().filter(|r| r.len() == n).collect();
    if n < 2 || rows.len() < 3 {
        return None;
    }
    let variances = if n == 2 {
        // Only the sum is seen: equal shares.
        let m = rows.iter().map(|r| (r[0] - r[1]).powi(2)).sum::<f64>() / rows.len() as f64;
        vec![m / 2.0; 2]
    } else {
        let pairs: Vec<(usize, usize)> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect();
        let mut a = nalgebra::DMatrix::<f64>::zeros(pairs.len(), n);
        let mut b = nalgebra::DVector::<f64>::zeros(pairs.len());
        for (k, &(i, j)) in pairs.iter().enumerate() {
            a[(k, i)] = 1.0;
            a[(k, j)] = 1.0;
            b[k] = rows.iter().map(|r| (r[i] - r[j]).powi(2)).sum::<f64>() / rows.len() as f64;
        }
        a.svd(true, true)
            .solve(&b, 1e-12)
            .ok()?
            .iter()
            .copied()
            .collect()
    };
    // With a hand's fourteen hinges each estimate is uncertain by about ±65 % (the mean squares
    // of fourteen differences), and a negative or near-zero one would hand its cue all the
    // weight: each is kept at least a third of their mean, so no cue outweighs another more
    // than threefold.
    let mean = variances.iter().sum::<f64>() / n as f64;
    let floor = (mean / MAX_CUE_WEIGHT_RATIO).max(MIN_CUE_VARIANCE);
    let variances: Vec<f64> = variances.iter().map(|v| v.max(floor)).collect();
    let inv: Vec<f64> = variances.iter().map(|v| 1.0 / v).collect();
    let total: f64 = inv.iter().sum();
    Some((inv.iter().map(|w| w / total).collect(), variances))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three-cornered hat: from many hinges' cues with independent errors of known SDs,
    /// each cue's variance comes back within 10 % and the weights are the normalised inverse
    /// variances; a cue far better than the others is held to three times the weight of the
    /// mean variance's cue, and too few hinges give none.
    #[test]
    fn cue_weights_recover_independent_variances() {
        let mut rng = crate::rng::Rng::new(8);
        let rows = |rng: &mut crate::rng::Rng, sd: [f64; 3]| -> Vec<Vec<f64>> {
            (0..20_000)
                .map(|_| {
                    let level = rng.gauss(0.0, 5.0);
                    sd.iter().map(|s| level + rng.gauss(0.0, *s)).collect()
                })
                .collect()
        };
        let (w, v) = cue_weights(&rows(&mut rng, [0.8, 1.0, 1.2])).unwrap();
        for (got, want) in v.iter().zip([0.64, 1.0, 1.44]) {
            assert!((got / want - 1.0).abs() < 0.1, "{v:?}");
        }
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((w[0] * v[0] - w[2] * v[2]).abs() < 1e-12 && w[0] > w[1] && w[1] > w[2]);
        let (w, v) = cue_weights(&rows(&mut rng, [0.1, 1.0, 1.0])).unwrap();
        let mean = (0.01 + 1.0 + 1.0) / 3.0;
        assert!(
            (v[0] / (mean / MAX_CUE_WEIGHT_RATIO) - 1.0).abs() < 0.1,
            "{v:?}"
        );
        // 1 / (mean / 3) against 1 and 1: 4.48 / 6.48.
        assert!((w[0] - 0.691).abs() < 0.03, "{w:?}");
        assert!(cue_weights(&[vec![0.0, 1.0, 2.0], vec![1.0, 0.0, 0.5]]).is_none());
    }
}
