//! Equation 1 of the seed paper (section 3.4): for every frame of a calibration trial, the
//! rigid transform that carries the parent link's markers onto their positions at the trial's
//! reference frame (Horn 1987), which expresses everything attached to the child link in the
//! parent's reference pose.

use crate::geometry::{absolute_orientation, Point, Registration};
use crate::mocap::trajectories::Trajectories;

/// A frame is dropped as an outlier when its registration residual exceeds this multiple of the
/// trial's median residual (and [`OUTLIER_FLOOR_MM`]): a marker swap or a bad reconstruction.
pub(crate) const OUTLIER_FACTOR: f64 = 5.0;
/// Residuals below this are never outliers, whatever the median (clean data has a median of 0).
pub const OUTLIER_FLOOR_MM: f64 = 0.5;

/// Per-frame registrations of a parent segment onto its reference frame.
#[derive(Clone, Debug)]
pub struct ParentRegistration {
    /// For each frame, the transform frame -> reference frame, or `None` when the frame was
    /// skipped (fewer than three valid parent markers) or dropped as an outlier.
    pub frames: Vec<Option<Registration>>,
    /// Frames skipped for too few visible parent markers.
    pub skipped: usize,
    /// Frames dropped as outliers.
    pub outliers: usize,
    /// Median registration residual over the kept frames, mm.
    pub median_rms_mm: f64,
}

/// Register `parent` markers of every frame onto their positions at `reference_frame`
/// (equation 1). Markers missing in a frame are left out of that frame's fit; a frame with
/// fewer than three is skipped. The reference positions must all be present (checked by the
/// caller with [`Trajectories::require_at`]).
pub fn register_parent(
    traj: &Trajectories,
    parent: &[&str],
    reference_frame: usize,
) -> ParentRegistration {
    let reference: Vec<Option<Point>> = parent
        .iter()
        .map(|n| traj.get(n, reference_frame))
        .collect();
    let tracks: Vec<&[Option<Point>]> = parent
        .iter()
        .map(|n| traj.track(n).unwrap_or(&[]))
        .collect();
    let mut frames = Vec::with_capacity(traj.n_frames());
    let mut skipped = 0;
    let mut src = Vec::with_capacity(parent.len());
    let mut dst = Vec::with_capacity(parent.len());
    for f in 0..traj.n_frames() {
        src.clear();
        dst.clear();
        for (t, r) in tracks.iter().zip(&reference) {
            if let (Some(Some(p)), Some(q)) = (t.get(f), r) {
                src.push(*p);
                dst.push(*q);
            }
        }
        let reg = if src.len() >= 3 {
            absolute_orientation(&src, &dst, None, false).ok()
        } else {
            None
        };
        if reg.is_none() {
            skipped += 1;
        }
        frames.push(reg);
    }
    let mut rms: Vec<f64> = frames.iter().flatten().map(|r| r.rms).collect();
    rms.sort_by(f64::total_cmp);
    let median = if rms.is_empty() {
        0.0
    } else {
        rms[rms.len() / 2]
    };
    let limit = (OUTLIER_FACTOR * median).max(OUTLIER_FLOOR_MM);
    let mut outliers = 0;
    for r in frames.iter_mut() {
        if r.is_some_and(|reg| reg.rms > limit) {
            *r = None;
            outliers += 1;
        }
    }
    ParentRegistration {
        frames,
        skipped,
        outliers,
        median_rms_mm: median,
    }
}

impl ParentRegistration {
    /// Number of frames kept.
    pub fn used(&self) -> usize {
        self.frames.iter().filter(|r| r.is_some()).count()
    }

    /// The trajectory of marker `name` in the parent's reference pose: one point per frame in
    /// which both the registration and the marker exist (gaps never reach a solver as NaN).
    pub fn express(&self, traj: &Trajectories, name: &str) -> Vec<Point> {
        let Some(track) = traj.track(name) else {
            return Vec::new();
        };
        self.frames
            .iter()
            .zip(track)
            .filter_map(|(r, p)| Some(r.as_ref()?.apply(p.as_ref()?)))
            .collect()
    }

    /// Per frame, the child markers in the parent's reference pose (`None` where either the
    /// registration or the marker is missing); aligned with the trial's frames.
    pub fn express_frames(&self, traj: &Trajectories, names: &[&str]) -> Vec<Vec<Option<Point>>> {
        let tracks: Vec<Option<&[Option<Point>]>> = names.iter().map(|n| traj.track(n)).collect();
        self.frames
            .iter()
            .enumerate()
            .map(|(f, r)| {
                tracks
                    .iter()
                    .map(|t| Some(r.as_ref()?.apply((*t)?.get(f)?.as_ref()?)))
                    .collect()
            })
            .collect()
    }
}
