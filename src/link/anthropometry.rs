//! A link model's proportions against published anthropometry: the plausibility gate between
//! the link model and the skin.
//!
//! Each link between two estimated centres (the thumb's metacarpal and proximal phalanx, each
//! finger's proximal and middle phalanx) predicts a hand length through its fraction of hand
//! length (Buchholz, Armstrong & Goldstein 1992, [`SEGMENT_FRACTIONS`]); the hand's length is
//! the median of the ten predictions, so that one wild centre cannot move it. Then:
//! * a hand length no human has (outside [`HUMAN_HAND_LENGTH_MM`]) is an error: the trials'
//!   units or markers are wrong, and a skin fitted to it would be a confident wrong hand;
//! * one outside [`TYPICAL_HAND_LENGTH_MM`] (children, the largest adults) is a warning;
//! * a link whose own length is far from what the others predict (outside
//!   [`LINK_RATIO_RANGE`] of its prediction) is a warning naming the link and its trial.
//!
//! The margins are generous on purpose: the drawn and the template-body hands of the project's
//! simulators span 0.66-1.13 of their predictions, and this gate is for gross errors only.

use crate::anatomy::{Finger, Joint, SEGMENT_FRACTIONS};
use crate::error::{Error, Result};
use crate::geometry::TriMesh;
use crate::skeleton::Skeleton;

/// Hand lengths a human hand can have, mm: from a newborn's (about 60 mm) to beyond the
/// largest recorded adult's.
pub const HUMAN_HAND_LENGTH_MM: (f64, f64) = (60.0, 330.0);

/// Hand lengths of children from about four years and of adults up to well past the 99th
/// percentile (ANSUR II: men 194 ± 9 mm, women 180 ± 9 mm), mm.
pub const TYPICAL_HAND_LENGTH_MM: (f64, f64) = (100.0, 260.0);

/// A link's length over what the hand's length predicts for it, outside which it is named.
pub const LINK_RATIO_RANGE: (f64, f64) = (0.5, 1.7);

/// The skin's box diagonal over the hand length, outside which skin and link model disagree
/// grossly (the fitted skins of both simulators' bodies give 1.25-1.60; a lab's template with a
/// longer forearm gives more).
pub const SKIN_RATIO_RANGE: (f64, f64) = (0.8, 3.0);

/// One link between two estimated centres and what the hand's length predicts for it.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkProportion {
    /// `T_CMC-T_MCP`, `I_MCP-I_PIP`, ...
    pub name: String,
    /// The digit (its calibration trial estimated the link's distal centre).
    pub finger: Finger,
    /// Distance between the centres, mm.
    pub length_mm: f64,
    /// Its fraction of hand length (Buchholz et al. 1992).
    pub fraction: f64,
}

/// A link model's hand length and its links' proportions.
#[derive(Clone, Debug, PartialEq)]
pub struct HandProportions {
    /// The median of the links' predictions of hand length, mm.
    pub hand_length_mm: f64,
    pub links: Vec<LinkProportion>,
}

impl HandProportions {
    /// Each link's length over its prediction from the hand length.
    pub fn ratio(&self, link: &LinkProportion) -> f64 {
        link.length_mm / (link.fraction * self.hand_length_mm)
    }
}

/// The ten links between estimated centres of `sk` and the hand length they predict.
pub fn hand_proportions(sk: &Skeleton) -> HandProportions {
    let mut links = Vec::with_capacity(10);
    for f in Finger::ALL {
        let js = f.joints();
        // The thumb's links are its metacarpal and proximal phalanx (fractions 0 and 1), a
        // finger's its proximal and middle phalanx (1 and 2): the finger's metacarpal starts at
        // a carpometacarpal joint the model does not have.
        let first = usize::from(f != Finger::Thumb);
        for k in 0..2 {
            let (a, b): (Joint, Joint) = (js[k], js[k + 1]);
            links.push(LinkProportion {
                name: format!("{}-{}", a.name(), b.name()),
                finger: f,
                length_mm: (sk.centre(b) - sk.centre(a)).norm(),
                fraction: SEGMENT_FRACTIONS[f as usize][first + k],
            });
        }
    }
    let mut predicted: Vec<f64> = links.iter().map(|l| l.length_mm / l.fraction).collect();
    predicted.sort_by(f64::total_cmp);
    let n = predicted.len();
    let hand_length_mm = 0.5 * (predicted[(n - 1) / 2] + predicted[n / 2]);
    HandProportions {
        hand_length_mm,
        links,
    }
}

/// The gate on a link model's proportions `p` ([`hand_proportions`]) of the subject `who` (a
/// folder, for the messages): an error when its hand length is not a human's, else the
/// warnings (an unusual hand length, links far from their prediction), each naming the link and
/// the trial to check.
pub fn check_link_proportions(p: &HandProportions, who: &str) -> Result<Vec<String>> {
    let length = p.hand_length_mm;
    let (lo, hi) = HUMAN_HAND_LENGTH_MM;
    if !(lo..=hi).contains(&length) {
        return Err(Error::invalid(format!(
            "{who}: the link model gives a hand {length:.0} mm long (the median over its links \
             of what each predicts; a human hand is {lo:.0}-{hi:.0} mm): check the calibration \
             trials' POINT:UNITS and the finger plates' markers"
        )));
    }
    let mut warnings = Vec::new();
    let (lo, hi) = TYPICAL_HAND_LENGTH_MM;
    if !(lo..=hi).contains(&length) {
        warnings.push(format!(
            "link model: a hand {length:.0} mm long (outside {lo:.0}-{hi:.0} mm, children from \
             four years to the largest adults); the template is an adult's, so the skin may \
             follow it poorly"
        ));
    }
    let (rlo, rhi) = LINK_RATIO_RANGE;
    for l in &p.links {
        let ratio = p.ratio(l);
        if !(rlo..=rhi).contains(&ratio) {
            warnings.push(format!(
                "link model: {} is {:.1} mm, {ratio:.2}x the {:.1} mm the other links predict \
                 (a {length:.0} mm hand, Buchholz et al. 1992): check the {} trial's markers",
                l.name,
                l.length_mm,
                l.fraction * length,
                l.finger.trial_name()
            ));
        }
    }
    Ok(warnings)
}

/// The gate on a fitted `skin` against the link model's hand length (its proportions `p`, of
/// the subject `who`): an error when the skin's size is grossly not the link model's.
pub fn check_skin_size(skin: &TriMesh, p: &HandProportions, who: &str) -> Result<()> {
    let length = p.hand_length_mm;
    let diagonal = skin.diagonal();
    let ratio = diagonal / length;
    let (lo, hi) = SKIN_RATIO_RANGE;
    if !(lo..=hi).contains(&ratio) || !ratio.is_finite() {
        return Err(Error::invalid(format!(
            "{who}: the fitted skin spans {diagonal:.0} mm, {ratio:.2}x the {length:.0} mm hand \
             the link model gives (expected {lo}-{hi}x): the landmark fit failed; check the \
             reference trial's landmark markers and the [dimensions] of subject.toml"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::geometry::{Point, Vec3};

    fn template_skeleton() -> Skeleton {
        crate::template::load_template(Side::Right)
            .unwrap()
            .skeleton
    }

    /// Every centre scaled by `s` about the wrist.
    fn scaled(sk: &Skeleton, s: f64) -> Skeleton {
        let mut out = sk.clone();
        let o = sk.centre(Joint::Wrist);
        for j in &mut out.joints {
            j.centre = o + (j.centre - o) * s;
        }
        out
    }

    #[test]
    fn hand_length_is_the_median_prediction_and_scales_with_the_hand() {
        let sk = template_skeleton();
        let p = hand_proportions(&sk);
        assert_eq!(p.links.len(), 10);
        // By hand: the median of the ten predictions.
        let mut pred: Vec<f64> = p.links.iter().map(|l| l.length_mm / l.fraction).collect();
        pred.sort_by(f64::total_cmp);
        assert!((p.hand_length_mm - 0.5 * (pred[4] + pred[5])).abs() < 1e-12);
        assert!((150.0..230.0).contains(&p.hand_length_mm), "{p:?}");
        let half = hand_proportions(&scaled(&sk, 0.5));
        assert!((half.hand_length_mm - 0.5 * p.hand_length_mm).abs() < 1e-9);
        // A link's ratio does not change with the hand's scale.
        for (a, b) in p.links.iter().zip(&half.links) {
            assert!((p.ratio(a) - half.ratio(b)).abs() < 1e-9);
        }
    }

    #[test]
    fn a_template_hand_passes_silently_and_a_hand_no_human_has_is_refused() {
        let sk = template_skeleton();
        assert_eq!(
            check_link_proportions(&hand_proportions(&sk), "S").unwrap(),
            Vec::<String>::new()
        );
        // Millimetres read as centimetres and the reverse.
        for s in [0.1, 10.0] {
            let e = check_link_proportions(&hand_proportions(&scaled(&sk, s)), "S").unwrap_err();
            assert!(
                e.to_string().starts_with("S: the link model gives a hand"),
                "{e}"
            );
        }
        // A child's hand (0.55 of the template): a warning, not an error.
        let w = check_link_proportions(&hand_proportions(&scaled(&sk, 0.55)), "S").unwrap();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("mm long (outside 100-260 mm"), "{w:?}");
    }

    #[test]
    fn one_wild_centre_is_named_and_does_not_move_the_hand_length() {
        let sk = template_skeleton();
        let before = hand_proportions(&sk).hand_length_mm;
        // The index DIP 30 mm further along its middle phalanx: only I_PIP-I_DIP changes.
        let mut wild = sk.clone();
        let (pip, dip) = (sk.centre(Joint::IPip), sk.centre(Joint::IDip));
        let along: Vec3 = (dip - pip).normalize();
        let moved: Point = dip + along * 30.0;
        wild.joints[Joint::IDip.index()].centre = moved;
        let after = hand_proportions(&wild).hand_length_mm;
        // The median moves by at most one neighbour's step.
        assert!((after - before).abs() < 0.1 * before, "{before} -> {after}");
        let w = check_link_proportions(&hand_proportions(&wild), "S").unwrap();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("link model: I_PIP-I_DIP is") && w[0].contains("the index trial"),
            "{w:?}"
        );
    }

    #[test]
    fn a_skin_of_another_size_than_the_link_model_is_refused() {
        let template = crate::template::load_template(Side::Right).unwrap();
        let p = hand_proportions(&template.skeleton);
        check_skin_size(&template.mesh, &p, "S").unwrap();
        for s in [0.3, 5.0] {
            let mut skin = template.mesh.clone();
            for v in &mut skin.vertices {
                *v = Point::from(v.coords * s);
            }
            let e = check_skin_size(&skin, &p, "S").unwrap_err().to_string();
            assert!(e.starts_with("S: the fitted skin spans"), "{e}");
        }
    }
}
