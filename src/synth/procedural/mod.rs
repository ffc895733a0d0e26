//! A second, independent true hand for the simulator (`synth --body procedural`): an anatomical
//! hand built from published proportions ([`proportions`]), its own skeleton ([`skeleton`]) and
//! an implicit skin of anatomical solids ([`implicit`]) polygonised on a grid ([`polygonise`]),
//! with the spec's landmarks placed by the template's rules ([`landmarks`]). Nothing of the
//! template (mesh, skinning, proportions) is used, so the template cannot reach this hand
//! exactly: the reconstruction's error on it is a fair one.

pub mod implicit;
pub mod landmarks;
pub mod polygonise;
pub mod proportions;
pub mod skeleton;

pub use implicit::HandField;
pub use proportions::{Proportions, Sex};
pub use skeleton::BodySkeleton;

use super::true_hand::TrueHand;
use crate::anatomy::Side;
use crate::error::Result;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::rng::Rng;
use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
use crate::skeleton::{JointFrame, Pose, Skeleton};
use nalgebra::{Matrix3, Rotation3};

/// Grid step of the polygonised skin, mm.
pub(crate) const MESH_VOXEL_MM: f64 = 0.9;

/// Everything of a built procedural hand (right hand, body frame), for the tests and tools.
#[derive(Clone, Debug)]
pub struct BuiltHand {
    pub proportions: Proportions,
    pub neutral: BodySkeleton,
    pub field: HandField,
    pub hand: TrueHand,
}

/// Build the right hand with proportions `p` and neutral skeleton `bs` in `posture` (relative
/// to the neutral, straight hand).
pub(crate) fn build_right_hand(
    p: &Proportions,
    bs: &BodySkeleton,
    posture: Pose,
) -> Result<BuiltHand> {
    let tf = link_transforms(&bs.skeleton, &posture);
    let posed = posed_skeleton(&bs.skeleton, &tf);
    let field = implicit::build_field(p, bs, &tf, &posed);
    let mut extent: Vec<Point> = posed.centres().into_iter().map(|(_, c)| c).collect();
    extent.extend(posed.tips);
    // The forearm stub's end.
    extent.push(
        tf[crate::anatomy::Link::Arm.index()] * Point::new(0.0, -0.3 * p.hand_length - 12.0, 0.0),
    );
    let skin =
        polygonise::polygonise(&field, &extent, 0.55 * p.wrist_breadth + 4.0, MESH_VOXEL_MM)?;
    let palm = tf[crate::anatomy::Link::Palm.index()];
    let bases = [palm * bs.metacarpal_bases[0], palm * bs.metacarpal_bases[3]];
    let landmarks = landmarks::place_landmarks(&skin, &field, &posed, bases)?;
    Ok(BuiltHand {
        proportions: p.clone(),
        neutral: bs.clone(),
        field,
        hand: TrueHand {
            skin,
            skeleton: posed,
            landmarks,
            posture,
            homologous_to_template: false,
        },
    })
}

/// The procedural body of a subject: proportions, skeleton and relaxed posture drawn from
/// `root` (forked by name), `posture` (the subject's drawn variation, relative to the body's own
/// reference posture) added to the relaxed posture; the left hand is the right one mirrored.
/// Neighbouring fingers the drawn posture would push into each other are spread back
/// ([`skeleton::keep_fingers_apart`]). The returned posture is the total, relative to the
/// neutral straight hand. `percentile`: the proportions of that sex and percentile
/// ([`Proportions::at_percentile`]) instead of drawn ones.
pub fn procedural_body(
    side: Side,
    root: &Rng,
    posture: Pose,
    percentile: Option<(Sex, f64)>,
) -> Result<TrueHand> {
    let rng = root.fork("procedural");
    let p = match percentile {
        Some((sex, pct)) => Proportions::at_percentile(sex, pct),
        None => Proportions::sample(&mut rng.fork("proportions")),
    };
    let bs = skeleton::build_skeleton(&p, &mut rng.fork("skeleton"))?;
    let relaxed = skeleton::relaxed_posture(&mut rng.fork("relaxed"));
    let total = skeleton::keep_fingers_apart(&bs, &p, &skeleton::add_postures(&relaxed, &posture));
    let built = build_right_hand(&p, &bs, total)?;
    Ok(match side {
        Side::Right => built.hand,
        Side::Left => mirror(&built.hand),
    })
}

/// The mirror image of a right hand across the body frame's sagittal plane (x -> -x): a left
/// hand. Faces are turned over to stay outward; joint frames keep y (dorsal) and z (distal)
/// mirrored and take x = y × z, so they stay right-handed (a mirrored x would make them
/// left-handed), which flips 1-DOF axes as the left-hand conventions want.
pub fn mirror(h: &TrueHand) -> TrueHand {
    let m = |p: &Point| Point::new(-p.x, p.y, p.z);
    let mv = |v: &Vec3| Vec3::new(-v.x, v.y, v.z);
    let skin = TriMesh {
        vertices: h.skin.vertices.iter().map(m).collect(),
        faces: h.skin.faces.iter().map(|&[a, b, c]| [a, c, b]).collect(),
    };
    let joints = h
        .skeleton
        .joints
        .iter()
        .map(|jf| {
            let (y, z) = (mv(&jf.y()), mv(&jf.z()));
            JointFrame {
                centre: m(&jf.centre),
                frame: Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
                    y.cross(&z),
                    y,
                    z,
                ])),
            }
        })
        .collect();
    TrueHand {
        skin,
        skeleton: Skeleton {
            side: Side::Left,
            joints,
            tips: h.skeleton.tips.map(|t| m(&t)),
        },
        landmarks: h
            .landmarks
            .iter()
            .map(|(k, (p, n))| (k.clone(), (m(p), mv(n))))
            .collect(),
        posture: h.posture.clone(),
        homologous_to_template: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{landmark_names, Finger, Joint};
    use crate::geometry::closest_point::{AabbTree, PseudoNormals};
    use crate::skeleton::forward_kinematics::posed_tips;

    fn built(seed: u64, posture: Pose) -> BuiltHand {
        let rng = Rng::new(seed).fork("procedural");
        let p = Proportions::sample(&mut rng.fork("proportions"));
        let bs = skeleton::build_skeleton(&p, &mut rng.fork("skeleton")).unwrap();
        build_right_hand(&p, &bs, posture).unwrap()
    }

    fn relaxed(seed: u64) -> Pose {
        skeleton::relaxed_posture(&mut Rng::new(seed))
    }

    #[test]
    fn skin_is_closed_outward_and_holds_the_skeleton() {
        let b = built(3, relaxed(3));
        let (h, f) = (&b.hand, &b.field);
        h.skin.check_closed_manifold().unwrap();
        let vol = h.skin.signed_volume();
        // A hand (about 350-550 ml) plus a forearm stub of 0.3 hand lengths, outward.
        assert!((3.0e5..9.0e5).contains(&vol), "{vol}");
        let tree = AabbTree::new(&h.skin);
        let normals = PseudoNormals::new(&h.skin);
        for j in Joint::ALL {
            let c = h.skeleton.centre(j);
            let d = tree.signed_distance(&normals, &c).unwrap();
            assert!(d < -3.0, "{j} is {d} mm from the skin");
            if let Some(finger) = j.finger() {
                // Inside its own digit's solids, not only inside the hand.
                assert!(f.digit_distance(finger, &c) < 0.0, "{j} outside its digit");
            }
        }
        // Finger joints sit at 40-60 % of the finger's thickness from the dorsal skin.
        for fi in &Finger::ALL[1..] {
            for j in &fi.joints()[1..] {
                let jf = h.skeleton.joint(*j);
                let t = |dir: Vec3| tree.ray_cast(&jf.centre, &dir, 0.0, 50.0).unwrap().t;
                let (up, down) = (t(jf.y()), t(-jf.y()));
                let frac = up / (up + down);
                assert!((0.40..=0.60).contains(&frac), "{j}: {frac}");
            }
        }
        // Every landmark on the skin, its normal outward.
        for name in landmark_names() {
            let (p, n) = h.landmarks[name];
            let c = tree.closest_point(&p).unwrap();
            assert!(c.distance < 0.2, "{name}: {} mm off the skin", c.distance);
            let face_n = h.skin.face_cross(c.face).normalize();
            assert!(
                n.dot(&face_n) > 0.7,
                "{name}: normal {n:?} vs face {face_n:?}"
            );
        }
    }

    #[test]
    fn the_straight_hand_has_the_drawn_length_and_breadth() {
        for seed in [1, 2] {
            let b = built(seed, Pose::zero());
            let p = &b.proportions;
            // Hand length: the distal wrist crease (y = 0 in the body frame) to the middle
            // fingertip, the furthest skin along +y.
            let tip = b
                .hand
                .skin
                .vertices
                .iter()
                .map(|v| v.y)
                .fold(f64::MIN, f64::max);
            assert!(
                (tip - p.hand_length).abs() < 3.0,
                "length {tip} vs {}",
                p.hand_length
            );
            // Hand breadth across the metacarpal heads, between the lateral landmarks.
            let l = &b.hand.landmarks;
            let breadth = (l["I_MCP_LAT"].0.x - l["L_MCP_LAT"].0.x).abs();
            assert!(
                (breadth - p.hand_breadth).abs() < 4.0,
                "breadth {breadth} vs {}",
                p.hand_breadth
            );
            // Finger breadth at the PIP: the chord through the joint along its axis.
            let tree = AabbTree::new(&b.hand.skin);
            for f in &Finger::ALL[1..] {
                let jf = b.hand.skeleton.joint(f.joints()[1]);
                let t = |dir: Vec3| tree.ray_cast(&jf.centre, &dir, 0.0, 50.0).unwrap().t;
                let chord = t(jf.x()) + t(-jf.x());
                let drawn = p.sections[*f as usize][0];
                assert!((chord - drawn).abs() < 1.0, "{f:?}: {chord} vs {drawn}");
            }
        }
    }

    #[test]
    fn the_left_hand_is_the_mirror_image_of_the_right() {
        let root = Rng::new(9);
        let pose = Pose::zero().with_deg(Joint::IMcp, [5.0, 8.0, 0.0]);
        let r = procedural_body(Side::Right, &root, pose.clone(), None).unwrap();
        let l = procedural_body(Side::Left, &root, pose, None).unwrap();
        let m = |p: &Point| Point::new(-p.x, p.y, p.z);
        assert_eq!(r.skin.n_faces(), l.skin.n_faces());
        for (a, b) in r.skin.vertices.iter().zip(&l.skin.vertices) {
            assert!((m(a) - b).norm() < 1e-12);
        }
        assert!(
            (r.skin.signed_volume() - l.skin.signed_volume()).abs() < 1e-6 * r.skin.signed_volume()
        );
        for name in landmark_names() {
            assert!((m(&r.landmarks[name].0) - l.landmarks[name].0).norm() < 1e-12);
        }
        for j in Joint::ALL {
            let fr = l.skeleton.joint(j).frame.matrix();
            assert!((fr.determinant() - 1.0).abs() < 1e-9, "{j}");
            let (x, y, z) = (
                l.skeleton.joint(j).x(),
                l.skeleton.joint(j).y(),
                l.skeleton.joint(j).z(),
            );
            assert!((y.cross(&z) - x).norm() < 1e-9, "{j}");
        }
        // The same angles move both hands as mirror images: flex, abduct and rotate every joint.
        let mut moved = Pose::zero();
        for j in Joint::ALL {
            moved = moved.with_deg(j, [25.0, 10.0, 8.0]);
        }
        let tr = posed_tips(&r.skeleton, &link_transforms(&r.skeleton, &moved));
        let tl = posed_tips(&l.skeleton, &link_transforms(&l.skeleton, &moved));
        for (a, b) in tr.iter().zip(&tl) {
            assert!((m(a) - b).norm() < 1e-9, "{a:?} vs {b:?}");
        }
        // And flexion is palmar on both: the index tip goes against the dorsal axis.
        for h in [&r, &l] {
            let flex = Pose::zero().with_deg(Joint::IPip, [60.0, 0.0, 0.0]);
            let t = posed_tips(&h.skeleton, &link_transforms(&h.skeleton, &flex))[1];
            let d = h.skeleton.joint(Joint::IPip).y();
            assert!((t - h.skeleton.tips[1]).dot(&d) < -5.0);
        }
    }

    #[test]
    fn flexed_fingers_converge() {
        // 1-DOF axes are tilted so that the fingertips, flexed at PIP and DIP, come closer
        // together than the straight fingers' lines would bring them.
        let b = built(4, Pose::zero());
        let sk = &b.hand.skeleton;
        let mut fist = Pose::zero();
        for f in &Finger::ALL[1..] {
            let [_, pip, dip] = f.joints();
            fist = fist
                .with_deg(pip, [100.0, 0.0, 0.0])
                .with_deg(dip, [70.0, 0.0, 0.0]);
        }
        let tips = posed_tips(sk, &link_transforms(sk, &fist));
        // Flexion about an axis perpendicular to the finger would keep the tip in the plane of
        // the finger and the dorsal axis; the tilt moves it sideways, toward the scaphoid.
        // (The index points straight away from the scaphoid, so only its plane is defined: it is
        // left out.)
        let dorsal = sk.joint(Joint::Wrist).y();
        for f in &Finger::ALL[2..] {
            let mcp = sk.centre(f.joints()[0]);
            let along = (sk.tips[*f as usize] - mcp).normalize();
            let toward = b.neutral.scaphoid - mcp;
            let side =
                (toward - along * toward.dot(&along) - dorsal * toward.dot(&dorsal)).normalize();
            let moved = (tips[*f as usize] - sk.tips[*f as usize]).dot(&side);
            assert!(moved > 1.0, "{f:?}: {moved} mm toward the scaphoid");
        }
        // No two 1-DOF axes are parallel.
        let axes: Vec<Vec3> = Joint::ALL
            .iter()
            .filter(|j| j.dof() == 1)
            .map(|&j| sk.joint(j).x())
            .collect();
        for (i, a) in axes.iter().enumerate() {
            for b in &axes[i + 1..] {
                assert!(a.dot(b).abs() < 0.99995, "parallel axes");
            }
        }
    }
}
