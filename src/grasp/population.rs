//! One scene over many hands: what a designer asks of a part ("what share of users can hold
//! it, and how?"). Each hand's [`GraspReport`] is summarised ([`HandOutcome`]: holds, force
//! closure, epsilon, contact area per digit, how it envelops the part, the joints that end at
//! an anatomical limit, the hand's size from its link model, and why it failed), and the hands
//! together ([`PopulationSummary`]: the share that holds, overall and per size third, the
//! count of each failure, and how many wrap the part). `ergohand grasp SCENE.toml --models DIR... --out DIR` writes it as
//! `population.json`, with a page made by [`crate::validate::population_report`].

use super::hand::PosableHand;
use super::GraspReport;
use crate::anatomy::{Finger, Joint};
use crate::skeleton::limits::joint_limits_deg;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A joint angle this close to an anatomical limit (degrees) counts as at the limit: the
/// grasp asked all the joint can give.
pub const AT_LIMIT_DEG: f64 = 2.0;

/// Why a hand does not hold the part.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Failure {
    /// No placement or approach closed the hand on the part (the scene ended with an error).
    NoGrasp,
    /// The contacts found cannot resist every wrench however hard the hand squeezes.
    NotForceClosure,
    /// Force closure, but the part moves more than 2 mm in the rapier hold test.
    Slips,
    /// Force closure, but the squeeze alone pushed the part at least as far as the hold test's
    /// limit (2 mm) while it settled, before any gravity, and it then dropped: the grip's forces
    /// do not balance, and nothing opposes the part where it is pushed
    /// ([`HandOutcome::squeezed_toward`]).
    SqueezedOut,
}

impl Failure {
    /// Words for tables.
    pub fn describe(self) -> &'static str {
        match self {
            Failure::NoGrasp => "no grasp found",
            Failure::NotForceClosure => "not force closure",
            Failure::Slips => "slips in the hold test",
            Failure::SqueezedOut => "pushed out by the squeeze",
        }
    }
}

/// One hand's outcome on the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HandOutcome {
    /// The hand's name (its model folder's name).
    pub name: String,
    /// The model folder.
    pub model: String,
    /// Hand length of the link model: the wrist joint's centre to the middle finger's distal
    /// end, mm.
    pub hand_length_mm: f64,
    /// Span of the index and little MCP joint centres, mm (a measure of palm breadth).
    pub mcp_span_mm: f64,
    /// Whether the hold test held in every direction.
    pub holds: bool,
    /// Force closure.
    pub force_closure: bool,
    /// Ferrari-Canny epsilon.
    pub epsilon: f64,
    /// The worst displacement of the hold test, mm.
    pub worst_displacement_mm: f64,
    /// Total contact area, mm².
    pub contact_area_mm2: f64,
    /// Contact area per digit and the palm, mm².
    pub contact_area_by_finger_mm2: BTreeMap<String, f64>,
    /// How the grasp envelops the part (the palm, the fingers wrapped with every phalanx).
    #[serde(default)]
    pub envelope: super::contact::Envelope,
    /// Joints ending within [`AT_LIMIT_DEG`] of an anatomical limit, as `JOINT dof at LIMIT°`.
    pub at_limit: Vec<String>,
    /// How far the hand moved along its palm from the scene's given approach, mm, toward the
    /// fingers when positive (a scene with `grasp.slide_mm`; `None` otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approach_slide_mm: Option<f64>,
    /// Why it does not hold (`None`: it holds).
    pub failure: Option<Failure>,
    /// Where the squeeze pushed the part out of the grip ([`Failure::SqueezedOut`]): the
    /// hand direction it moved furthest along ([`squeezed_toward`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub squeezed_toward: Option<String>,
    /// The scene's error when no grasp was found.
    pub error: Option<String>,
    /// Time of the scene, s (wall time; `grasp --models` runs hands side by side, so this is
    /// the scene's time while the others share the cores, up to about twice a lone run's).
    pub time_s: f64,
}

/// Hand length and MCP span of `hand`'s link model, mm.
pub fn hand_size(hand: &dyn PosableHand) -> (f64, f64) {
    let sk = hand.skeleton();
    let length = (sk.tips[Finger::Middle as usize] - sk.centre(Joint::Wrist)).norm();
    let span = (sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp)).norm();
    (length, span)
}

/// The joints of `pose_deg` (degrees by joint name, as in `grasp.json`) within [`AT_LIMIT_DEG`]
/// of a limit of [`joint_limits_deg`].
pub fn joints_at_limit(pose_deg: &BTreeMap<String, [f64; 3]>) -> Vec<String> {
    const DOF: [&str; 3] = ["flexion", "abduction", "axial"];
    let mut out = Vec::new();
    for j in Joint::ALL {
        let Some(a) = pose_deg.get(j.name()) else {
            continue;
        };
        for (d, [lo, hi]) in joint_limits_deg(j).into_iter().enumerate() {
            if hi - lo < 1e-9 {
                continue; // a DOF the joint does not have
            }
            for limit in [lo, hi] {
                if (a[d] - limit).abs() <= AT_LIMIT_DEG {
                    out.push(format!("{} {} at {limit:.0}°", j.name(), DOF[d]));
                }
            }
        }
    }
    out
}

/// The outcome of `hand` (named `name`, from the folder `model`) on a scene: its report, or
/// the error the scene ended with.
pub fn hand_outcome(
    name: &str,
    model: &str,
    hand: &dyn PosableHand,
    result: std::result::Result<&GraspReport, String>,
) -> HandOutcome {
    let (hand_length_mm, mcp_span_mm) = hand_size(hand);
    let mut o = HandOutcome {
        name: name.to_string(),
        model: model.to_string(),
        hand_length_mm,
        mcp_span_mm,
        holds: false,
        force_closure: false,
        epsilon: 0.0,
        worst_displacement_mm: f64::NAN,
        contact_area_mm2: 0.0,
        contact_area_by_finger_mm2: BTreeMap::new(),
        envelope: Default::default(),
        at_limit: Vec::new(),
        approach_slide_mm: None,
        failure: Some(Failure::NoGrasp),
        squeezed_toward: None,
        error: None,
        time_s: 0.0,
    };
    match result {
        Err(e) => o.error = Some(e),
        Ok(r) => {
            o.holds = r.holds;
            o.force_closure = r.force_closure;
            o.approach_slide_mm = r.approach_slide_mm;
            o.epsilon = r.epsilon;
            o.worst_displacement_mm = r
                .hold_test
                .trials
                .iter()
                .map(|t| t.displacement_mm)
                .fold(0.0, f64::max);
            o.contact_area_mm2 = r.total_contact_area_mm2;
            o.contact_area_by_finger_mm2 = r.contact_area_by_finger_mm2.clone();
            o.envelope = r.envelope.clone();
            o.at_limit = joints_at_limit(&r.pose_deg);
            o.failure = if r.holds {
                None
            } else if !r.force_closure {
                Some(Failure::NotForceClosure)
            } else if let Some(w) = pushed_out_toward(r) {
                o.squeezed_toward = Some(w.to_string());
                Some(Failure::SqueezedOut)
            } else {
                Some(Failure::Slips)
            };
            o.time_s = r.timings_s.total_s;
        }
    }
    o
}

/// The hand direction along which the part moved furthest while the squeeze settled it
/// (`settle` as [`GraspReport::settle_by_direction_mm`]), in words: "into the palm", "out of
/// the palm", "toward the thumb's side", "toward the little finger's side", "toward the
/// fingertips" or "toward the wrist". `None` when no direction is given.
pub fn squeezed_toward(settle: &BTreeMap<String, f64>) -> Option<&'static str> {
    let (name, d) = settle
        .iter()
        .filter(|(_, d)| d.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
    Some(match (name.as_str(), *d >= 0.0) {
        ("dorsal", true) => "into the palm",
        ("dorsal", false) => "out of the palm",
        ("radial", true) => "toward the thumb's side",
        ("radial", false) => "toward the little finger's side",
        ("distal", true) => "toward the fingertips",
        ("distal", false) => "toward the wrist",
        _ => return None,
    })
}

/// Where the squeeze pushed the part out of the grip of `r` ([`squeezed_toward`]), when it
/// does not hold and the squeeze alone moved it the hold test's limit or more while it
/// settled; `None` otherwise.
pub fn pushed_out_toward(r: &GraspReport) -> Option<&'static str> {
    if r.holds || r.hold_test.settle_mm < super::hold::HOLD_LIMIT_MM {
        return None;
    }
    squeezed_toward(&r.settle_by_direction_mm)
}

impl HandOutcome {
    /// Why it does not hold, in words, with where the squeeze pushed the part for
    /// [`Failure::SqueezedOut`] (`None`: it holds).
    pub fn failure_reason(&self) -> Option<String> {
        let f = self.failure?;
        Some(match &self.squeezed_toward {
            Some(w) if f == Failure::SqueezedOut => format!("{} {w}", f.describe()),
            _ => f.describe().to_string(),
        })
    }
}

/// The hands of one size third.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SizeGroup {
    /// "small", "medium" or "large" (thirds of the population by hand length).
    pub label: String,
    /// Shortest and longest hand in the group, mm.
    pub hand_length_mm: [f64; 2],
    /// Hands in the group.
    pub hands: usize,
    /// Of which hold.
    pub holding: usize,
}

/// `population.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PopulationSummary {
    /// The scene file.
    pub scene: String,
    /// Grasp type.
    pub grasp_type: String,
    /// Hands evaluated.
    pub hands: usize,
    /// Hands that hold.
    pub holding: usize,
    /// Hands in force closure.
    pub force_closure: usize,
    /// The share that holds, by thirds of hand length (fewer groups for fewer than 3 hands).
    pub by_size: Vec<SizeGroup>,
    /// How many hands fail for each reason.
    pub failures: BTreeMap<String, usize>,
    /// Hands that end with some joint at its limit.
    pub at_limit: usize,
    /// Hands whose grasp wraps the part: the palm and at least three fingers with every
    /// phalanx touching ([`super::contact::Envelope::wraps`]).
    #[serde(default)]
    pub wrapping: usize,
    /// Per hand, in the order given.
    pub outcomes: Vec<HandOutcome>,
}

/// Summarise the outcomes of one scene (`scene`, `grasp_type`) over hands.
pub fn summarise(scene: &str, grasp_type: &str, outcomes: Vec<HandOutcome>) -> PopulationSummary {
    let mut order: Vec<usize> = (0..outcomes.len()).collect();
    order.sort_by(|&a, &b| {
        outcomes[a]
            .hand_length_mm
            .total_cmp(&outcomes[b].hand_length_mm)
    });
    let groups = outcomes.len().min(3);
    let labels: &[&str] = match groups {
        3 => &["small", "medium", "large"],
        2 => &["smaller", "larger"],
        _ => &["all"],
    };
    let by_size = (0..groups)
        .map(|g| {
            // Thirds by rank: group g holds ranks [g n / k, (g + 1) n / k).
            let members: Vec<&HandOutcome> = order
                [g * outcomes.len() / groups..(g + 1) * outcomes.len() / groups]
                .iter()
                .map(|&i| &outcomes[i])
                .collect();
            SizeGroup {
                label: labels[g].to_string(),
                hand_length_mm: [
                    members.first().map_or(0.0, |o| o.hand_length_mm),
                    members.last().map_or(0.0, |o| o.hand_length_mm),
                ],
                hands: members.len(),
                holding: members.iter().filter(|o| o.holds).count(),
            }
        })
        .collect();
    let mut failures = BTreeMap::new();
    for why in outcomes.iter().filter_map(HandOutcome::failure_reason) {
        *failures.entry(why).or_insert(0) += 1;
    }
    PopulationSummary {
        scene: scene.to_string(),
        grasp_type: grasp_type.to_string(),
        hands: outcomes.len(),
        holding: outcomes.iter().filter(|o| o.holds).count(),
        force_closure: outcomes.iter().filter(|o| o.force_closure).count(),
        by_size,
        failures,
        at_limit: outcomes.iter().filter(|o| !o.at_limit.is_empty()).count(),
        wrapping: outcomes.iter().filter(|o| o.envelope.wraps).count(),
        outcomes,
    }
}

/// Which vertices of `part` a posed hand's skin touches: a part vertex within `tolerance_mm`
/// of the skin, or inside the skin by at most `search_mm` (signed by the skin's angle-weighted
/// pseudo-normals), the contact test of the grasp seen from the part's side (deeper than the
/// grasp's search radius the grasp does not look either).
pub fn part_vertices_touched(
    skin: &crate::geometry::TriMesh,
    part: &crate::geometry::TriMesh,
    tolerance_mm: f64,
    search_mm: f64,
) -> Vec<bool> {
    use crate::geometry::closest_point::{AabbTree, PseudoNormals};
    use rayon::prelude::*;
    let tree = AabbTree::new(skin);
    let normals = PseudoNormals::new(skin);
    let reach = tolerance_mm.max(search_mm);
    part.vertices
        .par_iter()
        .map(|p| match tree.closest_point_within(p, reach) {
            // Only near points need a sign, and only their sign decides.
            Some(c) if c.distance <= tolerance_mm => true,
            Some(c) => {
                let n = normals.of(skin, c.face, c.feature);
                (p - c.point).dot(&n) < 0.0
            }
            None => false,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(name: &str, length: f64, failure: Option<Failure>) -> HandOutcome {
        HandOutcome {
            name: name.into(),
            model: name.into(),
            hand_length_mm: length,
            mcp_span_mm: 70.0,
            holds: failure.is_none(),
            force_closure: failure != Some(Failure::NotForceClosure)
                && failure != Some(Failure::NoGrasp),
            epsilon: 0.03,
            worst_displacement_mm: 0.1,
            contact_area_mm2: 300.0,
            contact_area_by_finger_mm2: BTreeMap::new(),
            envelope: Default::default(),
            at_limit: Vec::new(),
            approach_slide_mm: None,
            failure,
            squeezed_toward: None,
            error: None,
            time_s: 1.0,
        }
    }

    /// Seven hands: the thirds by length take 2, 2 and 3 hands by rank (whatever the order
    /// given), each counting its own holders; failures are counted by reason, and the hands
    /// that wrap the part.
    #[test]
    fn thirds_by_length_and_failures_by_reason() {
        let wrapped = |mut o: HandOutcome| {
            o.envelope.wraps = true;
            o
        };
        let hands = vec![
            wrapped(outcome("g", 205.0, None)),
            wrapped(outcome("a", 160.0, Some(Failure::Slips))),
            outcome("e", 190.0, None),
            outcome("b", 170.0, Some(Failure::NoGrasp)),
            outcome("f", 200.0, Some(Failure::Slips)),
            outcome("c", 175.0, None),
            outcome("d", 180.0, Some(Failure::NotForceClosure)),
        ];
        let s = summarise("pen.toml", "tripod", hands);
        assert_eq!((s.hands, s.holding, s.force_closure), (7, 3, 5));
        assert_eq!(s.wrapping, 2);
        let g: Vec<(&str, usize, usize, [f64; 2])> = s
            .by_size
            .iter()
            .map(|g| (g.label.as_str(), g.hands, g.holding, g.hand_length_mm))
            .collect();
        assert_eq!(
            g,
            vec![
                ("small", 2, 0, [160.0, 170.0]),
                ("medium", 2, 1, [175.0, 180.0]),
                ("large", 3, 2, [190.0, 205.0]),
            ]
        );
        assert_eq!(s.failures["slips in the hold test"], 2);
        assert_eq!(s.failures["no grasp found"], 1);
        assert_eq!(s.failures["not force closure"], 1);
        // The outcomes keep the order given.
        assert_eq!(s.outcomes[0].name, "g");
    }

    /// The squeeze's direction is the hand direction of the largest displacement, by its
    /// sign; a hand pushed out is counted with it, apart from one that slips.
    #[test]
    fn a_part_pushed_out_is_counted_with_where_it_went() {
        let settle = |d: f64, r: f64, p: f64| -> BTreeMap<String, f64> {
            [("dorsal", d), ("radial", r), ("distal", p)]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect()
        };
        assert_eq!(
            squeezed_toward(&settle(-2.0, 1.0, -1.9)),
            Some("out of the palm")
        );
        assert_eq!(
            squeezed_toward(&settle(0.5, -3.0, 1.0)),
            Some("toward the little finger's side")
        );
        assert_eq!(
            squeezed_toward(&settle(0.5, 1.0, -1.5)),
            Some("toward the wrist")
        );
        assert_eq!(
            squeezed_toward(&settle(2.5, 1.0, -1.5)),
            Some("into the palm")
        );
        assert_eq!(squeezed_toward(&BTreeMap::new()), None);
        let mut out = outcome("a", 170.0, Some(Failure::SqueezedOut));
        out.squeezed_toward = squeezed_toward(&settle(0.5, 1.0, -1.5)).map(str::to_string);
        let s = summarise(
            "drill.toml",
            "power",
            vec![
                out,
                outcome("b", 180.0, Some(Failure::Slips)),
                outcome("c", 190.0, None),
            ],
        );
        assert_eq!(s.failures["pushed out by the squeeze toward the wrist"], 1);
        assert_eq!(s.failures["slips in the hold test"], 1);
        assert_eq!(s.failures.len(), 2);
    }

    /// A joint at its limit is named with the DOF and the limit; a DOF the joint does not have
    /// (a hinge's abduction, limits [0, 0]) never is.
    #[test]
    fn joints_at_their_limits_are_named() {
        let mut pose = BTreeMap::new();
        let [tlo, _] = joint_limits_deg(Joint::TIp)[0];
        let [_, phi] = joint_limits_deg(Joint::IPip)[0];
        pose.insert("T_IP".to_string(), [tlo + 1.0, 0.0, 0.0]);
        pose.insert("I_PIP".to_string(), [phi - 10.0, 0.0, 0.0]);
        let named = joints_at_limit(&pose);
        assert_eq!(named, vec![format!("T_IP flexion at {tlo:.0}°")]);
    }
}
