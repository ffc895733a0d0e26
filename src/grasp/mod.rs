//! Grasp and contact checks of a posed hand on a CAD part (spec section 4, `grasp`).
//!
//! A scene ([`scene`]) names a part, its pose, friction and mass, a hand and a grasp type.
//! [`autograsp`] closes the hand on the part from an approach pose (GraspIt's autograsp,
//! Miller & Allen 2004) or searches placements; [`contact`] measures contacts per link with
//! parry queries; [`quality`] computes force closure and the Ferrari-Canny epsilon and volume
//! qualities (Ferrari & Canny 1992); [`hold`] checks in rapier that the part stays in the hand
//! under gravity from six directions. [`run_scene`] runs a scene; the `grasp` command
//! (`ergohand grasp`) writes its `grasp.json`, `grasp.glb` (posed hand and part, contact
//! map as `COLOR_0`) and `contact_map.png`.

pub mod autograsp;
pub mod ball_mesh;
pub mod broad;
pub mod collide;
pub mod contact;
pub mod hand;
pub mod hold;
pub mod parts;
pub mod placement;
pub mod plan;
pub mod population;
pub mod quality;
pub mod scene;

pub use hand::{PosableHand, RigidHand, SkinnedHand};

use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use crate::io::Units;
use autograsp::{autograsp, root_for, AutograspOptions};
use contact::{contacts, vertex_areas, ContactOptions, ContactSet, PartShape};
use nalgebra::Isometry3;
use plan::grasp_plan_for;
use scene::{Approach, Scene};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Read a part mesh in its unit (by extension: `.obj`, `.stl`, `.gltf`/`.glb`), in mm.
pub(crate) fn read_part(path: &Path, units: Units) -> Result<TriMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "obj" => crate::io::obj::read_obj(path, units),
        "stl" => crate::io::stl::read_stl(path, units),
        "gltf" | "glb" => {
            let s = crate::io::gltf::read_gltf(path, units)?;
            let mut v = Vec::new();
            let mut f = Vec::new();
            for m in s.meshes {
                let o = v.len();
                v.extend(m.mesh.vertices);
                f.extend(m.mesh.faces.iter().map(|t| [t[0] + o, t[1] + o, t[2] + o]));
            }
            TriMesh::new(v, f).map_err(|e| e.in_file(path))
        }
        _ => Err(Error::input(
            path,
            "part file type unknown; use .obj, .stl, .gltf or .glb",
        )),
    }
}

/// The hand of a `reconstruct` output folder (`skin.obj` and `link_model.json`, read by the
/// pose stage, template weights), posed by linear blend skinning; `None`: the template of
/// `side` as an individual hand.
pub fn load_hand(model: Option<&Path>, side: crate::anatomy::Side) -> Result<SkinnedHand> {
    match model {
        None => SkinnedHand::template(side),
        Some(dir) => SkinnedHand::load(dir),
    }
}

/// One evaluation of a grasp (the speed goal): `hand` posed in `pose` into `posed` (a
/// reused buffer), its contacts with `part` ([`contacts`], default options, `areas` from
/// [`vertex_areas`]) and their force closure and Ferrari-Canny epsilon with friction `mu`
/// ([`quality::grasp_epsilon`], torques over the part's maximum radius; the volume quality,
/// which needs the whole hull, is left to the report).
pub fn evaluate(
    hand: &dyn PosableHand,
    part: &PartShape,
    pose: &crate::skeleton::Pose,
    mu: f64,
    areas: &[f64],
    posed: &mut Vec<Point>,
) -> (ContactSet, quality::Epsilon) {
    hand.pose_vertices(pose, posed);
    let cs = contacts(
        part,
        posed,
        hand.vertex_link(),
        areas,
        &ContactOptions::default(),
    );
    let q = quality::grasp_epsilon(&cs.contacts, mu, &part.centre_of_mass, part.max_radius);
    (cs, q)
}

/// `grasp.json`.
#[derive(Clone, Debug, Serialize)]
pub struct GraspReport {
    /// The scene file.
    pub scene: String,
    /// Grasp type.
    pub grasp_type: String,
    /// Approach used: the grasp frame in the world, `translation_mm` and `rotation_matrix` rows.
    pub approach: BTreeMap<String, Vec<[f64; 3]>>,
    /// Joint angles, degrees `[flexion, abduction, axial]`, by joint name.
    pub pose_deg: BTreeMap<String, [f64; 3]>,
    /// Force closure (L1 GWS, 8-edge cones).
    pub force_closure: bool,
    /// Ferrari-Canny epsilon.
    pub epsilon: f64,
    /// Volume of the grasp wrench space (its whole 6-D hull); `None` (`null`) where it was not
    /// asked for: a population run ([`run_scene_on`]) leaves it out, as its summary does not
    /// use it and the whole hull costs more than many a hold test.
    pub volume: Option<f64>,
    /// Whether the rapier hold test held in all six gravity directions.
    pub holds: bool,
    /// The hold test per direction.
    pub hold_test: hold::HoldReport,
    /// Point contacts (patches).
    pub contacts: Vec<contact::Contact>,
    /// Contact area per link, mm².
    pub contact_area_mm2: BTreeMap<String, f64>,
    /// Contact area per finger and palm, mm².
    pub contact_area_by_finger_mm2: BTreeMap<String, f64>,
    /// Total contact area, mm².
    pub total_contact_area_mm2: f64,
    /// How the contacts envelop the part: the palm touching, the fingers wrapped with all
    /// three phalanges, and whether that makes a wrap ([`contact::Envelope`]).
    pub envelope: contact::Envelope,
    /// Deepest skin penetration, mm.
    pub max_penetration_mm: f64,
    /// How the part's centre of mass moved while the squeeze settled it in the hold test
    /// (`hold_test.settle_mm` is its length), along the posed hand's directions
    /// ([`crate::skeleton::Skeleton::hand_directions`]), mm: `dorsal` (into the palm when
    /// positive, away from it when negative), `radial` (toward the thumb's side) and `distal`
    /// (toward the fingertips). It shows where a squeeze whose forces do not balance pushes the
    /// part: out of a grip that does not oppose it there.
    pub settle_by_direction_mm: BTreeMap<String, f64>,
    /// Wrist travel from the approach until the palm touched (power grasps), mm
    /// ([`autograsp::approach_to_contact`]).
    pub approach_to_contact_mm: f64,
    /// The squeeze after contact ([`autograsp::squeeze`]): the posture measured and tested is
    /// the squeezed one.
    pub squeeze: autograsp::Squeeze,
    /// Placements of the search closed and hold-tested: its best, then its runners-up and its
    /// reserves ([`placement::PlacementResult::reserves`]) while the hold test failed; likewise
    /// the positions of a given approach that slides (`grasp.slide_mm`); 0 for a given approach
    /// that does not.
    pub placement_tries: usize,
    /// How far the hand slid along its palm from the given approach, mm (toward the fingers
    /// when positive; only with `grasp.slide_mm`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub approach_slide_mm: Option<f64>,
    /// Active joints whose link never touched.
    pub untouched_joints: Vec<String>,
    /// Closing links stopped by another finger (finger-finger collision) before the part.
    pub finger_collisions: Vec<autograsp::FingerCollision>,
    /// Deepest entry of a finger's skin into another finger's core in the final posture, mm
    /// ([`collide::finger_entry`]; 0: no finger passes into another).
    pub finger_core_entry_mm: f64,
    /// Part facts.
    pub part: PartInfo,
    /// Warnings.
    pub warnings: Vec<String>,
    /// Time of each step, s.
    pub timings_s: Timings,
}

/// Part facts in `grasp.json`.
#[derive(Clone, Debug, Serialize)]
pub struct PartInfo {
    /// The mesh file.
    pub file: String,
    /// Triangles.
    pub triangles: usize,
    /// Closed 2-manifold (inside tests on).
    pub closed: bool,
    /// Centre of mass, mm (world).
    pub centre_of_mass_mm: [f64; 3],
    /// Torque scale, mm.
    pub max_radius_mm: f64,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Friction coefficient.
    pub friction: f64,
}

/// Wall-clock seconds of each step of [`run_scene`].
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timings {
    /// Reading the part and building its query structures.
    pub part_s: f64,
    /// Placement search (0 for a given approach), with the closing and hold test of its
    /// finalists rejected by the hold test.
    pub search_s: f64,
    /// The autograsp from the approach.
    pub autograsp_s: f64,
    /// Contacts, grasp quality and the finger-finger check of the final posture.
    pub evaluate_s: f64,
    /// The rapier hold test (the first try's volume quality, a whole hull, is built beside it).
    pub hold_s: f64,
    /// The whole scene (with the contact map distances), s.
    pub total_s: f64,
}

/// Everything computed for one scene, before writing.
pub struct GraspOutcome {
    /// The report.
    pub report: GraspReport,
    /// Posed skin.
    pub hand_mesh: TriMesh,
    /// Contact set of the final posture.
    pub contacts: ContactSet,
    /// Per skin vertex, signed distance to the part, mm (negative inside a closed part), at
    /// any distance: the contact map shows it up to [`COLOUR_RANGE_MM`] and `grasp.glb`
    /// carries it. `None` where no distance could be found (not for a non-empty part).
    pub colour_distance: Vec<Option<f64>>,
    /// Part in the world.
    pub part_mesh: TriMesh,
    /// The posed hand's wrist centre and its dorsal, radial and distal directions in the world
    /// ([`crate::skeleton::Skeleton::hand_directions`] carried by the palm).
    pub hand_frame: (Point, [crate::geometry::Vec3; 3]),
}

/// Distances shown by the contact map's colour ramp, mm.
pub(crate) const COLOUR_RANGE_MM: f64 = 10.0;

/// One grasp of a scene from one approach: closed, squeezed, measured and hold-tested.
struct Attempt {
    approach: nalgebra::Isometry3<f64>,
    g: autograsp::Autograsp,
    pose: crate::skeleton::Pose,
    squeezed: autograsp::Squeeze,
    cs: ContactSet,
    q: quality::Epsilon,
    hand_mesh: TriMesh,
    finger_entry: f64,
    hold: hold::HoldReport,
    /// The volume quality of the grasp wrench space (`None` until a runner-up is kept).
    volume: Option<f64>,
    timings: Timings,
}

/// Close `hand` on `part` from `approach` (the grasp frame in the world): [`autograsp`], the
/// [`autograsp::squeeze`] (or the `closing` already made from there with the default
/// options), [`evaluate`], the finger-finger check and the hold test, run as
/// `run` says; the volume quality beside the hold test with `volume` (given up when a
/// [`hold::HoldRun::UntilDrop`] test drops, the try then not kept), else left to the caller.
#[allow(clippy::too_many_arguments)]
fn grasp_from(
    scene: &Scene,
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &plan::GraspPlan,
    approach: &nalgebra::Isometry3<f64>,
    closing: Option<autograsp::Closing>,
    areas: &[f64],
    run: hold::HoldRun,
    volume: bool,
) -> Result<Attempt> {
    let mut timings = Timings::default();
    let clock = std::time::Instant::now();
    let (g, pose, squeezed) = match closing {
        Some(c) => (c.autograsp, c.pose, c.squeeze),
        None => {
            let root = root_for(hand, &nalgebra::Isometry3::identity(), approach);
            let opts = AutograspOptions::default();
            let g = autograsp(hand, part, plan, root, &opts).map_err(|e| e.in_file(&scene.path))?;
            let (pose, _, squeezed) = autograsp::squeeze(hand, part, plan, &g, &opts);
            (g, pose, squeezed)
        }
    };
    timings.autograsp_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();
    let mut pts = Vec::new();
    let (cs, q) = evaluate(hand, part, &pose, scene.friction, areas, &mut pts);
    let hand_mesh = TriMesh {
        vertices: pts,
        faces: hand.rest_mesh().faces.clone(),
    };
    let finger_entry = collide::finger_entry(
        hand,
        &hand_mesh.vertices,
        &crate::skeleton::forward_kinematics::link_transforms(hand.skeleton(), &pose),
    );
    timings.evaluate_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();
    // The volume quality needs the whole hull of the grasp wrench space (up to a second on one
    // core), which nothing else waits for: it is built beside the hold test, and given up as
    // soon as a hold test that stops at the first drop has dropped (the try is not kept).
    let hold_test = || {
        hold::hold_test_hand(
            hand,
            &hand_mesh.vertices,
            part,
            scene.mass_kg,
            scene.friction,
            run,
        )
    };
    let (hold, volume) = if volume {
        let unwanted = std::sync::atomic::AtomicBool::new(false);
        rayon::join(
            || {
                let h = hold_test();
                if run == hold::HoldRun::UntilDrop && !h.as_ref().is_ok_and(|h| h.holds) {
                    unwanted.store(true, std::sync::atomic::Ordering::Relaxed);
                }
                h
            },
            || {
                quality::grasp_volume_unless(
                    &cs.contacts,
                    scene.friction,
                    &part.centre_of_mass,
                    part.max_radius,
                    &unwanted,
                )
            },
        )
    } else {
        (hold_test(), None)
    };
    let hold = hold?;
    timings.hold_s = clock.elapsed().as_secs_f64();
    Ok(Attempt {
        approach: *approach,
        g,
        pose,
        squeezed,
        cs,
        q,
        hand_mesh,
        finger_entry,
        hold,
        volume,
        timings,
    })
}

/// The part of `scene` placed by `pose` (the scene's `part_pose` for a grasp, the identity for
/// the part's own frame), cleaned of duplicate and degenerate triangles and ready for queries,
/// with its warnings (cleaning, open mesh, size against a hand), each naming the scene and the
/// part's file.
pub fn scene_part(scene: &Scene, pose: &Isometry3<f64>) -> Result<(PartShape, Vec<String>)> {
    scene_part_with_band(scene, pose, contact::GRID_BAND_MM)
}

/// [`scene_part`] with the broad phase's band `band_mm` ([`PartShape::with_band`]).
pub fn scene_part_with_band(
    scene: &Scene,
    pose: &Isometry3<f64>,
    band_mm: f64,
) -> Result<(PartShape, Vec<String>)> {
    let read = read_part(&scene.part_file, scene.part_units)?.transformed(pose);
    // Duplicate and degenerate triangles out before anything else sees the part.
    let (mesh, cleaning) = parts::clean_part(&read);
    let (part, mut warnings) =
        PartShape::with_band(mesh, band_mm).map_err(|e| e.in_file(&scene.part_file))?;
    if cleaning.changed() {
        warnings.insert(0, cleaning.describe());
    }
    for w in warnings.iter_mut() {
        *w = format!(
            "{}: part.file = {}: {w}",
            scene.path.display(),
            scene.part_file.display()
        );
    }
    Ok((part, warnings))
}

/// Evaluate a scene with `hand` (as `ergohand grasp` does); the part's warnings (open mesh,
/// size against a hand) are logged as soon as the part is read, and kept in the report.
pub fn run_scene(scene: &Scene, hand: &dyn PosableHand) -> Result<GraspOutcome> {
    let clock = std::time::Instant::now();
    let (part, warnings) = scene_part(scene, &scene.part_pose)?;
    // Shown now, not with the results: a part in the wrong units usually ends the scene with
    // an error (the hand starts inside it), and the warning is what explains it.
    for w in &warnings {
        log::warn!("{w}");
    }
    let part_s = clock.elapsed().as_secs_f64();
    let mut o = run_scene_on(scene, hand, &part, &warnings, true)?;
    o.report.timings_s.part_s = part_s;
    o.report.timings_s.total_s += part_s;
    Ok(o)
}

/// [`run_scene`] on the scene's part as [`scene_part`] made it (`part_warnings`: its warnings,
/// kept in the report), so that many hands share one part: it is read, cleaned and indexed
/// once. `with_volume`: whether to build the grasp wrench space's whole hull for
/// [`GraspReport::volume`] (`None` without).
pub fn run_scene_on(
    scene: &Scene,
    hand: &dyn PosableHand,
    part: &PartShape,
    part_warnings: &[String],
    with_volume: bool,
) -> Result<GraspOutcome> {
    let mut timings = Timings::default();
    let started = std::time::Instant::now();
    let mut warnings = part_warnings.to_vec();
    let plan = grasp_plan_for(scene.grasp, hand);
    let clock = std::time::Instant::now();
    // Each approach with its slide along the palm (given approaches that may slide) and, for
    // the search's finalists, the closing it already made from there.
    let approaches: Vec<(Option<f64>, Isometry3<f64>, Option<autograsp::Closing>)> = match &scene
        .approach
    {
        Approach::Given(a) if scene.slide_mm > 0.0 => {
            let given = scene.part_pose * a;
            let ranked =
                placement::slide_search(hand, part, &plan, scene.friction, &given, scene.slide_mm);
            if ranked.is_empty() {
                // Every position starts inside the part: the given one says so.
                vec![(Some(0.0), given, None)]
            } else {
                ranked
                    .into_iter()
                    .map(|(o, a, c)| (Some(o), a, Some(c)))
                    .collect()
            }
        }
        Approach::Given(a) => vec![(None, scene.part_pose * a, None)],
        Approach::Auto => {
            let r = placement::placement_search(
                hand,
                part,
                &plan,
                scene.friction,
                scene.seed,
                scene.candidates,
                scene.time_limit_s,
            )
            .ok_or_else(|| {
                // A key pinch opens only so far: say so when the part cannot fit.
                let opening = autograsp::press_travel(hand, &plan)
                    .map(|t| {
                        format!(
                            " (a {} grasp opens its thumb pad {:.0} mm from the index's side; a thicker part does not fit)",
                            scene.grasp.name(),
                            t.norm()
                        )
                    })
                    .unwrap_or_default();
                Error::input(
                    &scene.path,
                    format!("grasp.approach = \"auto\": no placement closed the hand on the part{opening}; give an approach"),
                )
            })?;
            std::iter::once((r.approach, Some(r.closing)))
                .chain(r.runners_up.into_iter().map(|(a, c)| (a, Some(c))))
                .chain(r.reserves.into_iter().map(|a| (a, None)))
                .map(|(a, c)| (None, a, c))
                .collect()
        }
    };
    timings.search_s = clock.elapsed().as_secs_f64();
    let areas = vertex_areas(hand.rest_mesh());
    // The search's best first; when it does not hold in rapier, its runners-up in turn (the
    // search ranks by quality, which is blind to how the squeezed part settles), keeping the
    // first that holds, or the best when none does.
    // (its slide along the palm, the attempt)
    let mut tried: Vec<(Option<f64>, Attempt)> = Vec::new();
    for (k, (slide, approach, closing)) in approaches.into_iter().enumerate() {
        // The best is reported whether it holds or not; a runner-up only when it holds, so its
        // hold test may stop at the first drop.
        let run = if k == 0 {
            hold::HoldRun::Whole
        } else {
            hold::HoldRun::UntilDrop
        };
        // Each try's volume is built beside its hold test: the first is reported whether it
        // holds or not, a runner-up's hull is given up when it drops.
        let attempt = grasp_from(
            scene,
            hand,
            part,
            &plan,
            &approach,
            closing,
            &areas,
            run,
            with_volume,
        );
        let attempt = match attempt {
            Ok(a) => a,
            Err(e) if k == 0 => return Err(e),
            Err(_) => continue,
        };
        let holds = attempt.hold.holds;
        log::debug!(
            "hold test of try {k}: {:?}",
            attempt
                .hold
                .trials
                .iter()
                .map(|t| (
                    t.gravity_dir,
                    (t.displacement_mm * 100.0).round() / 100.0,
                    t.holds
                ))
                .collect::<Vec<_>>()
        );
        tried.push((slide, attempt));
        if holds {
            break;
        }
    }
    let pick = tried.iter().position(|(_, a)| a.hold.holds).unwrap_or(0);
    let placement_tries = if scene.slide_mm > 0.0 || scene.approach == Approach::Auto {
        tried.len()
    } else {
        0
    };
    for (k, (_, a)) in tried.iter().enumerate() {
        if k != pick {
            timings.search_s += a.timings.autograsp_s + a.timings.evaluate_s + a.timings.hold_s;
        }
    }
    let (
        approach_slide_mm,
        Attempt {
            approach,
            g,
            pose,
            squeezed,
            cs,
            q,
            hand_mesh,
            finger_entry,
            hold: ht,
            volume,
            timings: own,
        },
    ) = tried.swap_remove(pick);
    timings.autograsp_s = own.autograsp_s;
    timings.evaluate_s = own.evaluate_s;
    timings.hold_s = own.hold_s;
    // The kept try's volume was built beside its hold test: it is the first (whose hull is
    // never given up) or a runner-up that held.
    let dry: Vec<&str> = plan
        .pads
        .iter()
        .filter(|l| !cs.touches(l.index()))
        .map(|l| l.name())
        .collect();
    if !dry.is_empty() {
        warnings.push(format!(
            "{}: grasp.type = {}: the pads {} do not touch the part, so it is not held as a {} grasp",
            scene.path.display(),
            scene.grasp.name(),
            dry.join(", "),
            scene.grasp.name()
        ));
    }
    let colour_distance = contact::vertex_distances(part, &hand_mesh.vertices, f64::INFINITY)
        .into_iter()
        .map(|r| r.map(|x| x.0))
        .collect();
    let r = approach.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = approach.translation.vector;
    let mut approach_map = BTreeMap::new();
    approach_map.insert("translation_mm".to_string(), vec![[t.x, t.y, t.z]]);
    approach_map.insert(
        "rotation_matrix".to_string(),
        (0..3).map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]).collect(),
    );
    let pose_deg = Joint::ALL
        .iter()
        .map(|j| {
            (
                j.name().to_string(),
                pose.angles[j.index()].map(f64::to_degrees),
            )
        })
        .collect();
    let palm = crate::skeleton::forward_kinematics::link_transforms(hand.skeleton(), &pose)
        [crate::anatomy::Link::Palm.index()];
    let (origin, axes) = hand.skeleton().hand_directions();
    let c = part.centre_of_mass;
    let settled = ht.settle_motion * c - c;
    let settle_by_direction_mm = ["dorsal", "radial", "distal"]
        .into_iter()
        .zip(axes)
        .map(|(name, a)| (name.to_string(), settled.dot(&(palm * a))))
        .collect();
    let report = GraspReport {
        scene: scene.path.display().to_string(),
        grasp_type: scene.grasp.name().to_string(),
        approach: approach_map,
        pose_deg,
        force_closure: q.force_closure,
        epsilon: q.epsilon,
        volume,
        holds: ht.holds,
        hold_test: ht,
        contacts: cs.contacts.clone(),
        contact_area_mm2: cs.area_by_link(),
        contact_area_by_finger_mm2: cs.area_by_finger(),
        total_contact_area_mm2: cs.total_area_mm2(),
        envelope: cs.envelope(),
        max_penetration_mm: cs.max_depth_mm(),
        settle_by_direction_mm,
        approach_to_contact_mm: g.approach_mm,
        squeeze: squeezed,
        placement_tries,
        approach_slide_mm,
        untouched_joints: g.untouched.clone(),
        finger_collisions: g.collisions.clone(),
        finger_core_entry_mm: finger_entry,
        part: PartInfo {
            file: scene.part_file.display().to_string(),
            triangles: part.mesh.n_faces(),
            closed: part.closed,
            centre_of_mass_mm: part.centre_of_mass.coords.into(),
            max_radius_mm: part.max_radius,
            mass_kg: scene.mass_kg,
            friction: scene.friction,
        },
        warnings,
        timings_s: Timings {
            total_s: started.elapsed().as_secs_f64(),
            ..timings
        },
    };
    Ok(GraspOutcome {
        report,
        hand_mesh,
        contacts: cs,
        colour_distance,
        part_mesh: part.mesh.clone(),
        hand_frame: (palm * origin, axes.map(|a| palm * a)),
    })
}

/// Contact-map colours: skin within the tolerance or inside red, then viridis over 0..10 mm of
/// distance to the part, light grey beyond.
pub fn contact_colours(distance: &[Option<f64>], tol: f64) -> Vec<[u8; 3]> {
    distance
        .iter()
        .map(|d| match d {
            Some(d) if *d <= tol => [220, 30, 30],
            Some(d) if *d <= COLOUR_RANGE_MM => crate::render::viridis(d / COLOUR_RANGE_MM),
            _ => [200, 200, 200],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use std::sync::OnceLock;

    fn hand() -> &'static SkinnedHand {
        static H: OnceLock<SkinnedHand> = OnceLock::new();
        H.get_or_init(|| SkinnedHand::template(Side::Right).unwrap())
    }

    /// A scene file in `dir` naming `part` (written as STL, mm) with `grasp` lines.
    fn scene_with(dir: &Path, part: &TriMesh, grasp: &str) -> Scene {
        crate::io::stl::write_stl(&dir.join("p.stl"), part, Units::Millimetres).unwrap();
        let text = format!(
            "[part]\nfile = \"p.stl\"\nunits = \"mm\"\nfriction = 0.5\nmass_g = 100\n[grasp]\n{grasp}\n"
        );
        let path = dir.join("s.toml");
        std::fs::write(&path, &text).unwrap();
        scene::read_scene(&path).unwrap()
    }

    const SIDE: &str =
        "type = \"power\"\napproach = { translation_mm = [-25, -36, 90], rotation_deg = [-90, -90, 0] }";

    #[test]
    fn bad_parts_and_approaches_give_one_line_messages_naming_scene_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let scene_name = dir.path().join("s.toml").display().to_string();
        // A bottle-sized part written in metres read as mm: 1000 times too small.
        let tiny = crate::geometry::mesh::tests::cuboid(0.06, 0.06, 0.2);
        let s = scene_with(dir.path(), &tiny, SIDE);
        let o = run_scene(&s, hand()).unwrap();
        let w = o.report.warnings.join("\n");
        assert!(
            w.contains(&scene_name)
                && w.contains("part.units")
                && w.contains("0.0600 x 0.0600 x 0.2000 mm"),
            "{w}"
        );
        // An open part: inside tests off, surface distance only, with a warning.
        let mut open = crate::geometry::mesh::tests::cuboid(60.0, 60.0, 200.0)
            .transformed(&nalgebra::Isometry3::translation(-30.0, -30.0, 0.0));
        open.faces.truncate(open.faces.len() - 2);
        let s = scene_with(dir.path(), &open, SIDE);
        let o = run_scene(&s, hand()).unwrap();
        assert!(!o.report.part.closed);
        let w = o.report.warnings.join("\n");
        assert!(
            w.contains(&scene_name) && w.contains("part.file") && w.contains("closed 2-manifold"),
            "{w}"
        );
        assert!(o.report.warnings.iter().all(|w| !w.contains('\n')));
        // The hand placed inside the part.
        let bottle = parts::Part::Bottle.mesh().unwrap();
        let inside = "type = \"power\"\napproach = { translation_mm = [0, 0, 90], rotation_deg = [-90, -90, 0] }";
        let s = scene_with(dir.path(), &bottle, inside);
        let e = run_scene(&s, hand()).err().unwrap().to_string();
        assert!(
            e.contains(&scene_name)
                && e.contains("grasp.approach")
                && e.contains("inside the part"),
            "{e}"
        );
        assert!(!e.contains('\n'));
        // An unknown grasp type.
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            "[part]\nfile = \"p.stl\"\nunits = \"mm\"\nfriction = 0.5\nmass_g = 100\n[grasp]\ntype = \"hook\"\napproach = \"auto\"\n",
        )
        .unwrap();
        let e = scene::read_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains(&scene_name) && e.contains("grasp.type") && e.contains("hook"),
            "{e}"
        );
    }

    /// A part whose every triangle is there twice (once flipped) grasps exactly as the part
    /// itself, and the warning names what was removed.
    #[test]
    fn doubled_triangles_give_the_same_grasp() {
        let dir = tempfile::tempdir().unwrap();
        let cube = crate::geometry::mesh::tests::cuboid(60.0, 60.0, 200.0)
            .transformed(&nalgebra::Isometry3::translation(-30.0, -30.0, 0.0));
        let mut doubled = cube.clone();
        doubled
            .faces
            .extend(cube.faces.iter().map(|&[a, b, c]| [a, c, b]));
        let plain = run_scene(&scene_with(dir.path(), &cube, SIDE), hand()).unwrap();
        let twice = run_scene(&scene_with(dir.path(), &doubled, SIDE), hand()).unwrap();
        let (a, b) = (&plain.report, &twice.report);
        assert_eq!(a.force_closure, b.force_closure);
        assert_eq!(a.epsilon, b.epsilon);
        assert_eq!(
            serde_json::to_value(&a.contacts).unwrap(),
            serde_json::to_value(&b.contacts).unwrap()
        );
        assert!(!a.contacts.is_empty());
        let w = b.warnings.join("\n");
        assert!(w.contains("12 repeated") && w.contains("part.file"), "{w}");
        assert!(a.warnings.iter().all(|w| !w.contains("repeated")));
    }

    /// The report of the shipped scene `scenes/NAME.toml` with the default hand.
    fn shipped(name: &str) -> GraspReport {
        run_scene(&shipped_scene(name), hand()).unwrap().report
    }

    /// The shipped scene `scenes/NAME.toml`, read.
    fn shipped_scene(name: &str) -> Scene {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
        scene::read_scene(&path).unwrap()
    }

    /// A grasp held by its pads: every one of `pads` touches, each of `pressed` is pressed in
    /// by more than half the squeeze, none of `off` touches, no warning, force closure, and it
    /// holds in rapier in all six directions.
    fn assert_held_by_pads(r: &GraspReport, pads: &[&str], pressed: &[&str], off: &[&str]) {
        let area = |l: &str| r.contact_area_mm2.get(l).copied().unwrap_or(0.0);
        for pad in pads {
            assert!(area(pad) > 0.0, "{pad}: {:?}", r.contact_area_mm2);
        }
        for pad in pressed {
            let depth = r.squeeze.depth_mm.get(*pad).copied().unwrap_or(0.0);
            assert!(
                depth > autograsp::SQUEEZE_MM / 2.0,
                "{pad} pressed {depth} mm"
            );
        }
        for l in off {
            assert_eq!(area(l), 0.0, "{l}: {:?}", r.contact_area_mm2);
        }
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert!(r.force_closure && r.epsilon > 0.0, "{}", r.epsilon);
        assert!(r.holds, "{:?}", r.hold_test);
    }

    /// The shipped bottle scene (the 60 mm bottle in a power grasp) reaches force
    /// closure and holds in rapier with the default hand.
    #[test]
    fn shipped_bottle_scene_is_force_closure_and_holds() {
        let r = &shipped("bottle");
        assert!(r.force_closure && r.epsilon > 0.0, "{}", r.epsilon);
        assert!(r.holds, "{:?}", r.hold_test);
        // The palm came in, and the squeeze pressed the skin no deeper than its target, the
        // thenar no deeper than the approach let it give way.
        assert!(r.approach_to_contact_mm > 0.0);
        let power = plan::grasp_plan(scene::GraspType::Power);
        for c in &r.contacts {
            let bound = autograsp::SQUEEZE_MM.max(power.give(c.link_index));
            assert!(c.depth_mm <= bound + 0.5, "{}: {}", c.link, c.depth_mm);
        }
        // It wraps: the palm on the bottle and at least three fingers with every phalanx.
        assert!(r.envelope.wraps, "{:?}", r.envelope);
    }

    const SHORTER: f64 = 0.85;

    /// The template scaled about its wrist (every length times `s`): a hand of another size.
    fn scaled_template(s: f64) -> SkinnedHand {
        let t = crate::template::load_template(Side::Right).unwrap();
        let w = t.skeleton.centre(crate::anatomy::Joint::Wrist);
        let scale = |p: &Point| w + (p - w) * s;
        let mut sk = t.skeleton.clone();
        for j in &mut sk.joints {
            j.centre = scale(&j.centre);
        }
        for tip in &mut sk.tips {
            *tip = scale(tip);
        }
        let skin = TriMesh {
            vertices: t.mesh.vertices.iter().map(scale).collect(),
            faces: t.mesh.faces.clone(),
        };
        let h = crate::pose::IndividualHand::from_parts(Side::Right, skin, sk, t.weights.clone())
            .unwrap();
        SkinnedHand::new(h).unwrap()
    }

    /// A given approach is one hand's place (here the template's bottle grasp from its side,
    /// which synth's grasp trials use): from exactly there a hand 15 % shorter holds and wraps
    /// the bottle (it dropped it while the wrapping squeeze pressed only the fingertips); sliding
    /// along its palm up to 15 mm, the places ranked by quality, it closes at another place, a
    /// multiple of the slide's step away, with force closure. The shipped scene, which
    /// searches, holds the bottle in the shorter hand and wraps it (palm and three fingers with
    /// every phalanx).
    #[test]
    fn a_shorter_hand_slides_along_its_palm_and_the_searched_bottle_holds() {
        let small = scaled_template(SHORTER);
        let mut fixed = shipped_scene("bottle");
        assert_eq!(fixed.approach, scene::Approach::Auto);
        fixed.approach = scene::Approach::Given(scene::pose_from(
            parts::BOTTLE_SIDE_APPROACH.0,
            parts::BOTTLE_SIDE_APPROACH.1,
        ));
        fixed.slide_mm = 0.0;
        let r = run_scene(&fixed, &small).unwrap().report;
        assert!(r.holds && r.envelope.wraps, "{:?}", r.hold_test);
        assert_eq!(r.approach_slide_mm, None);
        let mut sliding = fixed.clone();
        sliding.slide_mm = 15.0;
        let r = run_scene(&sliding, &small).unwrap().report;
        assert!(r.force_closure, "{}", r.epsilon);
        let slide = r.approach_slide_mm.unwrap();
        assert!(slide != 0.0 && slide.abs() <= 15.0, "{slide}");
        assert_eq!(slide % placement::SLIDE_STEP_MM, 0.0);
        let r = run_scene(&shipped_scene("bottle"), &small).unwrap().report;
        assert!(
            r.holds && r.envelope.wraps,
            "{:?} {:?}",
            r.envelope,
            r.hold_test
        );
    }

    /// The pen in a lateral (key) pinch: held between the thumb's distal pad and the radial
    /// side of the index's middle phalanx, off the palm, force closure, and it holds in rapier
    /// in all six directions.
    #[test]
    fn lateral_grasp_of_the_pen_holds() {
        let mut s = shipped_scene("pen");
        s.grasp = scene::GraspType::Lateral;
        let r = &run_scene(&s, hand()).unwrap().report;
        assert_held_by_pads(r, &["T_DIST", "I_MID"], &["T_DIST"], &["PALM"]);
    }

    /// The pen in a pinch (thumb and index pads, the plan fitted to the hand): held pad to pad,
    /// both pressed in by the squeeze, off the palm, force closure, and it holds in rapier in
    /// all six directions (with the template plan's closed posture the pads met tip to tip in
    /// a V and the squeeze pushed the pen out).
    #[test]
    fn pinch_of_the_pen_holds_pad_to_pad() {
        let mut s = shipped_scene("pen");
        s.grasp = scene::GraspType::Pinch;
        let r = &run_scene(&s, hand()).unwrap().report;
        let pads = ["T_DIST", "I_DIST"];
        assert_held_by_pads(r, &pads, &pads, &["PALM"]);
    }

    /// A part thicker than the lateral grasp's opening (the 38 mm mouse) finds no placement,
    /// and the one-line error says why, with the opening.
    #[test]
    fn lateral_grasp_of_the_mouse_says_it_does_not_fit() {
        let mut s = shipped_scene("mouse");
        s.grasp = scene::GraspType::Lateral;
        s.candidates = 100;
        let e = run_scene(&s, hand()).err().unwrap().to_string();
        let opening = autograsp::press_travel(hand(), &plan::grasp_plan(s.grasp))
            .unwrap()
            .norm();
        assert!(opening < 38.0, "{opening}");
        assert!(
            e.contains("grasp.approach")
                && e.contains(&format!("{opening:.0} mm"))
                && e.contains("does not fit"),
            "{e}"
        );
        assert!(!e.contains('\n'));
    }

    /// The shipped pen scene (a 9 mm pen, tripod, placement search) is a real tripod: the pen
    /// is held between the thumb, index and middle distal pads, the thumb's and the index's
    /// pressed in by the squeeze (they pinch it; the middle supports it from below, as in the
    /// writer's dynamic tripod), off the palm, and it holds in rapier in all six directions.
    #[test]
    fn shipped_pen_scene_is_a_tripod_that_holds() {
        let r = &shipped("pen");
        let pads = ["T_DIST", "I_DIST", "M_DIST"];
        assert_held_by_pads(r, &pads, &pads[..2], &["PALM", "T_META", "T_PROX"]);
    }

    /// A frictionless pen, which no tripod holds (nothing resists it along its length): the
    /// scene tries the search's best, its runners-up and then its reserves before it reports
    /// the best that dropped.
    #[test]
    fn a_part_no_finalist_holds_is_tried_with_the_reserves() {
        let mut scene = shipped_scene("pen");
        scene.friction = 0.0;
        let r = run_scene(&scene, hand()).unwrap().report;
        assert!(!r.holds, "{:?}", r.hold_test);
        assert!(
            (placement::FINALISTS + 1..=placement::FINALISTS + placement::RESERVES)
                .contains(&r.placement_tries),
            "{}",
            r.placement_tries
        );
    }
}
