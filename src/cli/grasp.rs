//! `ergohand grasp`: a scene's hand closed on its part, and the files that show the grasp.

use crate::error::{Error, Result};
use crate::geometry::CreaseSplit;
use crate::grasp::contact::ContactOptions;
use crate::grasp::{
    contact_colours, load_hand, run_scene, run_scene_on, scene, GraspOutcome, GraspReport,
};
use crate::io::output_paths::{check_output_dir, Inputs};
use crate::io::Units;
use crate::validate::view_page::{
    view_html, Gradient, Legend, Swatch, ViewFrame, ViewGlb, ViewPage, ViewTable, ViewValue,
};
use std::path::{Path, PathBuf};

/// Write `grasp.json`, `grasp.glb` and `contact_map.png` of an outcome into `out`; returns
/// the PNG's bytes (for a page that embeds the picture). `part`: the outcome's part with its
/// vertices split at creases ([`part_with_creases`]; the same for every hand of one scene).
pub(crate) fn write_outputs(o: &GraspOutcome, part: &CreaseSplit, out: &Path) -> Result<Vec<u8>> {
    let _held = crate::io::atomic::FolderLock::acquire(out)?;
    let json = serde_json::to_string_pretty(&o.report)
        .map_err(|e| Error::invalid(format!("grasp.json: {e}")))?;
    crate::io::atomic::write_bytes_atomic(&out.join("grasp.json"), json.as_bytes())?;
    let colours = contact_colours(&o.colour_distance, ContactOptions::default().tolerance_mm);
    let lin = |c: [u8; 3]| {
        let f = |x: u8| ((x as f32 / 255.0).powf(2.2)).clamp(0.0, 1.0);
        [f(c[0]), f(c[1]), f(c[2]), 1.0]
    };
    let part_grey = [170u8, 175, 185];
    // The distances the colours show, for the page's readout (only when every vertex has one:
    // an open part far from some vertex leaves them without).
    let distance = o
        .colour_distance
        .iter()
        .map(|d| d.map(|x| x as f32))
        .collect::<Option<Vec<f32>>>()
        .map(|values| crate::io::gltf::VertexAttribute {
            name: DISTANCE_ATTRIBUTE.into(),
            values,
        });
    let scene = crate::io::gltf::Scene {
        meshes: vec![
            crate::io::gltf::SceneMesh {
                name: "hand".into(),
                mesh: o.hand_mesh.clone(),
                normals: Some(o.hand_mesh.vertex_normals()),
                colors: Some(colours.iter().map(|&c| lin(c)).collect()),
                skin: None,
                attributes: distance.into_iter().collect(),
                morph_targets: Vec::new(),
            },
            crate::io::gltf::SceneMesh {
                name: "part".into(),
                colors: Some(vec![lin(part_grey); part.mesh.n_vertices()]),
                mesh: part.mesh.clone(),
                normals: Some(part.normals.clone()),
                skin: None,
                attributes: Vec::new(),
                morph_targets: Vec::new(),
            },
        ],
        animations: Vec::new(),
    };
    let glb = crate::io::gltf::glb_bytes(&scene, Units::Metres)?;
    crate::io::atomic::write_bytes_atomic(&out.join("grasp.glb"), &glb)?;
    let page = view_page(o, glb);
    crate::io::atomic::write_bytes_atomic(&out.join("view.html"), view_html(&page).as_bytes())?;
    // Picture: the hand from the side that carries its contacts, with the legend.
    let img = crate::validate::grasp_picture::contact_picture(
        &o.hand_mesh,
        &colours,
        &o.report.contacts,
        &o.hand_frame,
        ContactOptions::default().tolerance_mm,
        crate::grasp::COLOUR_RANGE_MM,
        800,
    )?;
    let path = out.join("contact_map.png");
    let png = img.to_png().map_err(|e| e.in_file(&path))?;
    crate::io::atomic::write_bytes_atomic(&path, &png)?;
    Ok(png)
}

/// The part as `grasp.glb` shows it: the skin is smooth (one normal per vertex keeps it
/// homologous with skin.obj), the CAD part keeps its sharp edges (vertices split at creases).
pub(crate) fn part_with_creases(part: &crate::geometry::TriMesh) -> CreaseSplit {
    crate::geometry::crease_normals(part, crate::geometry::crease_normals::DEFAULT_CREASE_DEG)
}

/// The hand's attribute in `grasp.glb`: each skin vertex's signed distance to the part, mm
/// (negative inside), the value its contact-map colour shows.
pub(crate) const DISTANCE_ATTRIBUTE: &str = "_DISTANCE_MM";

/// The files [`write_outputs`] writes into its folder.
pub(crate) const OUTPUT_FILES: [&str; 4] =
    ["grasp.json", "grasp.glb", "contact_map.png", "view.html"];

/// The 3-D page of a grasp: `grasp.glb` (hand with its contact map, part), the contact map's
/// legend, the grasp's figures and the contact area per link.
fn view_page(o: &GraspOutcome, glb: Vec<u8>) -> ViewPage {
    let r = &o.report;
    let tol = ContactOptions::default().tolerance_mm;
    let range = crate::grasp::COLOUR_RANGE_MM;
    let held = r.hold_test.trials.iter().filter(|t| t.holds).count();
    let yes = |b: bool| if b { "yes" } else { "no" }.to_string();
    let scene_name = Path::new(&r.scene)
        .file_stem()
        .map_or_else(|| r.scene.clone(), |n| n.to_string_lossy().into_owned());
    let (origin, [dorsal, radial, distal]) = o.hand_frame;
    ViewPage {
        title: format!("grasp: {scene_name}, {}", r.grasp_type),
        kind: "grasp",
        glbs: vec![ViewGlb {
            name: "hand and part".into(),
            role: "scene",
            bytes: glb,
            value: Some(ViewValue {
                attribute: DISTANCE_ATTRIBUTE.into(),
                label: "distance to the part".into(),
                unit: "mm".into(),
            }),
        }],
        part_nodes: vec!["part".into()],
        legend: Some(Legend {
            title: "skin distance to the part".into(),
            unit: "mm".into(),
            entries: vec![Swatch::rgb(
                contact_colours(&[Some(0.0)], tol)[0],
                format!("touching or inside (within {tol} mm)"),
            )],
            gradient: Gradient {
                colormap: "viridis",
                min: 0.0,
                max: range,
            },
            beyond: Swatch::rgb(
                contact_colours(&[None], tol)[0],
                format!("farther than {range} mm"),
            ),
        }),
        facts: vec![
            ("scene".into(), r.scene.clone()),
            ("force closure".into(), yes(r.force_closure)),
            ("epsilon".into(), format!("{:.4}", r.epsilon)),
            (
                "holds".into(),
                format!(
                    "{}: {held} of {} directions",
                    yes(r.holds),
                    r.hold_test.trials.len()
                ),
            ),
            (
                "contact area".into(),
                format!("{:.0} mm²", r.total_contact_area_mm2),
            ),
            (
                "deepest penetration".into(),
                format!("{:.1} mm", r.max_penetration_mm),
            ),
        ],
        tables: vec![ViewTable {
            title: "contact area per link".into(),
            columns: vec!["link".into(), "area (mm²)".into()],
            rows: r
                .contact_area_mm2
                .iter()
                .filter(|(_, a)| **a > 0.0)
                .map(|(l, a)| vec![l.clone(), format!("{a:.1}")])
                .collect(),
        }],
        frame: Some(ViewFrame {
            origin,
            dorsal,
            radial,
            distal,
        }),
        // The contacts are on the palm's side, seen through the part.
        view: Some("palmar"),
        part_opacity: Some(0.35),
        rig: None,
    }
}

/// `ergohand grasp SCENE.toml --model OUT --out DIR`: read the scene, load the hand (`model`
/// overrides the scene's `hand.model`; neither: the template), check the output folder (see
/// [`crate::io::output_paths`]), close the hand on the part, measure, and write `grasp.json`,
/// `grasp.glb` and `contact_map.png` into `out`.
pub fn grasp(scene: &Path, model: Option<&Path>, out: &Path) -> Result<GraspReport> {
    let r = grasp_job(scene, model, out)?;
    // A grasp the squeeze pushed out of the hand says where to, which is why it drops.
    let pushed = crate::grasp::population::pushed_out_toward(&r)
        .map(|w| {
            format!(
                " (the squeeze pushed it {:.1} mm {w})",
                r.hold_test.settle_mm
            )
        })
        .unwrap_or_default();
    log::info!(
        "grasp: force closure {}, epsilon {:.4}, volume {}, holds {}{pushed}, contact {:.0} mm², {}; wrote {}",
        r.force_closure,
        r.epsilon,
        r.volume.map_or("not computed".into(), |v| format!("{v:.3e}")),
        r.holds,
        r.total_contact_area_mm2,
        r.envelope.describe(),
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
    write_outputs(&o, &part_with_creases(&o.part_mesh), out)?;
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

/// The population page's files, written into the `--out` folder beside one folder per hand.
pub(crate) const POPULATION_FILES: [&str; 5] = [
    "population.json",
    "population.md",
    "population.html",
    "contact_frequency.glb",
    "view.html",
];

/// The model folders named by `--models`: each path that holds `link_model.json`, else its
/// subfolders that do (a `batch` output), in name order.
fn model_folders(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.join("link_model.json").is_file() {
            out.push(p.clone());
            continue;
        }
        let entries = std::fs::read_dir(p).map_err(|e| Error::io(p, e))?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|d| d.join("link_model.json").is_file())
            .collect();
        if found.is_empty() {
            return Err(Error::input(
                p,
                "--models: no link_model.json in this folder or its subfolders; give reconstruct (or batch) output folders",
            ));
        }
        found.sort();
        out.extend(found);
    }
    Ok(out)
}

/// `ergohand grasp SCENE.toml --models DIR... --out DIR`: the scene with every hand (each a
/// `reconstruct` folder, or a folder of them), one after the other (each scene is parallel
/// inside); each hand's `grasp.json`, `grasp.glb` and `contact_map.png` in `out/NAME/`, and
/// `population.json`, `population.md` and `population.html` in `out`. Every model is read and
/// every output folder checked before the first scene; a hand on which the scene finds no
/// grasp is reported as such, not an error.
pub fn grasp_population(
    scene: &Path,
    models: &[PathBuf],
    out: &Path,
) -> Result<crate::grasp::population::PopulationSummary> {
    use crate::grasp::population::{hand_outcome, summarise};
    let s = scene::read_scene(scene)?;
    let folders = model_folders(models)?;
    let names: Vec<String> = folders
        .iter()
        .map(|f| {
            f.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| f.display().to_string())
        })
        .collect();
    for (i, n) in names.iter().enumerate() {
        if let Some(j) = names[..i].iter().position(|m| m == n) {
            return Err(Error::input(
                &folders[i],
                format!(
                    "--models: two models are named {n} ({} and this one); give folders with distinct names",
                    folders[j].display()
                ),
            ));
        }
    }
    let mut inputs = Inputs::files([scene.to_path_buf(), s.part_file.clone()]);
    for f in &folders {
        inputs = inputs.with_model(f);
    }
    check_output_dir(out, &POPULATION_FILES, "--out", &inputs)?;
    for n in &names {
        check_output_dir(&out.join(n), &OUTPUT_FILES, "--out", &inputs)?;
    }
    use rayon::prelude::*;
    // Loaded side by side; the first folder that fails (in the order given) is the one named.
    let hands = folders
        .par_iter()
        .map(|f| load_hand(Some(f), s.side))
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
    // One part for every hand: read, cleaned and indexed once.
    let (part, part_warnings) = crate::grasp::scene_part(&s, &s.part_pose)?;
    for w in &part_warnings {
        log::warn!("{w}");
    }
    let creased = part_with_creases(&part.mesh);
    let bar = crate::cli::progress(hands.len() as u64, "hands");
    let mut outcomes = Vec::new();
    let mut pictures = Vec::new();
    // Per part vertex: the hands whose skin touches it. Every hand meets the one part placed
    // where the scene puts it (the hand is what moves), so vertex k is the same place of the
    // part for every hand.
    let contact = ContactOptions::default();
    let mut touched = vec![0u32; part.mesh.n_vertices()];
    let mut grasped = 0;
    // The hands side by side on rayon's pool, which each scene's search and hold test share
    // (a lone scene leaves cores idle in its serial parts). Each hand's files, picture and
    // touched part vertices are made there too (a serial loop after the scenes left one core
    // idle while the other wrote); the logs and the summary follow in the order given.
    // Per hand: its scene's outcome with the part vertices it touches and its contact picture,
    // or the scene's error; the outer error is a file that could not be written.
    type Written = Result<(GraspOutcome, Vec<bool>, Vec<u8>)>;
    let results: Vec<Result<Written>> = hands
        .par_iter()
        .zip(&names)
        .map(|(hand, name)| {
            let written = match run_scene_on(&s, hand, &part, &part_warnings, false) {
                Ok(o) => {
                    let hit = crate::grasp::population::part_vertices_touched(
                        &o.hand_mesh,
                        &part.mesh,
                        contact.tolerance_mm,
                        contact.search_mm,
                    );
                    let picture = write_outputs(&o, &creased, &out.join(name))?;
                    Ok((o, hit, picture))
                }
                Err(e) => Err(e),
            };
            bar.inc(1);
            Ok(written)
        })
        .collect();
    for (((hand, name), folder), written) in hands.iter().zip(&names).zip(&folders).zip(results) {
        let (result, picture) = match written? {
            Ok((o, hit, picture)) => {
                grasped += 1;
                for (t, h) in touched.iter_mut().zip(hit) {
                    *t += h as u32;
                }
                (Ok(o), Some(picture))
            }
            Err(e) => {
                log::warn!("{}: {e}", folder.display());
                (Err(e), None)
            }
        };
        pictures.push(picture);
        let report = result
            .as_ref()
            .map(|o| &o.report)
            .map_err(|e| e.to_string());
        let o = hand_outcome(name, &folder.display().to_string(), hand, report);
        log::info!(
            "grasp {name}: {}",
            if o.holds {
                "holds".to_string()
            } else {
                o.failure.map_or("", |f| f.describe()).to_string()
            }
        );
        outcomes.push(o);
    }
    bar.finish_and_clear();
    let summary = summarise(&scene.display().to_string(), s.grasp.name(), outcomes);
    let _held = crate::io::atomic::FolderLock::acquire(out)?;
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::invalid(format!("population.json: {e}")))?;
    crate::io::atomic::write_bytes_atomic(&out.join("population.json"), json.as_bytes())?;
    crate::io::atomic::write_bytes_atomic(
        &out.join("population.md"),
        crate::validate::population_report::population_markdown(&summary).as_bytes(),
    )?;
    crate::io::atomic::write_bytes_atomic(
        &out.join("population.html"),
        crate::validate::population_report::population_html(&summary, &pictures).as_bytes(),
    )?;
    // The contact frequency map on the part in its own frame (as its file gives it).
    let own = part.mesh.transformed(&s.part_pose.inverse());
    // Opened facing the place most hands touch.
    let colours = crate::validate::pages::hand_share_colours(&touched, summary.hands);
    let share: Vec<f32> = touched
        .iter()
        .map(|&c| (100.0 * c as f64 / summary.hands.max(1) as f64) as f32)
        .collect();
    // Split at the part's creases, as in every hand's grasp.glb: smooth where the CAD surface
    // is, sharp at its edges.
    let split =
        crate::geometry::crease_normals(&own, crate::geometry::crease_normals::DEFAULT_CREASE_DEG);
    let glb = crate::io::gltf::glb_bytes(
        &crate::io::gltf::Scene {
            meshes: vec![crate::io::gltf::SceneMesh {
                name: "part".into(),
                mesh: split.mesh.clone(),
                normals: Some(split.normals.clone()),
                colors: Some(
                    split
                        .carry(&colours)
                        .into_iter()
                        .map(crate::validate::error_map::srgb_to_linear)
                        .collect(),
                ),
                skin: None,
                attributes: vec![crate::io::gltf::VertexAttribute {
                    name: crate::validate::pages::HAND_SHARE_ATTRIBUTE.into(),
                    values: split.carry(&share),
                }],
                morph_targets: Vec::new(),
            }],
            animations: Vec::new(),
        },
        Units::Metres,
    )?;
    crate::io::atomic::write_bytes_atomic(&out.join("contact_frequency.glb"), &glb)?;
    let mut page =
        crate::validate::pages::population_page(&summary, glb, grasped, contact.tolerance_mm);
    page.frame = crate::validate::pages::touched_side_frame(&own, &touched);
    page.view = page.frame.map(|_| "dorsal");
    crate::io::atomic::write_bytes_atomic(&out.join("view.html"), view_html(&page).as_bytes())?;
    log::info!(
        "grasp: {} of {} hands hold the part, {} in force closure; wrote {}",
        summary.holding,
        summary.hands,
        summary.force_closure,
        out.join("population.html").display()
    );
    Ok(summary)
}
