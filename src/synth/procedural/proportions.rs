//! A subject's hand proportions drawn from published anthropometry.
//!
//! Sources (all coefficients are in [`TABLE`], rounded):
//! * hand length (distal wrist crease to the tip of the middle finger) and hand breadth at the
//!   metacarpal heads: ANSUR II (Gordon et al. 2014), men 194 ± 9 mm and 90 ± 4 mm, women
//!   180 ± 9 mm and 79 ± 4 mm;
//! * segment lengths as fractions of hand length: Buchholz, Armstrong & Goldstein 1992 (joint
//!   centre to joint centre; the distal segment to the fingertip; the metacarpals from the
//!   carpometacarpal joint);
//! * finger breadths and thicknesses at the PIP (thumb: IP) and DIP joints, wrist breadth and
//!   thickness, hand thickness at the 3rd metacarpal head: approximate male means after Garrett
//!   1971 and Greiner 1991, scaled to the subject's hand breadth (so women's follow the ratio of
//!   the breadths).
//!
//! Correlations: one common size factor drives both hand length and breadth (correlation about
//! 0.6, as reported between them in ANSUR), and every segment and section dimension gets its own
//! log-normal residual (CV 3-4 %), so segments are correlated through the size factor only.
//! Stature is not drawn: its effect on the hand is what the size factor carries.

use crate::anatomy::Finger;
use crate::rng::Rng;

/// Sex of the simulated subject (selects the anthropometric means).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sex {
    Male,
    Female,
}

/// The coefficients of the proportion model.
pub struct Table {
    /// Hand length mean and SD, mm: `[male, female]`.
    pub hand_length: [(f64, f64); 2],
    /// Hand breadth (metacarpal) mean and SD, mm: `[male, female]`.
    pub hand_breadth: [(f64, f64); 2],
    /// Loading of hand length and breadth on the common size factor (their correlation is its
    /// square).
    pub size_loading: f64,
    /// Buchholz et al. 1992: per digit (thumb first) metacarpal, proximal, middle, distal
    /// segment lengths / hand length. The thumb has no middle phalanx (0).
    pub segments: [[f64; 4]; 5],
    /// Per digit, male means at hand breadth 90 mm: breadth and thickness at the PIP (thumb: IP)
    /// joint, breadth and thickness at the DIP joint (thumb: unused, 0), mm.
    pub finger_sections: [[f64; 4]; 5],
    /// Wrist breadth, wrist thickness and hand thickness at the 3rd metacarpal head per mm of
    /// hand breadth.
    pub wrist_breadth_per_hb: f64,
    pub wrist_thickness_per_hb: f64,
    pub palm_thickness_per_hb: f64,
    /// Coefficient of variation of each segment length's own residual.
    pub segment_cv: f64,
    /// Coefficient of variation of each section dimension's own residual.
    pub section_cv: f64,
}

/// The proportion model's coefficients (see the module documentation for the sources).
pub(crate) const TABLE: Table = Table {
    hand_length: [(194.0, 9.0), (180.0, 9.0)],
    hand_breadth: [(90.0, 4.0), (79.0, 4.0)],
    size_loading: 0.78,
    segments: crate::anatomy::SEGMENT_FRACTIONS,
    finger_sections: [
        [22.0, 19.5, 0.0, 0.0],
        [20.8, 19.0, 18.0, 15.5],
        [20.8, 19.5, 18.0, 16.0],
        [19.6, 18.5, 17.0, 15.0],
        [17.5, 16.5, 15.5, 13.5],
    ],
    wrist_breadth_per_hb: 0.66,
    wrist_thickness_per_hb: 0.43,
    palm_thickness_per_hb: 0.31,
    segment_cv: 0.03,
    section_cv: 0.04,
};

/// One subject's hand proportions, mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Proportions {
    pub sex: Sex,
    /// Distal wrist crease to the middle fingertip, straight hand.
    pub hand_length: f64,
    /// Across the metacarpal heads II-V.
    pub hand_breadth: f64,
    pub wrist_breadth: f64,
    pub wrist_thickness: f64,
    /// Hand thickness at the 3rd metacarpal head.
    pub palm_thickness: f64,
    /// Per digit (thumb first): metacarpal, proximal, middle (thumb: 0), distal (to the skin
    /// tip) lengths.
    pub segments: [[f64; 4]; 5],
    /// Per digit: breadth and thickness at the PIP (thumb: IP) joint, at the DIP joint (thumb:
    /// 0.9 of the IP's).
    pub sections: [[f64; 4]; 5],
}

impl Proportions {
    /// Draw a subject: sex 50/50, then the size factor and the residuals.
    pub fn sample(rng: &mut Rng) -> Proportions {
        let sex = if rng.uniform() < 0.5 {
            Sex::Male
        } else {
            Sex::Female
        };
        Self::sample_sex(rng, sex)
    }

    /// Draw a subject of the given sex.
    pub(crate) fn sample_sex(rng: &mut Rng, sex: Sex) -> Proportions {
        let t = &TABLE;
        let s = sex as usize;
        let size = rng.normal();
        let own = (1.0 - t.size_loading * t.size_loading).sqrt();
        let (lm, ls) = t.hand_length[s];
        let (bm, bs) = t.hand_breadth[s];
        let hand_length = lm + ls * (t.size_loading * size + own * rng.normal());
        let hand_breadth = bm + bs * (t.size_loading * size + own * rng.normal());
        Self::from_dimensions(sex, hand_length, hand_breadth, |cv| {
            (cv * rng.normal()).exp()
        })
    }

    /// The hand of one percentile of `sex` (0 < `percentile` < 100): hand length and breadth
    /// both at that percentile of the table's normal distributions, every segment and section
    /// at the table's proportion of them (no residuals): the designer's "5th percentile woman's
    /// hand".
    pub fn at_percentile(sex: Sex, percentile: f64) -> Proportions {
        let t = &TABLE;
        let s = sex as usize;
        let z = normal_quantile(percentile / 100.0);
        let (lm, ls) = t.hand_length[s];
        let (bm, bs) = t.hand_breadth[s];
        Self::from_dimensions(sex, lm + ls * z, bm + bs * z, |_| 1.0)
    }

    /// Segments and sections from hand length and breadth by the table's proportions, each
    /// times `residual(cv)` of its coefficient of variation (called in a fixed order: per digit,
    /// each segment then its section; then wrist breadth, wrist thickness, palm thickness).
    fn from_dimensions(
        sex: Sex,
        hand_length: f64,
        hand_breadth: f64,
        mut residual: impl FnMut(f64) -> f64,
    ) -> Proportions {
        let t = &TABLE;
        let mut segments = [[0.0; 4]; 5];
        let mut sections = [[0.0; 4]; 5];
        let breadth_scale = hand_breadth / t.hand_breadth[0].0;
        for f in Finger::ALL {
            let i = f as usize;
            for k in 0..4 {
                segments[i][k] = t.segments[i][k] * hand_length * residual(t.segment_cv);
                sections[i][k] = t.finger_sections[i][k] * breadth_scale * residual(t.section_cv);
            }
            // Thickness never exceeds breadth at a finger joint (elliptic sections).
            sections[i][1] = sections[i][1].min(sections[i][0] * 0.97);
            sections[i][3] = sections[i][3].min(sections[i][2] * 0.97);
        }
        sections[0][2] = 0.9 * sections[0][0];
        sections[0][3] = 0.9 * sections[0][1];
        // The middle ray is what hand length is: its segments sum to it exactly, the carpal part
        // (wrist crease to the 3rd carpometacarpal joint) taking the rest.
        Proportions {
            sex,
            hand_length,
            hand_breadth,
            wrist_breadth: hand_breadth * t.wrist_breadth_per_hb * residual(t.section_cv),
            wrist_thickness: hand_breadth * t.wrist_thickness_per_hb * residual(t.section_cv),
            palm_thickness: hand_breadth * t.palm_thickness_per_hb * residual(t.section_cv),
            segments,
            sections,
        }
    }

    /// Length of the middle ray from its carpometacarpal joint to the fingertip.
    pub fn middle_ray(&self) -> f64 {
        self.segments[Finger::Middle as usize].iter().sum()
    }
}

/// The standard normal quantile of `p` (0 < p < 1): Acklam's rational approximation (relative
/// error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known quantiles of the standard normal, and the percentile hands: the 50th is the
    /// table's mean, the 5th and 95th lie 1.645 SD either side.
    #[test]
    fn percentile_hands_follow_the_table() {
        for (p, z) in [
            (0.5, 0.0),
            (0.95, 1.6448536269514722),
            (0.05, -1.6448536269514722),
            (0.975, 1.959963984540054),
            (0.01, -2.3263478740408408),
        ] {
            assert!(
                (normal_quantile(p) - z).abs() < 1e-8,
                "{p}: {}",
                normal_quantile(p)
            );
        }
        for (sex, s) in [(Sex::Male, 0), (Sex::Female, 1)] {
            let (lm, ls) = TABLE.hand_length[s];
            let (bm, bs) = TABLE.hand_breadth[s];
            let mid = Proportions::at_percentile(sex, 50.0);
            assert!((mid.hand_length - lm).abs() < 1e-9 && (mid.hand_breadth - bm).abs() < 1e-9);
            let small = Proportions::at_percentile(sex, 5.0);
            let large = Proportions::at_percentile(sex, 95.0);
            assert!((small.hand_length - (lm - 1.6448536 * ls)).abs() < 1e-5);
            assert!((large.hand_breadth - (bm + 1.6448536 * bs)).abs() < 1e-5);
            // The middle ray sums to the hand length's table fraction.
            let frac: f64 = TABLE.segments[2].iter().sum();
            assert!((large.middle_ray() - frac * large.hand_length).abs() < 1e-9);
        }
    }

    #[test]
    fn draws_follow_the_table() {
        // 2,000 draws per sex: means within 3 SE, the length-breadth correlation near the
        // loading squared.
        for (sex, s) in [(Sex::Male, 0), (Sex::Female, 1)] {
            let mut rng = Rng::new(5 + s as u64);
            let n = 2000;
            let draws: Vec<Proportions> = (0..n)
                .map(|_| Proportions::sample_sex(&mut rng, sex))
                .collect();
            let mean =
                |f: &dyn Fn(&Proportions) -> f64| draws.iter().map(f).sum::<f64>() / n as f64;
            let (ml, mb) = (mean(&|p| p.hand_length), mean(&|p| p.hand_breadth));
            let (lm, ls) = TABLE.hand_length[s];
            let (bm, bs) = TABLE.hand_breadth[s];
            let se = (n as f64).sqrt();
            assert!((ml - lm).abs() < 3.0 * ls / se, "{ml}");
            assert!((mb - bm).abs() < 3.0 * bs / se, "{mb}");
            let cov = mean(&|p| (p.hand_length - ml) * (p.hand_breadth - mb));
            let sl = mean(&|p| (p.hand_length - ml).powi(2)).sqrt();
            let sb = mean(&|p| (p.hand_breadth - mb).powi(2)).sqrt();
            let r = cov / (sl * sb);
            let expect = TABLE.size_loading.powi(2);
            assert!((r - expect).abs() < 0.06, "r = {r}, expected {expect}");
            assert!((sl / ls - 1.0).abs() < 0.08, "{sl}");
            // Segments: Buchholz's fractions of hand length, on average.
            let frac = mean(&|p| p.segments[2][1] / p.hand_length);
            assert!((frac - TABLE.segments[2][1]).abs() < 0.002, "{frac}");
        }
    }
}
