//! `SCENE.toml`: a part, its pose, friction and mass, the hand and the grasp to try
//! (spec section 4, `ergohand grasp SCENE.toml --model OUT --out DIR`).
//!
//! ```toml
//! [part]
//! file = "bottle.stl"            # OBJ, STL, glTF/GLB; relative to this file's folder
//! units = "mm"                   # the file's length unit: mm, cm, m, in
//! translation_mm = [0, 0, 0]     # pose of the part in the world (optional, default identity)
//! rotation_deg = [0, 0, 0]       # fixed-axis x, then y, then z rotations, degrees (optional)
//! friction = 0.5                 # Coulomb coefficient between skin and part
//! mass_g = 350                   # grams
//!
//! [part.markers]                 # optional: motion-capture markers on the part (`PART_1`..
//! PART_1 = [0.0, 0.0, 204.0]     #   `PART_n`, three or more), mm, in the part file's frame,
//! PART_2 = [24.0, 0.0, 170.0]    #   whatever its `units`; a motion trial that carries them
//! PART_3 = [-14.0, 19.2, 170.0]  #   gives the part's pose frame by frame
//!
//! [hand]                         # optional table
//! model = "../out"               # a `reconstruct` output folder; omitted: the template hand
//! side = "right"                 # right | left (default right)
//!
//! [grasp]
//! type = "power"                 # power | precision | pinch | tripod | lateral
//! approach = "auto"              # or a table: the hand's grasp frame in the part's frame:
//! # approach = { translation_mm = [0, -55, 100], rotation_deg = [90, 0, 0] }
//! # slide_mm = 15                 # with a given approach (optional, default 0): the hand may
//! #                                #   slide along its palm up to this far either way, for
//! #                                #   the best grasp of its own size
//! seed = 1                       # placement search (approach = "auto"): seed,
//! candidates = 1000              #   number of candidate placements (tried in order until
//! #                                #   128 close on the part),
//! time_limit_s = 15              #   and a bound on its time
//! ```
//!
//! The hand's grasp frame ([`super::plan::grasp_frame`]) has its origin on the palm
//! surface, z out of the palm (palmar), y toward the fingers. Unknown keys are errors; every
//! error names the file and the key.

use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::io::Units;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Grasp taxonomy entries supported (after Feix et al. 2016, "The GRASP taxonomy").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GraspType {
    /// Whole-hand wrap: all fingers and the thumb close around the part.
    Power,
    /// Fingertips of the thumb and the four fingers.
    Precision,
    /// Thumb and index fingertips.
    Pinch,
    /// Thumb, index and middle fingertips.
    Tripod,
    /// Thumb pad against the side of the curled index.
    Lateral,
}

impl GraspType {
    /// Lower-case name as in scene files.
    pub fn name(self) -> &'static str {
        match self {
            GraspType::Power => "power",
            GraspType::Precision => "precision",
            GraspType::Pinch => "pinch",
            GraspType::Tripod => "tripod",
            GraspType::Lateral => "lateral",
        }
    }

    /// Parse a scene file's name.
    pub fn from_name(s: &str) -> Option<GraspType> {
        [
            GraspType::Power,
            GraspType::Precision,
            GraspType::Pinch,
            GraspType::Tripod,
            GraspType::Lateral,
        ]
        .into_iter()
        .find(|g| g.name() == s)
    }
}

/// Where the hand starts.
#[derive(Clone, Debug, PartialEq)]
pub enum Approach {
    /// Placement search.
    Auto,
    /// The grasp frame of the hand in the part's frame.
    Given(Isometry3<f64>),
}

/// A parsed scene, paths resolved, lengths in mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// The part's mesh file.
    pub part_file: PathBuf,
    /// Its unit.
    pub part_units: Units,
    /// Pose of the part in the world.
    pub part_pose: Isometry3<f64>,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Mass, kg.
    pub mass_kg: f64,
    /// A `reconstruct` output folder, or `None` for the template hand.
    pub hand_model: Option<PathBuf>,
    /// Which hand.
    pub side: Side,
    /// Grasp type.
    pub grasp: GraspType,
    /// Approach.
    pub approach: Approach,
    /// How far a given approach may slide along the palm (the grasp frame's y) either way,
    /// mm: each hand is closed at several positions and its best kept
    /// ([`super::placement::slide_search`]); 0 keeps the approach as given.
    pub slide_mm: f64,
    /// Placement search seed.
    pub seed: u64,
    /// Placement search candidates.
    pub candidates: usize,
    /// Placement search time bound, s.
    pub time_limit_s: f64,
    /// `[part.markers]`: marker name (`PART_<n>`) -> position in the part file's frame, mm;
    /// empty when the scene names none.
    pub part_markers: BTreeMap<String, Point>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    part: RawPart,
    hand: Option<RawHand>,
    grasp: RawGrasp,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPart {
    file: String,
    units: String,
    translation_mm: Option<[f64; 3]>,
    rotation_deg: Option<[f64; 3]>,
    friction: f64,
    mass_g: f64,
    #[serde(default)]
    markers: BTreeMap<String, [f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHand {
    model: Option<String>,
    side: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGrasp {
    #[serde(rename = "type")]
    kind: String,
    approach: toml::Value,
    slide_mm: Option<f64>,
    seed: Option<u64>,
    candidates: Option<usize>,
    time_limit_s: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPose {
    translation_mm: [f64; 3],
    rotation_deg: Option<[f64; 3]>,
}

/// Rigid pose from a translation (mm) and fixed-axis x-y-z rotations (degrees):
/// `R = Rz · Ry · Rx`.
pub fn pose_from(translation_mm: [f64; 3], rotation_deg: [f64; 3]) -> Isometry3<f64> {
    let r = rotation_deg.map(f64::to_radians);
    Isometry3::from_parts(
        Translation3::new(translation_mm[0], translation_mm[1], translation_mm[2]),
        UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
    )
}

fn finite(path: &Path, key: &str, v: &[f64]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::input(
            path,
            format!("'{key}' must be finite numbers"),
        ))
    }
}

/// Largest `grasp.slide_mm`: beyond it the slide is no longer the same approach (a palm is
/// about 100 mm long).
pub const MAX_SLIDE_MM: f64 = 50.0;

/// Read and check a scene file.
pub fn read_scene(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_scene(&text, path)
}

/// Parse scene `text` read from `path` (relative paths resolve against its folder).
pub(crate) fn parse_scene(text: &str, path: &Path) -> Result<Scene> {
    let raw: RawScene = toml::from_str(text).map_err(|e| Error::toml(path, text, &e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let p = &raw.part;
    let part_units: Units = p
        .units
        .parse()
        .map_err(|e: String| Error::input(path, format!("part.units: {e}")))?;
    let t = p.translation_mm.unwrap_or([0.0; 3]);
    let r = p.rotation_deg.unwrap_or([0.0; 3]);
    finite(path, "part.translation_mm", &t)?;
    finite(path, "part.rotation_deg", &r)?;
    if !(p.friction.is_finite() && p.friction >= 0.0 && p.friction <= 5.0) {
        return Err(Error::input(
            path,
            format!("part.friction = {} must be in [0, 5]", p.friction),
        ));
    }
    if !(p.mass_g.is_finite() && p.mass_g > 0.0 && p.mass_g <= 1e6) {
        return Err(Error::input(
            path,
            format!(
                "part.mass_g = {} must be a positive mass in grams",
                p.mass_g
            ),
        ));
    }
    if p.file.is_empty() {
        return Err(Error::input(
            path,
            "part.file is empty; name the part's mesh file",
        ));
    }
    let (hand_model, side) = match &raw.hand {
        None => (None, Side::Right),
        Some(h) => {
            let side = match h.side.as_deref() {
                None | Some("right") => Side::Right,
                Some("left") => Side::Left,
                Some(s) => {
                    return Err(Error::input(
                        path,
                        format!("hand.side = '{s}' is not 'right' or 'left'"),
                    ))
                }
            };
            (h.model.as_ref().map(|m| dir.join(m)), side)
        }
    };
    let g = &raw.grasp;
    let grasp = GraspType::from_name(&g.kind).ok_or_else(|| {
        Error::input(
            path,
            format!(
                "grasp.type = '{}' is unknown; use power, precision, pinch, tripod or lateral",
                g.kind
            ),
        )
    })?;
    let approach = match &g.approach {
        toml::Value::String(s) if s == "auto" => Approach::Auto,
        toml::Value::Table(_) => {
            let rp: RawPose = g
                .approach
                .clone()
                .try_into()
                .map_err(|e: toml::de::Error| {
                    Error::input(path, format!("grasp.approach: {}", e.message().replace('\n', " ")))
                })?;
            let rot = rp.rotation_deg.unwrap_or([0.0; 3]);
            finite(path, "grasp.approach.translation_mm", &rp.translation_mm)?;
            finite(path, "grasp.approach.rotation_deg", &rot)?;
            Approach::Given(pose_from(rp.translation_mm, rot))
        }
        _ => {
            return Err(Error::input(
                path,
                "grasp.approach must be \"auto\" or a table { translation_mm = [..], rotation_deg = [..] }",
            ))
        }
    };
    let slide_mm = g.slide_mm.unwrap_or(0.0);
    if !(0.0..=MAX_SLIDE_MM).contains(&slide_mm) {
        return Err(Error::input(
            path,
            format!("grasp.slide_mm must be a distance in mm from 0 to {MAX_SLIDE_MM}"),
        ));
    }
    if slide_mm > 0.0 && approach == Approach::Auto {
        return Err(Error::input(
            path,
            "grasp.slide_mm moves a given approach; with approach = \"auto\" the placement search places the hand, so remove slide_mm",
        ));
    }
    let candidates = g.candidates.unwrap_or(1000);
    if !(1..=1_000_000).contains(&candidates) {
        return Err(Error::input(
            path,
            "grasp.candidates must be in 1..=1000000",
        ));
    }
    let part_markers = part_markers(path, &p.markers)?;
    let time_limit_s = g.time_limit_s.unwrap_or(15.0);
    if !(time_limit_s.is_finite() && time_limit_s > 0.0) {
        return Err(Error::input(
            path,
            "grasp.time_limit_s must be a positive number of seconds",
        ));
    }
    Ok(Scene {
        path: path.to_path_buf(),
        part_file: dir.join(&p.file),
        part_units,
        part_pose: pose_from(t, r),
        friction: p.friction,
        mass_kg: p.mass_g / 1000.0,
        hand_model,
        side,
        grasp,
        approach,
        slide_mm,
        seed: g.seed.unwrap_or(1),
        candidates,
        time_limit_s,
        part_markers,
    })
}

/// Check `[part.markers]`: names `PART_<n>` (n >= 1), finite positions, none or at least three
/// (a rigid body's pose needs three), not all on one line.
fn part_markers(path: &Path, raw: &BTreeMap<String, [f64; 3]>) -> Result<BTreeMap<String, Point>> {
    let mut out = BTreeMap::new();
    for (name, v) in raw {
        let numbered = name
            .strip_prefix("PART_")
            .and_then(|n| n.parse::<u32>().ok())
            .is_some_and(|n| n >= 1 && name == &format!("PART_{n}"));
        if !numbered {
            return Err(Error::input(
                path,
                format!("part.markers: '{name}' is not named PART_1, PART_2, ..."),
            ));
        }
        finite(path, &format!("part.markers.{name}"), v)?;
        out.insert(name.clone(), Point::new(v[0], v[1], v[2]));
    }
    if !out.is_empty() && out.len() < 3 {
        return Err(Error::input(
            path,
            format!(
                "part.markers: {} marker(s); a part's pose needs three or more",
                out.len()
            ),
        ));
    }
    let pts: Vec<Point> = out.values().copied().collect();
    let n = pts.len();
    let off_a_line = (0..n).any(|i| {
        (i + 1..n)
            .any(|j| (j + 1..n).any(|k| (pts[j] - pts[i]).cross(&(pts[k] - pts[i])).norm() > 1.0))
    });
    if n >= 3 && !off_a_line {
        return Err(Error::input(
            path,
            "part.markers: the markers lie on one line; a part's pose needs three off a line",
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const OK: &str = r#"
[part]
file = "bottle.stl"
units = "mm"
friction = 0.5
mass_g = 350
[grasp]
type = "power"
approach = { translation_mm = [0, -50, 100], rotation_deg = [90, 0, 0] }
"#;

    #[test]
    fn parses_and_resolves_relative_paths() {
        let s = parse_scene(OK, Path::new("/a/b/s.toml")).unwrap();
        assert_eq!(s.part_file, PathBuf::from("/a/b/bottle.stl"));
        assert_eq!(s.grasp, GraspType::Power);
        assert!((s.mass_kg - 0.35).abs() < 1e-12);
        match s.approach {
            Approach::Given(iso) => {
                assert!((iso.translation.vector.y + 50.0).abs() < 1e-12);
                // Rx(90 deg) maps y to z.
                let y = iso.rotation * nalgebra::Vector3::y();
                assert!((y - nalgebra::Vector3::z()).norm() < 1e-12);
            }
            Approach::Auto => panic!("given approach read as auto"),
        }
    }

    /// A given approach keeps its place unless the scene lets it slide.
    #[test]
    fn slide_is_optional_and_read_in_mm() {
        let p = Path::new("s.toml");
        assert_eq!(parse_scene(OK, p).unwrap().slide_mm, 0.0);
        let s = parse_scene(&(OK.to_string() + "slide_mm = 12.5\n"), p).unwrap();
        assert_eq!(s.slide_mm, 12.5);
    }

    #[test]
    fn part_markers_are_optional_and_checked() {
        let p = Path::new("s.toml");
        assert!(parse_scene(OK, p).unwrap().part_markers.is_empty());
        let with = OK.replace(
            "mass_g = 350\n",
            "mass_g = 350\n[part.markers]\nPART_1 = [0, 30, 180]\nPART_2 = [26, -15, 180]\nPART_3 = [-26.5, -15, 180]\n",
        );
        let s = parse_scene(&with, p).unwrap();
        assert_eq!(s.part_markers.len(), 3);
        assert_eq!(s.part_markers["PART_3"], Point::new(-26.5, -15.0, 180.0));
        for (bad, key) in [
            (with.replace("PART_3 = [-26.5, -15, 180]\n", ""), "three"),
            (with.replace("PART_3", "MARK_3"), "MARK_3"),
            (with.replace("PART_3", "PART_03"), "PART_03"),
            (
                with.replace("[-26.5, -15, 180]", "[-26.5, -15]"),
                "length 3",
            ),
            (
                with.replace("[-26.5, -15, 180]", "[-26, 75, 180]"),
                "one line",
            ),
            (with.replace("[-26.5, -15, 180]", "[nan, 1, 1]"), "PART_3"),
        ] {
            let e = parse_scene(&bad, p).unwrap_err().to_string();
            assert!(e.contains("s.toml") && e.contains(key), "{key}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn errors_name_file_and_key() {
        let p = Path::new("s.toml");
        let cases = [
            (OK.replace("\"power\"", "\"hook\""), "grasp.type"),
            (OK.replace("mass_g = 350", "mass_g = -1"), "part.mass_g"),
            (
                OK.replace("friction = 0.5", "friction = 0.5\ncolour = 1"),
                "colour",
            ),
            (
                OK.replace("units = \"mm\"", "units = \"furlong\""),
                "part.units",
            ),
            (
                OK.replace("rotation_deg = [90, 0, 0] }", "rot = [90, 0, 0] }"),
                "grasp.approach",
            ),
            (
                OK.replace("{ translation_mm", "{ t")
                    .replace(", rotation_deg = [90, 0, 0]", ""),
                "grasp.approach",
            ),
            (
                OK.replace("approach = {", "approach = 3 #"),
                "grasp.approach",
            ),
            (OK.to_string() + "slide_mm = -5\n", "grasp.slide_mm"),
            (OK.to_string() + "slide_mm = 80\n", "grasp.slide_mm"),
            (OK.to_string() + "slide_mm = nan\n", "grasp.slide_mm"),
            (
                OK.replace(
                    "approach = { translation_mm = [0, -50, 100], rotation_deg = [90, 0, 0] }",
                    "approach = \"auto\"\nslide_mm = 10",
                ),
                "grasp.slide_mm",
            ),
        ];
        for (text, key) in cases {
            let e = parse_scene(&text, p).unwrap_err().to_string();
            assert!(e.contains("s.toml") && e.contains(key), "{key}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
