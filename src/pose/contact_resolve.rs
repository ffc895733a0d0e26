//! Keeping the digits of a posed hand out of each other (the goal: "in `fist` no finger passes
//! through another by more than 2 mm").
//!
//! A pose is a set of joint angles; the same angles close a broad hand's fingers into each
//! other where a slender hand's only touch. Measured on simulated subjects, the *true* hand
//! (true skin and skeleton) in the built-in `fist` enters a neighbour by up to 10 mm on two
//! of four subjects, so this is the pose meeting the individual, not a reconstruction error.
//! A real hand's fingers press against each other and give way; here the angles give way.
//!
//! The method is a damped least-norm inverse kinematics on contact constraints, as in
//! constraint-based posing (Buss 2004, "Introduction to inverse kinematics with Jacobian
//! transpose, pseudoinverse and damped least squares methods", section 5): for each pair of
//! digits whose deepest penetrating vertex `p` lies behind the other digit's surface point `q`
//! (outward normal `n`), the separation `s = (p − q)·n` must reach `−tolerance / 2`; `p` and
//! `q` are carried rigidly by their links, `∂s/∂θ_k` is taken by finite differences of the
//! forward kinematics over the two digits' joint angles, and the pairs' rows are solved
//! together for the weighted damped least-norm step `Δθ = W Jᵀ (J W Jᵀ + λ I)⁻¹ r` (each angle
//! by at most 3° per step), then the pose is clamped to the anatomical limits. The
//! weights keep the pose's intent: a finger makes room by spreading at its MCP (weight 1)
//! rather than by unbending (0.2); the thumb moves at all its joints.
//!
//! The penetrations are those of [`super::quality::posed_finger_penetration`]: a face that
//! skinning turned over (a crease folded through itself) faces into its finger, so a vertex of
//! the next digit facing it would read as inside by its whole distance, a reading no change of
//! the angles removes; such faces are skipped, as the digits' open rims are.

use super::hand::IndividualHand;
use super::quality::{posed_finger_penetration, Penetration};
use super::skinning::Skinning;
use crate::anatomy::{Finger, Joint};
use crate::geometry::{Point, TriMesh};
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::{clamp_pose, Pose};
use crate::template::dominant_links;

/// Options of [`resolve_finger_contacts`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResolveOptions {
    /// Largest penetration left alone, mm (the goal is 2 mm).
    pub tolerance_mm: f64,
    /// Most posing and measuring rounds.
    pub max_iterations: usize,
    /// Depths beyond this are the far side of a finger, not a penetration
    /// ([`finger_penetration`]'s `max_depth_mm`), mm.
    pub max_depth_mm: f64,
}

impl Default for ResolveOptions {
    fn default() -> Self {
        ResolveOptions {
            tolerance_mm: 1.0,
            max_iterations: 30,
            max_depth_mm: 12.0,
        }
    }
}

/// What [`resolve_finger_contacts`] did.
#[derive(Clone, Debug)]
pub struct Resolved {
    /// The pose with the digits apart (within the limits).
    pub pose: Pose,
    /// Deepest penetration of the pose as given, mm.
    pub depth_before_mm: f64,
    /// Deepest penetration of [`Resolved::pose`], mm.
    pub depth_after_mm: f64,
    /// Rounds run.
    pub iterations: usize,
    /// Per changed joint, the change `[flexion, abduction, axial]`, degrees.
    pub changes_deg: Vec<(Joint, [f64; 3])>,
}

impl Resolved {
    /// One line per changed joint (changes under 0.1° left out), for the warnings.
    pub fn describe(&self) -> Vec<String> {
        self.changes_deg
            .iter()
            .filter(|(_, d)| d.iter().any(|x| x.abs() >= 0.1))
            .map(|(j, d)| {
                let parts: Vec<String> = ["flexion", "abduction", "axial rotation"]
                    .iter()
                    .zip(d)
                    .filter(|(_, x)| x.abs() >= 0.1)
                    .map(|(n, x)| format!("{n} {x:+.1}°"))
                    .collect();
                format!(
                    "{j} {} to keep the digits apart (penetration {:.1} -> {:.1} mm)",
                    parts.join(", "),
                    self.depth_before_mm,
                    self.depth_after_mm
                )
            })
            .collect()
    }
}

/// Largest change of one angle in one round, radians: small steps keep the linearisation
/// honest where contacts appear and vanish between rounds.
const MAX_STEP: f64 = 3.0 * std::f64::consts::PI / 180.0;
/// Finite-difference step of the Jacobian, radians.
const DELTA: f64 = 1e-4;

/// Weight of a joint angle in the least-norm step (see the module documentation).
fn dof_weight(j: Joint, dof: usize) -> f64 {
    match (j.finger(), j.dof(), dof) {
        (Some(Finger::Thumb), _, 2) => 0.3,
        (Some(Finger::Thumb), _, _) => 1.0,
        (_, 3, 1) => 1.0,
        (_, 3, 2) => 0.05,
        _ => 0.2,
    }
}

/// Angles of a pose, three per joint (`3 * joint index + axis`).
const DOFS: usize = 48;

/// Damping of [`damped_least_norm_step`], relative to the mean diagonal of `J W Jᵀ`: two pairs
/// that are one contact seen from either digit give two nearly equal rows, which an undamped
/// solve would meet with a step as large as it is arbitrary.
const DAMPING: f64 = 0.1;

/// The weighted damped least-norm step `Δθ = W Jᵀ (J W Jᵀ + λ I)⁻¹ r` for the rows
/// `(∂s/∂θ, r)` of all the pairs at once (Buss 2004, section 5), `W` the [`dof_weight`]s.
/// Solved together, pairs that share joints (a finger between two neighbours, or one contact
/// seen from both digits) do not each take the whole correction, as summed single-pair steps
/// did, which made them overshoot and oscillate.
fn damped_least_norm_step(rows: &[([f64; DOFS], f64)]) -> [f64; DOFS] {
    let mut step = [0.0; DOFS];
    let m = rows.len();
    if m == 0 {
        return step;
    }
    let w: [f64; DOFS] = std::array::from_fn(|i| dof_weight(Joint::ALL[i / 3], i % 3));
    let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
    for (i, (gi, _)) in rows.iter().enumerate() {
        for (j, (gj, _)) in rows.iter().enumerate() {
            a[(i, j)] = (0..DOFS).map(|k| gi[k] * w[k] * gj[k]).sum();
        }
    }
    let mean = a.diagonal().mean();
    if mean.is_nan() || mean <= 1e-12 {
        return step;
    }
    for i in 0..m {
        a[(i, i)] += DAMPING * mean;
    }
    let r = nalgebra::DVector::from_iterator(m, rows.iter().map(|(_, r)| *r));
    let Some(y) = a.cholesky().map(|c| c.solve(&r)) else {
        return step;
    };
    for (i, (g, _)) in rows.iter().enumerate() {
        for k in 0..DOFS {
            step[k] += w[k] * g[k] * y[i];
        }
    }
    step
}

/// Change `pose` as little as the weights allow so that no digit of `hand` enters another by
/// more than `opts.tolerance_mm` when posed with `method` (see the module documentation).
/// Stops after `opts.max_iterations` rounds even if a contact remains (the result says how
/// deep). A pose already within the tolerance is returned unchanged.
pub fn resolve_finger_contacts(
    hand: &IndividualHand,
    pose: &Pose,
    method: Skinning,
    opts: &ResolveOptions,
) -> Resolved {
    let binding = hand.binding();
    let skin = |p: &Pose| -> std::result::Result<Vec<Point>, std::convert::Infallible> {
        Ok(binding.apply(method, &link_transforms(&hand.skeleton, p)))
    };
    match resolve_finger_contacts_on(hand, pose, skin, opts) {
        Ok(r) => r,
        Err(never) => match never {},
    }
}

/// [`resolve_finger_contacts`] on the skin `skin` makes of a pose (for example the skin with
/// the segment-volume correction, [`super::VolumeRig::corrected_skin`], whose swelling would
/// otherwise push digits that were just apart back into each other). The skin moves with the
/// pose only through `skin`; the step's linearisation still carries the contact points
/// rigidly on their links.
pub fn resolve_finger_contacts_on<E>(
    hand: &IndividualHand,
    pose: &Pose,
    skin: impl Fn(&Pose) -> std::result::Result<Vec<Point>, E>,
    opts: &ResolveOptions,
) -> std::result::Result<Resolved, E> {
    let dom = dominant_links(&hand.weights);
    let measure = |p: &Pose| -> std::result::Result<(Penetration, Vec<Point>), E> {
        let posed = TriMesh {
            vertices: skin(p)?,
            faces: hand.skin.faces.clone(),
        };
        Ok((
            posed_finger_penetration(hand, p, &posed, opts.max_depth_mm),
            posed.vertices,
        ))
    };
    let mut cur = pose.clone();
    let (mut pen, mut posed) = measure(&cur)?;
    let depth_before_mm = pen.depth_mm;
    // The steps linearise each contact alone, so an iteration can push one pair deeper while
    // it frees another: the least penetrating pose met is the one returned.
    let mut best = (pen.depth_mm, cur.clone());
    let mut iterations = 0;
    while pen.depth_mm > opts.tolerance_mm && iterations < opts.max_iterations {
        iterations += 1;
        let t = link_transforms(&hand.skeleton, &cur);
        // One row per pair still too deep: the separation's gradient over the two digits'
        // angles and the separation it lacks.
        let mut rows: Vec<([f64; DOFS], f64)> = Vec::new();
        for (k, &((a, b), depth)) in pen.by_pair.iter().enumerate() {
            if depth <= 0.5 * opts.tolerance_mm {
                continue;
            }
            let c = &pen.deepest[k];
            let n = c.normal.normalize();
            let (la, lb) = (dom[c.vertex], c.surface_link);
            // Both points ride rigidly on their links for the linearisation.
            let p_rest = t[la].inverse() * posed[c.vertex];
            let q_rest = t[lb].inverse() * c.surface_point;
            let sep = |tr: &[nalgebra::Isometry3<f64>]| (tr[la] * p_rest - tr[lb] * q_rest).dot(&n);
            let s0 = sep(&t);
            let mut g = [0.0; DOFS];
            for digit in [a, b] {
                for j in digit.joints() {
                    for d in 0..j.dof() {
                        let mut probe = cur.clone();
                        probe.angles[j.index()][d] += DELTA;
                        g[3 * j.index() + d] =
                            (sep(&link_transforms(&hand.skeleton, &probe)) - s0) / DELTA;
                    }
                }
            }
            rows.push((g, -0.5 * opts.tolerance_mm - s0));
        }
        let step = damped_least_norm_step(&rows);
        for (k, angles) in cur.angles.iter_mut().enumerate() {
            for (d, x) in angles.iter_mut().enumerate() {
                *x += step[3 * k + d].clamp(-MAX_STEP, MAX_STEP);
            }
        }
        cur = clamp_pose(&cur).0;
        (pen, posed) = measure(&cur)?;
        log::debug!(
            "contact round {iterations}: deepest {:.2} mm; {}",
            pen.depth_mm,
            pen.by_pair
                .iter()
                .map(|((a, b), d)| format!("{a:?} in {b:?} {d:.1}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        if pen.depth_mm < best.0 {
            best = (pen.depth_mm, cur.clone());
        }
    }
    let (depth_after_mm, cur) = best;
    let changes_deg = Joint::ALL
        .iter()
        .filter_map(|&j| {
            let d = [0, 1, 2]
                .map(|k| (cur.angles[j.index()][k] - pose.angles[j.index()][k]).to_degrees());
            d.iter().any(|x| *x != 0.0).then_some((j, d))
        })
        .collect();
    Ok(Resolved {
        pose: cur,
        depth_before_mm,
        depth_after_mm,
        iterations,
        changes_deg,
    })
}
