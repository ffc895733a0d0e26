//! The truth of a simulated grasp trial that needs the true skin: the fingertips and the true
//! skin's contact areas with the part, frame by frame.
//!
//! The true skin (reference posture, lab frame) is posed by linear blend skinning with the true
//! link transforms of every frame (the true skeleton moved by the trial's forearm motion and
//! joint angles, [`link_transforms`]). Its weights are the template's for the template body
//! (the skin is homologous to the template and was shaped and posed with them) and bone heat
//! weights on its own geometry for the procedural body, which has none of its own. Contacts
//! are measured exactly as `track` measures the tracked skin's ([`replay_frames`]: a vertex
//! within the tolerance of the part or inside it is in contact, its rest area counts for its
//! dominant link, the deepest penetration per link), against the part's mesh at the true pose.
//! The capsule closure of the simulated grasp is a model of the digits' skin, so the true skin
//! may reach into the part: that is the truth of the simulated world, and the depths say how
//! far.
//!
//! The fingertip is defined as the model defines it ([`tips_from_skin`]): the point of the
//! distal joint's long axis level with the farthest skin vertex of the distal link, carried by
//! the distal link; the long axis is the distal phalanx in the reference posture (toward the
//! true skeleton's own tip), not the parent-side frame a posed skeleton keeps. The true skeletons' own tips differ between the bodies (the template's at
//! the skin's end, the procedural body's at the distal bone's end inside the pulp), so one
//! definition on the skin keeps the tip error a measure of the model, not of definitions.

use super::grasp_motion::{GraspTask, GraspTrial};
use crate::anatomy::{Finger, Side};
use crate::error::Result;
use crate::geometry::TriMesh;
use crate::grasp::contact::PartShape;
use crate::grasp::hand::SkinnedHand;
use crate::grasp::parts::clean_part;
use crate::pose::hand::tips_from_skin;
use crate::pose::IndividualHand;
use crate::skeleton::forward_kinematics::{link_transforms, posed_tips};
use crate::skeleton::{Pose, Skeleton};
use crate::template::LinkWeights;
use crate::track::{replay_frames, ContactReplay, PosedFrame, ReplayOptions};
use nalgebra::Isometry3;
use std::collections::BTreeMap;

/// The true hand bound for posing: `skin` and `skeleton` in the reference posture (lab frame)
/// with `weights`, its fingertips set by [`tips_from_skin`].
pub fn true_skinned_hand(
    side: Side,
    skin: &TriMesh,
    skeleton: &Skeleton,
    weights: LinkWeights,
) -> Result<SkinnedHand> {
    let mut sk = skeleton.clone();
    // A skeleton posed into the reference posture keeps each joint's frame on its parent link,
    // so a distal joint flexed there has its z off the distal phalanx; the skeleton's own tip,
    // carried by the distal link, gives the phalanx. Only z turns about the hinge axis, so the
    // link transforms stay the same.
    for f in Finger::ALL {
        let j = f.joints()[2];
        let (long, dorsal) = (sk.tips[f as usize] - sk.centre(j), sk.joint(j).y());
        sk.aim_long_axis(j, &long, &dorsal);
    }
    sk.tips = tips_from_skin(&sk, skin, &weights);
    SkinnedHand::new(IndividualHand::from_parts(side, skin.clone(), sk, weights)?)
}

/// Every link's true transform from the reference posture to the lab in each frame of `trial`
/// (`sk` the true skeleton it was simulated with).
pub fn true_link_transforms(sk: &Skeleton, trial: &GraspTrial) -> Vec<[Isometry3<f64>; 17]> {
    trial
        .root
        .iter()
        .zip(&trial.angles)
        .map(|(root, angles)| {
            let pose = Pose::from_deg(angles, *root);
            let t = link_transforms(sk, &pose);
            std::array::from_fn(|l| t[l])
        })
        .collect()
}

/// The true skin's contacts with the part of `task` over `trial` ([`replay_frames`] with the
/// true link transforms and part poses), tolerance `opts.tolerance_mm`.
pub fn true_contacts(
    hand: &SkinnedHand,
    task: &GraspTask,
    trial: &GraspTrial,
    opts: &ReplayOptions,
) -> Result<ContactReplay> {
    let (mesh, _) = clean_part(&task.part.mesh()?);
    let (part, _) = PartShape::with_band(mesh, opts.tolerance_mm)?;
    let frames: Vec<Option<PosedFrame>> = true_link_transforms(&hand.hand.skeleton, trial)
        .into_iter()
        .zip(&trial.part)
        .map(|(links, p)| Some(PosedFrame { links, part: *p }))
        .collect();
    Ok(replay_frames(hand, &frames, &part, opts))
}

/// Add the fingertips and the true contacts to `trial.truth` (`hand` from
/// [`true_skinned_hand`] on the skin and skeleton the trial was simulated with).
pub fn add_skin_truth(hand: &SkinnedHand, task: &GraspTask, trial: &mut GraspTrial) -> Result<()> {
    let sk = &hand.hand.skeleton;
    let transforms = true_link_transforms(sk, trial);
    let mut tips: BTreeMap<String, Vec<[f64; 3]>> = BTreeMap::new();
    for t in &transforms {
        let p = posed_tips(sk, t);
        for f in Finger::ALL {
            tips.entry(f.letter().to_string())
                .or_default()
                .push(p[f as usize].coords.into());
        }
    }
    let replay = true_contacts(hand, task, trial, &ReplayOptions::default())?;
    trial.truth.tips = tips;
    trial.truth.contacts = Some(replay.records());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::synth::procedural::procedural_body;

    /// A procedural hand whose reference posture flexes every DIP (IP) by 25°: its skeleton
    /// keeps the distal frames on the middle phalanges, yet the true fingertip lies on the
    /// distal phalanx, the line from the DIP centre toward the skeleton's own tip.
    #[test]
    fn a_true_tip_lies_along_the_distal_phalanx_of_a_flexed_reference_posture() {
        let mut posture = Pose::zero();
        for f in Finger::ALL {
            posture = posture.with_deg(f.joints()[2], [25.0, 0.0, 0.0]);
        }
        let hand = procedural_body(Side::Right, &Rng::new(11), posture, None).unwrap();
        let sk = &hand.skeleton;
        let w =
            crate::pose::bone_heat_weights(&hand.skin, sk, &crate::pose::HeatOptions::default())
                .unwrap();
        let skinned = true_skinned_hand(Side::Right, &hand.skin, sk, w).unwrap();
        for f in Finger::ALL {
            let j = f.joints()[2];
            let (c, x) = (sk.centre(j), sk.joint(j).x());
            let bone = sk.tips[f as usize] - c;
            let bone = bone - x * bone.dot(&x);
            // The posture is real: the parent-side z is well off the phalanx.
            assert!(sk.joint(j).z().angle(&bone).to_degrees() > 15.0, "{f:?}");
            let tip = skinned.hand.skeleton.tips[f as usize] - c;
            assert!(
                tip.angle(&bone).to_degrees() < 1e-4,
                "{f:?}: {}",
                tip.angle(&bone).to_degrees()
            );
            // Level with the skin's end: beyond the bone's end inside the pulp.
            assert!(tip.norm() > bone.norm(), "{f:?}");
        }
    }
}
