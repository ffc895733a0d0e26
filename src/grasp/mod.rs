//! Grasp and contact checks of a posed hand on a CAD part (issue 8; spec section 4, `grasp`).
//!
//! A scene ([`scene`]) names a part, its pose, friction and mass, a hand and a grasp type.
//! [`autograsp`] closes the hand on the part from an approach pose (GraspIt's autograsp,
//! Miller & Allen 2004) or searches placements; [`contact`] measures contacts per link with
//! parry queries; [`quality`] computes force closure and the Ferrari-Canny epsilon and volume
//! qualities (Ferrari & Canny 1992); [`hold`] checks in rapier that the part stays in the hand
//! under gravity from six directions. [`grasp_command`] runs a scene and writes `grasp.json`,
//! `grasp.glb` (posed hand and part, contact map as `COLOR_0`) and `contact_map.png`.

pub mod autograsp;
pub mod contact;
pub mod hand;
pub mod hold;
pub mod parts;
pub mod quality;
pub mod scene;

pub use hand::{PosableHand, RigidHand};

use crate::anatomy::{Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use crate::io::Units;
use autograsp::{autograsp, grasp_plan, root_for, AutograspOptions};
use contact::{contacts, vertex_areas, ContactOptions, ContactSet, PartShape};
use scene::{Approach, Scene};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Read a part mesh in its unit (by extension: `.obj`, `.stl`, `.gltf`/`.glb`), in mm.
pub fn read_part(path: &Path, units: Units) -> Result<TriMesh> {
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

/// The hand of a `reconstruct` output folder (`skin.obj`, homologous to the template, and
/// `link_model.json`), posed rigidly by the template's dominant links; `None`: the template.
pub fn load_hand(model: Option<&Path>, side: crate::anatomy::Side) -> Result<RigidHand> {
    let template = RigidHand::template(side)?;
    let Some(dir) = model else {
        return Ok(template);
    };
    let skin_path = dir.join("skin.obj");
    let skin = crate::io::obj::read_obj(&skin_path, Units::Millimetres)?;
    if skin.n_vertices() != template.mesh.n_vertices() {
        return Err(Error::input(
            &skin_path,
            format!(
                "{} vertices, the template has {}: not a skin homologous to the template",
                skin.n_vertices(),
                template.mesh.n_vertices()
            ),
        ));
    }
    let lm = dir.join("link_model.json");
    let table = crate::validate::link_accuracy::read_joints(&lm)?;
    let mut sk = template.skeleton.clone();
    for j in Joint::ALL {
        let (c, r) = crate::skeleton::record::record_frame(&table, j, &lm)?;
        sk.joints[j.index()].centre = c;
        sk.joints[j.index()].frame = r;
    }
    for (i, f) in crate::anatomy::Finger::ALL.iter().enumerate() {
        let dj = f.joints()[2];
        sk.tips[i] = sk.centre(dj) + (template.skeleton.tips[i] - template.skeleton.centre(dj));
    }
    RigidHand::new(sk, skin, template.links)
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
    /// GWS volume.
    pub volume: f64,
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
    /// Deepest skin penetration, mm.
    pub max_penetration_mm: f64,
    /// Active joints whose link never touched.
    pub untouched_joints: Vec<String>,
    /// Part facts.
    pub part: PartInfo,
    /// Warnings.
    pub warnings: Vec<String>,
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

/// Everything computed for one scene, before writing.
pub struct GraspOutcome {
    /// The report.
    pub report: GraspReport,
    /// Posed skin.
    pub hand_mesh: TriMesh,
    /// Contact set of the final posture.
    pub contacts: ContactSet,
    /// Part in the world.
    pub part_mesh: TriMesh,
}

/// Evaluate a scene with `hand` (see [`grasp_command`]).
pub fn run_scene(scene: &Scene, hand: &dyn PosableHand, quiet: bool) -> Result<GraspOutcome> {
    let mesh = read_part(&scene.part_file, scene.part_units)?.transformed(&scene.part_pose);
    let (part, mut warnings) = PartShape::new(mesh).map_err(|e| e.in_file(&scene.part_file))?;
    let warnings_file = scene.part_file.display().to_string();
    for w in warnings.iter_mut() {
        *w = format!("{warnings_file}: {w}");
    }
    let plan = grasp_plan(scene.grasp);
    let approach = match &scene.approach {
        Approach::Given(a) => scene.part_pose * a,
        Approach::Auto => {
            autograsp::placement_search(
                hand,
                &part,
                &plan,
                scene.friction,
                scene.seed,
                scene.candidates,
                scene.time_limit_s,
                quiet,
            )
            .ok_or_else(|| {
                Error::input(
                    &scene.path,
                    "grasp.approach = \"auto\": no placement closed the hand on the part; give an approach",
                )
            })?
            .approach
        }
    };
    let root = root_for(hand, &nalgebra::Isometry3::identity(), &approach);
    let g = autograsp(hand, &part, &plan, root, &AutograspOptions::default())
        .map_err(|e| e.in_file(&scene.path))?;
    let mut pts = Vec::new();
    hand.pose_vertices(&g.pose, &mut pts);
    let areas = vertex_areas(hand.rest_mesh());
    let cs = contacts(
        &part,
        &pts,
        hand.vertex_link(),
        &areas,
        &ContactOptions::default(),
    );
    let q = quality::grasp_quality(
        &cs.contacts,
        scene.friction,
        &part.centre_of_mass,
        part.max_radius,
    );
    let mut link_points = vec![Vec::new(); Link::ALL.len()];
    for (p, &l) in pts.iter().zip(hand.vertex_link()) {
        if l != Link::Arm.index() {
            link_points[l].push(*p);
        }
    }
    let ht = hold::hold_test(&link_points, &part, scene.mass_kg, scene.friction)?;
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
                g.pose.angles[j.index()].map(f64::to_degrees),
            )
        })
        .collect();
    let report = GraspReport {
        scene: scene.path.display().to_string(),
        grasp_type: scene.grasp.name().to_string(),
        approach: approach_map,
        pose_deg,
        force_closure: q.force_closure,
        epsilon: q.epsilon,
        volume: q.volume,
        holds: ht.holds,
        hold_test: ht,
        contacts: cs.contacts.clone(),
        contact_area_mm2: cs.area_by_link(),
        contact_area_by_finger_mm2: cs.area_by_finger(),
        total_contact_area_mm2: cs.total_area_mm2(),
        max_penetration_mm: cs.max_depth_mm(),
        untouched_joints: g.untouched.clone(),
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
    };
    let hand_mesh = TriMesh {
        vertices: pts,
        faces: hand.rest_mesh().faces.clone(),
    };
    Ok(GraspOutcome {
        report,
        hand_mesh,
        contacts: cs,
        part_mesh: part.mesh,
    })
}

/// Contact-map colours: skin within the tolerance or inside red, then viridis over 0..10 mm of
/// distance to the part, light grey beyond.
pub fn contact_colours(c: &ContactSet, tol: f64) -> Vec<[u8; 3]> {
    c.vertex_distance
        .iter()
        .map(|d| match d {
            Some(d) if *d <= tol => [220, 30, 30],
            Some(d) => crate::render::viridis((d / 10.0).clamp(0.0, 1.0)),
            None => [200, 200, 200],
        })
        .collect()
}

/// Write `grasp.json`, `grasp.glb` and `contact_map.png` of an outcome into `out`.
pub fn write_outputs(o: &GraspOutcome, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let json = serde_json::to_string_pretty(&o.report)
        .map_err(|e| Error::invalid(format!("grasp.json: {e}")))?;
    crate::io::atomic::write_bytes_atomic(&out.join("grasp.json"), json.as_bytes())?;
    let colours = contact_colours(&o.contacts, ContactOptions::default().tolerance_mm);
    let lin = |c: [u8; 3]| {
        let f = |x: u8| ((x as f32 / 255.0).powf(2.2)).clamp(0.0, 1.0);
        [f(c[0]), f(c[1]), f(c[2]), 1.0]
    };
    let part_grey = [170u8, 175, 185];
    let scene = crate::io::gltf::Scene {
        meshes: vec![
            crate::io::gltf::SceneMesh {
                name: "hand".into(),
                mesh: o.hand_mesh.clone(),
                normals: None,
                colors: Some(colours.iter().map(|&c| lin(c)).collect()),
                skin: None,
            },
            crate::io::gltf::SceneMesh {
                name: "part".into(),
                mesh: o.part_mesh.clone(),
                normals: None,
                colors: Some(vec![lin(part_grey); o.part_mesh.n_vertices()]),
                skin: None,
            },
        ],
    };
    crate::io::gltf::write_glb(&out.join("grasp.glb"), &scene, Units::Metres)?;
    // Picture: hand and part together, seen from the palm side of the part.
    let mut v = o.hand_mesh.vertices.clone();
    let mut f = o.hand_mesh.faces.clone();
    let off = v.len();
    v.extend(o.part_mesh.vertices.iter().cloned());
    f.extend(
        o.part_mesh
            .faces
            .iter()
            .map(|t| [t[0] + off, t[1] + off, t[2] + off]),
    );
    let mut cols = colours;
    cols.extend(std::iter::repeat_n(part_grey, o.part_mesh.n_vertices()));
    let both = TriMesh {
        vertices: v,
        faces: f,
    };
    let com = o.report.part.centre_of_mass_mm;
    let centre = |pts: &[Point]| {
        Point::from(
            pts.iter().map(|p| p.coords).sum::<crate::geometry::Vec3>() / pts.len().max(1) as f64,
        )
    };
    let dir = Point::from(com) - centre(&o.hand_mesh.vertices);
    let view = crate::render::View::along(dir, crate::geometry::Vec3::z()).fit_mesh(&both, 0.05);
    let img = crate::render::render_mesh(&both, Some(&cols), &view, 800, 800);
    img.save_png(out.join("contact_map.png"))
}

/// `ergohand grasp SCENE.toml --model OUT --out DIR`: read the scene, load the hand (`model`
/// overrides the scene's `hand.model`; neither: the template), close it on the part, measure,
/// and write `grasp.json`, `grasp.glb` and `contact_map.png` into `out`.
pub fn grasp_command(
    scene: &Path,
    model: Option<&Path>,
    out: &Path,
    quiet: bool,
) -> Result<GraspReport> {
    let s = scene::read_scene(scene)?;
    let model = model.map(Path::to_path_buf).or(s.hand_model.clone());
    let hand = load_hand(model.as_deref(), s.side)?;
    let o = run_scene(&s, &hand, quiet)?;
    if !quiet {
        for w in &o.report.warnings {
            eprintln!("warning: {w}");
        }
    }
    write_outputs(&o, out)?;
    Ok(o.report)
}
