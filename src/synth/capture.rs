//! The simulated motion capture: marker placement (plates, palm, forearm, landmarks) and the
//! errors of a real session: marker noise, soft-tissue artefact, occlusion gaps and a hand that
//! is not clamped.

use super::motion::{trial_angles_varied, MotionVariation, Trial, SEATED_S};
use crate::anatomy::{Joint, Link};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::rng::Rng;
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::{Pose, Skeleton};
use crate::template::landmark_rule::ray_hit;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// Error model of a capture session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorModel {
    /// SD of the isotropic Gaussian noise on every coordinate, mm.
    pub noise_mm: f64,
    /// Range of the soft-tissue slide of a plate over its joints' ranges, mm.
    pub plate_sta_mm: (f64, f64),
    /// Range of the skin slide of a palm or forearm marker, mm.
    pub skin_sta_mm: (f64, f64),
    /// Fraction of frames each marker is occluded for (after the seated second).
    pub gap_fraction: f64,
    /// Amplitude of the hand's drift during a trial (translation mm, rotation degrees).
    pub drift: (f64, f64),
    /// Range-of-motion scale (1 typical, 0.5 small).
    pub rom: f64,
}

/// A marker rigidly attached to a link (apart from its soft-tissue slide).
#[derive(Clone, Debug)]
pub struct MarkerDef {
    /// Spec name, e.g. `I_MID_2`.
    pub name: String,
    /// The link it rides on.
    pub link: Link,
    /// Position in the reference posture, mm, reference (pre-lab) frame.
    pub position: Point,
    /// Soft-tissue slide: displacement per unit of each driver's normalised angle
    /// (reference frame, moves with the link), and the drivers (joint, full range in degrees).
    pub sta: Vec<(Vec3, Joint, f64)>,
}

/// Outward unit normal of the face hit, at the first hit of a ray from inside.
fn hit_with_normal(mesh: &TriMesh, origin: &Point, dir: &Vec3) -> Option<(Point, Vec3)> {
    let (f, p) = ray_hit(mesh, origin, dir)?;
    let n = mesh.face_cross(f).normalize();
    Some((p, n))
}

/// The three markers of a plate on `link`: a plate 10-20 mm above the dorsal skin at the middle
/// of the link, markers at 8-12 mm from its centre, 120° apart with a few degrees of jitter
/// (labs make plates asymmetric on purpose so the markers can be told apart).
pub fn plate_markers(
    mesh: &TriMesh,
    sk: &Skeleton,
    link: Link,
    rng: &mut Rng,
    sta_range: (f64, f64),
) -> Vec<MarkerDef> {
    let j = link.joint().expect("plates sit on finger links");
    let jf = sk.joint(j);
    let mid = jf.centre + (sk.distal_end(j) - jf.centre) * 0.5;
    let (hit, n) = hit_with_normal(mesh, &mid, &jf.y()).unwrap_or((mid + jf.y() * 8.0, jf.y()));
    let height = rng.range(10.0, 20.0);
    let centre = hit + n * height;
    let u = (jf.z() - n * jf.z().dot(&n)).normalize();
    let v = n.cross(&u);
    let phi0 = rng.range(0.0, std::f64::consts::TAU);
    // Drivers: the joint under the plate and the next one distal (the skin over a phalanx moves
    // with both ends' flexion).
    let mut drivers = vec![(j, 90.0)];
    if let Some(next) = Joint::ALL
        .iter()
        .find(|c| c.parent() == Some(j) && c.dof() == 1)
    {
        drivers.push((*next, 90.0));
    }
    // The plate's whole slide over the joints' ranges is 1-3 mm (typical), shared between the
    // drivers; mostly along the link (skin is pulled over the knuckles), some sideways.
    let total = rng.range(sta_range.0, sta_range.1);
    let share = rng.range(0.3, 0.7);
    let n = drivers.len();
    let sta: Vec<(Vec3, Joint, f64)> = drivers
        .into_iter()
        .enumerate()
        .map(|(k, (d, range))| {
            let dir = (jf.z() * rng.range(-1.0, 1.0) + rng.unit_vector() * 0.4).normalize();
            let part = if n == 1 {
                1.0
            } else if k == 0 {
                share
            } else {
                1.0 - share
            };
            (dir * total * part, d, range)
        })
        .collect();
    (0..3)
        .map(|k| {
            let phi = phi0 + k as f64 * std::f64::consts::TAU / 3.0 + rng.range(-0.15, 0.15);
            let r = rng.range(8.0, 12.0);
            MarkerDef {
                name: format!("{}_{}", link.name(), k + 1),
                link,
                position: centre + (u * phi.cos() + v * phi.sin()) * r,
                sta: sta.clone(),
            }
        })
        .collect()
}

/// A smooth drift of the whole hand during a trial, zero at t = 0: sums of two slow sinusoids
/// per axis (0.03-0.2 Hz) for translation and rotation.
pub struct Drift {
    terms: Vec<(Vec3, Vec3, f64, f64)>,
}

impl Drift {
    /// Draw a drift of `amplitude` (mm, degrees).
    pub fn new(rng: &mut Rng, amplitude: (f64, f64)) -> Drift {
        let terms = (0..2)
            .map(|_| {
                (
                    rng.unit_vector() * amplitude.0 * 0.5,
                    rng.unit_vector() * amplitude.1.to_radians() * 0.5,
                    rng.range(0.03, 0.2) * std::f64::consts::TAU,
                    rng.range(0.0, std::f64::consts::TAU),
                )
            })
            .collect();
        Drift { terms }
    }

    /// The rigid drift at time t (s), about `pivot`.
    pub fn at(&self, t: f64, pivot: &Point) -> Isometry3<f64> {
        let mut tr = Vec3::zeros();
        let mut rot = Vec3::zeros();
        for (a, r, w, ph) in &self.terms {
            let s = (w * t + ph).sin() - ph.sin();
            tr += a * s;
            rot += r * s;
        }
        let q = UnitQuaternion::from_scaled_axis(rot);
        Isometry3::from_parts(Translation3::from(pivot.coords - q * pivot.coords + tr), q)
    }
}

/// Occlusion gaps of one marker: a mask with `true` = visible. Gaps last 0.05-0.5 s and start
/// after the seated second, until `fraction` of the frames is hidden.
pub fn gap_mask(rng: &mut Rng, n: usize, rate: f64, fraction: f64) -> Vec<bool> {
    let mut visible = vec![true; n];
    let start = ((SEATED_S * rate) as usize + 1).min(n);
    if fraction <= 0.0 || n <= start + 1 {
        return visible;
    }
    let target = (fraction * n as f64) as usize;
    let mut hidden = 0;
    let mut guard = 0;
    while hidden < target && guard < 10_000 {
        guard += 1;
        let len = (rng.range(0.05, 0.5) * rate).round().max(1.0) as usize;
        let s = start + rng.below(n - start);
        for v in visible.iter_mut().skip(s).take(len) {
            if *v {
                *v = false;
                hidden += 1;
            }
        }
    }
    visible
}

/// Simulate one calibration trial: `n` frames at `rate` Hz of the markers in `defs`, the joints
/// moving as the protocol ([`super::motion`]) departed from by `var`.
/// `seat` is the rigid offset of the hand at the trial's reference frame (re-seated for every
/// trial); `to_lab` maps the reference frame to the lab. Returns positions in mm per marker per
/// frame (`None` where occluded) and, per frame, the true link transforms (for tests).
#[allow(clippy::too_many_arguments)]
pub fn simulate_trial(
    trial: Trial,
    sk: &Skeleton,
    defs: &[MarkerDef],
    n: usize,
    rate: f64,
    err: &ErrorModel,
    var: &MotionVariation,
    seat: &Isometry3<f64>,
    to_lab: &Isometry3<f64>,
    rng: &mut Rng,
) -> Vec<Vec<Option<Point>>> {
    let duration = n as f64 / rate;
    let drift = Drift::new(&mut rng.fork("drift"), err.drift);
    let mut noise_rng = rng.fork("noise");
    let mut gap_rng = rng.fork("gaps");
    let masks: Vec<Vec<bool>> = defs
        .iter()
        .map(|_| gap_mask(&mut gap_rng, n, rate, err.gap_fraction))
        .collect();
    let pivot = sk.centre(Joint::Wrist);
    let mut out = vec![Vec::with_capacity(n); defs.len()];
    for f in 0..n {
        // Frame index drives time, the masks and the outputs alike.
        let t = f as f64 / rate;
        let mut pose = Pose::zero();
        let angles = trial_angles_varied(trial, t, duration, err.rom, var);
        for &(j, a) in &angles {
            pose = pose.with_deg(j, a);
        }
        pose.root = to_lab * seat * drift.at(t, &pivot);
        let tf = link_transforms(sk, &pose);
        for ((m, d), mask) in defs.iter().enumerate().zip(&masks) {
            if !mask[f] {
                out[m].push(None);
                continue;
            }
            let mut q = d.position;
            for (dir, joint, range) in &d.sta {
                let a = angles
                    .iter()
                    .find(|(j, _)| j == joint)
                    .map(|(_, a)| a[0])
                    .unwrap_or(0.0);
                q += dir * (a / range);
            }
            let p = tf[d.link.index()] * q + noise_rng.gauss3(err.noise_mm);
            out[m].push(Some(p));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drift_is_zero_at_start_and_gaps_hit_their_fraction() {
        let mut rng = Rng::new(3);
        let d = Drift::new(&mut rng, (3.0, 2.0));
        let p = Point::new(10.0, 20.0, 30.0);
        assert!((d.at(0.0, &p).to_homogeneous() - nalgebra::Matrix4::identity()).norm() < 1e-15);
        let mask = gap_mask(&mut rng, 6000, 100.0, 0.03);
        let hidden = mask.iter().filter(|v| !**v).count();
        assert!((180..240).contains(&hidden), "{hidden}");
        assert!(
            mask[..101].iter().all(|v| *v),
            "the seated second stays visible"
        );
    }
}
