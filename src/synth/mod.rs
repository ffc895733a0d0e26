//! Simulated subjects with ground truth (`ergohand synth`): subject folders exactly as a lab
//! would produce them (subject-format spec, sections 1-2), together with the truth, so that every
//! stage of the pipeline is measured rather than assumed.
//!
//! The true hand is the template changed the way hands differ ([`anthropometry`]), roughened by a
//! smooth random surface field ([`surface_field`]) and, optionally, held in a reference posture
//! that differs from the template's. Its CT-like reference surface is a voxel scan of it
//! ([`voxel_scan`]). The capture ([`capture`], [`motion`]) moves it through the calibration motions
//! of the seed paper with the errors of a real session.

pub mod anthropometry;
pub mod capture;
pub mod grasp_motion;
pub mod motion;
pub mod procedural;
pub mod stamp;
pub mod suite;
pub mod surface_field;
pub mod true_contacts;
pub mod true_hand;
pub mod voxel_scan;

use crate::anatomy::{
    landmark_names, palm_markers, tip_marker_names, Dimension, Finger, Joint, Link, Side,
};
use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::mocap::c3d::write_c3d;
use crate::mocap::subject::Subject;
use crate::mocap::trajectories::Trajectories;
use crate::rng::Rng;
use crate::skeleton::record::{joint_records, JointRecord};
use crate::skeleton::{Pose, Skeleton};
use crate::template::{load_template, TemplateHand};
use capture::{
    forearm_markers, palm_sta, placed_landmark, plate_markers, seating, simulate_trial, ErrorModel,
    MarkerDef, Recording,
};
use motion::{MotionVariation, Trial};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::str::FromStr;
pub use true_hand::TrueHand;

/// Named sets of error and motion parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// 0.2 mm noise, 1-3 mm and 0.3-1° plate artefact, 0.4-1 mm skin marker slide, 3 % gaps,
    /// seated postures 0.75° off the static one, landmarks placed 1 mm off, full ranges of motion.
    Typical,
    /// As typical with half the ranges of motion.
    SmallRom,
    /// Double every error of typical (the drift excepted).
    Noisy,
    /// No error at all (for exactness tests); the hand still drifts, as it is not clamped, and
    /// the labels are still shuffled (no error: readers go by label).
    Clean,
}

impl Preset {
    /// All presets.
    pub const ALL: [Preset; 4] = [
        Preset::Typical,
        Preset::SmallRom,
        Preset::Noisy,
        Preset::Clean,
    ];

    /// The preset's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Typical => "typical",
            Preset::SmallRom => "small-rom",
            Preset::Noisy => "noisy",
            Preset::Clean => "clean",
        }
    }

    /// Error model of the capture.
    pub fn error_model(self) -> ErrorModel {
        let typical = ErrorModel {
            noise_mm: 0.2,
            plate_sta_mm: (1.0, 3.0),
            plate_spin_deg: (0.3, 1.0),
            palm_sta_mm: (0.4, 1.0),
            skin_sta_mm: (0.3, 1.0),
            gap_fraction: 0.03,
            seat: (5.0, 3.0),
            drift: (3.0, 2.0),
            seated_posture_sd_deg: 0.75,
            landmark_sd_mm: 1.0,
            shuffle_labels: true,
            rom: 1.0,
        };
        match self {
            Preset::Typical => typical,
            Preset::SmallRom => ErrorModel {
                rom: 0.5,
                ..typical
            },
            Preset::Noisy => ErrorModel {
                noise_mm: 0.4,
                plate_sta_mm: (2.0, 6.0),
                plate_spin_deg: (0.6, 2.0),
                palm_sta_mm: (0.8, 2.0),
                skin_sta_mm: (0.6, 2.0),
                gap_fraction: 0.06,
                seat: (10.0, 6.0),
                seated_posture_sd_deg: 1.5,
                landmark_sd_mm: 2.0,
                ..typical
            },
            Preset::Clean => ErrorModel {
                noise_mm: 0.0,
                plate_sta_mm: (0.0, 0.0),
                plate_spin_deg: (0.0, 0.0),
                palm_sta_mm: (0.0, 0.0),
                skin_sta_mm: (0.0, 0.0),
                gap_fraction: 0.0,
                seat: (0.0, 0.0),
                seated_posture_sd_deg: 0.0,
                landmark_sd_mm: 0.0,
                ..typical
            },
        }
    }

    /// SD of the caliper measurement error, mm.
    pub(crate) fn caliper_sd_mm(self) -> f64 {
        match self {
            Preset::Typical | Preset::SmallRom => 0.4,
            Preset::Noisy => 0.8,
            Preset::Clean => 0.0,
        }
    }
}

impl FromStr for Preset {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!("unknown preset '{s}' (expected one of: typical, small-rom, noisy, clean)")
            })
    }
}

/// The reference posture of the simulated subject.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Posture {
    /// The template's own posture.
    Template,
    /// Fingers spread or closed by 5-15°, flexed 0-20° at MCP and PIP, thumb 10-20° higher or
    /// lower: how seated subjects really differ. Drawn again where two neighbouring fingers
    /// would pass through each other.
    Varied,
}

impl FromStr for Posture {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "template" => Ok(Posture::Template),
            "varied" => Ok(Posture::Varied),
            _ => Err(format!(
                "unknown posture '{s}' (expected template or varied)"
            )),
        }
    }
}

/// Which true hand a simulated subject has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Body {
    /// The template deformed by its own skeleton ([`true_hand::template_body`]): the template can
    /// always reach it.
    Template,
    /// A procedural anatomical hand built from published proportions, independent of the
    /// template's mesh and skinning.
    Procedural,
}

impl Body {
    /// Both bodies.
    pub const ALL: [Body; 2] = [Body::Template, Body::Procedural];

    /// The body's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Body::Template => "template",
            Body::Procedural => "procedural",
        }
    }
}

impl FromStr for Body {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Body::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| format!("unknown body '{s}' (expected template or procedural)"))
    }
}

/// Everything that defines a simulated subject.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthOptions {
    /// The seed: the same options give byte-identical files.
    pub seed: u64,
    /// Error model.
    pub preset: Preset,
    /// Which hand.
    #[serde(default = "default_side")]
    pub hand: Side,
    /// Reference posture.
    #[serde(default = "default_posture")]
    pub posture: Posture,
    /// The true hand's body.
    #[serde(default = "default_body")]
    pub body: Body,
    /// Length of every calibration trial, s; `None` draws 40-80 s per trial.
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// Voxel size of the CT-like scan, mm.
    #[serde(default = "default_voxel")]
    pub voxel_mm: f64,
    /// Marker radius plus base: skin surface to marker centre, mm.
    #[serde(default = "default_offset")]
    pub marker_offset_mm: f64,
    /// Repeat number of the capture session: the same hand (same seed) captured again with new
    /// plates, noise, artefact and gaps (0 = the first session). For repeatability studies.
    #[serde(default)]
    pub repeat: u32,
    /// Repeat number of the calibration trials within that session: the plates stay where they
    /// are (same placement, same soft-tissue slide, same static reference trial) and every
    /// calibration motion is recorded again: a new realisation of the motion
    /// ([`motion::MotionVariation`]), a new seating and drift of the hand, new noise and gaps.
    /// 0 = the session's first recording, which follows the protocol's nominal motion; the seed
    /// paper's repeatability measure (section 4: calibration motions measured five times) is over
    /// `trial_repeat` 1-5. Not written to `truth.json` when 0, so older truths stay identical.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub trial_repeat: u32,
    /// Length of each grasp motion trial ([`grasp_motion`]), s; `None` writes none. Not written
    /// to `truth.json` when `None`, so that subjects without motions stay byte-identical.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_s: Option<f64>,
    /// A percentile hand of the procedural body instead of a drawn one: sex and percentile of
    /// hand length and breadth ([`procedural::Proportions::at_percentile`]). Not written to
    /// `truth.json` when `None`, so drawn subjects stay byte-identical.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub percentile_hand: Option<(procedural::Sex, f64)>,
    /// Write the optional fingertip markers (`T_TIP`..`L_TIP`, an extension of the spec) into
    /// the static reference trial, placed as the other landmarks are (on the true skin where
    /// the distal phalanx's long axis leaves it, the lab's placement error, the marker offset).
    /// Their draws come from streams of their own: every other file is the same with or without
    /// them. Not written to `truth.json` when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub tip_markers: bool,
    /// Keep the fingertip markers of `tip_markers` on through the grasp motion trials (riding
    /// the distal links, sliding with the DIP as the nails do; noise and gaps from streams of
    /// their own, so every other marker's track is the same). A lab may leave them off there,
    /// where a grasp's fingertips meet the part. Not written to `truth.json` when false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub tip_markers_worn: bool,
}

fn is_false(v: &bool) -> bool {
    !*v
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn default_side() -> Side {
    Side::Right
}
fn default_posture() -> Posture {
    Posture::Template
}
fn default_body() -> Body {
    Body::Template
}
fn default_voxel() -> f64 {
    0.5
}
fn default_offset() -> f64 {
    4.0
}

impl SynthOptions {
    /// Options with defaults for everything but seed and preset.
    pub fn new(seed: u64, preset: Preset) -> Self {
        SynthOptions {
            seed,
            preset,
            hand: Side::Right,
            posture: Posture::Template,
            body: Body::Template,
            duration_s: None,
            voxel_mm: default_voxel(),
            marker_offset_mm: default_offset(),
            repeat: 0,
            trial_repeat: 0,
            motion_s: None,
            percentile_hand: None,
            tip_markers: false,
            tip_markers_worn: false,
        }
    }
}

/// Capture frame rate, Hz (the seed paper's).
pub const FRAME_RATE: f64 = 100.0;
/// Frames of the static reference trial (averaged by the reader).
pub(crate) const REFERENCE_FRAMES: usize = 10;

/// Ground truth of a simulated subject (`truth.json`, spec section 3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Always "mm".
    pub units: String,
    /// Always "reference": the lab frame of the static reference trial.
    pub frame: String,
    /// True joint centres and axes in that frame.
    pub joints: BTreeMap<String, JointRecord>,
    /// Error-free values of the 22 dimensions, mm: the calipers by their definitions
    /// ([`crate::measure::caliper`]) on the true skin.
    pub dimensions: BTreeMap<String, f64>,
    /// The reference posture relative to the template's, degrees per joint.
    pub reference_posture_deg: BTreeMap<String, [f64; 3]>,
    /// How the subject was made.
    pub synth: SynthOptions,
}

/// A simulated subject in memory, before it is written.
#[derive(Clone, Debug)]
pub struct SyntheticSubject {
    /// The subject file's content.
    pub subject: Subject,
    /// Trials by `[trials]` key (`reference`, `wrist`, `thumb`, ...), mm, lab frame, f64.
    pub trials: BTreeMap<String, Trajectories>,
    /// Ground truth.
    pub truth: Truth,
    /// The true skin in the reference posture, lab frame (homologous to the template for the
    /// template body only: see `skin_homologous`).
    pub true_skin: TriMesh,
    /// `true_skin` has the template's vertices and faces (written as `truth_skin.ply`).
    pub skin_homologous: bool,
    /// The true skeleton in the reference posture, lab frame.
    pub true_skeleton: Skeleton,
    /// Marker definitions per trial key (for exactness tests).
    pub markers: BTreeMap<String, Vec<MarkerDef>>,
    /// How each calibration trial's recording departed from the protocol and the static trial
    /// (seating, seated posture, motion), per trial key (for tests).
    pub recordings: BTreeMap<String, Recording>,
    /// The CT-like reference surface, lab frame.
    pub reference: TriMesh,
    /// Grasp motion trials with their truth, by motion name (`[motions]` key).
    pub motions: BTreeMap<String, grasp_motion::GraspTrial>,
}

/// The rotation from the template's frame to a lab's with the hand palm-down on a seat: the
/// back of the hand (the wrist frame's y) up along +Z, the palm's long axis (its z) along +X.
fn template_to_lab_rotation(sk: &Skeleton) -> Rotation3<f64> {
    let w = sk.joint(Joint::Wrist);
    let (l, d) = (w.z(), w.y());
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[l, d.cross(&l), d]).transpose())
}

/// Draw the subject's reference posture relative to the template's (degrees).
fn draw_posture(rng: &mut Rng, posture: Posture) -> Pose {
    let mut pose = Pose::zero();
    if posture == Posture::Template {
        return pose;
    }
    let sign = |rng: &mut Rng| if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
    for f in &Finger::ALL[1..] {
        let [mcp, pip, dip] = f.joints();
        let abd = sign(rng) * rng.range(5.0, 15.0);
        pose = pose
            .with_deg(mcp, [rng.range(0.0, 20.0), abd, 0.0])
            .with_deg(pip, [rng.range(0.0, 20.0), 0.0, 0.0])
            .with_deg(dip, [rng.range(0.0, 10.0), 0.0, 0.0]);
    }
    pose = pose.with_deg(
        Joint::TCmc,
        [
            sign(rng) * rng.range(10.0, 20.0),
            sign(rng) * rng.range(10.0, 20.0),
            0.0,
        ],
    );
    pose
}

/// How close, mm, the bones of two neighbouring fingers may come in a drawn reference posture.
/// A finger's bone runs near the middle of its cross-section, so two fingers whose skins do not
/// overlap keep their bones at least the sum of their half-breadths apart. The slenderest pair
/// either body makes, ring and little, is about 15 and 13 mm broad at the PIP (the template
/// body; the procedural body's 5th percentile woman has 15.8 and 14.1 mm), so about 14 mm. 12 mm
/// leaves a millimetre a side for the soft tissue that yields where adducted fingers press
/// together (the template's own posture keeps 18 mm, the procedural body's own rule 15 mm), and
/// still refuses every posture whose skins pass through each other.
const FINGER_BONE_CLEARANCE_MM: f64 = 12.0;

/// How many times a varied posture whose fingers cross is drawn again before giving up.
const MAX_POSTURE_REDRAWS: usize = 20;

/// The closest distance, mm, between the bones of two neighbouring fingers (index-middle,
/// middle-ring, ring-little) of `sk`, and which two: each finger's bone is the polyline MCP ->
/// PIP -> DIP -> the distal link's tip.
fn closest_neighbouring_fingers(sk: &Skeleton) -> (f64, Finger, Finger) {
    let bone = |f: Finger| -> [Point; 4] {
        let [mcp, pip, dip] = f.joints().map(|j| sk.centre(j));
        [mcp, pip, dip, sk.tips[f as usize]]
    };
    Finger::ALL[1..]
        .windows(2)
        .map(|pair| {
            let (a, b) = (bone(pair[0]), bone(pair[1]));
            let d = a
                .windows(2)
                .flat_map(|sa| b.windows(2).map(move |sb| segment_segment_distance(sa, sb)))
                .fold(f64::INFINITY, f64::min);
            (d, pair[0], pair[1])
        })
        .fold((f64::INFINITY, Finger::Index, Finger::Middle), |best, x| {
            if x.0 < best.0 {
                x
            } else {
                best
            }
        })
}

/// The closest distance between the segments `a[0]-a[1]` and `b[0]-b[1]`.
fn segment_segment_distance(a: &[Point], b: &[Point]) -> f64 {
    let (d1, d2, r) = (a[1] - a[0], b[1] - b[0], a[0] - b[0]);
    let (aa, ee, f) = (d1.norm_squared(), d2.norm_squared(), d2.dot(&r));
    let eps = 1e-12;
    let (s, t) = if aa <= eps && ee <= eps {
        (0.0, 0.0)
    } else if aa <= eps {
        (0.0, (f / ee).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if ee <= eps {
            ((-c / aa).clamp(0.0, 1.0), 0.0)
        } else {
            let bb = d1.dot(&d2);
            let denom = aa * ee - bb * bb;
            let mut s = if denom > eps {
                ((bb * f - c * ee) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (bb * s + f) / ee;
            if t < 0.0 {
                t = 0.0;
                s = (-c / aa).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((bb - c) / aa).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    ((a[0] + d1 * s) - (b[0] + d2 * t)).norm()
}

/// The true hand of `opts` in its reference posture. A varied posture spreads or closes each
/// finger on its own, so two neighbouring fingers can converge until their bones nearly meet and
/// their skins pass through each other, which no hand can do (and the calipers would then measure
/// a finger's breadth through its neighbour). Such a posture is drawn again, from streams of its
/// own (`posture-redraw-1`, `-2`, ...), so every hand whose fingers stayed apart is exactly as
/// the first draw made it.
fn reference_body(opts: &SynthOptions, template: &TemplateHand, root: &Rng) -> Result<TrueHand> {
    let build = |posture: Pose| match opts.body {
        Body::Template => true_hand::template_body(template, root, posture),
        Body::Procedural => {
            procedural::procedural_body(opts.hand, root, posture, opts.percentile_hand)
        }
    };
    let mut body = build(draw_posture(&mut root.fork("posture"), opts.posture))?;
    if opts.posture == Posture::Template {
        return Ok(body);
    }
    let mut redraws = 0;
    loop {
        let (gap, a, b) = closest_neighbouring_fingers(&body.skeleton);
        if gap >= FINGER_BONE_CLEARANCE_MM {
            return Ok(body);
        }
        if redraws == MAX_POSTURE_REDRAWS {
            return Err(Error::invalid(format!(
                "seed {}: no varied posture in {MAX_POSTURE_REDRAWS} redraws keeps neighbouring \
                 fingers' bones {FINGER_BONE_CLEARANCE_MM} mm apart (the last brings the {} and \
                 {} fingers to {gap:.1} mm)",
                opts.seed,
                a.trial_name(),
                b.trial_name()
            )));
        }
        redraws += 1;
        log::debug!(
            "synth seed {}: the {} and {} fingers' bones are {gap:.1} mm apart (under \
             {FINGER_BONE_CLEARANCE_MM} mm): posture drawn again ({redraws})",
            opts.seed,
            a.trial_name(),
            b.trial_name()
        );
        let stream = format!("posture-redraw-{redraws}");
        body = build(draw_posture(&mut root.fork(&stream), opts.posture))?;
    }
}

/// Simulate a subject with its preset's error model.
pub fn simulate(opts: &SynthOptions) -> Result<SyntheticSubject> {
    simulate_with(opts, &opts.preset.error_model())
}

/// Simulate a subject with the error model `err` instead of its preset's (to study one error
/// source at a time; `truth.json` still names the preset).
pub fn simulate_with(opts: &SynthOptions, err: &ErrorModel) -> Result<SyntheticSubject> {
    let err = *err;
    if !(0.05..=2.0).contains(&opts.voxel_mm) {
        return Err(Error::invalid(format!(
            "voxel size {} mm is outside 0.05-2 mm",
            opts.voxel_mm
        )));
    }
    if let Some(d) = opts.duration_s {
        if !(2.0..=600.0).contains(&d) {
            return Err(Error::invalid(format!(
                "trial duration {d} s is outside 2-600 s"
            )));
        }
    }
    if let Some(d) = opts.motion_s {
        let (lo, hi) = grasp_motion::MOTION_S_RANGE;
        if !(d.is_finite() && (lo..=hi).contains(&d)) {
            return Err(Error::invalid(format!(
                "motion trial length {d} s is outside {lo}-{hi} s"
            )));
        }
    }
    let root = Rng::new(opts.seed);
    let template: TemplateHand = load_template(opts.hand)?;

    // 1. The true hand in its reference posture.
    let body = reference_body(opts, &template, &root)?;

    // 2. Into the lab frame.
    let mut lab_rng = root.fork("lab");
    let yaw =
        UnitQuaternion::from_axis_angle(&Vec3::z_axis(), lab_rng.range(-10f64, 10.0).to_radians());
    let rot = yaw * UnitQuaternion::from_rotation_matrix(&template_to_lab_rotation(&body.skeleton));
    let centre = body.skeleton.centre(Joint::Wrist).coords;
    let offset = Vec3::new(250.0, 150.0, 100.0) + lab_rng.gauss3(20.0);
    let to_lab = Isometry3::from_parts(Translation3::from(offset - rot * centre), rot);
    let hand = body.transformed(&to_lab);
    let true_skin = hand.skin.clone();
    let true_skeleton = hand.skeleton.clone();
    let posture = hand.posture.clone();

    // 4. Truth: joints, and the error-free dimensions: the calipers' definitions applied to the
    // true skin with the true skeleton and the true landmark points.
    let landmark_points: BTreeMap<String, Point> = hand
        .landmarks
        .iter()
        .map(|(k, (p, _))| (k.clone(), *p))
        .collect();
    let by_definition =
        crate::measure::measure_dimensions(&true_skin, &true_skeleton, &landmark_points);
    let mut dimensions = BTreeMap::new();
    let mut measured = BTreeMap::new();
    let mut cal_rng = root.fork("caliper");
    for d in Dimension::all() {
        let v = by_definition[&d]
            .clone()
            .map_err(|e| Error::invalid(format!("the true hand's {d} cannot be measured: {e}")))?;
        dimensions.insert(d.name(), v);
        // Digital calipers read to 0.01 mm.
        let m = v + cal_rng.normal() * opts.preset.caliper_sd_mm();
        measured.insert(d, (m * 100.0).round() / 100.0);
    }
    let truth = Truth {
        units: "mm".into(),
        frame: "reference".into(),
        joints: joint_records(&true_skeleton),
        dimensions,
        reference_posture_deg: Joint::ALL
            .iter()
            .map(|&j| {
                (
                    j.name().to_string(),
                    posture.angles[j.index()].map(|a| a.to_degrees()),
                )
            })
            .collect(),
        synth: opts.clone(),
    };

    // 5. Markers, in the reference posture (lab frame): landmarks placed by the lab near their
    // anatomical points, at the marker offset along the skin's normal; plates on the links of
    // each finger; forearm markers. What the lab attaches (landmark placement, palm slide) is
    // drawn once per session; a repeated session attaches everything again.
    let session = |name: &str| {
        if opts.repeat == 0 {
            root.fork(name)
        } else {
            root.fork(&format!("{name}-repeat-{}", opts.repeat))
        }
    };
    let skin_tree = AabbTree::new(&true_skin);
    let skin_normals = true_skin.vertex_normals();
    let place = |name: &str, rng: &mut Rng| -> Point {
        let (p, n) = hand.landmarks[name];
        placed_landmark(
            &skin_tree,
            &skin_normals,
            &p,
            &n,
            opts.marker_offset_mm,
            err.landmark_sd_mm,
            rng,
        )
    };
    let mut place_rng = session("landmark-placement");
    let placed: BTreeMap<&str, Point> = landmark_names()
        .into_iter()
        .map(|name| (name, place(name, &mut place_rng)))
        .collect();
    let mut palm_rng = session("palm-sta");
    let palm_defs: Vec<MarkerDef> = palm_markers()
        .iter()
        .map(|&name| MarkerDef {
            name: name.to_string(),
            link: Link::Palm,
            position: placed[name],
            sta: palm_sta(
                name,
                &hand.landmarks[name].1,
                &mut palm_rng,
                err.palm_sta_mm,
            ),
            sta_centre: placed[name],
        })
        .collect();
    let wrist = true_skeleton.joint(Joint::Wrist);
    let arm_defs = forearm_markers(
        &true_skin,
        wrist,
        opts.hand,
        opts.marker_offset_mm,
        &mut root.fork("sta"),
        err.skin_sta_mm,
    );

    let durations: Vec<f64> = {
        let mut r = root.fork("durations");
        (0..6)
            .map(|_| opts.duration_s.unwrap_or_else(|| r.range(40.0, 80.0)))
            .collect()
    };
    let mut trials = BTreeMap::new();
    let mut markers = BTreeMap::new();
    let mut recordings = BTreeMap::new();
    let trial_list: Vec<(String, Trial)> = std::iter::once(("wrist".to_string(), Trial::Wrist))
        .chain(
            Finger::ALL
                .iter()
                .map(|&f| (f.trial_name().to_string(), Trial::Finger(f))),
        )
        .collect();
    // The simulation runs in the lab frame: the skeleton is already there, so `to_lab` is the
    // identity for the trials.
    let ident = Isometry3::identity();
    for ((key, trial), duration) in trial_list.iter().zip(&durations) {
        let mut trng = if opts.repeat == 0 {
            root.fork(&format!("trial-{key}"))
        } else {
            root.fork(&format!("trial-{key}-repeat-{}", opts.repeat))
        };
        let mut defs: Vec<MarkerDef> = palm_defs.clone();
        match trial {
            Trial::Wrist => defs.extend(arm_defs.iter().cloned()),
            Trial::Finger(f) => {
                for link in f.links() {
                    defs.extend(plate_markers(
                        &true_skin,
                        &true_skeleton,
                        link,
                        &mut trng,
                        &err,
                    ));
                }
            }
        }
        let n = (duration * FRAME_RATE).round() as usize;
        // A repeated recording of the trial keeps the plates drawn above and draws everything
        // of the recording itself (motion, seating, drift, noise, gaps) from its own stream;
        // the first recording continues the trial's stream, as it always has.
        let mut take_rng;
        let (rng, var) = if opts.trial_repeat == 0 {
            (&mut trng, MotionVariation::NOMINAL)
        } else {
            take_rng = trng.fork(&format!("take-{}", opts.trial_repeat));
            let var = MotionVariation::draw(&mut take_rng.fork("motion"));
            (&mut take_rng, var)
        };
        let rec = Recording {
            var,
            seat: seating(rng, err.seat, &wrist.centre),
            seated_deg: motion::seated_posture(
                &mut rng.fork("seated-posture"),
                err.seated_posture_sd_deg,
            ),
        };
        let positions = simulate_trial(
            *trial,
            &true_skeleton,
            &defs,
            n,
            FRAME_RATE,
            &err,
            &rec,
            &ident,
            rng,
        );
        let traj = Trajectories {
            frame_rate: FRAME_RATE,
            labels: defs.iter().map(|d| d.name.clone()).collect(),
            positions,
            source: PathBuf::from(format!("trials/{key}.c3d")),
        };
        let traj = if err.shuffle_labels {
            shuffled(traj, &mut rng.fork("label-order"))
        } else {
            traj
        };
        trials.insert(key.clone(), traj);
        recordings.insert(key.clone(), rec);
        markers.insert(key.clone(), defs);
    }

    // The static reference trial: every landmark, a few noisy frames.
    // A repeated session re-records the static trial too (new noise), as it re-records the
    // calibration motions.
    let mut ref_rng = if opts.repeat == 0 {
        root.fork("reference-trial")
    } else {
        root.fork(&format!("reference-trial-repeat-{}", opts.repeat))
    };
    let mut names = landmark_names();
    let mut positions: Vec<Vec<Option<Point>>> = names
        .iter()
        .map(|n| {
            let p = placed[n];
            (0..REFERENCE_FRAMES)
                .map(|_| Some(p + ref_rng.gauss3(err.noise_mm)))
                .collect()
        })
        .collect();
    let mut placed_tips: Vec<(&str, Point)> = Vec::new();
    if opts.tip_markers {
        let mut tip_place = session("tip-placement");
        let mut tip_noise = session("reference-trial-tips");
        for name in tip_marker_names() {
            let q = place(name, &mut tip_place);
            placed_tips.push((name, q));
            names.push(name);
            positions.push(
                (0..REFERENCE_FRAMES)
                    .map(|_| Some(q + tip_noise.gauss3(err.noise_mm)))
                    .collect(),
            );
        }
    }
    let reference = Trajectories {
        frame_rate: FRAME_RATE,
        labels: names.iter().map(|s| s.to_string()).collect(),
        positions,
        source: PathBuf::from("trials/reference.c3d"),
    };
    let reference = if err.shuffle_labels {
        shuffled(reference, &mut ref_rng.fork("label-order"))
    } else {
        reference
    };
    trials.insert("reference".into(), reference);

    // 6. Grasp motion trials: the landmarks' markers as placed for the static trial (now riding
    // their links and sliding with flexion), the palm and forearm markers of the calibration
    // trials, and the part's markers. Every draw comes from streams of their own, so the
    // calibration trials are the same with or without motions.
    let mut motions = BTreeMap::new();
    if let Some(motion_s) = opts.motion_s {
        let mut sta_rng = session("grasp-skin-sta");
        let mut defs: Vec<MarkerDef> = palm_defs.clone();
        for name in landmark_names() {
            if palm_markers().contains(&name) {
                continue;
            }
            let normal = hand.landmarks[name].1;
            if let Some(d) = grasp_motion::landmark_marker(
                name,
                placed[name],
                &normal,
                err.skin_sta_mm,
                &mut sta_rng,
            ) {
                defs.push(d);
            }
        }
        defs.extend(arm_defs.iter().cloned());
        // Fingertip markers kept on for the grasp slide from streams of their own.
        let mut tip_sta_rng = session("grasp-tip-sta");
        let worn: &[(&str, Point)] = if opts.tip_markers_worn {
            &placed_tips
        } else {
            &[]
        };
        let extra: Vec<MarkerDef> = worn
            .iter()
            .filter_map(|&(name, q)| {
                grasp_motion::landmark_marker(
                    name,
                    q,
                    &hand.landmarks[name].1,
                    err.skin_sta_mm,
                    &mut tip_sta_rng,
                )
            })
            .collect();
        let gerr = grasp_motion::GraspErrors::from_model(&err);
        // The true skin's weights for its contacts: the template's by homology, or bone heat
        // on the procedural body's own skin. No draws: the trials do not change.
        let weights = if hand.homologous_to_template {
            template.weights.clone()
        } else {
            crate::pose::bone_heat_weights(
                &true_skin,
                &true_skeleton,
                &crate::pose::HeatOptions::default(),
            )?
        };
        let skinned =
            true_contacts::true_skinned_hand(opts.hand, &true_skin, &true_skeleton, weights)?;
        for task in &grasp_motion::GRASP_TASKS {
            let mut trial = grasp_motion::simulate_grasp(
                task,
                grasp_motion::GraspInputs {
                    skeleton: &true_skeleton,
                    hand: &skinned,
                    markers: defs.clone(),
                    extra: extra.clone(),
                },
                motion_s,
                FRAME_RATE,
                &err,
                &gerr,
                &session(&format!("motion-{}", task.name)),
            )?;
            true_contacts::add_skin_truth(&skinned, task, &mut trial)?;
            motions.insert(task.name.to_string(), trial);
        }
    }

    // 7. The CT-like reference surface.
    let reference = voxel_scan::ct_surface(&true_skin, opts.voxel_mm)?;

    let name = format!("SYN{:04}", opts.seed % 10_000);
    let subject = Subject {
        dir: PathBuf::new(),
        name,
        hand: opts.hand,
        marker_offset_mm: opts.marker_offset_mm,
        reference_frame: 0,
        trials: trials
            .keys()
            .map(|k| (k.clone(), PathBuf::from(format!("trials/{k}.c3d"))))
            .collect(),
        dimensions: measured,
        labels: BTreeMap::new(),
        motions: motions
            .keys()
            .map(|k| (k.clone(), PathBuf::from(format!("trials/{k}.c3d"))))
            .collect(),
    };
    Ok(SyntheticSubject {
        subject,
        trials,
        truth,
        true_skin,
        skin_homologous: hand.homologous_to_template,
        true_skeleton,
        markers,
        recordings,
        reference,
        motions,
    })
}

/// `t` with its markers (labels and tracks together) in a random order (Fisher-Yates).
fn shuffled(mut t: Trajectories, rng: &mut Rng) -> Trajectories {
    for i in (1..t.labels.len()).rev() {
        let j = rng.below(i + 1);
        t.labels.swap(i, j);
        t.positions.swap(i, j);
    }
    t
}

/// Write a simulated subject folder at `dir`: `subject.toml`, `trials/*.c3d`, `reference.ply`,
/// `truth.json` and (an extension of the spec, template body only) `truth_skin.ply`, the true
/// skin homologous to the template. Everything is written into a temporary sibling folder that replaces `dir` only when
/// complete. A non-empty `dir` is an error unless `force`.
pub fn write_subject(dir: &Path, s: &SyntheticSubject, force: bool) -> Result<()> {
    check_subject_dir(dir, force)?;
    let parent = dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    let name = dir
        .file_name()
        .ok_or_else(|| Error::input(dir, "output folder has no name"))?
        .to_string_lossy()
        .into_owned();
    let tmp = parent.join(format!(".{name}.{}.tmp", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let result = write_into(&tmp, s);
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    std::fs::rename(&tmp, dir).map_err(|e| Error::io(dir, e))
}

/// Whether [`write_subject`] may write a subject folder at `dir`: a non-empty folder is an
/// error unless `force`. Commands call it before simulating, so a refusal costs nothing.
pub fn check_subject_dir(dir: &Path, force: bool) -> Result<()> {
    if dir.exists() {
        let non_empty = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .next()
            .is_some();
        if non_empty && !force {
            return Err(Error::input(
                dir,
                "output folder exists and is not empty; pass --force to replace it",
            ));
        }
    }
    Ok(())
}

fn write_into(tmp: &Path, s: &SyntheticSubject) -> Result<()> {
    let trials_dir = tmp.join("trials");
    std::fs::create_dir_all(&trials_dir).map_err(|e| Error::io(&trials_dir, e))?;
    let mut subject = s.subject.clone();
    subject.dir = tmp.to_path_buf();
    subject.save()?;
    for (key, traj) in &s.trials {
        write_c3d(&trials_dir.join(format!("{key}.c3d")), traj)?;
    }
    crate::io::ply::write_ply(
        &tmp.join("reference.ply"),
        &s.reference,
        crate::io::Units::Millimetres,
        None,
    )?;
    if s.skin_homologous {
        crate::io::ply::write_ply(
            &tmp.join("truth_skin.ply"),
            &s.true_skin,
            crate::io::Units::Millimetres,
            None,
        )?;
    }
    let json = serde_json::to_string_pretty(&s.truth).expect("truth serialises");
    crate::io::atomic::write_bytes_atomic(&tmp.join("truth.json"), json.as_bytes())?;
    if !s.motions.is_empty() {
        let truth_dir = tmp.join("truth_motion");
        std::fs::create_dir_all(&truth_dir).map_err(|e| Error::io(&truth_dir, e))?;
        for (name, m) in &s.motions {
            write_c3d(&trials_dir.join(format!("{name}.c3d")), &m.trajectories)?;
            // Compact: one line of numbers per frame would triple the file for no reader's gain.
            let json = serde_json::to_string(&m.truth).expect("motion truth serialises");
            crate::io::atomic::write_bytes_atomic(
                &truth_dir.join(format!("{name}.json")),
                json.as_bytes(),
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::absolute_orientation;

    fn short(seed: u64, preset: Preset) -> SynthOptions {
        SynthOptions {
            duration_s: Some(4.0),
            voxel_mm: 1.0,
            ..SynthOptions::new(seed, preset)
        }
    }

    /// The registration of a parent's markers at frame `f` onto frame 0 (equation 1 of the seed
    /// paper), from the trial data alone.
    fn to_reference(
        t: &Trajectories,
        parent: &[String],
        f: usize,
    ) -> crate::geometry::Registration {
        let at = |k: usize| -> Vec<Point> {
            parent
                .iter()
                .map(|n| t.get(n, k).expect("clean data has no gaps"))
                .collect()
        };
        absolute_orientation(&at(f), &at(0), None, false).unwrap()
    }

    #[test]
    fn clean_markers_keep_their_distance_to_the_true_centres() {
        let s = simulate(&short(11, Preset::Clean)).unwrap();
        let t = &s.trials["index"];
        let centre = |j: Joint| {
            let c = s.truth.joints[j.name()].centre;
            Point::new(c[0], c[1], c[2])
        };
        let palm: Vec<String> = palm_markers().iter().map(|s| s.to_string()).collect();
        let plates = |l: Link| l.plate_markers().to_vec();
        for (joint, parent, child) in [
            (Joint::IMcp, palm.clone(), plates(Link::IProx)),
            (Joint::IPip, plates(Link::IProx), plates(Link::IMid)),
            (Joint::IDip, plates(Link::IMid), plates(Link::IDist)),
        ] {
            let c = centre(joint);
            let axis = s.truth.joints[joint.name()]
                .axis
                .map(|a| Vec3::new(a[0], a[1], a[2]));
            for m in &child {
                let p0 = t.get(m, 0).unwrap();
                let (r0, h0) = ((p0 - c).norm(), axis.map(|a| (p0 - c).dot(&a)));
                let mut max_dev: f64 = 0.0;
                for f in (0..t.n_frames()).step_by(7) {
                    let reg = to_reference(t, &parent, f);
                    let p = reg.apply(&t.get(m, f).unwrap());
                    max_dev = max_dev.max(((p - c).norm() - r0).abs());
                    if let (Some(a), Some(h0)) = (axis, h0) {
                        max_dev = max_dev.max(((p - c).dot(&a) - h0).abs());
                    }
                }
                assert!(max_dev < 1e-6, "{joint} {m}: {max_dev:e} mm");
            }
        }
    }

    #[test]
    fn the_motion_covers_the_ranges_relative_to_the_parent() {
        // The index PIP must really move in the clean index trial: the MID plate sweeps an arc of
        // at least 90 degrees about the true axis, as seen from the PROX plate.
        let s = simulate(&short(12, Preset::Clean)).unwrap();
        let t = &s.trials["index"];
        let prox = Link::IProx.plate_markers().to_vec();
        let c = s.truth.joints["I_PIP"].centre;
        let c = Point::new(c[0], c[1], c[2]);
        let m = "I_MID_1";
        let v0 = t.get(m, 0).unwrap() - c;
        let mut max_angle: f64 = 0.0;
        for f in 0..t.n_frames() {
            let reg = to_reference(t, &prox, f);
            let v = reg.apply(&t.get(m, f).unwrap()) - c;
            max_angle = max_angle.max(v.angle(&v0).to_degrees());
        }
        // A 4 s trial reaches only part of the distal phase; half of the 100° PIP range at least.
        assert!(max_angle > 30.0, "{max_angle}");
    }

    #[test]
    fn reference_surface_is_closed_and_keeps_the_volume() {
        let s = simulate(&short(13, Preset::Typical)).unwrap();
        s.reference.check_closed_manifold().unwrap();
        let (vr, vt) = (s.reference.signed_volume(), s.true_skin.signed_volume());
        assert!((vr / vt - 1.0).abs() < 0.01, "{vr} vs {vt}");
        // Nothing in common with the template's topology.
        assert_ne!(s.reference.n_vertices(), s.true_skin.n_vertices());
        // Every landmark lies at the marker offset off the true skin.
        let t = &s.trials["reference"];
        assert_eq!(t.labels.len(), landmark_names().len());
    }

    #[test]
    fn same_seed_gives_byte_identical_files() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        let opts = short(21, Preset::Typical);
        write_subject(&a, &simulate(&opts).unwrap(), false).unwrap();
        write_subject(&b, &simulate(&opts).unwrap(), false).unwrap();
        let mut files: Vec<PathBuf> = Vec::new();
        for e in walk(&a) {
            files.push(e.strip_prefix(&a).unwrap().to_path_buf());
        }
        assert!(files.len() >= 10, "{files:?}");
        for f in &files {
            let x = std::fs::read(a.join(f)).unwrap();
            let y = std::fs::read(b.join(f)).unwrap();
            assert!(x == y, "{} differs", f.display());
        }
        // A different seed differs.
        let c = dir.path().join("c");
        write_subject(&c, &simulate(&short(22, Preset::Typical)).unwrap(), false).unwrap();
        assert_ne!(
            std::fs::read(a.join("truth.json")).unwrap(),
            std::fs::read(c.join("truth.json")).unwrap()
        );
        // The folder reads back as a subject with every trial, through the C3D reader.
        let subj = Subject::load(&a).unwrap();
        for kind in [
            "reference",
            "wrist",
            "thumb",
            "index",
            "middle",
            "ring",
            "little",
        ] {
            assert!(subj.trials.contains_key(kind), "{kind}");
        }
        // A non-empty folder is refused without force, and replaced with it.
        let e = write_subject(&a, &simulate(&opts).unwrap(), false).unwrap_err();
        assert!(e.to_string().contains("--force"), "{e}");
        write_subject(&a, &simulate(&opts).unwrap(), true).unwrap();
    }

    #[test]
    fn a_procedural_subject_is_byte_identical_for_a_seed_and_measured_from_its_skin() {
        let dir = tempfile::tempdir().unwrap();
        let opts = SynthOptions {
            body: Body::Procedural,
            hand: Side::Left,
            posture: Posture::Varied,
            ..short(31, Preset::Typical)
        };
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        let s = simulate(&opts).unwrap();
        write_subject(&a, &s, false).unwrap();
        write_subject(&b, &simulate(&opts).unwrap(), false).unwrap();
        let files = walk(&a);
        assert!(files.len() >= 10, "{files:?}");
        for f in &files {
            let rel = f.strip_prefix(&a).unwrap();
            assert!(
                std::fs::read(f).unwrap() == std::fs::read(b.join(rel)).unwrap(),
                "{} differs",
                rel.display()
            );
        }
        // Not homologous to the template: no truth_skin.ply.
        assert!(!s.skin_homologous && !a.join("truth_skin.ply").exists());
        s.reference.check_closed_manifold().unwrap();
        let (vr, vt) = (s.reference.signed_volume(), s.true_skin.signed_volume());
        assert!((vr / vt - 1.0).abs() < 0.01, "{vr} vs {vt}");
        // Every dimension is a hand's, finger breadths exceed thicknesses at the same joint.
        for d in Dimension::all() {
            let v = s.truth.dimensions[&d.name()];
            let (lo, hi) = d.plausible_range_mm();
            assert!((lo..=hi).contains(&v), "{d}: {v}");
        }
        for f in Finger::ALL {
            let get = |d: Dimension| s.truth.dimensions[&d.name()];
            assert!(
                get(Dimension::BreadthProximal(f)) > get(Dimension::ThicknessProximal(f)),
                "{f:?}"
            );
        }
    }

    fn walk(dir: &Path) -> Vec<PathBuf> {
        let mut out = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else {
                out.push(p);
            }
        }
        out.sort();
        out
    }

    /// A marker's placement and soft-tissue artefact.
    type Plate = (Point, Vec<capture::StaDriver>);

    /// A repeated recording keeps the session's plates, soft-tissue slide, static trial and
    /// truth and records every motion anew; a new session re-attaches the plates.
    #[test]
    fn trial_repeats_keep_the_plates_and_redo_the_recording() {
        let base = short(23, Preset::Typical);
        let take = |repeat: u32, trial_repeat: u32| {
            simulate(&SynthOptions {
                repeat,
                trial_repeat,
                ..base.clone()
            })
            .unwrap()
        };
        let (a, b, c, other) = (take(0, 0), take(0, 1), take(0, 2), take(1, 1));
        for key in ["wrist", "thumb", "index", "little"] {
            let plates = |s: &SyntheticSubject| -> Vec<Plate> {
                s.markers[key]
                    .iter()
                    .map(|d| (d.position, d.sta.clone()))
                    .collect()
            };
            assert!(
                plates(&a) == plates(&b) && plates(&b) == plates(&c),
                "{key}"
            );
            assert!(plates(&b) != plates(&other), "{key}");
            let p = |s: &SyntheticSubject| s.trials[key].positions.clone();
            assert!(p(&a) != p(&b) && p(&b) != p(&c), "{key}");
        }
        assert_eq!(
            a.trials["reference"].positions,
            c.trials["reference"].positions
        );
        assert_eq!(a.truth.joints, c.truth.joints);
        // The first recording's truth.json is what it was before trial repeats existed.
        let json = |s: &SyntheticSubject| serde_json::to_string(&s.truth).unwrap();
        assert!(!json(&a).contains("trial_repeat"));
        assert!(json(&c).contains("\"trial_repeat\":2"));
    }

    /// The clean model with one error switched on by `f`, and no drift (so the link transforms
    /// are those of the posture alone) and the labels in order.
    fn clean_but(f: impl FnOnce(&mut ErrorModel)) -> ErrorModel {
        let mut e = Preset::Clean.error_model();
        e.drift = (0.0, 0.0);
        e.shuffle_labels = false;
        f(&mut e);
        e
    }

    /// True link transforms at frame `f` of a trial: the protocol's nominal angles plus the
    /// recording's seated posture, from the skeleton's forward kinematics.
    fn true_transforms(s: &SyntheticSubject, key: &str, f: usize) -> Vec<Isometry3<f64>> {
        let trial = if key == "wrist" {
            Trial::Wrist
        } else {
            Trial::Finger(*Finger::ALL.iter().find(|x| x.trial_name() == key).unwrap())
        };
        let t = &s.trials[key];
        let rec = &s.recordings[key];
        let duration = t.n_frames() as f64 / FRAME_RATE;
        let mut angles = rec.seated_deg.clone();
        for (j, a) in motion::trial_angles(trial, f as f64 / FRAME_RATE, duration, 1.0) {
            for d in 0..3 {
                angles[j.index()][d] += a[d];
            }
        }
        let pose = Pose::from_deg(&angles, Isometry3::identity());
        crate::skeleton::forward_kinematics::link_transforms(&s.true_skeleton, &pose)
    }

    fn angles_of(s: &SyntheticSubject, key: &str, f: usize) -> Vec<[f64; 3]> {
        let trial = if key == "wrist" {
            Trial::Wrist
        } else {
            Trial::Finger(*Finger::ALL.iter().find(|x| x.trial_name() == key).unwrap())
        };
        let duration = s.trials[key].n_frames() as f64 / FRAME_RATE;
        let mut angles = vec![[0.0; 3]; Joint::ALL.len()];
        for (j, a) in motion::trial_angles(trial, f as f64 / FRAME_RATE, duration, 1.0) {
            angles[j.index()] = a;
        }
        angles
    }

    #[test]
    fn palm_markers_slide_with_their_own_mcp_and_the_wrist() {
        let err = clean_but(|e| e.palm_sta_mm = (0.4, 1.0));
        let s = simulate_with(&short(31, Preset::Clean), &err).unwrap();
        let defs = &s.markers["index"];
        let palm: Vec<&MarkerDef> = defs.iter().filter(|d| d.link == Link::Palm).collect();
        assert_eq!(palm.len(), 4);
        // Drawn: 0.4-1 mm in all over the joints' ranges; the heads mostly by their MCP.
        for d in &palm {
            let total: f64 = d.sta.iter().map(|x| x.slide.norm()).sum();
            assert!((0.4..=1.0).contains(&total), "{}: {total}", d.name);
            let mcp = d.sta.iter().find(|x| x.joint != Joint::Wrist).unwrap();
            let share = mcp.slide.norm() / total;
            let head = d.name == "PALM_1" || d.name == "PALM_2";
            assert!(if head { share >= 0.5 } else { share <= 0.3 }, "{}", d.name);
        }
        // Independent directions per marker.
        for (a, b) in palm.iter().zip(palm.iter().skip(1)) {
            let cos = a.sta[0].slide.normalize().dot(&b.sta[0].slide.normalize());
            assert!(cos.abs() < 0.999, "{} {}", a.name, b.name);
        }
        // On the data: each palm marker, seen from the true palm, is displaced by its drawn
        // slides times the protocol's angles; a marker whose drivers do not move stays put.
        for key in ["index", "little", "wrist"] {
            let t = &s.trials[key];
            let mut moved = BTreeMap::new();
            for f in (0..t.n_frames()).step_by(5) {
                let tf = true_transforms(&s, key, f);
                let angles = angles_of(&s, key, f);
                for d in &palm {
                    let seen = tf[Link::Palm.index()].inverse() * t.get(&d.name, f).unwrap();
                    let want: Vec3 = d
                        .sta
                        .iter()
                        .map(|x| x.slide * angles[x.joint.index()][x.dof] / x.range_deg)
                        .sum();
                    let got = seen - d.position;
                    assert!((got - want).norm() < 1e-9, "{key} {} frame {f}", d.name);
                    let m: &mut f64 = moved.entry(d.name.clone()).or_default();
                    *m = m.max(got.norm());
                }
            }
            let still: &[&str] = match key {
                "index" => &["PALM_2", "PALM_4"],
                "little" => &["PALM_1", "PALM_3"],
                _ => &[],
            };
            for (name, m) in &moved {
                if still.contains(&name.as_str()) {
                    assert!(*m < 1e-12, "{key} {name} {m}");
                } else {
                    assert!(*m > 0.01, "{key} {name} {m}");
                }
            }
        }
    }

    #[test]
    fn plates_turn_as_rigid_clusters_about_their_centres() {
        let err = clean_but(|e| e.plate_spin_deg = (0.3, 1.0));
        let s = simulate_with(&short(32, Preset::Clean), &err).unwrap();
        let t = &s.trials["index"];
        let mut max_angle: f64 = 0.0;
        for link in Finger::Index.links() {
            let defs: Vec<&MarkerDef> = s.markers["index"]
                .iter()
                .filter(|d| d.link == link)
                .collect();
            let drawn: f64 = defs[0].sta.iter().map(|x| x.spin.norm()).sum();
            assert!((0.3..=1.0).contains(&drawn.to_degrees()), "{link}: {drawn}");
            for f in (0..t.n_frames()).step_by(9) {
                let tf = true_transforms(&s, "index", f)[link.index()];
                let rigid: Vec<Point> = defs.iter().map(|d| tf * d.position).collect();
                let seen: Vec<Point> = defs.iter().map(|d| t.get(&d.name, f).unwrap()).collect();
                let reg = absolute_orientation(&rigid, &seen, None, false).unwrap();
                assert!(reg.rms < 1e-9, "{link} frame {f}: not rigid, {}", reg.rms);
                // The centre stays where the link puts it; the angle is the drawn spin's.
                let c = tf * defs[0].sta_centre;
                assert!((reg.apply(&c) - c).norm() < 1e-6, "{link} frame {f}");
                let angles = angles_of(&s, "index", f);
                let want: Vec3 = defs[0]
                    .sta
                    .iter()
                    .map(|x| x.spin * angles[x.joint.index()][x.dof] / x.range_deg)
                    .sum();
                let got = reg.rotation.angle();
                assert!((got - want.norm()).abs() < 1e-6, "{link} frame {f}");
                max_angle = max_angle.max(got.to_degrees());
            }
        }
        assert!(max_angle > 0.2, "{max_angle}");
    }

    #[test]
    fn seated_postures_scatter_about_the_static_one() {
        let mut rng = Rng::new(33);
        let mut samples = Vec::new();
        for _ in 0..400 {
            let p = motion::seated_posture(&mut rng, 0.75);
            for (j, a) in Joint::ALL.iter().zip(&p) {
                assert_eq!(a[2], 0.0);
                samples.push(a[0]);
                if j.dof() == 3 {
                    samples.push(a[1]);
                } else {
                    assert_eq!(a[1], 0.0);
                }
            }
        }
        let n = samples.len() as f64;
        let mean = samples.iter().sum::<f64>() / n;
        let sd = (samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        // SE of the SD about 0.75 / sqrt(2 n) = 0.006 for n = 8,000.
        assert!(mean.abs() < 0.03 && (sd - 0.75).abs() < 0.03, "{mean} {sd}");

        // On the data: the seated second holds the drawn posture, not the static one.
        let err = clean_but(|e| e.seated_posture_sd_deg = 0.75);
        let s = simulate_with(&short(34, Preset::Clean), &err).unwrap();
        let t = &s.trials["index"];
        let defs: Vec<&MarkerDef> = s.markers["index"]
            .iter()
            .filter(|d| d.link == Link::IProx)
            .collect();
        for f in [0, 50, 99, 250] {
            let tf = true_transforms(&s, "index", f)[Link::IProx.index()];
            for d in &defs {
                let p = t.get(&d.name, f).unwrap();
                assert!((tf * d.position - p).norm() < 1e-9, "{} frame {f}", d.name);
            }
        }
        let static_pos: Vec<Point> = defs.iter().map(|d| d.position).collect();
        let first: Vec<Point> = defs.iter().map(|d| t.get(&d.name, 0).unwrap()).collect();
        let turn = absolute_orientation(&static_pos, &first, None, false)
            .unwrap()
            .rotation
            .angle()
            .to_degrees();
        assert!(turn > 0.05 && turn < 6.0, "{turn}");
        let mid: Vec<Point> = defs.iter().map(|d| t.get(&d.name, 99).unwrap()).collect();
        assert_eq!(first, mid);
    }

    #[test]
    fn landmarks_are_placed_off_their_points_along_the_skin() {
        // On a sphere of radius 40 mm: the offset along the surface has the drawn SD in each
        // tangent direction and none along the normal; the marker sits at the offset off it.
        let sphere = crate::geometry::mesh::tests::icosphere(40.0, 4);
        let tree = AabbTree::new(&sphere);
        let normals = sphere.vertex_normals();
        let mut rng = Rng::new(35);
        let (mut tangential, mut normal, mut count) = (0.0, 0.0, 0.0);
        for k in 0..4000u64 {
            let n = Rng::new(k + 7777).unit_vector();
            let p = Point::from(n * 40.0);
            let m = placed_landmark(&tree, &normals, &p, &n, 4.0, 1.0, &mut rng);
            let d = tree.distance(&m).unwrap();
            assert!((d - 4.0).abs() < 0.05, "{d}");
            let skin = m - m.coords.normalize() * 4.0;
            let off = skin - p;
            tangential += (off - n * off.dot(&n)).norm_squared();
            // Along the skin: the moved point is on the sphere (up to the facets' 0.03 mm).
            normal += (skin.coords.norm() - 40.0).powi(2);
            count += 1.0;
        }
        // SD per tangent direction; its standard error is about 0.008 here.
        let sd = (tangential / (2.0 * count)).sqrt();
        assert!((sd - 1.0).abs() < 0.04, "{sd}");
        assert!(
            (normal / count).sqrt() < 0.03,
            "{}",
            (normal / count).sqrt()
        );

        // On the data: the static trial's landmarks move, the truth does not, and the palm
        // markers stay where they were placed through the calibration trials.
        let opts = short(36, Preset::Clean);
        let exact = simulate_with(&opts, &clean_but(|_| {})).unwrap();
        let placed = simulate_with(&opts, &clean_but(|e| e.landmark_sd_mm = 1.0)).unwrap();
        assert_eq!(exact.truth, placed.truth);
        let (a, b) = (&exact.trials["reference"], &placed.trials["reference"]);
        let offsets: Vec<f64> = a
            .labels
            .iter()
            .map(|n| (a.get(n, 0).unwrap() - b.get(n, 0).unwrap()).norm())
            .collect();
        // |offset| of a 2-D Gaussian of SD 1: mean sqrt(pi/2) = 1.25.
        let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
        assert!((0.8..1.8).contains(&mean), "{mean}");
        for m in palm_markers() {
            let static_at = b.get(m, 0).unwrap();
            assert!((placed.trials["index"].get(m, 0).unwrap() - static_at).norm() < 1e-9);
        }
    }

    /// The optional fingertip markers join the static trial only, placed as the landmarks are
    /// (at the marker offset from the true skin, where the distal bone's line leaves it), and
    /// change nothing else: every other marker of every trial, and the truth, are the same.
    #[test]
    fn fingertip_markers_join_the_static_trial_and_change_nothing_else() {
        for body in [Body::Template, Body::Procedural] {
            let opts = SynthOptions {
                body,
                ..short(38, Preset::Typical)
            };
            let plain = simulate(&opts).unwrap();
            let tipped = simulate(&SynthOptions {
                tip_markers: true,
                ..opts.clone()
            })
            .unwrap();
            assert_eq!(plain.truth.joints, tipped.truth.joints);
            assert_eq!(plain.subject.dimensions, tipped.subject.dimensions);
            for (k, a) in &plain.trials {
                let b = &tipped.trials[k];
                for n in &a.labels {
                    assert_eq!(a.track(n), b.track(n), "{body:?} {k} {n}");
                }
                let extra: Vec<&String> =
                    b.labels.iter().filter(|n| !a.labels.contains(n)).collect();
                if k == "reference" {
                    assert_eq!(extra.len(), 5, "{body:?}");
                } else {
                    assert!(extra.is_empty(), "{body:?} {k}: {extra:?}");
                }
            }
            let tree = AabbTree::new(&tipped.true_skin);
            let sk = &tipped.true_skeleton;
            for f in Finger::ALL {
                let m = tipped.trials["reference"]
                    .mean_position(f.tip_marker(), 0..REFERENCE_FRAMES)
                    .unwrap();
                let d = tree.distance(&m).unwrap();
                assert!(
                    (d - opts.marker_offset_mm).abs() < 0.5,
                    "{body:?} {f:?}: {d:.2}"
                );
                // Beyond the bone's end, near its line (the lab's placement is a few mm off).
                let c = sk.centre(f.joints()[2]);
                let bone = sk.tips[f as usize] - c;
                let along = (m - c).dot(&bone.normalize());
                assert!(along > bone.norm(), "{body:?} {f:?}");
                let off = ((m - c) - bone.normalize() * along).norm();
                assert!(off < 6.0, "{body:?} {f:?}: {off:.1} mm off the line");
            }
        }
    }

    #[test]
    fn fingertip_markers_ride_the_grasp_trials_from_draws_of_their_own() {
        let opts = SynthOptions {
            motion_s: Some(2.0),
            ..short(39, Preset::Typical)
        };
        let plain = simulate(&opts).unwrap();
        let tipped = simulate(&SynthOptions {
            tip_markers: true,
            tip_markers_worn: true,
            ..opts.clone()
        })
        .unwrap();
        assert!(!plain.motions.is_empty());
        let sk = &tipped.true_skeleton;
        for (k, a) in &plain.motions {
            let b = &tipped.motions[k];
            for n in &a.trajectories.labels {
                assert_eq!(a.trajectories.track(n), b.trajectories.track(n), "{k} {n}");
            }
            assert_eq!(b.trajectories.labels.len(), a.trajectories.labels.len() + 5);
            for f in Finger::ALL {
                let n = f.tip_marker();
                assert_eq!(b.truth.marker_links[n], f.links()[2].name(), "{k} {n}");
                // On the distal phalanx: as far from the true DIP centre as in the static
                // trial, but for its slide over the bone (0.5 mm at most here) and the noise.
                let dip = f.joints()[2];
                let rest = (tipped.trials["reference"]
                    .mean_position(n, 0..REFERENCE_FRAMES)
                    .unwrap()
                    - sk.centre(dip))
                .norm();
                let track = b.trajectories.track(n).unwrap();
                let centres = &b.truth.joints[dip.name()].centre;
                let seen: Vec<f64> = track
                    .iter()
                    .zip(centres)
                    .filter_map(|(p, c)| p.map(|p| (p - Point::from(*c)).norm() - rest))
                    .collect();
                assert!(seen.len() > track.len() / 2, "{k} {n}: {} seen", seen.len());
                let worst = seen.iter().fold(0.0f64, |m, d| m.max(d.abs()));
                assert!(worst < 2.0, "{k} {n}: {worst:.2} mm off its rest distance");
            }
        }
    }

    #[test]
    fn shuffled_labels_read_back_by_name() {
        let opts = short(37, Preset::Typical);
        let ordered = Preset::Typical.error_model();
        let ordered = ErrorModel {
            shuffle_labels: false,
            ..ordered
        };
        let a = simulate_with(&opts, &ordered).unwrap();
        let b = simulate(&opts).unwrap();
        let mut reordered = 0;
        for (key, ta) in &a.trials {
            let tb = &b.trials[key];
            let mut la = ta.labels.clone();
            let mut lb = tb.labels.clone();
            reordered += usize::from(la != lb);
            la.sort();
            lb.sort();
            assert_eq!(la, lb, "{key}");
            for name in &ta.labels {
                assert_eq!(ta.track(name), tb.track(name), "{key} {name}");
            }
        }
        assert_eq!(reordered, a.trials.len(), "every trial reordered");
        // Through the files: the C3D reader finds every marker by its label.
        let dir = tempfile::tempdir().unwrap();
        write_subject(dir.path(), &b, true).unwrap();
        let subj = Subject::load(dir.path()).unwrap();
        for kind in [
            crate::mocap::subject::TrialKind::Reference,
            crate::mocap::subject::TrialKind::Wrist,
            crate::mocap::subject::TrialKind::Finger(Finger::Index),
        ] {
            let read = subj.load_trial(kind).unwrap();
            let mem = &a.trials[kind.key()];
            for name in &mem.labels {
                for f in (0..mem.n_frames()).step_by(13) {
                    let (x, y) = (mem.get(name, f), read.get(name, f));
                    match (x, y) {
                        (Some(x), Some(y)) => assert!((x - y).norm() < 1e-3, "{name} {f}"),
                        (x, y) => assert_eq!(x.is_some(), y.is_some(), "{name} {f}"),
                    }
                }
            }
        }
    }

    #[test]
    fn forearm_markers_sit_on_the_skin_or_on_its_continuation() {
        let wrist = crate::skeleton::JointFrame {
            centre: Point::origin(),
            frame: Rotation3::identity(),
        };
        let mut rng = Rng::new(38);
        // A skin that covers the whole forearm: every marker 4 mm off it.
        let big = crate::geometry::mesh::tests::icosphere(100.0, 4);
        let tree = AabbTree::new(&big);
        let defs = forearm_markers(&big, &wrist, Side::Right, 4.0, &mut rng, (0.4, 1.0));
        assert_eq!(defs.len(), 3);
        for d in &defs {
            assert!((tree.distance(&d.position).unwrap() - 4.0).abs() < 1e-9);
            assert!(d.position.y > 0.0 && d.position.z < -40.0, "{}", d.name);
        }
        // A skin cut 30 mm behind the wrist: the markers continue its last section.
        let small = crate::geometry::mesh::tests::icosphere(30.0, 5);
        let defs = forearm_markers(&small, &wrist, Side::Left, 4.0, &mut rng, (0.4, 1.0));
        let height = (30.0f64.powi(2) - 27.0f64.powi(2)).sqrt() + 4.0;
        for (d, (along, deg)) in defs.iter().zip(capture::ARM_STATIONS) {
            let p = d.position;
            assert!((p.z + along).abs() < 1e-9, "{}", d.name);
            let r = (p.x * p.x + p.y * p.y).sqrt();
            assert!((r - height).abs() < 0.2, "{}: {r} vs {height}", d.name);
            // Left hand: radial is -x.
            assert!(
                ((-p.x).atan2(p.y).to_degrees() - deg).abs() < 1e-6,
                "{}",
                d.name
            );
        }
    }

    /// A varied subject with the posture's draws of `seed`, the train_shape_prior.sh way: the
    /// template body (even seeds), the left hand when `seed / 2` is odd.
    fn varied(seed: u64) -> SynthOptions {
        SynthOptions {
            hand: if (seed / 2) % 2 == 1 {
                Side::Left
            } else {
                Side::Right
            },
            posture: Posture::Varied,
            ..short(seed, Preset::Typical)
        }
    }

    #[test]
    fn a_varied_posture_whose_fingers_cross_is_drawn_again() {
        // Seed 1026's first draw closes the middle and ring fingers onto each other: their bones
        // come within 2 mm, and the calipers measured a finger's breadth through its neighbour.
        let opts = varied(1026);
        let root = Rng::new(opts.seed);
        let template = load_template(opts.hand).unwrap();
        let first = draw_posture(&mut root.fork("posture"), opts.posture);
        let crossed = true_hand::template_body(&template, &root, first.clone()).unwrap();
        let (gap, _, _) = closest_neighbouring_fingers(&crossed.skeleton);
        assert!(
            gap < FINGER_BONE_CLEARANCE_MM,
            "the first draw is apart: {gap} mm"
        );

        let s = simulate(&opts).unwrap();
        let (gap, a, b) = closest_neighbouring_fingers(&s.true_skeleton);
        assert!(
            gap >= FINGER_BONE_CLEARANCE_MM,
            "{a:?}-{b:?} bones {gap} mm apart"
        );
        assert_ne!(
            s.truth.reference_posture_deg["M_MCP"],
            first.angles[Joint::MMcp.index()].map(|a| a.to_degrees())
        );
        for d in Dimension::all() {
            if !matches!(
                d,
                Dimension::BreadthProximal(_) | Dimension::BreadthDistal(_)
            ) {
                continue;
            }
            let (lo, hi) = d.plausible_range_mm();
            assert_eq!(lo, 8.0, "the toolkit's floor for a finger breadth");
            let (truth, measured) = (s.truth.dimensions[&d.name()], s.subject.dimensions[&d]);
            for v in [truth, measured] {
                assert!((lo..=hi).contains(&v), "{d}: {v} mm");
            }
        }
    }

    #[test]
    fn segments_are_as_far_apart_as_their_closest_points() {
        let p = |x: f64, y: f64, z: f64| Point::new(x, y, z);
        let d = |a: [Point; 2], b: [Point; 2]| segment_segment_distance(&a, &b);
        // Skew, closest points inside both.
        let skew = d(
            [p(-1.0, 0.0, 0.0), p(1.0, 0.0, 0.0)],
            [p(0.0, -1.0, 3.0), p(0.0, 1.0, 3.0)],
        );
        assert!((skew - 3.0).abs() < 1e-12, "{skew}");
        // Crossing.
        let crossing = d(
            [p(-1.0, 0.0, 0.0), p(1.0, 0.0, 0.0)],
            [p(0.0, -1.0, 0.0), p(0.0, 1.0, 0.0)],
        );
        assert!(crossing.abs() < 1e-12, "{crossing}");
        // Parallel, overlapping.
        let parallel = d(
            [p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0)],
            [p(1.0, 2.0, 0.0), p(3.0, 2.0, 0.0)],
        );
        assert!((parallel - 2.0).abs() < 1e-12, "{parallel}");
        // Beyond an end: the end to the other segment.
        let beyond = d(
            [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0)],
            [p(4.0, -1.0, 0.0), p(4.0, 1.0, 0.0)],
        );
        assert!((beyond - 3.0).abs() < 1e-12, "{beyond}");
        // A point.
        let point = d(
            [p(0.0, 5.0, 0.0), p(0.0, 5.0, 0.0)],
            [p(-1.0, 0.0, 0.0), p(1.0, 0.0, 0.0)],
        );
        assert!((point - 5.0).abs() < 1e-12, "{point}");
    }

    #[test]
    fn a_posture_whose_fingers_stay_apart_is_the_first_draw() {
        // Seed 1008 varied (template body, right hand) keeps its fingers apart; seed 1026 in the
        // template's posture too. Both keep the posture the first draw gave.
        for opts in [
            varied(1008),
            SynthOptions {
                posture: Posture::Template,
                ..varied(1026)
            },
        ] {
            let root = Rng::new(opts.seed);
            let template = load_template(opts.hand).unwrap();
            let first = draw_posture(&mut root.fork("posture"), opts.posture);
            let body = reference_body(&opts, &template, &root).unwrap();
            assert_eq!(body.posture, first, "seed {} {:?}", opts.seed, opts.posture);
            let built = true_hand::template_body(&template, &root, first).unwrap();
            assert_eq!(body.skin, built.skin);
            assert_eq!(body.skeleton, built.skeleton);
        }
    }

    #[test]
    fn presets_and_postures_parse() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>().unwrap(), p);
        }
        let e = "typcal".parse::<Preset>().unwrap_err();
        assert!(e.contains("typcal") && e.contains("small-rom"));
        assert!("varied".parse::<Posture>().is_ok());
    }
}
