//! The placement search for `approach = "auto"`: wrist poses sampled around the part, screened,
//! closed by [`super::autograsp`] and scored by the grasp quality, the best kept (after the
//! optimisation-based grasp posture generation of Endo et al.: sample, close, score, keep the
//! best).

use super::autograsp::{
    autograsp, pad_point, pose_at, press_travel, squeeze, starts_clear, AutograspOptions, Closing,
};
use super::contact::PartShape;
use super::hand::PosableHand;
use super::plan::{grasp_frame, GraspPlan};
use crate::geometry::{Point, Vec3};
use crate::rng::Rng;
use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion};

/// A candidate placement: the grasp frame looks along `-dir` at the part from just outside its
/// surface, rolled by `roll` about its z axis.
pub fn placement(part: &PartShape, dir: &Vec3, roll: f64, gap_mm: f64) -> Option<Isometry3<f64>> {
    let d = dir.try_normalize(1e-12)?;
    let far = part.centre_of_mass + d * (part.max_radius + 50.0);
    let toi = part.ray_cast(&far, &-d)?;
    let hit = far - d * toi;
    let (x0, y0, z) = unrolled_axes(&d);
    let (s, c) = roll.sin_cos();
    let x = x0 * c + y0 * s;
    let y = z.cross(&x);
    let rot = Rotation3::from_basis_unchecked(&[x, y, z]);
    Some(Isometry3::from_parts(
        Translation3::from((hit + d * gap_mm).coords),
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

/// The axes of a grasp frame looking along `-d` (a unit vector) at roll 0: x, y, z = `-d`.
fn unrolled_axes(d: &Vec3) -> (Vec3, Vec3, Vec3) {
    let z = -d;
    let helper = if z.z.abs() < 0.9 {
        Vec3::z()
    } else {
        Vec3::x()
    };
    let x0 = helper.cross(&z).normalize();
    (x0, z.cross(&x0), z)
}

/// A candidate placement of a precision grasp: the grasp frame oriented as by [`placement`]
/// (looking along `-dir`, rolled by `roll`) and moved so that the plan's [`pad_point`] `pad`
/// (grasp frame) lies halfway through the part along `dir` through its centre of mass, where
/// the pads closing from either side meet it (for a pen seen from its side: on its axis).
pub fn pad_placement(
    part: &PartShape,
    dir: &Vec3,
    roll: f64,
    pad: &Vec3,
) -> Option<Isometry3<f64>> {
    let entry = placement(part, dir, roll, 0.0)?;
    let d = dir.try_normalize(1e-12)?;
    let far = part.centre_of_mass - d * (part.max_radius + 50.0);
    let exit = far + d * part.ray_cast(&far, &d)?;
    let centre = Point::from((entry.translation.vector + exit.coords) / 2.0);
    Some(Isometry3::from_parts(
        Translation3::from(centre.coords - entry.rotation * pad),
        entry.rotation,
    ))
}

/// A candidate placement of a grasp with a [`GraspPlan::support`]: the grasp frame oriented
/// as by [`placement`] (looking along `-dir`, rolled by `roll`) and moved so that the plan's
/// [`pad_point`] `pad` (on the support's skin, grasp frame) lies on the part's surface where a
/// line through the centre of mass along the pads' closing direction `press` (grasp frame)
/// leaves it: the part rests on the support, and the thumb closing along `press` pushes it
/// through its centre of mass onto the support (no torque about the contacts from the squeeze).
pub fn support_placement(
    part: &PartShape,
    dir: &Vec3,
    roll: f64,
    pad: &Vec3,
    press: &Vec3,
) -> Option<Isometry3<f64>> {
    let rot = placement(part, dir, roll, 0.0)?.rotation;
    let d = (rot * press).try_normalize(1e-12)?;
    // From beyond the part on the far side of the support, back toward it: the first hit is
    // the face the support touches.
    let far = part.centre_of_mass + d * (part.max_radius + 50.0);
    let hit = far - d * part.ray_cast(&far, &-d)?;
    Some(Isometry3::from_parts(
        Translation3::from(hit.coords - rot * pad),
        rot,
    ))
}

/// Where a power grasp's candidates put the part under the palm: its surface point facing the
/// palm this far proximal of the MCP row (mm, the mean of the four fingers' MCP centres along
/// the grasp frame's y), drawn uniformly per candidate. A power grip holds a handle across the
/// distal palm, over the heads of the metacarpals (Napier 1956; Cutkosky 1989), so that the
/// proximal phalanges close onto it first: a straight finger swinging about its MCP meets a
/// cylinder that touches the palm `c` proximal of the joint at `c` along the finger, and the
/// grasp frame's origin at the palm's centre (40-50 mm proximal) put that beyond the proximal
/// phalanx, so that the fingers met the part with their middle and distal phalanges and hooked.
/// The range is the one whose screening wrapped the drill on most of the dev hands (README,
/// "Power grasps placed on a handle").
pub const POWER_REACH_MM: [f64; 2] = [0.0, 20.0];

/// A candidate placement of a power grasp: the grasp frame oriented and set off the part as by
/// [`placement`], then moved along its own y (toward the wrist) by `ahead_mm`, so that the part's
/// surface where the palm meets it lies `ahead_mm` distal of the frame's origin, under the
/// distal palm (see [`POWER_REACH_MM`]).
pub fn power_placement(
    part: &PartShape,
    dir: &Vec3,
    roll: f64,
    gap_mm: f64,
    ahead_mm: f64,
) -> Option<Isometry3<f64>> {
    Some(placement(part, dir, roll, gap_mm)? * Translation3::new(0.0, -ahead_mm, 0.0))
}

/// Radius of the part's surface about a candidate's contact point that [`wrap_axis`] reads, mm:
/// about a hand's breadth across the fingers' reach round a handle.
pub const WRAP_AXIS_RADIUS_MM: f64 = 30.0;

/// Largest angle between a power grasp's MCP row and the handle's axis among the candidates,
/// degrees: a handle lies obliquely across the palm, from the hypothenar toward the base of the
/// index (Napier 1956), not square to the fingers.
pub const POWER_OBLIQUE_DEG: f64 = 30.0;

/// The axis the part's surface curves about within `radius_mm` of `at`, the one a power grasp's
/// fingers wrap round: the direction along which its normals do not turn (the eigenvector of
/// least eigenvalue of the area-weighted scatter of the face normals there, which is zero along
/// a cylinder's axis). `None` where the surface curves about no single axis: flat (the normals
/// spread by less than about 13°, second eigenvalue under 0.05) or curved both ways (least
/// eigenvalue above a third of the second).
pub fn wrap_axis(part: &PartShape, at: &Point, radius_mm: f64) -> Option<Vec3> {
    let mut scatter = nalgebra::Matrix3::<f64>::zeros();
    let mut total = 0.0;
    // A face whose centre lies within the radius has its nearest point within it too: the
    // tree's range query finds them all, in face order, without visiting the whole part.
    let mut near = Vec::new();
    part.tree.faces_within(at, radius_mm, &mut near);
    for &(f, _) in &near {
        let [a, b, c] = part.mesh.corners(f);
        let centre = Point::from((a.coords + b.coords + c.coords) / 3.0);
        if (centre - at).norm() > radius_mm {
            continue;
        }
        let n = &part.face_normals[f];
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        scatter += n * n.transpose() * area;
        total += area;
    }
    if total <= 0.0 {
        return None;
    }
    let eig = nalgebra::SymmetricEigen::new(scatter / total);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let (second, least) = (eig.eigenvalues[order[1]], eig.eigenvalues[order[2]]);
    if second < 0.05 || least > second / 3.0 {
        return None;
    }
    Some(eig.eigenvectors.column(order[2]).into_owned())
}

/// The roll of [`placement`] that lays the grasp frame's x (across the palm, along the MCP row)
/// along `axis` seen from `dir`; `None` when `axis` is along `dir`.
fn roll_along(dir: &Vec3, axis: &Vec3) -> Option<f64> {
    let (x0, y0, z) = unrolled_axes(&dir.try_normalize(1e-12)?);
    let a = axis - z * z.dot(axis);
    if a.norm() < 1e-6 {
        return None;
    }
    Some(a.dot(&y0).atan2(a.dot(&x0)))
}

/// How far the MCP row lies distal of the [`grasp_frame`]'s origin, mm: the mean of the four
/// fingers' MCP centres along the frame's y.
pub fn mcp_row_ahead(hand: &dyn PosableHand) -> f64 {
    use crate::anatomy::Joint;
    let to_frame = grasp_frame(hand).inverse();
    let sk = hand.skeleton();
    [Joint::IMcp, Joint::MMcp, Joint::RMcp, Joint::LMcp]
        .iter()
        .map(|&j| (to_frame * sk.centre(j)).y)
        .sum::<f64>()
        / 4.0
}

/// How far a closed grasp envelops the part, the first key of a power grasp's placement
/// ranking: 1 for the palm touching, plus the fingers wrapped with all three phalanges (up to
/// [`super::contact::WRAP_FINGERS`]), so that a grasp that [wraps](super::contact::Envelope)
/// ranks first.
fn envelope_rank(e: &super::contact::Envelope) -> usize {
    usize::from(e.palm) + e.fingers_wrapped.len().min(super::contact::WRAP_FINGERS)
}

/// Result of [`placement_search`].
#[derive(Clone, Debug)]
pub struct PlacementResult {
    /// Best approach (grasp frame in the part's world frame).
    pub approach: Isometry3<f64>,
    /// The hand closed and squeezed from it with the default [`AutograspOptions`] (the
    /// finalists' full evaluation made it).
    pub closing: Closing,
    /// How many of the plan's [`GraspPlan::pads`] touch the part in it (full evaluation); for a
    /// power grasp, how far it envelops the part (the palm touching counts 1, each finger
    /// wrapped with all three phalanges 1, up to three).
    pub pads_touching: usize,
    /// Its epsilon (full evaluation).
    pub epsilon: f64,
    /// Candidates screened (not rejected, within the time bound).
    pub evaluated: usize,
    /// The other finalists' approaches with their closings, best first (for a caller that
    /// rejects the best, e.g. by the hold test).
    pub runners_up: Vec<(Isometry3<f64>, Closing)>,
    /// The candidates ranked next by the screening alone (not evaluated in full), best first:
    /// for a caller whose finalists all fail ([`RESERVES`]).
    pub reserves: Vec<Isometry3<f64>>,
}

/// Skin vertex stride of the placement search's screening (closing checks and contacts) for a
/// precision grasp: its pads are fingertip patches, which a sparser sample ranks worse.
pub(crate) const SCREEN_STRIDE: usize = 4;

/// [`SCREEN_STRIDE`] of a power grasp, whose contacts spread over the palm and every
/// phalanx: a sample half as dense ranks its candidates as well for half the closing's
/// queries (checked over a population of both bodies: the same share holds and wraps).
pub(crate) const POWER_SCREEN_STRIDE: usize = 8;

/// The screening's skin vertex stride for `plan` ([`SCREEN_STRIDE`], or
/// [`POWER_SCREEN_STRIDE`] for a plan without pads).
fn screen_stride(plan: &GraspPlan) -> usize {
    if plan.pads.is_empty() {
        POWER_SCREEN_STRIDE
    } else {
        SCREEN_STRIDE
    }
}

/// Friction cone edges of the screening quality (a subset of the full cone's edges, so its
/// epsilon is a lower bound of the full one's).
pub(crate) const SCREEN_CONE_EDGES: usize = 4;

/// Screened candidates whose full evaluation decides (taken down the screening ranking,
/// skipping those the full autograsp refuses).
pub(crate) const FINALISTS: usize = 6;

/// Candidates of the screening's ranking after the finalists kept in reserve
/// ([`PlacementResult::reserves`]).
pub const RESERVES: usize = 10;

/// The screening stops once this many candidates have closed on the part.
pub(crate) const SCREEN_CLOSED: usize = 128;

/// Candidates screened at a time (in parallel) between checks of [`SCREEN_CLOSED`].
pub(crate) const SCREEN_CHUNK: usize = 32;

/// Whether any skin vertex at the preshape of `plan` from `root` lies inside the part deeper
/// than the broad phase's band (every vertex, by the voxel grid alone: the autograsp would
/// refuse such a start).
fn starts_deep_inside(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    root: Isometry3<f64>,
    buf: &mut Vec<Point>,
) -> bool {
    hand.pose_vertices(&pose_at(plan, &[0.0; 16], root), buf);
    part.closed
        && buf
            .iter()
            .any(|p| part.grid.zone(p) == super::broad::Zone::Inside)
}

/// Quality of the hand closed by `opts` from `root` ([`Score`]), the contacts measured on
/// every `stride`-th skin vertex (each standing for `stride` vertices' area) and the friction
/// cones linearised with `edges` edges; epsilon and the distance from force closure of the
/// pads' contacts alone for a plan with [`GraspPlan::pads`]; with `squeezed`,
/// measured after the [`squeeze`], as the scene is; with `envelope_first`, the first key is how
/// far the grasp envelops the part ([`envelope_rank`]) instead of the pads touching. `None`
/// when the autograsp refuses the start. With `squeezed`, also the [`Closing`] made with `opts`
/// (a finalist's, with the default options: the scene takes it instead of closing again).
#[allow(clippy::too_many_arguments)]
fn closed_quality(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    mu: f64,
    root: Isometry3<f64>,
    opts: &AutograspOptions,
    sample: &(Vec<usize>, Vec<usize>, Vec<f64>),
    edges: usize,
    squeezed: bool,
    envelope_first: bool,
    index: usize,
) -> Option<(Score, Option<Closing>)> {
    let g = autograsp(hand, part, plan, root, opts).ok()?;
    let (pose, closing) = if squeezed {
        let (pose, _, s) = squeeze(hand, part, plan, &g, opts);
        (
            pose.clone(),
            Some(Closing {
                autograsp: g,
                pose,
                squeeze: s,
            }),
        )
    } else {
        (g.pose, None)
    };
    let mut pts = Vec::new();
    hand.pose_vertices(&pose, &mut pts);
    let (idx, links, areas) = sample;
    let pts: Vec<Point> = idx.iter().map(|&i| pts[i]).collect();
    let c = super::contact::contacts(part, &pts, links, areas, &opts.contact);
    // A precision grasp is scored by its pads alone: the other links (tucked fingers, palm)
    // are not closed onto the part and press it with no controlled force, and their contacts
    // far along a pen's length inflated epsilon for grasps whose pads did not oppose.
    let held: Vec<super::contact::Contact> = c
        .contacts
        .iter()
        .filter(|k| plan.pads.is_empty() || plan.pads.iter().any(|l| l.index() == k.link_index))
        .cloned()
        .collect();
    let w = super::quality::cone_wrenches(&held, mu, &part.centre_of_mass, part.max_radius, edges);
    let e = super::quality::epsilon(&w);
    let pads = if envelope_first {
        envelope_rank(&c.envelope())
    } else {
        plan.pads.iter().filter(|l| c.touches(l.index())).count()
    };
    // Grasps without force closure all have epsilon 0: how far each is from it orders them.
    let closure = if e.force_closure {
        0.0
    } else {
        -super::quality::closure_distance(&w)
    };
    Some((
        (index, pads, e.epsilon, closure, c.total_area_mm2()),
        closing,
    ))
}

/// A candidate's score: (its index, pads of the plan touching or, ranking by the envelope, its
/// [`envelope_rank`], epsilon, minus its distance from force closure
/// ([`super::quality::closure_distance`], 0 with force closure), contact area).
///
/// The third key orders the grasps without force closure, which all tie at epsilon 0. It was
/// the volume of the wrench space's hull: tens of thousands of facets for a few hundred
/// wrenches, most of a search's time where finalists tie, and 0 where the hull's construction
/// failed on a legitimate grasp. The distance says instead how much is missing for force
/// closure, by Wolfe's nearest point without any hull, and never fails.
type Score = (usize, usize, f64, f64, f64);

/// The order [`screen_and_rank`] keeps: best first by [`by_quality`], ties to the lower index.
fn better_first(a: &Score, b: &Score) -> std::cmp::Ordering {
    by_quality(b, a).then(a.0.cmp(&b.0))
}

/// The order of [`closed_quality`]'s scores, the index aside: pads touching, then epsilon,
/// then nearness to force closure (for grasps without it), then contact area.
fn by_quality(a: &Score, b: &Score) -> std::cmp::Ordering {
    a.1.cmp(&b.1)
        .then(a.2.total_cmp(&b.2))
        .then(a.3.total_cmp(&b.3))
        .then(a.4.total_cmp(&b.4))
}

/// The placement search's two stages on candidate approaches `0..n` (`approach_of(i)`: the
/// grasp frame in the part's world, `None` to skip): in index order until [`SCREEN_CLOSED`]
/// have closed, each screened (parallel, until `time_limit_s`) by the coarse autograsp
/// ([`screening_options`]) and scored on every [`screen_stride`]-th vertex with
/// [`SCREEN_CONE_EDGES`]-edge cones, a start deep inside the part rejected by the voxel grid;
/// then down that ranking, `finalists` at a time until `finalists` succeed, closed by the
/// default autograsp, squeezed and scored in full. `envelope_first`: the first ranking key
/// is how far the grasp envelops the part ([`envelope_rank`]) instead of the plan's pads.
/// Returns the finalists' scores and closings, best first (ties to the lower index), how many candidates
/// closed in the screening, and the next [`RESERVES`] candidates of the screening's ranking
/// (indices, not evaluated in full).
#[allow(clippy::too_many_arguments)]
fn screen_and_rank(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    mu: f64,
    n: usize,
    approach_of: &(dyn Fn(usize) -> Option<Isometry3<f64>> + Sync),
    finalists: usize,
    time_limit_s: f64,
    envelope_first: bool,
) -> (Vec<(Score, Closing)>, usize, Vec<usize>) {
    use rayon::prelude::*;
    let gf = grasp_frame(hand);
    let coarse = screening_options(plan);
    // A bar only where status lines are logged (the command line without --quiet).
    let bar = if log::log_enabled!(log::Level::Info) && n > 50 {
        indicatif::ProgressBar::new(n as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let started = std::time::Instant::now();
    let coarse_sample = skin_sample(hand, coarse.stride);
    let root_of = |i: usize| Some(approach_of(i)? * gf.inverse());
    let score = |i: usize, root, opts: &AutograspOptions, sample: &_, edges, squeezed| {
        closed_quality(
            hand,
            part,
            plan,
            mu,
            root,
            opts,
            sample,
            edges,
            squeezed,
            envelope_first,
            i,
        )
    };
    // Candidates in index order, a chunk at a time (in parallel within a chunk), until
    // `SCREEN_CLOSED` have closed: a sample that large ranks as well as every candidate would,
    // and where few candidates close (a large flat part) the search still tries them all.
    use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
    let (no_place, deep, late) = (
        AtomicUsize::new(0),
        AtomicUsize::new(0),
        AtomicUsize::new(0),
    );
    let mut scored: Vec<Score> = Vec::new();
    let mut tried = 0;
    while tried < n && scored.len() < SCREEN_CLOSED {
        let end = (tried + SCREEN_CHUNK).min(n);
        scored.extend(
            (tried..end)
                .into_par_iter()
                .map_init(Vec::new, |buf, i| {
                    bar.inc(1);
                    if started.elapsed().as_secs_f64() > time_limit_s {
                        late.fetch_add(1, Relaxed);
                        return None;
                    }
                    let Some(root) = root_of(i) else {
                        no_place.fetch_add(1, Relaxed);
                        return None;
                    };
                    if starts_deep_inside(hand, part, plan, root, buf) {
                        deep.fetch_add(1, Relaxed);
                        return None;
                    }
                    score(i, root, &coarse, &coarse_sample, SCREEN_CONE_EDGES, false)
                        .map(|(s, _)| s)
                })
                .collect::<Vec<_>>()
                .into_iter()
                .flatten(),
        );
        tried = end;
    }
    bar.finish_and_clear();
    let evaluated = scored.len();
    let (no_place, deep, late) = (no_place.into_inner(), deep.into_inner(), late.into_inner());
    log::debug!(
        "placement search: screening {:.2} s: {tried} of {n} candidates tried, {evaluated} closed, {no_place} without a placement, {deep} starting inside the part, {} refused by the autograsp, {late} past the time limit",
        started.elapsed().as_secs_f64(),
        tried - evaluated - no_place - deep - late,
    );
    let mut ranked = scored;
    ranked.sort_by(better_first);
    let full_sample = skin_sample(hand, 1);
    let full = AutograspOptions::default();
    // Down the ranking, `finalists` at a time, until `finalists` full evaluations succeed.
    let step = finalists.max(1);
    let mut pos = 0;
    let mut finals: Vec<(Score, Closing)> = Vec::new();
    while finals.len() < finalists && pos < ranked.len() {
        let end = (pos + step).min(ranked.len());
        finals.extend(
            ranked[pos..end]
                .par_iter()
                .filter_map(|s| {
                    let i = s.0;
                    let (s, closing) = score(
                        i,
                        root_of(i)?,
                        &full,
                        &full_sample,
                        super::quality::CONE_EDGES,
                        true,
                    )?;
                    Some((s, closing?))
                })
                .collect::<Vec<_>>(),
        );
        pos = end;
    }
    finals.sort_by(|a, b| better_first(&a.0, &b.0));
    log::debug!(
        "placement search: finalists {:.2} s",
        started.elapsed().as_secs_f64()
    );
    let reserves = ranked[pos..].iter().take(RESERVES).map(|s| s.0).collect();
    (finals, evaluated, reserves)
}

/// The screening's coarse autograsp: steps of 0.1 in the closing parameter, every
/// [`screen_stride`]-th skin vertex of `plan`'s hand, links up to 2 mm deep.
fn screening_options(plan: &GraspPlan) -> AutograspOptions {
    AutograspOptions {
        step: 0.1,
        min_step: 0.05,
        max_depth_mm: 2.0,
        stride: screen_stride(plan),
        ..AutograspOptions::default()
    }
}

/// Step of [`backed_off`]'s retreat, mm.
pub const BACK_OFF_STEP_MM: f64 = 4.0;

/// Farthest [`backed_off`] moves an approach back, mm: well within a power grasp's approach to
/// contact ([`GraspPlan::approach_mm`]), which brings the palm back onto the part.
pub const BACK_OFF_MAX_MM: f64 = 24.0;

/// A power approach whose preshape starts inside the part moved back along its palmar axis, in
/// [`BACK_OFF_STEP_MM`] steps up to [`BACK_OFF_MAX_MM`], to the first place the hand starts clear
/// of it ([`starts_clear`]); the approach as given when it starts clear or nothing within reach
/// does, or when the plan has no approach to contact to bring the hand back. A hand reaching for
/// a part comes at it from outside: placed at the part's surface, the open hand's thumb or
/// fingers of a large flat part (a phone laid on the palm) start inside it, and the candidate
/// was lost, though the same placement reached from a little farther back closes well.
pub fn backed_off(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    approach: Isometry3<f64>,
    opts: &AutograspOptions,
) -> Isometry3<f64> {
    if plan.approach_mm <= 0.0 {
        return approach;
    }
    let gf = grasp_frame(hand).inverse();
    let axis = approach.rotation * Vec3::z();
    let steps = (BACK_OFF_MAX_MM / BACK_OFF_STEP_MM).round() as usize;
    let back = |k: usize| Translation3::from(-axis * (k as f64 * BACK_OFF_STEP_MM)) * approach;
    let clear = |a: &Isometry3<f64>| starts_clear(hand, part, plan, a * gf, opts);
    if clear(&approach) {
        return approach;
    }
    // The farthest first: a part the open hand lies across (its plane through the fingers)
    // stays in the way however far back the hand goes, and is given up after one check.
    if !clear(&back(steps)) {
        return approach;
    }
    (1..=steps).map(back).find(clear).unwrap_or(approach)
}

/// Spacing of the positions [`slide_search`] closes the hand at, mm.
pub const SLIDE_STEP_MM: f64 = 5.0;

/// Positions of a [`slide_search`] evaluated in full after the screening.
pub const SLIDE_FINALISTS: usize = 3;

/// A given approach refined for the hand: its grasp frame moved along its own y (toward the
/// fingers; toward the wrist when negative) by multiples of [`SLIDE_STEP_MM`] up to `slide_mm`
/// either way, screened and ranked as the placement search's candidates are
/// ([`SLIDE_FINALISTS`] evaluated in full: closed, squeezed, every vertex, the full friction
/// cones). A scene's approach is written for one hand: on a hand of another size or
/// proportions the part sits elsewhere under the palm and the digits reach round it
/// differently, as a person's grip moves along the palm to suit the hand.
///
/// `approach` is the grasp frame in the part's world. Returns the positions, best first, as
/// (offset along the palm, mm; approach; the closing made from there), the finalists only; a position where the hand starts
/// inside the part is left out (empty when all are). Among equal scores the smaller slide
/// comes first.
pub fn slide_search(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    mu: f64,
    approach: &Isometry3<f64>,
    slide_mm: f64,
) -> Vec<(f64, Isometry3<f64>, Closing)> {
    let n = (slide_mm / SLIDE_STEP_MM + 1e-9).floor() as i64;
    // Nearest the given approach first, so that ties go to the smaller slide.
    let offsets: Vec<f64> = std::iter::once(0)
        .chain((1..=n).flat_map(|k| [-k, k]))
        .map(|k| k as f64 * SLIDE_STEP_MM)
        .collect();
    let at = |o: f64| approach * Translation3::new(0.0, o, 0.0);
    let (finals, _, _) = screen_and_rank(
        hand,
        part,
        plan,
        mu,
        offsets.len(),
        &|i| Some(at(offsets[i])),
        SLIDE_FINALISTS,
        f64::INFINITY,
        false,
    );
    finals
        .into_iter()
        .map(|(s, c)| (offsets[s.0], at(offsets[s.0]), c))
        .collect()
}

/// Every `stride`-th skin vertex: (indices, links, areas scaled to stand for the skipped).
fn skin_sample(hand: &dyn PosableHand, stride: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let areas = super::contact::vertex_areas(hand.rest_mesh());
    let idx: Vec<usize> = (0..areas.len()).step_by(stride.max(1)).collect();
    let links = idx.iter().map(|&i| hand.vertex_link()[i]).collect();
    let a = idx.iter().map(|&i| areas[i] * stride as f64).collect();
    (idx, links, a)
}

/// Placement search: `candidates` seeded random placements (directions uniform on the sphere,
/// rolls uniform), screened cheaply, the best few evaluated in full; the result is the best of
/// the full evaluations by (pads touching, epsilon, nearness to force closure, contact area).
///
/// A wrapping plan (power, [`GraspPlan::wrap`]) is placed with the palm 3 mm off the part, the
/// part under the distal palm ([`power_placement`], [`POWER_REACH_MM`]) and, where the part
/// curves about an axis, the MCP row along it ([`wrap_axis`], [`POWER_OBLIQUE_DEG`]), and its
/// candidates rank first by how far they envelop the part (the palm, then the fingers wrapped
/// with all three phalanges; [`super::contact::Envelope`]): a power grasp holds the part against
/// the palm with the fingers wrapped round it (Cutkosky 1989), and epsilon alone preferred grasps
/// by the fingertips with the palm off the part, which hold too but are not the grasp a person
/// makes; another plan without pads with the palm 3 mm off the part ([`placement`]); a
/// precision plan with its [`pad_point`] in the part ([`pad_placement`]); a
/// plan with a [`GraspPlan::support`] (lateral) with the part resting on the support where the
/// thumb's closing line through the centre of mass leaves it ([`support_placement`]). Candidates
/// of a plan with pads rank first by how many of its pads touch the part, and
/// its epsilon is that of the pads' contacts: a precision grasp is one held by the pads
/// (Cutkosky 1989), and epsilon of every contact preferred a tripod held by the thenar and one
/// fingertip, which is force closure but drops the pen.
///
/// A power placement whose open hand starts inside the part is first moved back along the
/// palmar axis to a clear start ([`backed_off`]). Screening (parallel, in index order until
/// [`SCREEN_CLOSED`] candidates have closed, stops early at `time_limit_s`): a placement where
/// a skin vertex is deep inside the part at the preshape is rejected by the voxel grid (every
/// vertex); the others are closed by a coarse autograsp (steps of 0.1, every
/// [`screen_stride`]-th vertex) and scored with contacts on the same vertices and friction cones of [`SCREEN_CONE_EDGES`] edges (a lower
/// bound of the full epsilon). The [`FINALISTS`] best are closed by the default autograsp,
/// squeezed ([`squeeze`]) and scored by the full model (every vertex,
/// [`super::quality::CONE_EDGES`] edges), as the scene evaluation will; a candidate whose full
/// autograsp refuses the start (a vertex 2 to 3 mm inside, which the grid and the thinned
/// check can miss) is replaced by the next. The finalists come back ranked
/// ([`PlacementResult::runners_up`]).
/// Deterministic for a seed when the time bound is not reached.
#[allow(clippy::too_many_arguments)]
pub fn placement_search(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    mu: f64,
    seed: u64,
    candidates: usize,
    time_limit_s: f64,
) -> Option<PlacementResult> {
    let mut rng = Rng::new(seed).fork("placement");
    let cand: Vec<(Vec3, f64)> = (0..candidates)
        .map(|_| {
            (
                rng.unit_vector(),
                rng.range(0.0, 2.0 * std::f64::consts::PI),
            )
        })
        .collect();
    // A stream of its own, so that the other grasp types' candidates stay those of their seed.
    let mut draw = Rng::new(seed).fork("power reach");
    let mcp = mcp_row_ahead(hand);
    let oblique = POWER_OBLIQUE_DEG.to_radians();
    // Per candidate: how far the MCP row lies ahead of the part, and the roll off the
    // handle's axis (either way round: the thumb toward either end).
    let power: Vec<(f64, f64)> = (0..candidates)
        .map(|_| {
            let ahead = mcp - draw.range(POWER_REACH_MM[0], POWER_REACH_MM[1]);
            let off = draw.range(-oblique, oblique);
            let flip = if draw.range(0.0, 1.0) < 0.5 {
                0.0
            } else {
                std::f64::consts::PI
            };
            (ahead, off + flip)
        })
        .collect();
    // Where the part curves about an axis (a handle), the MCP row lies along it; elsewhere the
    // candidate's own roll.
    let power_roll = |i: usize| {
        let (dir, roll) = cand[i];
        placement(part, &dir, roll, 0.0)
            .and_then(|at| {
                wrap_axis(
                    part,
                    &Point::from(at.translation.vector),
                    WRAP_AXIS_RADIUS_MM,
                )
            })
            .and_then(|axis| roll_along(&dir, &axis))
            .map_or(roll, |r| r + power[i].1)
    };
    // The back-off checks the start as the screening's autograsp will.
    let screen_opts = screening_options(plan);
    let pad = pad_point(hand, plan);
    let press = press_travel(hand, plan);
    let approach_of = |i: usize| match (&pad, &press) {
        (Some(p), Some(n)) => support_placement(part, &cand[i].0, cand[i].1, p, n),
        (Some(p), None) => pad_placement(part, &cand[i].0, cand[i].1, p),
        (None, _) if plan.wrap => power_placement(part, &cand[i].0, power_roll(i), 3.0, power[i].0)
            .map(|a| backed_off(hand, part, plan, a, &screen_opts)),
        (None, _) => placement(part, &cand[i].0, cand[i].1, 3.0),
    };
    let (finals, evaluated, reserves) = screen_and_rank(
        hand,
        part,
        plan,
        mu,
        candidates,
        &approach_of,
        FINALISTS,
        time_limit_s,
        plan.wrap,
    );
    log::debug!(
        "placement search: {evaluated} of {candidates} candidates screened, {} finalists",
        finals.len(),
    );
    let best = finals.first()?.0;
    // Every finalist was screened, so it has an approach.
    let finalists: Vec<(Isometry3<f64>, Closing)> = finals
        .into_iter()
        .filter_map(|(s, c)| Some((approach_of(s.0)?, c)))
        .collect();
    let mut finalists = finalists.into_iter();
    let (approach, closing) = finalists.next()?;
    Some(PlacementResult {
        approach,
        closing,
        pads_touching: best.1,
        epsilon: best.2,
        evaluated,
        runners_up: finalists.collect(),
        reserves: reserves.into_iter().filter_map(approach_of).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A power candidate is the plain placement moved toward the wrist along its own y: the
    /// part's surface that the plain placement's frame looked at, 3 mm along its palmar axis,
    /// lies `ahead` distal of the moved frame's origin, for any direction and roll.
    #[test]
    fn power_placement_puts_the_part_ahead_of_the_frame() {
        use crate::grasp::parts::Part;
        let part = PartShape::new(Part::Bottle.mesh().unwrap()).unwrap().0;
        let mut rng = Rng::new(11);
        for _ in 0..20 {
            let (dir, roll, ahead) = (
                rng.unit_vector(),
                rng.range(0.0, std::f64::consts::TAU),
                rng.range(0.0, 50.0),
            );
            let Some(plain) = placement(&part, &dir, roll, 3.0) else {
                continue;
            };
            let moved = power_placement(&part, &dir, roll, 3.0, ahead).unwrap();
            assert!((moved.rotation.angle_to(&plain.rotation)).abs() < 1e-12);
            let probe = moved * Point::new(0.0, ahead, 0.0);
            assert!((probe - Point::from(plain.translation.vector)).norm() < 1e-9);
            let palmar = moved.rotation * Vec3::z();
            let toi = part.ray_cast(&probe, &palmar).unwrap();
            assert!((toi - 3.0).abs() < 1e-6, "{toi}");
        }
    }

    /// The phone laid on the template's palm from random sides: where the open hand starts
    /// inside it, the power approach moves back along the palmar axis, by whole steps within
    /// the limit, to where it starts clear (and not a step sooner); an approach that starts
    /// clear, and any approach of a plan without an approach to contact, is kept as given.
    #[test]
    fn a_power_approach_starting_inside_the_part_backs_off_to_a_clear_start() {
        use crate::anatomy::Side;
        use crate::grasp::hand::RigidHand;
        use crate::grasp::parts::Part;
        use crate::grasp::plan::grasp_plan;
        use crate::grasp::scene::GraspType;
        let hand = RigidHand::template(Side::Right).unwrap();
        let part = PartShape::new(Part::Phone.mesh().unwrap()).unwrap().0;
        let (power, pinch) = (grasp_plan(GraspType::Power), grasp_plan(GraspType::Pinch));
        let opts = AutograspOptions {
            stride: SCREEN_STRIDE,
            ..AutograspOptions::default()
        };
        let gf = grasp_frame(&hand).inverse();
        let mut rng = Rng::new(5);
        let (mut moved, mut kept) = (0, 0);
        for _ in 0..40 {
            let (dir, roll) = (rng.unit_vector(), rng.range(0.0, std::f64::consts::TAU));
            let Some(a) = power_placement(&part, &dir, roll, 3.0, 10.0) else {
                continue;
            };
            let clear = |x: &Isometry3<f64>| starts_clear(&hand, &part, &power, x * gf, &opts);
            let b = backed_off(&hand, &part, &power, a, &opts);
            assert_eq!(backed_off(&hand, &part, &pinch, a, &opts), a);
            if clear(&a) {
                assert_eq!(b, a);
                kept += 1;
                continue;
            }
            if b == a {
                continue;
            }
            moved += 1;
            assert!(clear(&b));
            let back = b.translation.vector - a.translation.vector;
            let axis = a.rotation * Vec3::z();
            assert!((b.rotation.angle_to(&a.rotation)).abs() < 1e-12);
            let d = -back.dot(&axis);
            assert!((back + axis * d).norm() < 1e-9, "{back:?}");
            let k = (d / BACK_OFF_STEP_MM).round();
            assert!((d - k * BACK_OFF_STEP_MM).abs() < 1e-9 && d <= BACK_OFF_MAX_MM + 1e-9);
            let one_less = Translation3::from(axis * BACK_OFF_STEP_MM) * b;
            assert!(!clear(&one_less), "{d} mm back, clear a step sooner");
        }
        assert!(moved >= 5 && kept >= 1, "moved {moved}, kept {kept}");
    }

    /// The axis a power grasp wraps round, against shapes whose answer is known: along the
    /// bottle's axis on its side (and square to the view, so the MCP row lies along it from
    /// any side), none on the bottle's flat base or on a sphere (curved both ways).
    #[test]
    fn wrap_axis_is_a_cylinders_axis_and_nothing_elsewhere() {
        use crate::grasp::parts::Part;
        let bottle = PartShape::new(Part::Bottle.mesh().unwrap()).unwrap().0;
        for phi in [0.0f64, 1.0, 2.5, 4.0] {
            let dir = Vec3::new(phi.cos(), phi.sin(), 0.0);
            let at = Point::new(30.0 * dir.x, 30.0 * dir.y, 100.0);
            let axis = wrap_axis(&bottle, &at, WRAP_AXIS_RADIUS_MM).unwrap();
            assert!(axis.z.abs() > 0.999, "{axis:?}");
            let roll = roll_along(&dir, &axis).unwrap();
            let frame = placement(&bottle, &dir, roll, 3.0).unwrap();
            assert!((frame.rotation * Vec3::x()).z.abs() > 0.999);
        }
        assert_eq!(
            wrap_axis(&bottle, &Point::new(0.0, 0.0, 0.0), WRAP_AXIS_RADIUS_MM),
            None
        );
        let ball = PartShape::new(crate::geometry::mesh::tests::icosphere(40.0, 4))
            .unwrap()
            .0;
        assert_eq!(
            wrap_axis(&ball, &Point::new(0.0, 40.0, 0.0), WRAP_AXIS_RADIUS_MM),
            None
        );
    }

    /// The template's power grasp of the drill, searched as `scenes/drill.toml` does: the
    /// finalist ranked first wraps the grip (palm and three fingers with every phalanx), checked
    /// on the full evaluation of its approach, not on the ranking's own key; searched from the
    /// palm's centre by epsilon alone, as before, the template held the drill by its fingertips
    /// with the palm off.
    #[test]
    fn a_power_search_wraps_the_drill_grip() {
        use crate::anatomy::Side;
        use crate::grasp::autograsp::root_for;
        use crate::grasp::contact::{contacts, vertex_areas};
        use crate::grasp::hand::RigidHand;
        use crate::grasp::parts::Part;
        use crate::grasp::plan::grasp_plan;
        use crate::grasp::scene::GraspType;
        let hand = RigidHand::template(Side::Right).unwrap();
        let part = PartShape::new(Part::Drill.mesh().unwrap()).unwrap().0;
        let plan = grasp_plan(GraspType::Power);
        let r = placement_search(&hand, &part, &plan, 0.5, 1, 300, f64::INFINITY).unwrap();
        let opts = AutograspOptions::default();
        let root = root_for(&hand, &Isometry3::identity(), &r.approach);
        let g = autograsp(&hand, &part, &plan, root, &opts).unwrap();
        let (pose, _, squeezed) = squeeze(&hand, &part, &plan, &g, &opts);
        // The closing the search hands over is the one the scene would make from its approach.
        assert_eq!(r.closing.autograsp, g);
        assert_eq!(r.closing.pose, pose);
        assert_eq!(r.closing.squeeze, squeezed);
        for (a, c) in &r.runners_up {
            let root = root_for(&hand, &Isometry3::identity(), a);
            let g = autograsp(&hand, &part, &plan, root, &opts).unwrap();
            assert_eq!(c.pose, squeeze(&hand, &part, &plan, &g, &opts).0);
            assert_eq!(c.autograsp, g);
        }
        let mut pts = Vec::new();
        hand.pose_vertices(&pose, &mut pts);
        let areas = vertex_areas(hand.rest_mesh());
        let c = contacts(&part, &pts, hand.vertex_link(), &areas, &opts.contact);
        let e = c.envelope();
        assert!(e.wraps, "{e:?}");
        assert_eq!(r.pads_touching, envelope_rank(&e));
        // Reserves: a full set, none of them a finalist.
        assert_eq!(r.reserves.len(), RESERVES);
        let finalists: Vec<&Isometry3<f64>> = std::iter::once(&r.approach)
            .chain(r.runners_up.iter().map(|(a, _)| a))
            .collect();
        for a in &r.reserves {
            assert!(finalists.iter().all(|f| *f != a), "{a:?}");
        }
    }
}
