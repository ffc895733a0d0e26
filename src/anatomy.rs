//! The named parts of a hand, as the subject-format spec (`shared/spec/subject-format.md`,
//! section 2) defines them: fingers, joints, links, landmark markers, plate markers and the
//! 22 caliper dimensions of the seed paper's Table 1.
//!
//! Every other module refers to these names, so a typo in a file is caught in one place.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Left or right hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Right,
    Left,
}

impl Side {
    /// `"right"` or `"left"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Right => "right",
            Side::Left => "left",
        }
    }
}

impl fmt::Display for Side {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The five digits, thumb first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Finger {
    Thumb,
    Index,
    Middle,
    Ring,
    Little,
}

impl Finger {
    /// All five, thumb to little.
    pub const ALL: [Finger; 5] = [
        Finger::Thumb,
        Finger::Index,
        Finger::Middle,
        Finger::Ring,
        Finger::Little,
    ];

    /// The spec's one-letter prefix: `T`, `I`, `M`, `R`, `L`.
    pub fn letter(self) -> &'static str {
        match self {
            Finger::Thumb => "T",
            Finger::Index => "I",
            Finger::Middle => "M",
            Finger::Ring => "R",
            Finger::Little => "L",
        }
    }

    /// The name of this digit's optional fingertip marker (see [`tip_marker_names`]).
    pub fn tip_marker(self) -> &'static str {
        match self {
            Finger::Thumb => "T_TIP",
            Finger::Index => "I_TIP",
            Finger::Middle => "M_TIP",
            Finger::Ring => "R_TIP",
            Finger::Little => "L_TIP",
        }
    }

    /// Name of the digit's nail marker (spec section 1): `T_NAIL`, `I_NAIL`, ...
    pub fn nail_marker(self) -> &'static str {
        match self {
            Finger::Thumb => "T_NAIL",
            Finger::Index => "I_NAIL",
            Finger::Middle => "M_NAIL",
            Finger::Ring => "R_NAIL",
            Finger::Little => "L_NAIL",
        }
    }

    /// The digit whose fingertip marker is `name` (`T_TIP` -> thumb), if it is one.
    pub fn from_tip_marker(name: &str) -> Option<Finger> {
        Finger::ALL.into_iter().find(|f| f.tip_marker() == name)
    }

    /// The trial key in `subject.toml`: `thumb`, `index`, ...
    pub fn trial_name(self) -> &'static str {
        match self {
            Finger::Thumb => "thumb",
            Finger::Index => "index",
            Finger::Middle => "middle",
            Finger::Ring => "ring",
            Finger::Little => "little",
        }
    }

    /// Anthropometric number: thumb = 1 ... little = 5 (as in `finger1_breadth_proximal`).
    pub fn number(self) -> usize {
        self as usize + 1
    }

    /// The three joints of the digit, proximal first (`T_CMC, T_MCP, T_IP` or `X_MCP, X_PIP, X_DIP`).
    pub fn joints(self) -> [Joint; 3] {
        let j = |k: usize| Joint::ALL[1 + 3 * (self as usize) + k];
        [j(0), j(1), j(2)]
    }

    /// The three links of the digit, proximal first.
    pub fn links(self) -> [Link; 3] {
        self.joints().map(|j| j.child_link())
    }
}

/// Segment lengths as fractions of hand length (distal wrist crease to the tip of the middle
/// finger), Buchholz, Armstrong & Goldstein 1992: per digit (thumb first) metacarpal (from the
/// carpometacarpal joint), proximal, middle (the thumb has none: 0) and distal (to the
/// fingertip) segments, joint centre to joint centre.
pub const SEGMENT_FRACTIONS: [[f64; 4]; 5] = [
    [0.251, 0.196, 0.0, 0.158],
    [0.374, 0.245, 0.143, 0.097],
    [0.373, 0.266, 0.170, 0.108],
    [0.336, 0.244, 0.165, 0.107],
    [0.295, 0.204, 0.117, 0.093],
];

/// A joint of the hand model (spec section 2), each at the proximal end of its child link.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[allow(missing_docs)]
pub enum Joint {
    Wrist,
    TCmc,
    TMcp,
    TIp,
    IMcp,
    IPip,
    IDip,
    MMcp,
    MPip,
    MDip,
    RMcp,
    RPip,
    RDip,
    LMcp,
    LPip,
    LDip,
}

impl Joint {
    /// All sixteen joints, parents before children.
    pub const ALL: [Joint; 16] = [
        Joint::Wrist,
        Joint::TCmc,
        Joint::TMcp,
        Joint::TIp,
        Joint::IMcp,
        Joint::IPip,
        Joint::IDip,
        Joint::MMcp,
        Joint::MPip,
        Joint::MDip,
        Joint::RMcp,
        Joint::RPip,
        Joint::RDip,
        Joint::LMcp,
        Joint::LPip,
        Joint::LDip,
    ];

    /// Index in [`Joint::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The spec's name, e.g. `I_MCP`.
    pub fn name(self) -> &'static str {
        const NAMES: [&str; 16] = [
            "WRIST", "T_CMC", "T_MCP", "T_IP", "I_MCP", "I_PIP", "I_DIP", "M_MCP", "M_PIP",
            "M_DIP", "R_MCP", "R_PIP", "R_DIP", "L_MCP", "L_PIP", "L_DIP",
        ];
        NAMES[self as usize]
    }

    /// The kind of joint, its name without the digit: `MCP`, `PIP`, `DIP`, the thumb's `CMC`,
    /// `MCP`, `IP`, and `WRIST`.
    pub fn kind(self) -> &'static str {
        self.name().rsplit('_').next().unwrap_or("")
    }

    /// Parse a spec name.
    pub fn from_name(s: &str) -> Option<Joint> {
        Joint::ALL.into_iter().find(|j| j.name() == s)
    }

    /// The digit the joint belongs to (`None` for the wrist).
    pub fn finger(self) -> Option<Finger> {
        match self {
            Joint::Wrist => None,
            j => Some(Finger::ALL[(j as usize - 1) / 3]),
        }
    }

    /// Position in its digit: 0 = MCP/CMC, 1 = PIP/MCP(thumb), 2 = DIP/IP.
    pub fn rank(self) -> usize {
        (self as usize + 2) % 3
    }

    /// Degrees of freedom: 3 for WRIST, T_CMC and the finger MCPs, else 1 (seed paper 3.1).
    pub fn dof(self) -> usize {
        if self == Joint::Wrist || self.rank() == 0 {
            3
        } else {
            1
        }
    }

    /// The parent joint in the link tree (`None` for the wrist, the root).
    pub fn parent(self) -> Option<Joint> {
        match self {
            Joint::Wrist => None,
            j if j.rank() == 0 => Some(Joint::Wrist),
            j => Some(Joint::ALL[j as usize - 1]),
        }
    }

    /// The link that rotates about this joint.
    pub fn child_link(self) -> Link {
        Link::ALL[self as usize + 1]
    }

    /// The link on the parent side of this joint.
    pub fn parent_link(self) -> Link {
        match self.parent() {
            None => Link::Arm,
            Some(p) => p.child_link(),
        }
    }
}

impl fmt::Display for Joint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A rigid link (body) of the hand model (spec section 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[allow(missing_docs)]
pub enum Link {
    Arm,
    Palm,
    TMeta,
    TProx,
    TDist,
    IProx,
    IMid,
    IDist,
    MProx,
    MMid,
    MDist,
    RProx,
    RMid,
    RDist,
    LProx,
    LMid,
    LDist,
}

impl Link {
    /// All seventeen links, parents before children (`ALL[j + 1]` is the child of `Joint::ALL[j]`).
    pub const ALL: [Link; 17] = [
        Link::Arm,
        Link::Palm,
        Link::TMeta,
        Link::TProx,
        Link::TDist,
        Link::IProx,
        Link::IMid,
        Link::IDist,
        Link::MProx,
        Link::MMid,
        Link::MDist,
        Link::RProx,
        Link::RMid,
        Link::RDist,
        Link::LProx,
        Link::LMid,
        Link::LDist,
    ];

    /// Index in [`Link::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The spec's name, e.g. `I_PROX`.
    pub fn name(self) -> &'static str {
        const NAMES: [&str; 17] = [
            "ARM", "PALM", "T_META", "T_PROX", "T_DIST", "I_PROX", "I_MID", "I_DIST", "M_PROX",
            "M_MID", "M_DIST", "R_PROX", "R_MID", "R_DIST", "L_PROX", "L_MID", "L_DIST",
        ];
        NAMES[self as usize]
    }

    /// Parse a spec name.
    pub fn from_name(s: &str) -> Option<Link> {
        Link::ALL.into_iter().find(|l| l.name() == s)
    }

    /// The joint this link rotates about (`None` for the arm, the root).
    pub fn joint(self) -> Option<Joint> {
        match self {
            Link::Arm => None,
            l => Some(Joint::ALL[l as usize - 1]),
        }
    }

    /// The parent link.
    pub fn parent(self) -> Option<Link> {
        self.joint().map(|j| j.parent_link())
    }

    /// The three plate-marker names of this link: `<LINK>_1`..`<LINK>_3` (`PALM_1..4` and
    /// `ARM_1..3` are the palm's and forearm's own sets; see [`palm_markers`], [`arm_markers`]).
    pub fn plate_markers(self) -> [String; 3] {
        [1, 2, 3].map(|k| format!("{}_{k}", self.name()))
    }
}

impl fmt::Display for Link {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The four palm markers of every trial (spec section 2).
pub fn palm_markers() -> [&'static str; 4] {
    ["PALM_1", "PALM_2", "PALM_3", "PALM_4"]
}

/// The three forearm markers of the wrist trial.
pub fn arm_markers() -> [&'static str; 3] {
    ["ARM_1", "ARM_2", "ARM_3"]
}

/// Every landmark marker of the static reference trial, in a fixed order (spec section 2):
/// the four palm markers, one per joint (named after the joint), one per nail, two on the thumb
/// metacarpal, the two MCP laterals and the two styloids.
pub fn landmark_names() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = palm_markers().to_vec();
    v.extend(Joint::ALL.iter().map(|j| j.name()));
    v.extend(["T_NAIL", "I_NAIL", "M_NAIL", "R_NAIL", "L_NAIL"]);
    v.extend([
        "T_MC_1",
        "T_MC_2",
        "I_MCP_LAT",
        "L_MCP_LAT",
        "WRIST_RAD",
        "WRIST_ULN",
    ]);
    v
}

/// The optional fingertip markers of the static reference trial (an extension of the spec, see
/// the README): one per digit on the fingertip's apex, where the distal phalanx's long axis
/// leaves the skin (thumb first). Nothing else marks the fingertip beyond the nail, so where a
/// lab places them the skin's fingertips, and the distal frames carried by the skin, follow
/// them; without them the template shapes the fingertips alone.
pub fn tip_marker_names() -> [&'static str; 5] {
    Finger::ALL.map(Finger::tip_marker)
}

/// One of the 22 caliper dimensions of the seed paper's Table 1 (spec section 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Dimension {
    WristBreadth,
    WristThickness,
    HandBreadthDiagonal,
    HandThicknessMc3,
    /// Breadth of finger N (1 = thumb) at the PIP (thumb: IP) joint.
    BreadthProximal(Finger),
    /// Thickness of finger N at the PIP (thumb: IP) joint.
    ThicknessProximal(Finger),
    /// Breadth of finger N (2..5) at the DIP joint.
    BreadthDistal(Finger),
    /// Thickness of finger N (2..5) at the DIP joint.
    ThicknessDistal(Finger),
}

impl Dimension {
    /// All 22, in the spec's order.
    pub fn all() -> Vec<Dimension> {
        let mut v = vec![
            Dimension::WristBreadth,
            Dimension::WristThickness,
            Dimension::HandBreadthDiagonal,
            Dimension::HandThicknessMc3,
        ];
        for f in Finger::ALL {
            v.push(Dimension::BreadthProximal(f));
            v.push(Dimension::ThicknessProximal(f));
        }
        for f in &Finger::ALL[1..] {
            v.push(Dimension::BreadthDistal(*f));
            v.push(Dimension::ThicknessDistal(*f));
        }
        v
    }

    /// The `subject.toml` key, e.g. `finger2_breadth_distal`.
    pub fn name(self) -> String {
        match self {
            Dimension::WristBreadth => "wrist_breadth".into(),
            Dimension::WristThickness => "wrist_thickness".into(),
            Dimension::HandBreadthDiagonal => "hand_breadth_diagonal".into(),
            Dimension::HandThicknessMc3 => "hand_thickness_mc3".into(),
            Dimension::BreadthProximal(f) => format!("finger{}_breadth_proximal", f.number()),
            Dimension::ThicknessProximal(f) => format!("finger{}_thickness_proximal", f.number()),
            Dimension::BreadthDistal(f) => format!("finger{}_breadth_distal", f.number()),
            Dimension::ThicknessDistal(f) => format!("finger{}_thickness_distal", f.number()),
        }
    }

    /// Parse a `subject.toml` key; `None` for anything that is not one of the 22.
    pub fn from_name(s: &str) -> Option<Dimension> {
        Dimension::all().into_iter().find(|d| d.name() == s)
    }

    /// The joint whose cross-section a finger dimension is measured at (the PIP, the thumb's
    /// IP, the DIP); `None` for the wrist and hand dimensions.
    pub fn section_joint(self) -> Option<Joint> {
        match self {
            Dimension::BreadthProximal(f) | Dimension::ThicknessProximal(f) => {
                Some(if f == Finger::Thumb {
                    f.joints()[2]
                } else {
                    f.joints()[1]
                })
            }
            Dimension::BreadthDistal(f) | Dimension::ThicknessDistal(f) => Some(f.joints()[2]),
            _ => None,
        }
    }

    /// Plausible range for an adult hand, mm, used to reject absurd inputs (a value in metres or
    /// inches, a typo). Generous bounds around the extremes of published hand anthropometry
    /// (e.g. Kouchi's AIST hand database, Greiner 1991): a value outside is not a hand.
    pub fn plausible_range_mm(self) -> (f64, f64) {
        match self {
            Dimension::WristBreadth => (35.0, 100.0),
            Dimension::WristThickness => (20.0, 70.0),
            Dimension::HandBreadthDiagonal => (55.0, 140.0),
            Dimension::HandThicknessMc3 => (15.0, 50.0),
            Dimension::BreadthProximal(_) | Dimension::BreadthDistal(_) => (8.0, 35.0),
            Dimension::ThicknessProximal(_) | Dimension::ThicknessDistal(_) => (6.0, 35.0),
        }
    }
}

impl fmt::Display for Dimension {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fingertip_marker_names_its_digit_and_nothing_else_does() {
        for f in Finger::ALL {
            assert_eq!(Finger::from_tip_marker(f.tip_marker()), Some(f));
            assert_eq!(f.nail_marker(), format!("{}_NAIL", f.letter()));
            assert_eq!(Finger::from_tip_marker(f.nail_marker()), None);
        }
        assert_eq!(Finger::from_tip_marker("i_tip"), None);
        assert_eq!(Finger::from_tip_marker("PALM_1"), None);
    }

    #[test]
    fn tree_is_consistent() {
        for (i, j) in Joint::ALL.iter().enumerate() {
            assert_eq!(j.index(), i);
            assert_eq!(Joint::from_name(j.name()), Some(*j));
            assert_eq!(j.child_link().joint(), Some(*j));
            if let Some(p) = j.parent() {
                assert!(p.index() < j.index());
                assert_eq!(j.parent_link(), p.child_link());
            }
        }
        assert_eq!(Joint::IPip.parent(), Some(Joint::IMcp));
        assert_eq!(Joint::TCmc.parent(), Some(Joint::Wrist));
        assert_eq!(Joint::TCmc.parent_link(), Link::Palm);
        assert_eq!(Joint::TMcp.dof(), 1);
        assert_eq!(Joint::TCmc.dof(), 3);
        assert_eq!(Joint::LMcp.dof(), 3);
        assert_eq!(
            Finger::Ring.joints(),
            [Joint::RMcp, Joint::RPip, Joint::RDip]
        );
        assert_eq!(
            Finger::Thumb.links(),
            [Link::TMeta, Link::TProx, Link::TDist]
        );
        assert_eq!(Link::IDist.parent(), Some(Link::IMid));
        assert_eq!(Link::Palm.parent(), Some(Link::Arm));
        assert_eq!(
            Joint::ALL.iter().map(|j| j.dof()).sum::<usize>(),
            6 * 3 + 10
        );
    }

    #[test]
    fn twenty_two_dimensions() {
        let all = Dimension::all();
        assert_eq!(all.len(), 22);
        for d in all {
            assert_eq!(Dimension::from_name(&d.name()), Some(d));
        }
        assert_eq!(Dimension::from_name("finger1_breadth_distal"), None);
        assert_eq!(
            Dimension::ThicknessProximal(Finger::Thumb).section_joint(),
            Some(Joint::TIp)
        );
        assert_eq!(
            Dimension::BreadthProximal(Finger::Ring).section_joint(),
            Some(Joint::RPip)
        );
        assert_eq!(
            Dimension::ThicknessDistal(Finger::Little).section_joint(),
            Some(Joint::LDip)
        );
        assert_eq!(Dimension::WristThickness.section_joint(), None);
        let kinds: Vec<&str> = [
            Joint::Wrist,
            Joint::TCmc,
            Joint::TIp,
            Joint::MPip,
            Joint::LDip,
        ]
        .iter()
        .map(|j| j.kind())
        .collect();
        assert_eq!(kinds, ["WRIST", "CMC", "IP", "PIP", "DIP"]);
        assert_eq!(landmark_names().len(), 4 + 16 + 5 + 6);
    }
}
