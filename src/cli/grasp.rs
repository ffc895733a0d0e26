//! `ergohand grasp`: a scene's hand closed on its part, and the files that show the grasp.

use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use crate::grasp::contact::ContactOptions;
use crate::grasp::{contact_colours, load_hand, run_scene, scene, GraspOutcome, GraspReport};
use crate::io::output_paths::{check_output_dir, Inputs};
use crate::io::Units;
use std::path::{Path, PathBuf};

/// Write `grasp.json`, `grasp.glb` and `contact_map.png` of an outcome into `out`.
pub(crate) fn write_outputs(o: &GraspOutcome, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let json = serde_json::to_string_pretty(&o.report)
        .map_err(|e| Error::invalid(format!("grasp.json: {e}")))?;
    crate::io::atomic::write_bytes_atomic(&out.join("grasp.json"), json.as_bytes())?;
    let colours = contact_colours(&o.colour_distance, ContactOptions::default().tolerance_mm);
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
        animations: Vec::new(),
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

/// The files [`write_outputs`] writes into its folder.
pub(crate) const OUTPUT_FILES: [&str; 3] = ["grasp.json", "grasp.glb", "contact_map.png"];

/// `ergohand grasp SCENE.toml --model OUT --out DIR`: read the scene, load the hand (`model`
/// overrides the scene's `hand.model`; neither: the template), check the output folder (see
/// [`crate::io::output_paths`]), close the hand on the part, measure, and write `grasp.json`,
/// `grasp.glb` and `contact_map.png` into `out`.
pub fn grasp(scene: &Path, model: Option<&Path>, out: &Path) -> Result<GraspReport> {
    let r = grasp_job(scene, model, out)?;
    log::info!(
        "grasp: force closure {}, epsilon {:.4}, volume {:.3e}, holds {}, contact {:.0} mm²; wrote {}",
        r.force_closure,
        r.epsilon,
        r.volume,
        r.holds,
        r.total_contact_area_mm2,
        out.display()
    );
    Ok(r)
}

/// [`grasp`] without its closing status line.
fn grasp_job(scene: &Path, model: Option<&Path>, out: &Path) -> Result<GraspReport> {
    let s = scene::read_scene(scene)?;
    let model = model.map(Path::to_path_buf).or(s.hand_model.clone());
    let mut inputs = Inputs::files([scene.to_path_buf(), s.part_file.clone()]);
    if let Some(m) = &model {
        inputs = inputs.with_model(m);
    }
    check_output_dir(out, &OUTPUT_FILES, "--out", &inputs)?;
    let hand = load_hand(model.as_deref(), s.side)?;
    let o = run_scene(&s, &hand)?;
    write_outputs(&o, out)?;
    Ok(o.report)
}

/// The demo's grasp: writes the shipped bottle scene (`scenes/bottle.toml`, embedded) and its
/// part (generated, [`crate::grasp::parts::Part::Bottle`]) into `out`, then grasps it with the hand of the
/// `reconstruct` folder `model_dir` ([`grasp`]), outputs in `out`.
pub fn demo_bottle(model_dir: &Path, out: &Path) -> Result<GraspReport> {
    let scene = demo_bottle_scene(out)?;
    grasp_job(&scene, Some(model_dir), out)
}

/// Write the shipped bottle scene and its part into `out` (`bottle.toml`, `bottle.stl`) and
/// return the scene's path.
pub(crate) fn demo_bottle_scene(out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let scene = out.join("bottle.toml");
    crate::io::atomic::write_bytes_atomic(
        &scene,
        include_str!("../../scenes/bottle.toml").as_bytes(),
    )?;
    crate::io::stl::write_stl(
        &out.join("bottle.stl"),
        &crate::grasp::parts::Part::Bottle.mesh()?,
        Units::Millimetres,
    )?;
    Ok(scene)
}
