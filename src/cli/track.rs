//! `ergohand track SUBJECT_DIR --model OUT --motion NAME [--scene SCENE.toml] --out DIR`: a
//! motion trial of the subject replayed with its reconstructed link model, written as
//! `DIR/motion.json` (spec section 5) and animated as `DIR/motion.glb`, with its contact map
//! (`contact_map.png`, `contact_map.glb`), charts against time (`angles.png`,
//! `contact_area.png`) and a page gathering them (`report.html`).

use super::Voice;
use crate::error::{Error, Result};
use crate::grasp::contact::PartShape;
use crate::grasp::hand::SkinnedHand;
use crate::grasp::scene::Scene;
use crate::io::atomic::write_bytes_atomic;
use crate::io::gltf::glb_bytes;
use crate::io::output_paths::{check_output_dir, Inputs};
use crate::io::Units;
use crate::mocap::subject::{Subject, TrialKind};
use crate::track::{
    keep_out_of_part, load_link_model, observations, replay_contacts, track_trial, ContactReplay,
    IkOptions, KeepOutOptions, PartSetup, ReplayOptions, Solver, Tracked,
};
use crate::validate::motion_contact_map::{contact_map_picture, contact_map_scene, ContactMap};
use crate::validate::motion_plots::{angles_chart, contact_area_chart};
use crate::validate::motion_report::{motion_report_html, PagePicture};
use std::path::{Path, PathBuf};

/// The files `track` writes into its output folder.
pub const OUTPUT_FILES: [&str; 9] = [
    "motion.json",
    "motion.glb",
    "contact_map.png",
    "contact_map.glb",
    "angles.png",
    "contact_area.png",
    "report.html",
    "view.html",
    "contact_map.view.html",
];

/// What [`track`] did.
#[derive(Clone, Debug)]
pub struct TrackSummary {
    /// The file written.
    pub written: PathBuf,
    /// Frames in the trial.
    pub frames: usize,
    /// Frames that could not be solved.
    pub unsolved: usize,
    /// Warnings, each naming the trial and the markers, joints or frames.
    pub warnings: Vec<String>,
}

/// Track the motion `motion` of the subject folder `subject_dir` with the link model of the
/// `reconstruct` folder `model_dir` (its markers attached from the subject's static reference
/// trial), the part of `scene` (if given) followed by its markers or standing where the scene
/// places it, and write `out/motion.json` and `out/motion.glb` (the skinned hand and the part
/// animated over the trial) atomically, with the contact map over the trial as a picture and
/// a coloured GLB, the charts of the joint angles and the contact area against time and
/// `out/report.html` (see [`crate::validate::motion_report`]). Without `skin.obj` in the model
/// folder the GLBs and the contact map are not written (a warning names the file); without a
/// scene there is no contact map. With `keep_out` (an allowance, mm) and a scene, the frames
/// whose skin reaches deeper than the allowance into the part are solved again to keep it out
/// where the markers allow ([`crate::track::keep_out`]); a warning names the frames where they
/// do not.
///
/// Errors, one line naming the file and the field or marker: no `subject.toml`, no such
/// motion in `[motions]`, no `link_model.json` in the model folder or one of the other hand, a
/// trial without three palm markers, a bad scene.
pub fn track(
    subject_dir: &Path,
    model_dir: &Path,
    motion: &str,
    scene: Option<&Path>,
    keep_out: Option<f64>,
    out: &Path,
) -> Result<TrackSummary> {
    track_job(
        subject_dir,
        model_dir,
        motion,
        scene,
        keep_out,
        out,
        Voice::Command,
    )
}

/// [`track`], speaking with `voice`.
pub(crate) fn track_job(
    subject_dir: &Path,
    model_dir: &Path,
    motion: &str,
    scene: Option<&Path>,
    keep_out: Option<f64>,
    out: &Path,
    voice: Voice,
) -> Result<TrackSummary> {
    if let Some(a) = keep_out.filter(|a| !(a.is_finite() && *a >= 0.0)) {
        return Err(Error::invalid(format!(
            "--keep-out {a}: the allowance must be a distance of 0 mm or more"
        )));
    }
    let subject = Subject::load(subject_dir)?;
    let mut inputs = Inputs::files(
        std::iter::once(subject.toml_path())
            .chain(subject.trials.values().map(|p| subject.dir.join(p)))
            .chain(subject.motions.values().map(|p| subject.dir.join(p)))
            .chain(scene.map(Path::to_path_buf)),
    )
    .with_model(model_dir);
    inputs.files.push(model_dir.join("link_model.json"));
    check_output_dir(out, &OUTPUT_FILES, "--out", &inputs)?;

    let clock = std::time::Instant::now();
    let lap = |what: &str| {
        log::debug!(
            "track: {what} done at {:.2} s",
            clock.elapsed().as_secs_f64()
        )
    };
    let mut kin = load_link_model(model_dir)?;
    if kin.skeleton.side != subject.hand {
        return Err(Error::input(
            model_dir.join("link_model.json"),
            format!(
                "field 'hand' is {} but {} says hand = \"{}\"; --model must be this subject's \
                 reconstruction",
                kin.skeleton.side,
                subject.toml_path().display(),
                subject.hand
            ),
        ));
    }
    let static_trial = subject.load_trial(TrialKind::Reference)?;
    let trial = subject.load_motion(motion)?;
    let scene = scene.map(crate::grasp::scene::read_scene).transpose()?;
    lap("reading the trials and the scene");
    let part = scene.as_ref().map(|s| PartSetup {
        markers: s.part_markers.clone(),
        placed: s.part_pose,
    });
    // The skin and the part are read while the frames are solved.
    let glb = out.join("motion.glb");
    let skin = model_dir.join("skin.obj");
    let replay_opts = ReplayOptions::default();
    let ik_opts = IkOptions::default();
    let (tracked, loaded) = rayon::join(
        || track_trial(&kin, &static_trial, &trial, part.as_ref(), &ik_opts),
        || -> Result<_> {
            // The skin poses for the animation and the contacts; without it motion.json still
            // stands.
            let hand = if skin.is_file() {
                Some(SkinnedHand::load(model_dir)?)
            } else {
                None
            };
            let part_shape = match &scene {
                // The part in its own frame, where the markers' positions are given.
                Some(s) => Some(crate::grasp::scene_part_with_band(
                    s,
                    &nalgebra::Isometry3::identity(),
                    replay_opts.tolerance_mm,
                )?),
                None => None,
            };
            Ok((hand, part_shape))
        },
    );
    let mut tracked = tracked?;
    let (hand, part_shape) = loaded?;
    lap("inverse kinematics, reading the skin and the part");
    let mut warnings = tracked.warnings.clone();
    if hand.is_none() {
        warnings.push(format!(
            "{}: not found, so {} and the contact map ({}, {}) are not written and contacts \
             are not computed; re-run reconstruct into the --model folder",
            skin.display(),
            glb.display(),
            OUTPUT_FILES[2],
            OUTPUT_FILES[3]
        ));
    }
    // The fingertips the hand carries: derived from the skin (the link model has none), as
    // the contacts and the animation see them (the fit does not use them).
    if let Some(h) = &hand {
        kin.skeleton.tips = h.hand.skeleton.tips;
    }
    let part_shape = part_shape.map(|(p, w)| {
        warnings.extend(w);
        p
    });
    if let (Some(h), Some(p), Some(allowance_mm)) = (&hand, &part_shape, keep_out) {
        let att = tracked.attachment.clone();
        let solver = Solver::new(&kin, &att, ik_opts.clone());
        let obs = observations(&att, &trial);
        let opts = KeepOutOptions {
            allowance_mm,
            ..KeepOutOptions::default()
        };
        let k = keep_out_of_part(&kin, &solver, &obs, &mut tracked, h, p, &opts)?;
        log::debug!(
            "track: {} frames kept out of the part (deepest skin point {:.2} -> {:.2} mm)",
            k.frames.len(),
            k.deepest_before_mm,
            k.deepest_after_mm
        );
        if !k.still_inside.is_empty() {
            warnings.push(format!(
                "{}: the skin stays more than {} mm inside the part in {} frames, where the \
                 markers hold the hand there (up to {:.1} mm): frames {}",
                trial.source.display(),
                opts.allowance_mm + 1.0,
                k.still_inside.len(),
                k.deepest_after_mm,
                crate::track::ranges(&k.still_inside)
            ));
        }
        lap("keeping the skin out of the part");
    }
    let replay = match (&hand, &part_shape, &scene) {
        (Some(h), Some(p), Some(s)) => Some(contacts(
            h,
            p,
            s,
            &kin,
            &tracked,
            &replay_opts,
            &mut warnings,
        )),
        _ => None,
    };
    lap("contacts");
    let animated = match &hand {
        Some(h) => {
            Some(tracked.animated_scene(&kin, &h.hand, part_shape.as_ref().map(|p| &p.mesh))?)
        }
        None => None,
    };
    lap("the animated scene");
    let map = match (&hand, &part_shape, &replay) {
        (Some(h), Some(p), Some(r)) => Some(crate::validate::motion_contact_map::contact_map(
            h, &kin, &tracked, &p.mesh, r,
        )?),
        _ => None,
    };
    lap("the contact map");
    let records = replay
        .as_ref()
        .map(ContactReplay::records)
        .unwrap_or_default();
    let mut file = tracked.motion_file(&kin, records);
    file.warnings = warnings.clone();
    let _held = crate::io::atomic::FolderLock::acquire(out)?;
    let written = out.join("motion.json");
    let (json, glb_written) = rayon::join(
        || file.write(&written),
        || -> Result<Option<Vec<u8>>> {
            match &animated {
                Some(a) => {
                    let bytes = glb_bytes(a, Units::Metres).map_err(|e| e.in_file(&glb))?;
                    write_bytes_atomic(&glb, &bytes)?;
                    Ok(Some(bytes))
                }
                None => {
                    remove_stale(&glb)?;
                    Ok(None)
                }
            }
        },
    );
    json?;
    let motion_glb = glb_written?;
    lap("motion.json and motion.glb");
    let (map_png, map_glb) = write_map(out, map.as_ref())?.unzip();
    if map.is_none() && hand.is_some() {
        log::log!(
            voice.info(),
            "track {motion}: no --scene, so no part and no contact map"
        );
    }
    let title = format!(
        "{} \u{b7} {motion}",
        subject.dir.file_name().map_or_else(
            || subject.dir.display().to_string(),
            |n| n.to_string_lossy().into_owned()
        )
    );
    let mut sources: Vec<String> = subject
        .motions
        .get(motion)
        .map(|p| subject.dir.join(p).display().to_string())
        .into_iter()
        .collect();
    sources.push(model_dir.join("link_model.json").display().to_string());
    if let Some(s) = &scene {
        sources.push(s.path.display().to_string());
    }
    write_charts_and_page(out, &title, &sources, &file, map_png)?;
    write_view_pages(out, &title, &file, motion_glb, map.as_ref().zip(map_glb))?;
    lap("the contact map's pictures, the charts and the pages");
    for w in &warnings {
        log::log!(voice.warn(), "{w}");
    }
    let unsolved = file.unsolved_frames.len();
    log::log!(
        voice.info(),
        "track {motion}: {} frames at {} Hz, {} solved -> {}",
        file.frames,
        file.rate,
        file.frames - unsolved,
        written.display()
    );
    Ok(TrackSummary {
        written,
        frames: file.frames,
        unsolved,
        warnings,
    })
}

/// Remove `path` if a previous run left it (an output this run does not write).
fn remove_stale(path: &Path) -> Result<()> {
    if path.is_file() {
        std::fs::remove_file(path).map_err(|e| Error::io(path, e))?;
    }
    Ok(())
}

/// Write `contact_map.png` and `contact_map.glb` of `map` into `out` and return their bytes,
/// or remove stale ones when there is no map.
fn write_map(out: &Path, map: Option<&ContactMap>) -> Result<Option<(Vec<u8>, Vec<u8>)>> {
    let (png, glb) = (out.join(OUTPUT_FILES[2]), out.join(OUTPUT_FILES[3]));
    match map {
        Some(m) => {
            let bytes = contact_map_picture(m, 420)?.to_png()?;
            write_bytes_atomic(&png, &bytes)?;
            let g = glb_bytes(&contact_map_scene(m), Units::Metres).map_err(|e| e.in_file(&glb))?;
            write_bytes_atomic(&glb, &g)?;
            Ok(Some((bytes, g)))
        }
        None => {
            remove_stale(&png)?;
            remove_stale(&glb)?;
            Ok(None)
        }
    }
}

/// The 3-D pages of the trial: `view.html` (the animated `motion.glb`) and
/// `contact_map.view.html` (`contact_map.glb` with its legend), each written when its GLB is,
/// a stale one removed when it is not.
fn write_view_pages(
    out: &Path,
    title: &str,
    file: &crate::track::MotionFile,
    motion_glb: Option<Vec<u8>>,
    map: Option<(&ContactMap, Vec<u8>)>,
) -> Result<()> {
    use crate::validate::pages::{track_contact_page, track_motion_page};
    use crate::validate::view_page::{view_html, ViewFrame};
    let (motion_page, map_page) = (out.join(OUTPUT_FILES[7]), out.join(OUTPUT_FILES[8]));
    match motion_glb {
        Some(g) => write_bytes_atomic(
            &motion_page,
            view_html(&track_motion_page(title, file, g)).as_bytes(),
        )?,
        None => remove_stale(&motion_page)?,
    }
    match map {
        Some((m, g)) => {
            let (origin, [dorsal, radial, distal]) = m.posed_frame;
            let frame = ViewFrame {
                origin,
                dorsal,
                radial,
                distal,
            };
            let page = track_contact_page(title, file, g, m.frames, m.frame, frame);
            write_bytes_atomic(&map_page, view_html(&page).as_bytes())?
        }
        None => remove_stale(&map_page)?,
    }
    Ok(())
}

/// Write `angles.png`, `contact_area.png` and `report.html` (with the contact map's picture
/// `map_png` when there is one) for the trial `file`.
fn write_charts_and_page(
    out: &Path,
    title: &str,
    sources: &[String],
    file: &crate::track::MotionFile,
    map_png: Option<Vec<u8>>,
) -> Result<()> {
    let mut pictures = Vec::new();
    if let Some(png) = map_png {
        pictures.push(PagePicture {
            png,
            file: OUTPUT_FILES[2].into(),
            caption: "Contact map: each place of the hand (open, at the reference posture, \
                      seen from the palm) and of the part coloured by the share of the tracked \
                      frames it touched; grey: never. The same colours on the hand and part \
                      at the frame of most contact: contact_map.glb."
                .into(),
        });
    }
    let charts = [
        (
            OUTPUT_FILES[4],
            angles_chart(file)?,
            "Joint angles against time: the flexion of each joint of each digit and the \
             wrist's flexion and abduction, degrees from the static trial's posture; gaps: \
             unsolved frames.",
        ),
        (
            OUTPUT_FILES[5],
            contact_area_chart(file)?,
            "Contact area of each digit and of the palm against time, and the RMS of the \
             markers' residuals per frame; gaps: frames whose contacts are unknown.",
        ),
    ];
    for (name, png, caption) in charts {
        write_bytes_atomic(&out.join(name), &png)?;
        pictures.push(PagePicture {
            png,
            file: name.into(),
            caption: caption.into(),
        });
    }
    let html = motion_report_html(title, sources, file, &pictures);
    write_bytes_atomic(&out.join(OUTPUT_FILES[6]), html.as_bytes())
}

/// The contacts of the model's skin with the scene's part over `tracked`, with a warning
/// naming the solved frames that have none for want of the part's pose.
fn contacts(
    hand: &SkinnedHand,
    part: &PartShape,
    scene: &Scene,
    kin: &crate::track::Kinematics,
    tracked: &Tracked,
    opts: &ReplayOptions,
    warnings: &mut Vec<String>,
) -> ContactReplay {
    let replay = replay_contacts(hand, kin, tracked, part, opts);
    let missing = replay.missing(tracked);
    if !missing.is_empty() {
        warnings.push(format!(
            "{}: the part's pose is unknown (fewer than three of its markers seen) in {} solved \
             frames, which have no contacts: frames {}",
            scene.path.display(),
            missing.len(),
            crate::track::ranges(&missing)
        ));
    }
    replay
}
