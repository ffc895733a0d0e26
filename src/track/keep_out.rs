//! Keeping the tracked hand out of the part: each frame's inverse kinematics solved again
//! with one-sided terms on the skin points that lie inside the part.
//!
//! Input: a [`Tracked`] trial with the part's pose per frame, its observations, the subject's
//! [`SkinnedHand`] and the part ([`PartShape`], its own frame). Output: the frames whose skin
//! reached deeper than an allowance into the part, solved again so that it does not where the
//! markers allow, with their states and marker residuals replaced.
//!
//! Method (the contact terms of marker-based hand capture with objects, as in the GRAB data
//! set's MoSh++ fits, Taheri et al. 2020, and the penetration terms of hand-object pose
//! estimation, Hasson et al. 2019): skin points, one per `spacing_mm` cell of the rest skin
//! per link, are posed by linear blend skinning; every point deeper than the allowance minus
//! a millimetre becomes a term `w · min(0, n·(p − q) + allowance)²`, with `q` its closest
//! point on the part and `n` the outward normal there, riding its dominant link with the
//! blend's offset frozen; the frame is solved again by [`Solver::refine`] (the markers, limits
//! and coupling as before), and the points re-linearised, for a few rounds (an ICP-like
//! iteration). The allowance stands for the soft tissue a holding hand presses in; the weight
//! is a marker's, so a penetration costs as much as a marker moved as far, per point.

use super::inverse_kinematics::{ContactPlane, Solver};
use super::kinematics::Kinematics;
use super::Tracked;
use crate::anatomy::Link;
use crate::error::Result;
use crate::geometry::Point;
use crate::grasp::contact::{PartShape, Probe, GRID_BAND_MM};
use crate::grasp::hand::{PosableHand, SkinnedHand};
use crate::pose::skinning::SkinBinding;
use nalgebra::Isometry3;
use rayon::prelude::*;
use std::collections::HashSet;

/// Settings of [`keep_out_of_part`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeepOutOptions {
    /// How far the skin may lie inside the part before a term acts, mm: the soft tissue a
    /// holding hand presses in (the grasp stage squeezes its contacts 1.5 mm).
    pub allowance_mm: f64,
    /// Weight of a skin point's term, relative to a marker's.
    pub weight: f64,
    /// One skin point per cell of this size of the rest skin, per link, mm.
    pub spacing_mm: f64,
    /// Solves per frame at most (the points re-linearised before each).
    pub rounds: usize,
}

impl Default for KeepOutOptions {
    fn default() -> Self {
        KeepOutOptions {
            allowance_mm: 1.0,
            weight: 1.0,
            spacing_mm: 3.0,
            rounds: 4,
        }
    }
}

/// What [`keep_out_of_part`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KeepOutSummary {
    /// Frames whose skin points lay deeper than the allowance, solved again (ascending).
    pub frames: Vec<usize>,
    /// The deepest skin point over those frames, before and after, mm.
    pub deepest_before_mm: f64,
    /// As above, after.
    pub deepest_after_mm: f64,
    /// Frames where a skin point still lies more than a millimetre deeper than the allowance:
    /// the markers hold the hand there.
    pub still_inside: Vec<usize>,
}

/// One frame solved again: its deepest skin point before and after, mm, its state and its
/// markers' residuals.
struct Refined {
    frame: usize,
    before: f64,
    after: f64,
    state: super::HandState,
    residual_mm: Vec<Option<f64>>,
}

/// The skin points: one rest vertex per `spacing` cell per link (the forearm's left out).
fn skin_points(hand: &SkinnedHand, spacing: f64) -> Vec<usize> {
    let rest = hand.rest_mesh();
    let links = hand.vertex_link();
    let mut seen = HashSet::new();
    let cell = |x: f64| (x / spacing).floor() as i64;
    (0..rest.n_vertices())
        .filter(|&i| links[i] != Link::Arm.index())
        .filter(|&i| {
            let v = rest.vertices[i];
            seen.insert((links[i], cell(v.x), cell(v.y), cell(v.z)))
        })
        .collect()
}

/// The signed distance of `q` (part frame) from the part, its closest point and the outward
/// normal there; `None` when farther than the grid's band outside (or unknown).
fn signed(part: &PartShape, q: &Point) -> Option<(f64, Point, nalgebra::Vector3<f64>)> {
    match part.probe(q, GRID_BAND_MM) {
        Probe::Hit(d, c, n) => Some((d, c, n)),
        Probe::Far => None,
        Probe::Deep => match part.probe(q, f64::INFINITY) {
            Probe::Hit(d, c, n) => Some((d, c, n)),
            _ => None,
        },
    }
}

/// Solve again every frame of `tracked` (observations `obs`, by `solver` of `kin`) whose
/// skin (`hand`) lies deeper than the allowance into `part` (its own frame, posed by
/// `tracked.part`), so that it does not where the markers allow; the frames' states and
/// marker residuals are replaced. Frames run in parallel. Errors only if the hand's weights
/// cannot be bound to its skin points.
pub fn keep_out_of_part(
    kin: &Kinematics,
    solver: &Solver,
    obs: &[Vec<Option<Point>>],
    tracked: &mut Tracked,
    hand: &SkinnedHand,
    part: &PartShape,
    opts: &KeepOutOptions,
) -> Result<KeepOutSummary> {
    let Some((poses, _)) = tracked.part.as_ref() else {
        return Ok(KeepOutSummary::default());
    };
    let points = skin_points(hand, opts.spacing_mm);
    let rest: Vec<Point> = points
        .iter()
        .map(|&i| hand.rest_mesh().vertices[i])
        .collect();
    let weights: Vec<_> = points
        .iter()
        .map(|&i| hand.hand.weights[i].clone())
        .collect();
    let binding = SkinBinding::new(&rest, &weights, Link::ALL.len())?;
    let link_of = hand.vertex_link();
    let allow = opts.allowance_mm;
    // The deepest point of the frame at `state`, and its terms.
    let probe = |state: &super::HandState, pose: &Isometry3<f64>| {
        let e = kin.evaluate(state);
        let to_part = pose.inverse();
        let mut deepest = 0.0f64;
        let mut planes = Vec::new();
        let mut posed = Vec::new();
        binding.linear_into(&e.links, &mut posed);
        for (&i, &p) in points.iter().zip(&posed) {
            let Some((d, c, n)) = signed(part, &(to_part * p)) else {
                continue;
            };
            deepest = deepest.max(-d);
            if d < 1.0 - allow {
                let l = link_of[i];
                planes.push(ContactPlane {
                    link: l,
                    reference: e.links[l].inverse() * p,
                    on_part: pose * c,
                    normal: pose.rotation * n,
                    allowance_mm: allow,
                });
            }
        }
        (deepest, planes)
    };
    let done: Vec<Option<Refined>> = (0..tracked.frames.len())
        .into_par_iter()
        .map(|f| {
            let sol = &tracked.frames[f];
            let (state, pose) = (sol.state.as_ref()?, poses[f].as_ref()?);
            let (before, mut planes) = probe(state, pose);
            if before <= allow + 0.05 {
                return None;
            }
            let (mut s, mut res) = (state.clone(), sol.residual_mm.clone());
            let mut after = before;
            for _ in 0..opts.rounds {
                let Some((next, r)) = solver.refine(sol, &s, &obs[f], &planes, opts.weight) else {
                    break;
                };
                (s, res) = (next, r);
                (after, planes) = probe(&s, pose);
                if after <= allow + 0.05 {
                    break;
                }
            }
            Some(Refined {
                frame: f,
                before,
                after,
                state: s,
                residual_mm: res,
            })
        })
        .collect();
    let mut summary = KeepOutSummary::default();
    for r in done.into_iter().flatten() {
        summary.frames.push(r.frame);
        summary.deepest_before_mm = summary.deepest_before_mm.max(r.before);
        summary.deepest_after_mm = summary.deepest_after_mm.max(r.after);
        if r.after > allow + 1.0 {
            summary.still_inside.push(r.frame);
        }
        tracked.frames[r.frame].state = Some(r.state);
        tracked.frames[r.frame].residual_mm = r.residual_mm;
    }
    Ok(summary)
}
