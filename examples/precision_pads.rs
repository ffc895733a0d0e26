//! Where the thumb's pad meets the fingers' pads in the tripod plan's closed posture, per hand:
//! the plan's own angles against the plan fitted to the hand (`fit_thumb_to_pads`).
//! `cargo run --release --example precision_pads -- [MODEL_DIR...]` (none: the template).
use ergohand::anatomy::{Finger, Joint, Side};
use ergohand::grasp::plan::{fit_thumb_to_pads, grasp_plan, pad_meeting, GraspPlan};
use ergohand::grasp::scene::GraspType;
use ergohand::grasp::{PosableHand, SkinnedHand};

fn describe(hand: &dyn PosableHand, plan: &GraspPlan) -> String {
    let (apart, off) = pad_meeting(hand, plan).expect("distal pads");
    let deg = |j: Joint, d: usize| plan.closed[j.index()][d].to_degrees();
    let [cmc, mcp, ip] = Finger::Thumb.joints();
    format!(
        "pads {apart:5.1} mm apart, {off:5.1}° from opposition; index [{:.0} {:.0} {:.0}], thumb CMC [{:.0} {:.0} {:.0}] MCP {:.0} IP {:.0}",
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
