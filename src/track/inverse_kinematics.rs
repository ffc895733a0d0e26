//! Per-frame inverse kinematics: the palm's pose and every joint angle from the markers seen.
//!
//! Input: the [`Kinematics`] of a link model, its [`Attachment`] and a motion trial's
//! markers. Output per frame ([`FrameSolution`]): the [`HandState`] (or none where the frame
//! cannot be solved), each marker's residual, the markers rejected as outliers and the joints
//! held for want of markers.
//!
//! Method. Parameters: the palm's rigid motion (a rotation vector about the posed wrist
//! centre and a translation, applied as increments) and each joint's angles, with the DOF the
//! link model gives it ([`Kinematics`]); at most 34. Each frame minimises
//!
//! `Σ_markers ρ(|T_link(x)·m_ref − m_obs|) + λ_s |x − x_pred|² + λ_l Σ excess(x)² + λ_c Σ c(x)²`
//!
//! by Levenberg-Marquardt on dense normal equations (34 × 34, Cholesky) with analytic
//! Jacobians (every DOF a world axis through a world centre). `ρ` is Huber's (iteratively
//! reweighted), `x_pred` the previous frame extrapolated at constant velocity (the warm start
//! and the temporal term: with the default small `λ_s` it only holds directions the markers do
//! not determine and does not bias the rest), `excess` how far an angle is beyond its
//! anatomical range ([`crate::skeleton::joint_limits_deg`]) widened by a margin (soft limits),
//! and `c` the coupling terms of joints the markers do not determine (below).
//!
//! Robustness, per frame:
//! * gaps: a missing sample is left out; a joint none of whose distal markers is seen keeps its
//!   previous angles (held), as does a whole digit without markers (and the thumb with fewer
//!   than two); the wrist is held without two forearm markers. A finger is not held where the
//!   hand's coupling tells what the markers do not: its DIP without a marker distal to it
//!   follows its PIP (the DIP-PIP coupling of the flexing finger, `Δθ_DIP = k Δθ_PIP` from the
//!   last solved frame, k = 2/3 after Rijpkema & Girard 1991), and a finger with a single marker
//!   keeps the MCP's abduction and axial angles of the last solved frame, so that the marker
//!   fixes the MCP and PIP flexions. Both are soft terms (`λ_c`); held and coupled joints are
//!   reported.
//! * outliers and swapped labels: a marker farther than `jump_mm` (per frame since the last
//!   solved one) from where the prediction puts it is left out of the first solve; afterwards
//!   every seen marker within `gate_mm` of the fit is let in and the worst one beyond is
//!   dropped, until none changes.
//! * a frame with fewer than three palm markers (any marker riding on the palm) seen, or whose
//!   fit stays worse than `max_rms_mm`, is unsolved (`None`); the next solved frame restarts
//!   from the last solution. The first frame (and the first after an unsolved one) tries three
//!   starting flexions per digit and keeps each digit's best.
//!
//! Frames are sequential (warm starts), so the solve is kept small: fixed-size matrices, no
//! allocation in the iterations.

use super::attachment::Attachment;
use super::kinematics::{Evaluated, HandState, Kinematics, MAX_PARAMS};
use crate::anatomy::{Finger, Joint, Link};
use crate::geometry::{absolute_orientation, Point, Vec3};
use crate::mocap::trajectories::Trajectories;
use crate::skeleton::joint_limits_deg;
use nalgebra::{Cholesky, Isometry3, SMatrix, SVector, UnitQuaternion};

type Mat = SMatrix<f64, MAX_PARAMS, MAX_PARAMS>;
type Col = SVector<f64, MAX_PARAMS>;

/// Settings of the solver; the defaults suit skin markers at 100 Hz.
#[derive(Clone, Debug, PartialEq)]
pub struct IkOptions {
    /// Weight of the temporal term toward the constant-velocity prediction, mm² per rad²
    /// (angles, palm rotation) and per mm² (palm translation).
    pub smoothness: f64,
    /// Huber threshold of a marker's residual, mm.
    pub huber_mm: f64,
    /// A marker whose residual after the fit exceeds this is an outlier, mm.
    pub gate_mm: f64,
    /// A marker this far from its predicted position (per frame since the last solved) sits
    /// out the first solve, mm.
    pub jump_mm: f64,
    /// A frame whose inliers' RMS residual exceeds this is unsolved, mm.
    pub max_rms_mm: f64,
    /// Anatomical ranges are widened by this before the soft limit acts, degrees.
    pub limit_margin_deg: f64,
    /// Weight of the soft limits, mm² per rad² beyond the range.
    pub limit_weight: f64,
    /// Fewest palm markers that fix the palm.
    pub min_palm_markers: usize,
    /// Fewest markers on a digit for its angles to be solved (else held).
    pub min_digit_markers: usize,
    /// Levenberg-Marquardt iterations at most per solve.
    pub max_iterations: usize,
    /// Longest gap in the part's markers bridged by interpolating its pose, s.
    pub part_gap_s: f64,
    /// Weight of the coupling terms, mm² per rad².
    pub coupling_weight: f64,
    /// A finger's DIP flexion follows its PIP flexion by this ratio where no marker is distal
    /// to the DIP (`Δθ_DIP = k Δθ_PIP`).
    pub dip_pip_coupling: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            smoothness: 1e-3,
            huber_mm: 3.0,
            gate_mm: 10.0,
            jump_mm: 12.0,
            max_rms_mm: 8.0,
            limit_margin_deg: 15.0,
            limit_weight: 1e4,
            min_palm_markers: 3,
            min_digit_markers: 2,
            max_iterations: 40,
            part_gap_s: 0.5,
            coupling_weight: 1e3,
            dip_pip_coupling: 2.0 / 3.0,
        }
    }
}

/// The result of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSolution {
    /// The solved state, `None` where the frame could not be solved.
    pub state: Option<HandState>,
    /// Per attachment marker: distance between the fitted and the seen position, mm (`None`
    /// when not seen or the frame is unsolved); rejected markers keep theirs.
    pub residual_mm: Vec<Option<f64>>,
    /// Attachment indices of markers seen but rejected as outliers.
    pub rejected: Vec<usize>,
    /// Joints whose angles were held (too few markers distal to them).
    pub held: Vec<Joint>,
    /// Joints whose angles (a DIP) or whose MCP's abduction and axial angles (an MCP) followed
    /// the coupling terms instead of markers.
    pub coupled: Vec<Joint>,
    /// Levenberg-Marquardt iterations spent.
    pub iterations: usize,
}

/// Why a frame was not solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unsolved {
    /// Fewer palm markers than [`IkOptions::min_palm_markers`] seen.
    TooFewPalmMarkers,
    /// The fit stayed worse than [`IkOptions::max_rms_mm`].
    PoorFit,
}

/// The observations of a trial, one row per frame and one column per attachment marker.
pub fn observations(att: &Attachment, traj: &Trajectories) -> Vec<Vec<Option<Point>>> {
    let cols: Vec<Option<usize>> = att.markers.iter().map(|m| traj.index_of(&m.name)).collect();
    (0..traj.n_frames())
        .map(|f| {
            cols.iter()
                .map(|c| {
                    c.and_then(|i| traj.positions[i][f])
                        .filter(|p| p.coords.iter().all(|x| x.is_finite()))
                })
                .collect()
        })
        .collect()
}

/// The solver for one subject: its model, attachment and options, with the per-marker
/// tables it needs prepared once.
pub struct Solver<'a> {
    kin: &'a Kinematics,
    att: &'a Attachment,
    opts: IkOptions,
    /// Per marker: its link, and the digit it belongs to (`None`: palm or forearm).
    digit: Vec<Option<Finger>>,
    /// Soft limits per parameter (radians, widened), `None` for the palm's.
    limits: Vec<Option<(f64, f64)>>,
    /// Per parameter: the (joint index, DOF) it is the angle of (the palm's: unused).
    which: [(usize, usize); MAX_PARAMS],
}

/// Flexions a digit is started from where its angles tell nothing (a fresh start, or markers
/// that come back far from stale angles), degrees on each flexion DOF.
const START_FLEXIONS_DEG: [f64; 3] = [0.0, 40.0, 80.0];

/// What one frame's solve starts from and is held toward.
#[derive(Clone, Debug)]
struct Prior {
    /// The constant-velocity prediction.
    predicted: HandState,
    /// The last solved state (held joints keep its angles).
    last: HandState,
    /// Frames since it.
    frames_since: usize,
    /// The joints it held.
    held: Vec<Joint>,
    /// The joints it coupled (a digit solved from fewer markers than it has).
    coupled: Vec<Joint>,
    /// Per marker: rejected as an outlier and not accepted since (unseen frames keep it so).
    suspect: Vec<bool>,
}

impl<'a> Solver<'a> {
    /// A solver of `kin`'s model with the markers of `att`.
    pub fn new(kin: &'a Kinematics, att: &'a Attachment, opts: IkOptions) -> Solver<'a> {
        let digit = att
            .markers
            .iter()
            .map(|m| m.link.joint().and_then(Joint::finger))
            .collect();
        let mut limits = vec![None; kin.n_params];
        let mut which = [(0usize, 0usize); MAX_PARAMS];
        let margin = opts.limit_margin_deg;
        for j in Joint::ALL {
            for (d, [lo, hi]) in joint_limits_deg(j).into_iter().enumerate() {
                if let Some(k) = kin.param[j.index()][d] {
                    limits[k] = Some(((lo - margin).to_radians(), (hi + margin).to_radians()));
                    which[k] = (j.index(), d);
                }
            }
        }
        Solver {
            kin,
            att,
            opts,
            digit,
            limits,
            which,
        }
    }

    /// Track every frame of `obs` ([`observations`]) in order, each warm-started from the
    /// last solved one.
    pub fn track(&self, obs: &[Vec<Option<Point>>]) -> Vec<FrameSolution> {
        let mut out: Vec<FrameSolution> = Vec::with_capacity(obs.len());
        let mut prior: Option<Prior> = None;
        let mut prev_solved: Option<HandState> = None;
        for frame in obs {
            let sol = self.solve_frame(frame, prior.as_ref());
            match &sol.state {
                Some(s) => {
                    // Velocity only from two consecutive solved frames.
                    let mut predicted = match (&prev_solved, &prior) {
                        (Some(p), Some(pr)) if pr.frames_since == 1 => extrapolate(p, s),
                        _ => s.clone(),
                    };
                    // A joint held in either frame has no velocity to carry on: its angles
                    // jumped from stale ones to seen ones (or did not move at all).
                    let held_before = prior.as_ref().map_or(&[][..], |p| &p.held[..]);
                    for j in sol.held.iter().chain(held_before) {
                        predicted.angles[j.index()] = s.angles[j.index()];
                    }
                    let mut suspect = prior
                        .as_ref()
                        .map_or_else(|| vec![false; frame.len()], |p| p.suspect.clone());
                    for (i, sus) in suspect.iter_mut().enumerate() {
                        if sol.rejected.contains(&i) {
                            *sus = true;
                        } else if sol.residual_mm[i].is_some() {
                            *sus = false;
                        }
                    }
                    prior = Some(Prior {
                        predicted,
                        last: s.clone(),
                        frames_since: 1,
                        held: sol.held.clone(),
                        coupled: sol.coupled.clone(),
                        suspect,
                    });
                    prev_solved = Some(s.clone());
                }
                None => {
                    if let Some(p) = &mut prior {
                        p.predicted = p.last.clone();
                        p.frames_since += 1;
                    }
                    prev_solved = None;
                }
            }
            out.push(sol);
        }
        out
    }

    /// The solved frame `sol` of `obs` solved again from `start` with the plane terms `planes`
    /// (weight `plane_weight`) added: the same markers (its inliers off held links), its held
    /// joints fixed, its coupled joints tied to their changes from `sol`, and `sol`'s state
    /// the temporal term's target. Returns the state and the markers' residuals; `None` when
    /// `sol` is unsolved.
    pub fn refine(
        &self,
        sol: &FrameSolution,
        start: &HandState,
        obs: &[Option<Point>],
        planes: &[ContactPlane],
        plane_weight: f64,
    ) -> Option<(HandState, Vec<Option<f64>>)> {
        let state = sol.state.as_ref()?;
        let on_held = self.on_held(&sol.held);
        let fit: Vec<bool> = (0..obs.len())
            .map(|i| obs[i].is_some() && !sol.rejected.contains(&i) && !on_held[i])
            .collect();
        let con = Constraints {
            held: &sol.held,
            coupled: &sol.coupled,
            anchor: Some(state),
            planes,
            plane_weight,
        };
        let (s, _) = self.solve(start.clone(), obs, &fit, &con, Some(state));
        let res = self.residuals(&self.kin.evaluate(&s), obs);
        Some((s, res))
    }

    /// Solve one frame from `prior` (none: a fresh start).
    fn solve_frame(&self, obs: &[Option<Point>], prior: Option<&Prior>) -> FrameSolution {
        let n = obs.len();
        let seen: Vec<bool> = obs.iter().map(Option::is_some).collect();
        let unsolved = |_: Unsolved| FrameSolution {
            state: None,
            residual_mm: vec![None; n],
            rejected: Vec::new(),
            held: Vec::new(),
            coupled: Vec::new(),
            iterations: 0,
        };
        let palm_seen = (0..n)
            .filter(|&i| seen[i] && self.att.markers[i].link == Link::Palm)
            .count();
        if palm_seen < self.opts.min_palm_markers {
            return unsolved(Unsolved::TooFewPalmMarkers);
        }
        let mut iterations = 0;
        // Start and inliers.
        let (mut state, mut inlier, hold_from) = match prior {
            Some(p) => {
                let gate = self.opts.jump_mm * p.frames_since as f64;
                let e = self.kin.evaluate(&p.predicted);
                let mut inl: Vec<bool> = (0..n)
                    .map(|i| {
                        obs[i].is_some_and(|o| {
                            let m = &self.att.markers[i];
                            (e.links[m.link.index()] * m.reference - o).norm() <= gate
                        })
                    })
                    .collect();
                if self.palm_count(&inl) < self.opts.min_palm_markers {
                    inl = seen.clone();
                }
                (p.predicted.clone(), inl, p.last.clone())
            }
            None => {
                let Some(palm) = self.palm_by_horn(obs) else {
                    return unsolved(Unsolved::TooFewPalmMarkers);
                };
                let (s, it) = self.multi_start(HandState::at(palm), obs, &seen);
                iterations += it;
                (s.clone(), seen.clone(), s)
            }
        };
        let mut held = Vec::new();
        let mut coupled = Vec::new();
        let mut fit = inlier.clone();
        for _round in 0..8 {
            (held, coupled) = self.held_joints(&inlier);
            let mut start = state.clone();
            for &j in &held {
                start.angles[j.index()] = hold_from.angles[j.index()];
            }
            // A marker beyond a held joint sits where stale angles put it: in the fit it
            // would pull the palm and the joints that are solved.
            let on_held = self.on_held(&held);
            fit = (0..n).map(|i| inlier[i] && !on_held[i]).collect();
            let con = Constraints {
                held: &held,
                coupled: &coupled,
                anchor: Some(&hold_from),
                planes: &[],
                plane_weight: 0.0,
            };
            let (s, it) = self.solve(start, obs, &fit, &con, prior.map(|p| &p.predicted));
            iterations += it;
            state = s;
            // Let in every seen marker that fits; drop the worst that does not (markers on
            // held links are judged neither way).
            let e = self.kin.evaluate(&state);
            let res = self.residuals(&e, obs);
            let mut changed = false;
            for i in 0..n {
                if on_held[i] {
                    continue;
                }
                if let Some(r) = res[i] {
                    if !inlier[i] && r <= self.opts.gate_mm {
                        inlier[i] = true;
                        changed = true;
                    }
                }
            }
            if !changed {
                changed = self.readmit(&mut inlier, &mut state, obs, prior, &hold_from);
            }
            if !changed {
                let worst = (0..n)
                    .filter(|&i| inlier[i] && !on_held[i])
                    .filter_map(|i| res[i].map(|r| (i, r)))
                    .filter(|&(_, r)| r > self.opts.gate_mm)
                    .max_by(|a, b| a.1.total_cmp(&b.1));
                match worst {
                    Some((i, _)) => inlier[i] = false,
                    None => break,
                }
            }
        }
        let e = self.kin.evaluate(&state);
        let residual_mm = self.residuals(&e, obs);
        let (mut ss, mut cnt) = (0.0, 0usize);
        for i in 0..n {
            if fit[i] {
                if let Some(r) = residual_mm[i] {
                    ss += r * r;
                    cnt += 1;
                }
            }
        }
        let rms = if cnt > 0 {
            (ss / cnt as f64).sqrt()
        } else {
            f64::INFINITY
        };
        let finite = state.palm.translation.vector.iter().all(|x| x.is_finite())
            && state.angles.iter().flatten().all(|a| a.is_finite());
        if self.palm_count(&inlier) < self.opts.min_palm_markers
            || !finite
            || rms > self.opts.max_rms_mm
        {
            return unsolved(Unsolved::PoorFit);
        }
        let rejected = (0..n).filter(|&i| seen[i] && !inlier[i]).collect();
        FrameSolution {
            state: Some(state),
            residual_mm,
            rejected,
            held,
            coupled,
            iterations,
        }
    }

    /// Give a held digit (or the forearm) back the seen markers the jump gate kept out, if
    /// together they fit it: after an occlusion the held angles predict nothing, so a marker
    /// that comes back far from them may be right; a swapped label, though, cannot be fitted
    /// together with the digit's other markers. A group is let in when, solved with it, each
    /// of the digit's markers lies within `gate_mm` and their RMS within `huber_mm`. With two
    /// markers on a digit of five DOF even a swapped label fits, so a marker rejected and not
    /// accepted since (suspect) comes back only in a group of three or more markers on the
    /// digit, where a swapped one cannot. Only a group whose prediction is stale is
    /// considered: one the frame before `prior` did not solve, or solved only through the
    /// coupling terms (a finger with one marker: its angles followed the hand's coupling, not
    /// its markers, and may have drifted from the finger), or that is not the frame before. A
    /// group its markers solved in the frame before predicts well, and a marker that jumped
    /// past the gate from there is a swapped label or a stray sample. A coupled digit's
    /// markers come back only three together, as suspect ones do: its prediction held the
    /// finger near where its one marker is, so two returning markers could fit a swapped
    /// label. Returns whether any group was let in.
    fn readmit(
        &self,
        inlier: &mut [bool],
        state: &mut HandState,
        obs: &[Option<Point>],
        prior: Option<&Prior>,
        anchor: &HandState,
    ) -> bool {
        let (pred, suspect) = match prior {
            Some(p) => (Some(&p.predicted), &p.suspect[..]),
            None => (None, &[][..]),
        };
        let any_of = |joints: &[Joint], f: Finger| f.joints().iter().any(|j| joints.contains(j));
        // A digit the frame before solved through the coupling terms and held nothing of.
        let coupled_before = |g: Option<Finger>| match (prior, g) {
            (Some(p), Some(f)) if p.frames_since == 1 => {
                any_of(&p.coupled, f) && !any_of(&p.held, f)
            }
            _ => false,
        };
        let stale = |g: Option<Finger>| match prior {
            Some(p) if p.frames_since == 1 => match g {
                None => p.held.contains(&Joint::Wrist),
                Some(f) => any_of(&p.held, f) || coupled_before(g),
            },
            _ => true,
        };
        let n = inlier.len();
        let on_held = self.on_held(&self.held_joints(inlier).0);
        let mut any = false;
        // `None`: the forearm's markers (the palm's are never on a held link).
        let groups = [None].into_iter().chain(Finger::ALL.map(Some));
        for g in groups.filter(|&g| stale(g)) {
            let was_coupled = coupled_before(g);
            let member = |i: usize| {
                self.digit[i] == g
                    && (on_held[i] || (was_coupled && self.att.markers[i].link != Link::Palm))
            };
            let is_suspect = |i: usize| was_coupled || suspect.get(i).copied().unwrap_or(false);
            let mut candidates: Vec<usize> = (0..n)
                .filter(|&i| member(i) && !inlier[i] && obs[i].is_some())
                .collect();
            let on_digit = |t: &[bool]| {
                (0..n)
                    .filter(|&i| t[i] && self.digit[i] == g)
                    .filter(|&i| self.att.markers[i].link != Link::Palm)
                    .count()
            };
            let mut trial = inlier.to_vec();
            for &i in &candidates {
                trial[i] = true;
            }
            if candidates.iter().any(|&i| is_suspect(i)) && on_digit(&trial) < 3 {
                candidates.retain(|&i| !is_suspect(i));
                for i in 0..n {
                    trial[i] = inlier[i] || candidates.contains(&i);
                }
            }
            if candidates.is_empty() {
                continue;
            }
            let (held, coupled) = self.held_joints(&trial);
            let still_held = self.on_held(&held);
            let fit: Vec<bool> = (0..n).map(|i| trial[i] && !still_held[i]).collect();
            if candidates.iter().all(|&i| still_held[i]) {
                continue;
            }
            let con = Constraints {
                held: &held,
                coupled: &coupled,
                anchor: Some(anchor),
                planes: &[],
                plane_weight: 0.0,
            };
            // The group's fit from the state solved without it and, for a digit, from the
            // flexions of its joints a fresh start tries (its stale angles may lie far from the
            // returning markers, too far for one descent); the best is judged.
            let mut starts = vec![state.clone()];
            if let Some(f) = g {
                for flex in START_FLEXIONS_DEG {
                    let mut s = state.clone();
                    for j in f.joints().into_iter().filter(|j| !held.contains(j)) {
                        s.angles[j.index()][0] = flex.to_radians();
                    }
                    starts.push(s);
                }
            }
            let mut best: Option<(f64, Vec<f64>, HandState)> = None;
            for start in starts {
                let (s, _) = self.solve(start, obs, &fit, &con, pred);
                let res = self.residuals(&self.kin.evaluate(&s), obs);
                // Every marker of the digit, not only the candidates: a swapped label fits
                // only by pulling the digit off its other markers.
                let group_res: Vec<f64> = (0..n)
                    .filter(|&i| {
                        fit[i] && self.digit[i] == g && self.att.markers[i].link != Link::Palm
                    })
                    .filter_map(|i| res[i])
                    .collect();
                let rms = (group_res.iter().map(|r| r * r).sum::<f64>()
                    / group_res.len().max(1) as f64)
                    .sqrt();
                if best.as_ref().is_none_or(|b| rms < b.0) {
                    best = Some((rms, group_res, s));
                }
            }
            let (rms, group_res, s) = best.expect("at least one start");
            // A coupled digit's markers each within the Huber scale, not the gate: its one
            // marker held it near the hand's other digits, and a neighbour's swapped label
            // fits within the gate by bending the finger sideways.
            let each = if was_coupled {
                self.opts.huber_mm
            } else {
                self.opts.gate_mm
            };
            if group_res.iter().all(|&r| r <= each) && rms <= self.opts.huber_mm {
                inlier.copy_from_slice(&trial);
                // The next round starts where the group fits, not back at the stale angles.
                *state = s;
                any = true;
            }
        }
        any
    }

    fn palm_count(&self, use_: &[bool]) -> usize {
        (0..use_.len())
            .filter(|&i| use_[i] && self.att.markers[i].link == Link::Palm)
            .count()
    }

    /// The palm's pose from its markers alone (Horn's closed form), a fresh start.
    fn palm_by_horn(&self, obs: &[Option<Point>]) -> Option<Isometry3<f64>> {
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for (m, o) in self.att.markers.iter().zip(obs) {
            if let (Link::Palm, Some(o)) = (m.link, o) {
                src.push(m.reference);
                dst.push(*o);
            }
        }
        absolute_orientation(&src, &dst, None, false)
            .ok()
            .map(|r| r.isometry())
    }

    /// A fresh start: every digit from each of [`START_FLEXIONS_DEG`] on each flexion DOF, each
    /// digit keeping its best; then one solve from the combination.
    fn multi_start(
        &self,
        start: HandState,
        obs: &[Option<Point>],
        use_: &[bool],
    ) -> (HandState, usize) {
        let (held, coupled) = self.held_joints(use_);
        let on_held = self.on_held(&held);
        let fit: Vec<bool> = (0..use_.len()).map(|i| use_[i] && !on_held[i]).collect();
        let use_ = &fit[..];
        // A fresh start has no last frame: the coupling is taken from the static posture.
        let con = Constraints {
            held: &held,
            coupled: &coupled,
            anchor: None,
            planes: &[],
            plane_weight: 0.0,
        };
        let mut best: [(f64, [[f64; 3]; 3]); 5] = [(f64::INFINITY, [[0.0; 3]; 3]); 5];
        let mut palm = start.palm;
        let mut wrist = [0.0; 3];
        let mut iterations = 0;
        let mut best_total = f64::INFINITY;
        for flex in START_FLEXIONS_DEG {
            let mut s = start.clone();
            for j in &Joint::ALL[1..] {
                s.angles[j.index()][0] = flex.to_radians();
            }
            let (s, it) = self.solve(s, obs, use_, &con, None);
            iterations += it;
            let e = self.kin.evaluate(&s);
            let res = self.residuals(&e, obs);
            let mut per_digit = [0.0; 5];
            let mut total = 0.0;
            for (i, r) in res.iter().enumerate() {
                if let (true, Some(r)) = (use_[i], r) {
                    let c = self.huber(*r);
                    total += c;
                    if let Some(f) = self.digit[i] {
                        per_digit[f as usize] += c;
                    }
                }
            }
            if total < best_total {
                best_total = total;
                palm = s.palm;
                wrist = s.angles[0];
            }
            for f in Finger::ALL {
                if per_digit[f as usize] < best[f as usize].0 {
                    best[f as usize] = (
                        per_digit[f as usize],
                        f.joints().map(|j| s.angles[j.index()]),
                    );
                }
            }
        }
        let mut s = HandState::at(palm);
        s.angles[0] = wrist;
        for f in Finger::ALL {
            for (k, j) in f.joints().iter().enumerate() {
                s.angles[j.index()] = best[f as usize].1[k];
            }
        }
        let (s, it) = self.solve(s, obs, use_, &con, None);
        (s, iterations + it)
    }

    /// Joints to hold given the markers in use, and the fingers' joints that follow the
    /// coupling terms instead ([`Constraints`]). A digit without markers is held entirely, as
    /// is the thumb with fewer than [`IkOptions::min_digit_markers`]; otherwise each joint with
    /// no marker on its child link or beyond is held, except a finger's DIP whose PIP is
    /// solved (coupled); a finger with fewer than `min_digit_markers` markers has its MCP
    /// coupled (abduction and axial kept) and its DIP coupled wherever its marker is. The
    /// wrist is held without two forearm markers.
    fn held_joints(&self, use_: &[bool]) -> (Vec<Joint>, Vec<Joint>) {
        let mut per_link = [0usize; 17];
        for (i, m) in self.att.markers.iter().enumerate() {
            if use_[i] {
                per_link[m.link.index()] += 1;
            }
        }
        let mut held = Vec::new();
        let mut coupled = Vec::new();
        if per_link[Link::Arm.index()] < 2 {
            held.push(Joint::Wrist);
        }
        for f in Finger::ALL {
            let links = f.links();
            let on: Vec<usize> = links.iter().map(|l| per_link[l.index()]).collect();
            let total: usize = on.iter().sum();
            let joints = f.joints();
            let finger = f != Finger::Thumb;
            if total == 0 || (!finger && total < self.opts.min_digit_markers) {
                held.extend(joints);
                continue;
            }
            // One marker leaves three flexions for the two coordinates it gives in the
            // finger's plane: the DIP follows the PIP even when the marker is beyond it.
            let one = finger && total < self.opts.min_digit_markers;
            if one {
                coupled.push(joints[0]);
            }
            for (k, j) in joints.iter().enumerate() {
                let seen_beyond = on[k..].iter().sum::<usize>() > 0;
                if seen_beyond && !(one && k == 2) {
                    continue;
                }
                if finger && k == 2 && !held.contains(&joints[1]) {
                    coupled.push(*j);
                } else if !seen_beyond {
                    held.push(*j);
                }
            }
        }
        (held, coupled)
    }

    /// The coupling terms of `con` at `s`: each a residual (rad) and its coefficients on the
    /// parameters (the terms are linear in the angles). A coupled DIP: `(θ_DIP − a_DIP) −
    /// k (θ_PIP − a_PIP)`; a coupled MCP: its abduction and axial angles minus the anchor's
    /// (`a`: the anchor's angles, or zero, the static posture, without one).
    fn coupling_terms(&self, s: &HandState, con: &Constraints) -> Vec<(f64, [(usize, f64); 2])> {
        let a = |j: Joint, d: usize| con.anchor.map_or(0.0, |h| h.angles[j.index()][d]);
        let k = self.opts.dip_pip_coupling;
        let mut out = Vec::new();
        for &j in con.coupled {
            let Some(f) = j.finger() else { continue };
            let [mcp, pip, dip] = f.joints();
            if j == dip {
                let (Some(kd), Some(kp)) = (
                    self.kin.param[dip.index()][0],
                    self.kin.param[pip.index()][0],
                ) else {
                    continue;
                };
                let r = (s.angles[dip.index()][0] - a(dip, 0))
                    - k * (s.angles[pip.index()][0] - a(pip, 0));
                out.push((r, [(kd, 1.0), (kp, -k)]));
            } else if j == mcp {
                for d in 1..3 {
                    if let Some(km) = self.kin.param[mcp.index()][d] {
                        let r = s.angles[mcp.index()][d] - a(mcp, d);
                        out.push((r, [(km, 1.0), (km, 0.0)]));
                    }
                }
            }
        }
        out
    }

    /// Per marker: whether one of the `held` joints moves its link relative to the palm (the
    /// solve's root: the wrist moves the forearm, a digit's joints its phalanges).
    fn on_held(&self, held: &[Joint]) -> Vec<bool> {
        self.att
            .markers
            .iter()
            .map(|m| moved_by_held(m.link, held))
            .collect()
    }

    /// Residual distances of every seen marker under `e`.
    fn residuals(&self, e: &Evaluated, obs: &[Option<Point>]) -> Vec<Option<f64>> {
        self.att
            .markers
            .iter()
            .zip(obs)
            .map(|(m, o)| o.map(|o| (e.links[m.link.index()] * m.reference - o).norm()))
            .collect()
    }

    fn huber(&self, r: f64) -> f64 {
        let c = self.opts.huber_mm;
        if r <= c {
            r * r
        } else {
            2.0 * c * r - c * c
        }
    }

    /// The objective at `s`: robust marker terms, the temporal term toward `pred`, the soft
    /// limits, the coupling terms of `con`.
    fn cost(
        &self,
        s: &HandState,
        obs: &[Option<Point>],
        use_: &[bool],
        con: &Constraints,
        pred: Option<&HandState>,
    ) -> f64 {
        let e = self.kin.evaluate(s);
        let mut c = 0.0;
        for (i, (m, o)) in self.att.markers.iter().zip(obs).enumerate() {
            if let (true, Some(o)) = (use_[i], o) {
                c += self.huber((e.links[m.link.index()] * m.reference - o).norm());
            }
        }
        let d = self.deviation(s, pred);
        for (k, dk) in d.iter().enumerate().take(self.kin.n_params) {
            c += self.opts.smoothness * dk * dk;
            if let Some(x) = self.excess(s, k) {
                c += self.opts.limit_weight * x * x;
            }
        }
        for (r, _) in self.coupling_terms(s, con) {
            c += self.opts.coupling_weight * r * r;
        }
        for pl in con.planes {
            let r = pl.residual(&(e.links[pl.link] * pl.reference));
            c += con.plane_weight * r * r;
        }
        c
    }

    /// `x − x_pred` per parameter (zero without a prediction): the palm's as a rotation
    /// vector and the move of its wrist centre.
    fn deviation(&self, s: &HandState, pred: Option<&HandState>) -> Col {
        let mut d = Col::zeros();
        let Some(p) = pred else {
            return d;
        };
        let rot: UnitQuaternion<f64> = s.palm.rotation * p.palm.rotation.inverse();
        let w = rot.scaled_axis();
        let cw = self.kin.skeleton.centre(Joint::Wrist);
        let t = s.palm * cw - p.palm * cw;
        for k in 0..3 {
            d[k] = w[k];
            d[3 + k] = t[k];
        }
        for j in Joint::ALL {
            for dd in 0..3 {
                if let Some(k) = self.kin.param[j.index()][dd] {
                    d[k] = s.angles[j.index()][dd] - p.angles[j.index()][dd];
                }
            }
        }
        d
    }

    /// How far parameter `k` of `s` is beyond its widened range (signed), `None` inside.
    fn excess(&self, s: &HandState, k: usize) -> Option<f64> {
        let (lo, hi) = self.limits.get(k).copied().flatten()?;
        let a = self.angle(s, k);
        if a < lo {
            Some(a - lo)
        } else if a > hi {
            Some(a - hi)
        } else {
            None
        }
    }

    fn angle(&self, s: &HandState, k: usize) -> f64 {
        let (j, d) = self.which[k];
        s.angles[j][d]
    }

    /// Levenberg-Marquardt from `start` on the markers in `use_`, the held joints of `con`
    /// fixed and its coupled ones tied.
    fn solve(
        &self,
        start: HandState,
        obs: &[Option<Point>],
        use_: &[bool],
        con: &Constraints,
        pred: Option<&HandState>,
    ) -> (HandState, usize) {
        let np = self.kin.n_params;
        let mut free = [true; MAX_PARAMS];
        free[np..].fill(false);
        for j in con.held {
            for d in 0..3 {
                if let Some(k) = self.kin.param[j.index()][d] {
                    free[k] = false;
                }
            }
        }
        let mut s = start;
        let mut cost = self.cost(&s, obs, use_, con, pred);
        let mut mu = 1e-4;
        let mut it = 0;
        while it < self.opts.max_iterations {
            it += 1;
            let (h, g) = self.normal_equations(&s, obs, use_, con, pred, &free);
            let mut accepted = false;
            let mut step_norm = 0.0;
            for _ in 0..12 {
                let mut a = h;
                for k in 0..MAX_PARAMS {
                    a[(k, k)] += mu * h[(k, k)].max(1e-6);
                }
                let Some(ch) = Cholesky::new(a) else {
                    mu *= 10.0;
                    continue;
                };
                let delta = -ch.solve(&g);
                let trial = self.kin.step(&s, delta.as_slice());
                let c = self.cost(&trial, obs, use_, con, pred);
                if c.is_finite() && c <= cost {
                    step_norm = delta.amax();
                    accepted = c < cost || step_norm == 0.0;
                    s = trial;
                    cost = c;
                    mu = (mu / 3.0).max(1e-12);
                    break;
                }
                mu *= 4.0;
            }
            if !accepted || step_norm < 1e-12 {
                break;
            }
        }
        (s, it)
    }

    /// The derivatives of the point `p` riding `link` under `e` with respect to the palm's
    /// rotation (about the posed wrist centre) and translation and the free angles of the
    /// joints that move the link (each a world axis through a world centre), written into
    /// `cols` as (parameter, derivative); returns how many.
    fn point_columns(
        &self,
        e: &Evaluated,
        link: Link,
        p: &Point,
        free: &[bool; MAX_PARAMS],
        cols: &mut [(usize, Vec3); 12],
    ) -> usize {
        let v = p - e.centres[Joint::Wrist.index()];
        let mut n = 0;
        for k in 0..3 {
            let mut ek = Vec3::zeros();
            ek[k] = 1.0;
            cols[n] = (k, ek.cross(&v));
            cols[n + 1] = (3 + k, ek);
            n += 2;
        }
        for &j in self.kin.chain(link) {
            for d in 0..3 {
                if let Some(k) = self.kin.param[j.index()][d] {
                    if free[k] {
                        cols[n] = (k, e.axes[j.index()][d].cross(&(p - e.centres[j.index()])));
                        n += 1;
                    }
                }
            }
        }
        n
    }

    /// Gauss-Newton normal equations `H δ = −g` at `s` (robust weights at `s`).
    fn normal_equations(
        &self,
        s: &HandState,
        obs: &[Option<Point>],
        use_: &[bool],
        con: &Constraints,
        pred: Option<&HandState>,
        free: &[bool; MAX_PARAMS],
    ) -> (Mat, Col) {
        let e = self.kin.evaluate(s);
        let mut h = Mat::zeros();
        let mut g = Col::zeros();
        let c = self.opts.huber_mm;
        let mut cols: [(usize, Vec3); 12] = [(0, Vec3::zeros()); 12];
        for (i, (m, o)) in self.att.markers.iter().zip(obs).enumerate() {
            let (true, Some(o)) = (use_[i], o) else {
                continue;
            };
            let p = e.links[m.link.index()] * m.reference;
            let r = p - o;
            let rn = r.norm();
            let w = if rn <= c { 1.0 } else { c / rn };
            let n = self.point_columns(&e, m.link, &p, free, &mut cols);
            add_point_term(&mut h, &mut g, &cols[..n], w, &r);
        }
        let wp = con.plane_weight;
        for pl in con.planes {
            let p = e.links[pl.link] * pl.reference;
            let r = pl.residual(&p);
            if r == 0.0 {
                continue;
            }
            let n = self.point_columns(&e, Link::ALL[pl.link], &p, free, &mut cols);
            // The plane's term is the point's along the normal alone.
            for c in &mut cols[..n] {
                c.1 = pl.normal * pl.normal.dot(&c.1);
            }
            add_point_term(&mut h, &mut g, &cols[..n], wp, &(pl.normal * r));
        }
        let d = self.deviation(s, pred);
        let lam = self.opts.smoothness;
        for k in 0..self.kin.n_params {
            h[(k, k)] += lam;
            g[k] += lam * d[k];
            if let Some(x) = self.excess(s, k) {
                h[(k, k)] += self.opts.limit_weight;
                g[k] += self.opts.limit_weight * x;
            }
        }
        let wc = self.opts.coupling_weight;
        for (r, row) in self.coupling_terms(s, con) {
            for &(ka, ca) in &row {
                g[ka] += wc * ca * r;
                for &(kb, cb) in &row {
                    h[(ka, kb)] += wc * ca * cb;
                }
            }
        }
        for k in 0..MAX_PARAMS {
            if !free[k] {
                for l in 0..MAX_PARAMS {
                    h[(k, l)] = 0.0;
                    h[(l, k)] = 0.0;
                }
                h[(k, k)] = 1.0;
                g[k] = 0.0;
            }
        }
        (h, g)
    }
}

/// Add a point's term `w |r|²` to the normal equations `h`, `g`, its derivatives `cols` (as
/// [`Solver::point_columns`] gives them: parameter, derivative of the point).
fn add_point_term(h: &mut Mat, g: &mut Col, cols: &[(usize, Vec3)], w: f64, r: &Vec3) {
    for (a, &(ia, ca)) in cols.iter().enumerate() {
        g[ia] += w * ca.dot(r);
        for &(ib, cb) in &cols[a..] {
            let v = w * ca.dot(&cb);
            h[(ia, ib)] += v;
            if ia != ib {
                h[(ib, ia)] += v;
            }
        }
    }
}

/// Whether one of the `held` joints moves `link` relative to the palm (the solve's root: the
/// wrist moves the forearm, a digit's joints its phalanges), so that the link's pose rests on
/// stale angles.
pub(super) fn moved_by_held(link: Link, held: &[Joint]) -> bool {
    match link {
        Link::Palm => false,
        Link::Arm => held.contains(&Joint::Wrist),
        l => {
            let mut j = l.joint();
            while let Some(jj) = j.filter(|&jj| jj != Joint::Wrist) {
                if held.contains(&jj) {
                    return true;
                }
                j = jj.parent();
            }
            false
        }
    }
}

/// What a solve keeps fixed and what it ties: the held joints, the coupled ones
/// ([`Solver::held_joints`]) and the state their coupling is measured from (the last solved
/// frame; `None`: the static posture).
struct Constraints<'c> {
    held: &'c [Joint],
    coupled: &'c [Joint],
    anchor: Option<&'c HandState>,
    /// One-sided terms that keep skin points out of the part ([`Solver::refine`]).
    planes: &'c [ContactPlane],
    /// Weight of a plane term, mm² per mm² (a marker's is 1).
    plane_weight: f64,
}

/// A skin point held out of the part, linearised at a closest point: the point `reference`
/// (rest posture) rides `link`; the term is `min(0, n·(p − q) + allowance)²` with `p` the point
/// posed, `q` its closest point on the part and `n` the part's outward normal there (lab frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPlane {
    /// The [`Link::index`] the point rides.
    pub link: usize,
    /// The point in the rest posture, mm.
    pub reference: Point,
    /// The closest point on the part, lab frame, mm.
    pub on_part: Point,
    /// The part's outward unit normal there.
    pub normal: Vec3,
    /// How far the point may lie inside before the term acts, mm.
    pub allowance_mm: f64,
}

impl ContactPlane {
    /// The term's residual at the posed point `p`: negative where it lies deeper than the
    /// allowance, else zero.
    fn residual(&self, p: &Point) -> f64 {
        (self.normal.dot(&(p - self.on_part)) + self.allowance_mm).min(0.0)
    }
}

/// The state one frame after `b` at the rate from `a` to `b`.
fn extrapolate(a: &HandState, b: &HandState) -> HandState {
    let mut out = b.clone();
    // The palm: the same relative motion again.
    let rel = b.palm * a.palm.inverse();
    out.palm = rel * b.palm;
    // Products of quaternions drift off unit length, and a conjugate taken as the inverse
    // makes the drift grow by 1 + √2 per frame: a non-unit quaternion scales the hand.
    out.palm.rotation.renormalize();
    for j in 0..16 {
        for d in 0..3 {
            out.angles[j][d] = 2.0 * b.angles[j][d] - a.angles[j][d];
        }
    }
    out
}
