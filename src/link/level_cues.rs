//! A hinge's level along its axis from several cues (the dorsal landmark, the plates, the skin's
//! cross-section), each off the true level by its own error: the cues' error variances
//! estimated over the hinges of a hand from their pairwise differences (the three-cornered hat
//! of clock comparison, Gray & Allan 1974), and the inverse-variance weights they give; and a
//! hinge's depth from the motion and the skin, weighed by how their errors are shared.

use std::collections::BTreeMap;

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

/// [`depth_weight`] keeps the skin's weight in a hinge's depth within this and one minus it:
/// with a hand's nine or ten such hinges each variance is uncertain by about ±50 %, and neither
/// cue is ever known to be exact.
const DEPTH_WEIGHT_BOUND: f64 = 0.1;

/// How a hand's hinge depths weigh the skin against the motion ([`depth_weight`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthWeight {
    /// The skin's weight in each depth; the motion's is one minus it.
    pub skin: f64,
    /// The motion's error variance, mm².
    pub motion_variance: f64,
    /// The skin's error variance, mm².
    pub skin_variance: f64,
}

/// The weight of the skin's depth of a hinge against the motion's, from all of a hand's
/// hinges that have both: `cues` holds per hinge its kind (PIP, DIP, IP) and the skin's depth
/// minus the motion's, mm.
///
/// Two cues alone say only the sum of their error variances; what tells them apart is how
/// their errors are shared. The motion's depth is off by each plate's slide along its bone,
/// a new placement on every digit, so its error varies from hinge to hinge; the skin's is off
/// where the subject's proportions differ from the template's (how deep a PIP sits in the
/// finger's thickness), the same way at every hinge of a kind. So, a variance-components
/// split (one-way random effects): the spread of the differences about their kind's mean is
/// the motion's variance (`n − K` degrees of freedom), the mean square of the kinds' means,
/// less the motion's share in each mean (`v_m / n_k`), the skin's; the skin's weight is
/// `v_m / (v_m + v_s)`, kept within [`DEPTH_WEIGHT_BOUND`] of 0 and 1. The skin fit's own error
/// per hinge is counted with the motion's, a plate slide shared by a kind with the skin's:
/// both err toward the other cue. `None` with fewer than `K + 2` hinges.
pub fn depth_weight(cues: &[(&str, f64)]) -> Option<DepthWeight> {
    let mut kinds: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for &(k, d) in cues {
        kinds.entry(k).or_default().push(d);
    }
    let n = cues.len();
    if n < kinds.len() + 2 {
        return None;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let spread: f64 = kinds
        .values()
        .map(|v| {
            let m = mean(v);
            v.iter().map(|d| (d - m).powi(2)).sum::<f64>()
        })
        .sum();
    let motion_variance = (spread / (n - kinds.len()) as f64).max(MIN_CUE_VARIANCE);
    let shared: f64 = kinds
        .values()
        .map(|v| v.len() as f64 * (mean(v).powi(2) - motion_variance / v.len() as f64))
        .sum::<f64>()
        / n as f64;
    let skin_variance = shared.max(MIN_CUE_VARIANCE);
    let skin = (motion_variance / (motion_variance + skin_variance))
        .clamp(DEPTH_WEIGHT_BOUND, 1.0 - DEPTH_WEIGHT_BOUND);
    Some(DepthWeight {
        skin,
        motion_variance,
        skin_variance,
    })
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

    /// Hinge depths whose motion errors are independent per hinge and whose skin errors are
    /// one offset per kind: the split gives back the motion's variance and the kinds' mean
    /// square (within 15 % over many hands' worth of hinges), and the weight their ratio. A
    /// hand whose motion is exact (no plate slide) keeps the motion at the bound, and one whose
    /// skin is exact leans on the skin at the bound; too few hinges give none.
    #[test]
    fn depth_weight_splits_per_hinge_from_per_kind_errors() {
        let mut rng = crate::rng::Rng::new(9);
        let kinds = ["PIP", "DIP", "IP"];
        // Skin offsets per kind (mean square 1.0) and motion errors of SD 1.5 mm.
        let bias = [1.2, -0.9, 0.8];
        let cues: Vec<(&str, f64)> = (0..30_000)
            .map(|i| {
                let k = i % 3;
                (kinds[k], bias[k] - rng.gauss(0.0, 1.5))
            })
            .collect();
        let w = depth_weight(&cues).unwrap();
        let shared = bias.iter().map(|b| b * b).sum::<f64>() / 3.0;
        assert!((w.motion_variance / 2.25 - 1.0).abs() < 0.15, "{w:?}");
        assert!((w.skin_variance / shared - 1.0).abs() < 0.15, "{w:?}");
        assert!((w.skin - 2.25 / (2.25 + shared)).abs() < 0.03, "{w:?}");
        // A hand's nine hinges, the motion exact: the skin's offsets are all shared.
        let exact: Vec<(&str, f64)> = [("PIP", 1.0); 4]
            .into_iter()
            .chain([("DIP", -0.7); 4])
            .chain([("IP", 1.5)])
            .collect();
        assert_eq!(depth_weight(&exact).unwrap().skin, DEPTH_WEIGHT_BOUND);
        // The skin exact: the differences scatter about zero in every kind.
        let scattered: Vec<(&str, f64)> = [1.8, -2.0, 1.1, -0.9, 2.2, -1.7, 0.6, -1.3, 0.0]
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                (
                    if i < 4 {
                        "PIP"
                    } else if i < 8 {
                        "DIP"
                    } else {
                        "IP"
                    },
                    d,
                )
            })
            .collect();
        assert_eq!(
            depth_weight(&scattered).unwrap().skin,
            1.0 - DEPTH_WEIGHT_BOUND
        );
        assert!(depth_weight(&exact[..2]).is_none());
    }
}
