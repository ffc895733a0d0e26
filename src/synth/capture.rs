//! The simulated motion capture: marker placement (plates, palm, forearm, landmarks) and the
//! errors of a real session: marker noise, soft-tissue artefact (markers that slide, plates that
//! slide and spin), occlusion gaps, landmark markers placed off their anatomical points, a hand
//! that is not clamped (re-seated for every trial, drifting during it) and a seated posture at
//! the start of each trial that is only close to the static reference posture.

use super::motion::{trial_angles_varied, MotionVariation, Trial, SEATED_S};
use crate::anatomy::{Joint, Link, Side};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::rng::Rng;
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::{JointFrame, Pose, Skeleton};
use crate::template::landmark_rule::ray_hit;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// Error model of a capture session. Sizes of the `typical` preset in brackets; `noisy` doubles
/// them, `clean` has none but the drift.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorModel {
    /// SD of the isotropic Gaussian noise on every coordinate, mm (0.2).
    pub noise_mm: f64,
    /// Range of the soft-tissue slide of a plate over its joints' ranges, mm (1-3).
    pub plate_sta_mm: (f64, f64),
    /// Range of the rotation of a plate, as a rigid cluster about its centre, over its joints'
    /// ranges, degrees (0.3-1).
    pub plate_spin_deg: (f64, f64),
    /// Range of the skin slide of a palm marker over its joints' ranges, mm (0.4-1).
    pub palm_sta_mm: (f64, f64),
    /// Range of the skin slide of a forearm marker over the wrist's flexion, mm (0.3-1).
    pub skin_sta_mm: (f64, f64),
    /// Fraction of frames each marker is occluded for (after the seated second) (3 %).
    pub gap_fraction: f64,
    /// SD of the hand's placement at the start of each trial about the static trial's, per axis
    /// (translation mm, rotation degrees) (5 mm, 3°).
    pub seat: (f64, f64),
    /// Amplitude of the hand's drift during a trial (translation mm, rotation degrees) (3, 2).
    pub drift: (f64, f64),
    /// SD of every joint angle of a trial's seated posture about the static reference posture,
    /// degrees (0.75).
    pub seated_posture_sd_deg: f64,
    /// SD of a landmark marker's placement along the skin off its anatomical point, per tangent
    /// direction, mm (1).
    pub landmark_sd_mm: f64,
    /// Write every trial's markers in a seeded random order (readers go by label).
    pub shuffle_labels: bool,
    /// Range-of-motion scale (1 typical, 0.5 small).
    pub rom: f64,
}

impl ErrorModel {
    /// This model without the sources the first capture simulator did not have (palm marker
    /// slide, plate spin, seated postures off the static one, landmark placement error, shuffled
    /// labels) and with its re-seating of 1.5 mm / 1°: for profiling the sources one at a time,
    /// and for the tests whose expectations were set against that simulator.
    pub fn first_capture_model(self) -> ErrorModel {
        ErrorModel {
            palm_sta_mm: (0.0, 0.0),
            plate_spin_deg: (0.0, 0.0),
            seated_posture_sd_deg: 0.0,
            landmark_sd_mm: 0.0,
            shuffle_labels: false,
            seat: if self.seat == (0.0, 0.0) {
                self.seat
            } else {
                (1.5, 1.0)
            },
            ..self
        }
    }
}

/// One driver of a marker's soft-tissue artefact: a joint angle, normalised by `range_deg`,
/// times a slide and a spin.
#[derive(Clone, Debug, PartialEq)]
pub struct StaDriver {
    /// The joint whose angle drives it.
    pub joint: Joint,
    /// Which of the joint's angles: 0 flexion, 1 abduction (wrist: deviation).
    pub dof: usize,
    /// The angle (degrees, relative to the reference posture) that counts as 1.
    pub range_deg: f64,
    /// Translation per unit of normalised angle, mm, in the link's reference frame.
    pub slide: Vec3,
    /// Rotation vector (radians) per unit of normalised angle about
    /// [`MarkerDef::sta_centre`], in the link's reference frame: a plate's markers share it, so
    /// the plate turns as a rigid cluster.
    pub spin: Vec3,
}

/// A marker rigidly attached to a link (apart from its soft-tissue artefact).
#[derive(Clone, Debug)]
pub struct MarkerDef {
    /// Spec name, e.g. `I_MID_2`.
    pub name: String,
    /// The link it rides on.
    pub link: Link,
    /// Position in the reference posture, mm, reference (pre-lab) frame.
    pub position: Point,
    /// Soft-tissue artefact: the marker moves with the link, then by
    /// `R(Σ spin·a) (p - c) + c + Σ slide·a` for the drivers' normalised angles `a`, where `c`
    /// is [`MarkerDef::sta_centre`].
    pub sta: Vec<StaDriver>,
    /// Centre of the artefact's rotation (a plate's centre; the marker itself for skin markers).
    pub sta_centre: Point,
}

impl MarkerDef {
    /// The marker in its link's reference frame with its artefact at the joint angles `angles`
    /// (degrees per joint, [`Joint::ALL`] order).
    pub fn displaced(&self, angles: &[[f64; 3]]) -> Point {
        let mut slide = Vec3::zeros();
        let mut spin = Vec3::zeros();
        for d in &self.sta {
            let a = angles[d.joint.index()][d.dof] / d.range_deg;
            slide += d.slide * a;
            spin += d.spin * a;
        }
        let c = self.sta_centre;
        let p = if spin == Vec3::zeros() {
            self.position
        } else {
            c + UnitQuaternion::from_scaled_axis(spin) * (self.position - c)
        };
        p + slide
    }
}

/// A unit vector drawn uniformly in the plane normal to `n`.
fn tangent_direction(rng: &mut Rng, n: &Vec3) -> Vec3 {
    let v = rng.unit_vector();
    (v - n * v.dot(n))
        .try_normalize(1e-9)
        .unwrap_or_else(|| n.cross(&Vec3::x()).try_normalize(1e-9).unwrap_or(Vec3::y()))
}

/// The soft-tissue slide of a palm marker (spec section 2: `PALM_1` over the head of the 2nd
/// metacarpal, `PALM_2` over the 5th's, `PALM_3`/`PALM_4` over their bases), drawn once per
/// session. The dorsal skin over the metacarpal heads is pulled as the MCP under it flexes
/// (the extensor hood), and all of the back of the hand slides as the wrist flexes and deviates;
/// so a head marker is driven mostly (50-80 %) by its MCP's flexion, a base marker mostly
/// (70-90 %) by the wrist, the rest shared 2:1 between wrist flexion and deviation. Each
/// driver slides the marker along the skin (tangent to `normal`) in its own random direction;
/// the sum of the slides over the joints' ranges (MCP 0-80°, wrist ±60° and ±20°) is drawn in
/// `range` mm. An assumption of the simulator (after the 0.5-1 mm of the markers over the
/// metacarpals reported by skin-marker studies), not a measured distribution.
pub fn palm_sta(name: &str, normal: &Vec3, rng: &mut Rng, range: (f64, f64)) -> Vec<StaDriver> {
    let (mcp, head) = match name {
        "PALM_1" => (Joint::IMcp, true),
        "PALM_2" => (Joint::LMcp, true),
        "PALM_3" => (Joint::IMcp, false),
        _ => (Joint::LMcp, false),
    };
    let total = rng.range(range.0, range.1);
    let mcp_share = if head {
        rng.range(0.5, 0.8)
    } else {
        rng.range(0.1, 0.3)
    };
    let wrist = 1.0 - mcp_share;
    [
        (mcp, 0, 80.0, mcp_share),
        (Joint::Wrist, 0, 120.0, wrist * 2.0 / 3.0),
        (Joint::Wrist, 1, 40.0, wrist / 3.0),
    ]
    .into_iter()
    .map(|(joint, dof, range_deg, share)| StaDriver {
        joint,
        dof,
        range_deg,
        slide: tangent_direction(rng, normal) * total * share,
        spin: Vec3::zeros(),
    })
    .collect()
}

/// A landmark marker as a lab places it: by palpation and by eye, so off the anatomical point
/// `p` (outward normal `n`) along the skin by a tangential Gaussian of `sd_mm` per direction,
/// brought back onto the skin (closest point) and lifted by `offset_mm` along the skin's
/// normal there (interpolated vertex normals `normals`). Returns the marker centre.
pub fn placed_landmark(
    tree: &AabbTree,
    normals: &[Vec3],
    p: &Point,
    n: &Vec3,
    offset_mm: f64,
    sd_mm: f64,
    rng: &mut Rng,
) -> Point {
    if sd_mm <= 0.0 {
        return p + n * offset_mm;
    }
    let u = tangent_direction(rng, n);
    let v = n.cross(&u);
    let q = p + (u * rng.normal() + v * rng.normal()) * sd_mm;
    match tree.closest_point(&q) {
        Some(c) => {
            let f = tree.mesh().faces[c.face];
            let nn: Vec3 = (0..3).map(|k| normals[f[k]] * c.barycentric[k]).sum();
            c.point + nn.try_normalize(1e-12).unwrap_or(*n) * offset_mm
        }
        None => q + n * offset_mm,
    }
}

/// Outward unit normal of the face hit, at the first hit of a ray from inside.
fn hit_with_normal(mesh: &TriMesh, origin: &Point, dir: &Vec3) -> Option<(Point, Vec3)> {
    let (f, p) = ray_hit(mesh, origin, dir)?;
    let n = mesh.face_cross(f).normalize();
    Some((p, n))
}

/// The three markers of a plate on `link`: a plate 10-20 mm above the dorsal skin at the middle
/// of the link, markers at 8-12 mm from its centre, 120° apart with a few degrees of jitter
/// (labs make plates asymmetric on purpose so the markers can be told apart). Its soft-tissue
/// artefact: the plate slides by `err.plate_sta_mm` and turns about its centre by
/// `err.plate_spin_deg` over its joints' ranges (a plate on skin both shifts and tilts as the
/// skin under it stretches; its three markers move as one rigid cluster).
pub fn plate_markers(
    mesh: &TriMesh,
    sk: &Skeleton,
    link: Link,
    rng: &mut Rng,
    err: &ErrorModel,
) -> Vec<MarkerDef> {
    let j = link.joint().expect("plates sit on finger links");
    let jf = sk.joint(j);
    let mid = jf.centre + (sk.distal_end(j) - jf.centre) * 0.5;
    let (hit, n) = hit_with_normal(mesh, &mid, &jf.y()).unwrap_or((mid + jf.y() * 8.0, jf.y()));
    // The spin has its own stream, so the plates' other draws do not depend on it.
    let mut spin_rng = rng.fork("spin");
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
    // drivers; mostly along the link (skin is pulled over the knuckles), some sideways. Its
    // spin is shared the same way, each driver about its own random axis.
    let total = rng.range(err.plate_sta_mm.0, err.plate_sta_mm.1);
    let share = rng.range(0.3, 0.7);
    let spin_total = spin_rng
        .range(err.plate_spin_deg.0, err.plate_spin_deg.1)
        .to_radians();
    let n = drivers.len();
    let sta: Vec<StaDriver> = drivers
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
            StaDriver {
                joint: d,
                dof: 0,
                range_deg: range,
                slide: dir * total * part,
                spin: spin_rng.unit_vector() * spin_total * part,
            }
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
                sta_centre: centre,
            }
        })
        .collect()
}

/// Where the forearm markers `ARM_1`..`ARM_3` sit: (distance proximal of the wrist centre along
/// the forearm, mm; angle from dorsal toward radial, degrees).
pub const ARM_STATIONS: [(f64, f64); 3] = [(45.0, 0.0), (80.0, 0.0), (60.0, 40.0)];

/// The forearm markers of the wrist trial, at [`ARM_STATIONS`] on the dorsal forearm of the
/// skin `mesh` (`wrist` the wrist joint's frame, its z along the hand and forearm, y dorsal):
/// for each station a ray from the forearm's axis toward the station's direction, the marker
/// `offset_mm` off the skin along the normal where it hits. Where the body's skin ends before
/// the station (a hand cut above the wrist, as the template is), the forearm is continued as a
/// cylinder of the last covered cross-section: the ray is cast there (3 mm inside the cut,
/// found by a ray along the axis) and carried to the station. Each marker slides with the
/// wrist's flexion by `sta_range` mm over its ±60°, in a random direction.
pub fn forearm_markers(
    mesh: &TriMesh,
    wrist: &JointFrame,
    side: Side,
    offset_mm: f64,
    rng: &mut Rng,
    sta_range: (f64, f64),
) -> Vec<MarkerDef> {
    let radial = wrist.x() * if side == Side::Right { 1.0 } else { -1.0 };
    let back = -wrist.z();
    // How far proximally the skin reaches along the axis.
    let reach = ray_hit(mesh, &wrist.centre, &back)
        .map(|(_, p)| (p - wrist.centre).norm())
        .unwrap_or(0.0);
    ARM_STATIONS
        .iter()
        .enumerate()
        .map(|(k, &(along, deg))| {
            let dir = wrist.y() * deg.to_radians().cos() + radial * deg.to_radians().sin();
            let axis_point = wrist.centre + back * along;
            let direct = (along < reach)
                .then(|| hit_with_normal(mesh, &axis_point, &dir))
                .flatten();
            let position = match direct {
                Some((hit, n)) => hit + n * offset_mm,
                None => {
                    let last = wrist.centre + back * (reach - 3.0).max(0.0);
                    let height = hit_with_normal(mesh, &last, &dir)
                        .map(|(hit, _)| (hit - last).dot(&dir))
                        .unwrap_or(22.0);
                    axis_point + dir * (height + offset_mm)
                }
            };
            let slide = rng.unit_vector() * rng.range(sta_range.0, sta_range.1);
            MarkerDef {
                name: format!("ARM_{}", k + 1),
                link: Link::Arm,
                position,
                sta: vec![StaDriver {
                    joint: Joint::Wrist,
                    dof: 0,
                    range_deg: 60.0,
                    slide,
                    spin: Vec3::zeros(),
                }],
                sta_centre: position,
            }
        })
        .collect()
}

/// A smooth drift of the whole hand during a trial, zero at t = 0: sums of two slow sinusoids
/// per axis (0.03-0.2 Hz) for translation and rotation.
pub(crate) struct Drift {
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
pub(crate) fn gap_mask(rng: &mut Rng, n: usize, rate: f64, fraction: f64) -> Vec<bool> {
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

/// The hand's placement for one trial relative to the static trial's: a rotation about `pivot`
/// and a translation, Gaussian per axis with SDs `seat` (mm, degrees); the identity when both
/// are zero (no draw).
pub fn seating(rng: &mut Rng, seat: (f64, f64), pivot: &Point) -> Isometry3<f64> {
    if seat == (0.0, 0.0) {
        return Isometry3::identity();
    }
    let q = UnitQuaternion::from_scaled_axis(rng.gauss3(seat.1.to_radians()));
    let c = pivot.coords;
    Isometry3::from_parts(Translation3::from(c - q * c + rng.gauss3(seat.0)), q)
}

/// How one recording of a trial departs from the protocol and from the static trial.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The motion's departure from the protocol.
    pub var: MotionVariation,
    /// The hand's rigid offset at the trial's start from the static trial (re-seated for every
    /// trial).
    pub seat: Isometry3<f64>,
    /// The seated posture's joint angles relative to the static reference posture, degrees per
    /// joint ([`Joint::ALL`] order): held through the seated second, the motion adds to it.
    pub seated_deg: Vec<[f64; 3]>,
}

impl Recording {
    /// The protocol's motion from exactly the static posture and placement.
    pub fn nominal() -> Recording {
        Recording {
            var: MotionVariation::NOMINAL,
            seat: Isometry3::identity(),
            seated_deg: vec![[0.0; 3]; Joint::ALL.len()],
        }
    }
}

/// Simulate one calibration trial: `n` frames at `rate` Hz of the markers in `defs`, the joints
/// moving as the protocol ([`super::motion`]) departed from by `rec.var`, from the seated
/// posture `rec.seated_deg`, the hand placed at `rec.seat` and drifting by `err.drift`; `to_lab`
/// maps the reference frame to the lab. Returns positions in mm per marker per frame (`None`
/// where occluded).
#[allow(clippy::too_many_arguments)]
pub fn simulate_trial(
    trial: Trial,
    sk: &Skeleton,
    defs: &[MarkerDef],
    n: usize,
    rate: f64,
    err: &ErrorModel,
    rec: &Recording,
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
        let mut angles = rec.seated_deg.clone();
        for (j, a) in trial_angles_varied(trial, t, duration, err.rom, &rec.var) {
            for (x, y) in angles[j.index()].iter_mut().zip(a) {
                *x += y;
            }
        }
        let pose = Pose::from_deg(&angles, to_lab * rec.seat * drift.at(t, &pivot));
        let tf = link_transforms(sk, &pose);
        for ((m, d), mask) in defs.iter().enumerate().zip(&masks) {
            if !mask[f] {
                out[m].push(None);
                continue;
            }
            let p = tf[d.link.index()] * d.displaced(&angles) + noise_rng.gauss3(err.noise_mm);
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
