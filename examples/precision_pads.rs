//! Where the thumb's pad meets the fingers' pads in the tripod plan's closed posture, per hand:
//! the plan's own angles against the plan fitted to the hand (`fit_thumb_to_pads`).
//! `cargo run --release --example precision_pads -- [MODEL_DIR...]` (none: the template).
use ergohand::anatomy::{Finger, Joint, Side};
use ergohand::grasp::plan::{distal_pad, fit_thumb_to_pads, grasp_plan, GraspPlan};
use ergohand::grasp::scene::GraspType;
use ergohand::grasp::{PosableHand, SkinnedHand};
use ergohand::skeleton::forward_kinematics::link_transforms;
use ergohand::skeleton::Pose;

fn describe(hand: &dyn PosableHand, plan: &GraspPlan) -> String {
    let tr = link_transforms(
        hand.skeleton(),
        &Pose {
            angles: plan.closed,
            root: nalgebra::Isometry3::identity(),
        },
    );
    let pad = |f| distal_pad(hand, f).expect("a distal pad").posed(&tr);
    let (t, i, m) = (pad(Finger::Thumb), pad(Finger::Index), pad(Finger::Middle));
    let facing = (i.1 + m.1).normalize();
    let deg = |j: Joint, d: usize| plan.closed[j.index()][d].to_degrees();
    let [cmc, mcp, ip] = Finger::Thumb.joints();
    format!(
        "pads {:5.1} mm apart, {:5.1}° from opposition; index [{:.0} {:.0} {:.0}], thumb CMC [{:.0} {:.0} {:.0}] MCP {:.0} IP {:.0}",
        (t.0 - nalgebra::center(&i.0, &m.0)).norm(),
        (-t.1.dot(&facing)).clamp(-1.0, 1.0).acos().to_degrees(),
        deg(Joint::IMcp, 0),
        deg(Joint::IPip, 0),
        deg(Joint::IDip, 0),
        deg(cmc, 0),
        deg(cmc, 1),
        deg(cmc, 2),
        deg(mcp, 0),
        deg(ip, 0),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dirs: Vec<String> = std::env::args().skip(1).collect();
    let hands: Vec<(String, SkinnedHand)> = if dirs.is_empty() {
        vec![("template".into(), SkinnedHand::template(Side::Right)?)]
    } else {
        dirs.iter()
            .map(|d| Ok((d.clone(), SkinnedHand::load(std::path::Path::new(d))?)))
            .collect::<ergohand::Result<_>>()?
    };
    let plan = grasp_plan(GraspType::Tripod);
    for (name, hand) in &hands {
        let fitted = fit_thumb_to_pads(&plan, hand);
        println!("{name}");
        println!("  plan   {}", describe(hand, &plan));
        println!("  fitted {}", describe(hand, &fitted));
    }
    Ok(())
}
