//! Finger-finger collisions while the hand closes: each phalanx has a *core*, a capsule around
//! its bone (from its joint centre to the next joint centre or the fingertip) whose radius is
//! 90 % of the smallest distance from the bone to the phalanx's own skin along its middle
//! 70 %, so the core lies inside the finger. A skin vertex of one digit inside the core of
//! another is inside that finger by at least the skin's thickness over the core: the fingers
//! have passed into each other. The thumb's metacarpal is the thenar eminence (palm) and has no
//! core, as in [`crate::pose::quality::finger_penetration`].

use super::hand::PosableHand;
use crate::anatomy::{Finger, Link};
use crate::geometry::{Point, Vec3};
use nalgebra::Isometry3;

/// One phalanx core in the rest posture.
#[derive(Clone, Debug, PartialEq)]
pub struct Core {
    /// Link ([`Link::index`]).
    pub link: usize,
    /// Its digit.
    pub digit: Finger,
    /// Bone segment, rest posture, mm.
    pub a: Point,
    /// Bone segment end, mm.
    pub b: Point,
    /// Core radius, mm.
    pub radius: f64,
}

/// The phalanx cores of a hand.
#[derive(Clone, Debug, PartialEq)]
pub struct Cores {
    /// Every phalanx with skin around its bone.
    pub cores: Vec<Core>,
}

/// Distance from `p` to the segment `a..b`, and the segment parameter of the closest point.
pub(crate) fn segment_distance(p: &Point, a: &Point, b: &Point) -> (f64, f64) {
    let ab: Vec3 = b - a;
    let l2 = ab.norm_squared();
    let s = if l2 > 0.0 {
        ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p - (a + ab * s)).norm(), s)
}

/// Whether `link` is a phalanx with a core (every digit link but the thumb's metacarpal).
pub fn has_core(link: Link) -> bool {
    link != Link::TMeta && link.joint().and_then(|j| j.finger()).is_some()
}

impl Cores {
    /// The cores of `hand` in its rest posture.
    pub fn new(hand: &dyn PosableHand) -> Cores {
        let sk = hand.skeleton();
        let rest = &hand.rest_mesh().vertices;
        let mut cores = Vec::new();
        for f in Finger::ALL {
            let joints = f.joints();
            for (k, link) in f.links().into_iter().enumerate() {
                if !has_core(link) {
                    continue;
                }
                let a = sk.centre(joints[k]);
                let b = if k + 1 < 3 {
                    sk.centre(joints[k + 1])
                } else {
                    sk.tips[f as usize]
                };
                let r = hand.link_vertices()[link.index()]
                    .iter()
                    .filter_map(|&i| {
                        let (d, s) = segment_distance(&rest[i], &a, &b);
                        (0.15..=0.85).contains(&s).then_some(d)
                    })
                    .fold(f64::INFINITY, f64::min);
                if r.is_finite() && r > 1.0 {
                    cores.push(Core {
                        link: link.index(),
                        digit: f,
                        a,
                        b,
                        radius: 0.9 * r,
                    });
                }
            }
        }
        Cores { cores }
    }

    /// Core segments moved by the link transforms (same order as `cores`).
    pub fn posed(&self, t: &[Isometry3<f64>]) -> Vec<(Point, Point)> {
        self.cores
            .iter()
            .map(|c| (t[c.link] * c.a, t[c.link] * c.b))
            .collect()
    }

    /// Deepest entry of `pts` (skin of digit `digit`) into the cores of the other digits, mm
    /// (0 when none), and the link entered. `posed` from [`Cores::posed`].
    pub fn penetration(
        &self,
        posed: &[(Point, Point)],
        digit: Finger,
        pts: &[Point],
    ) -> (f64, Option<usize>) {
        if pts.is_empty() {
            return (0.0, None);
        }
        let (mut lo, mut hi) = (pts[0], pts[0]);
        for p in pts {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let mut best = (0.0, None);
        for (c, (a, b)) in self.cores.iter().zip(posed) {
            if c.digit == digit {
                continue;
            }
            // Bounding boxes first: most cores are far from the moving phalanges.
            let r = c.radius;
            if (0..3).any(|k| a[k].min(b[k]) - r > hi[k] || a[k].max(b[k]) + r < lo[k]) {
                continue;
            }
            for p in pts {
                let d = r - segment_distance(p, a, b).0;
                if d > best.0 {
                    best = (d, Some(c.link));
                }
            }
        }
        best
    }
}

/// Deepest entry of any digit's phalanx skin into another digit's core in a posed hand, mm
/// (`posed`: the whole skin in rest vertex order for the link transforms `t`).
pub fn finger_entry(hand: &dyn PosableHand, posed: &[Point], t: &[Isometry3<f64>]) -> f64 {
    let cores = Cores::new(hand);
    let segs = cores.posed(t);
    Finger::ALL
        .iter()
        .map(|&f| {
            let pts: Vec<Point> = f
                .links()
                .iter()
                .filter(|l| has_core(**l))
                .flat_map(|l| hand.link_vertices()[l.index()].iter().map(|&i| posed[i]))
                .collect();
            cores.penetration(&segs, f, &pts).0
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{Joint, Side};
    use crate::grasp::hand::SkinnedHand;
    use crate::skeleton::forward_kinematics::link_transforms;
    use crate::skeleton::Pose;

    #[test]
    fn cores_lie_inside_the_rest_skin_and_see_a_crossed_finger() {
        let h = SkinnedHand::template(Side::Right).unwrap();
        let cores = Cores::new(&h);
        // Index to little have three cores each, the thumb two.
        assert_eq!(cores.cores.len(), 14, "{:?}", cores.cores.len());
        let t = link_transforms(h.skeleton(), &Pose::zero());
        let posed = cores.posed(&t);
        let mut pts = Vec::new();
        h.pose_vertices(&Pose::zero(), &mut pts);
        for f in Finger::ALL {
            let mine: Vec<Point> = f
                .links()
                .iter()
                .flat_map(|l| h.link_vertices()[l.index()].iter().map(|&i| pts[i]))
                .collect();
            let (d, _) = cores.penetration(&posed, f, &mine);
            assert!(d < 0.5, "{f:?} enters another finger by {d} mm at rest");
        }
        // Adduct the index hard toward the middle finger: it enters the middle's core.
        let mut pose = Pose::zero();
        pose.angles[Joint::IMcp.index()] = [0.0, -40f64.to_radians(), 0.0];
        let t = link_transforms(h.skeleton(), &pose);
        let mut pts = Vec::new();
        h.pose_vertices(&pose, &mut pts);
        let index: Vec<Point> = Finger::Index
            .links()
            .iter()
            .flat_map(|l| h.link_vertices()[l.index()].iter().map(|&i| pts[i]))
            .collect();
        let (d, l) = cores.penetration(&cores.posed(&t), Finger::Index, &index);
        assert!(d > 2.0, "{d}");
        let entered = Link::ALL[l.unwrap()];
        assert_eq!(
            entered.joint().and_then(|j| j.finger()),
            Some(Finger::Middle)
        );
    }
}
