//! `ergohand demo`: every stage on the default subject.

use super::batch::MOTIONS_DIR;
use super::grasp::{demo_bottle, demo_bottle_scene};
use super::pose::{pose_job, PoseOptions};
use super::reconstruct::reconstruct_job;
use super::template::template;
use super::track::track_job;
use super::validate::validate_job;
use super::{create_dir, Voice};
use crate::anatomy::Side;
use crate::error::Result;
use crate::skin::pipeline::SkinOptions;
use crate::synth::{self, SynthOptions};
use std::path::Path;
use std::time::Instant;

/// The default subject of the demo: seed 1, typical errors, right hand, with its grasp of the
/// bottle captured.
pub fn default_subject_options() -> SynthOptions {
    SynthOptions {
        motion_s: Some(synth::grasp_motion::DEFAULT_MOTION_S),
        ..SynthOptions::new(1, synth::Preset::Typical)
    }
}

/// `ergohand demo`: every stage that exists, on the default subject, into `out`.
///
/// Today: the template, the simulated default subject, its link model
/// and the link model's validation against the truth; the skin, tetrahedral mesh,
/// posing and grasping join as they are built.
pub fn demo(out: &Path) -> Result<()> {
    let t0 = Instant::now();
    create_dir(out)?;
    let t = template(&out.join("template"), &[Side::Right, Side::Left])?;
    let subject_dir = out.join("subject");
    let opts = default_subject_options();
    let t1 = Instant::now();
    let s = synth::simulate(&opts)?;
    synth::write_subject(&subject_dir, &s, true)?;
    let synth_s = t1.elapsed().as_secs_f64();
    let model_dir = out.join("model");
    let report_dir = out.join("report");
    let t2 = Instant::now();
    // Every stage's warnings, as report.json lists them (the link model's among them).
    let model_warnings = reconstruct_job(
        &subject_dir,
        &model_dir,
        &SkinOptions::default(),
        None,
        None,
        Voice::Nested,
    )?
    .report
    .warnings
    .len();
    let link_s = t2.elapsed().as_secs_f64();
    // The captured grasp replayed with the subject's own hand, where `validate` finds it.
    let t3 = Instant::now();
    let scene = demo_bottle_scene(&out.join("grasp"))?;
    let motion = "grasp_bottle";
    let track_dir = model_dir.join(MOTIONS_DIR).join(motion);
    let tracked = track_job(
        &subject_dir,
        &model_dir,
        motion,
        Some(&scene),
        None,
        &track_dir,
        Voice::Nested,
    )?;
    let track_s = t3.elapsed().as_secs_f64();
    let fist = pose_job(
        &model_dir,
        "fist",
        &model_dir.join("fist.glb"),
        &PoseOptions::default(),
        Voice::Nested,
    )?;
    let grasp_dir = out.join("grasp");
    let grasp = demo_bottle(&model_dir, &grasp_dir)?;
    // Validated last, so that its report has the grasp and the posed fist in it.
    let v = validate_job(
        &subject_dir,
        &model_dir,
        &report_dir,
        &[],
        std::slice::from_ref(&grasp_dir),
        Voice::Nested,
    )?;
    let (acc, surface) = v.against_references(&subject_dir)?;
    if super::show_summaries() {
        println!(
            "ergohand demo: stages run: template, synth, link model, skin (sections 3.5-3.6), tetrahedral mesh, skinned hand, track, pose, grasp, validation report"
        );
        for h in &t.hands {
            let (lo, hi) = h.mesh.bounds().expect("non-empty template");
            println!(
                "  {} template: {} vertices / {} faces, {:.0} x {:.0} x {:.0} mm, {} landmarks",
                h.side,
                h.mesh.n_vertices(),
                h.mesh.n_faces(),
                hi.x - lo.x,
                hi.y - lo.y,
                hi.z - lo.z,
                h.spec.landmarks.len()
            );
        }
        let frames: usize = s.trials.values().map(|t| t.n_frames()).sum();
        println!(
            "  default subject {} (seed {}, {}): {} trials / {} frames, reference surface {} faces, volume {:.0} cm³ (true {:.0} cm³), {:.1} s",
            s.subject.name,
            opts.seed,
            opts.preset.name(),
            s.trials.len(),
            frames,
            s.reference.n_faces(),
            s.reference.signed_volume() / 1000.0,
            s.true_skin.signed_volume() / 1000.0,
            synth_s
        );
        let errs = |three: bool| -> Vec<f64> {
            let mut v: Vec<f64> = acc
                .joints
                .iter()
                .filter(|e| {
                    crate::anatomy::Joint::from_name(&e.joint).map(|j| j.dof() == 3) == Some(three)
                })
                .map(|e| e.centre_mm)
                .collect();
            v.sort_by(f64::total_cmp);
            v
        };
        let (e3, e1) = (errs(true), errs(false));
        println!(
            "  reconstruction (link model, skin, tet, hand) in {:.2} s, {} warnings (report.json); link model centre error vs truth: 3-DOF median {:.2} mm (max {:.2}), 1-DOF median {:.2} mm (max {:.2})",
            link_s,
            model_warnings,
            e3[e3.len() / 2],
            e3.last().copied().unwrap_or(0.0),
            e1[e1.len() / 2],
            e1.last().copied().unwrap_or(0.0)
        );
        println!(
            "  skin: homologous to the template ({} faces); distance to the CT-like reference: mean {:.2} mm, 95th percentile {:.2} mm, max {:.2} mm",
            t.hands[0].mesh.n_faces(),
            surface.mean_mm,
            surface.p95_mm,
            surface.max_mm
        );
        println!(
            "  pose `fist` on the reconstructed hand: deepest finger-finger penetration {:.2} mm ({} joints moved to keep the digits apart)",
            fist.penetration_mm,
            fist.warnings.len()
        );
        println!(
            "  grasp of the 60 mm bottle (power, reconstructed hand): force closure {}, epsilon {:.4}, volume {}, holds {}, contact {:.0} mm², {}, {:.1} s; {}",
            grasp.force_closure,
            grasp.epsilon,
            grasp.volume.map_or("not computed".into(), |v| format!("{v:.2e}")),
            grasp.holds,
            grasp.total_contact_area_mm2,
            grasp.envelope.describe(),
            grasp.timings_s.total_s,
            out.join("grasp").join("grasp.json").display()
        );
        let scored = v
            .motions
            .iter()
            .find(|m| m.motion == motion)
            .and_then(|m| Some((m.centre.as_ref()?.rms_mm, m.tip.as_ref()?.rms_mm)))
            .map_or(String::new(), |(c, t)| {
                format!(" joint centres {c:.2} mm RMS from the truth, fingertips {t:.1} mm;")
            });
        println!(
            "  track of the captured grasp `{motion}` with the reconstructed hand: {} of {} frames solved,{scored} {} warnings, {:.1} s; {}",
            tracked.frames - tracked.unsolved,
            tracked.frames,
            tracked.warnings.len(),
            track_s,
            tracked.written.display()
        );
        println!("  files:");
        for f in &t.files {
            println!("    {}", f.display());
        }
        println!(
            "    {}/ (subject.toml, trials/*.c3d, reference.ply, truth.json)",
            subject_dir.display()
        );
        println!("    {}", model_dir.join("link_model.json").display());
        println!(
            "    {}/ (motion.json, motion.glb, view.html, contact_map.view.html)",
            track_dir.display()
        );
        for f in [
            "skin.obj",
            "tet.vtk",
            "tet.msh",
            "hand.glb",
            "fist.glb",
            "fist.baked.glb",
            "fist.pose.json",
            "report.json",
        ] {
            println!("    {}", model_dir.join(f).display());
        }
        println!("    {}", report_dir.join("metrics.json").display());
        println!("    {}", report_dir.join("report.md").display());
        println!(
            "    {} (the fist in 3-D with joint sliders: open it in a browser)",
            fist.view.display()
        );
        println!(
            "    {} (the skin's error map in 3-D)",
            report_dir.join("view.html").display()
        );
        println!(
            "    {} (the grasp in 3-D: open it in a browser)",
            out.join("grasp").join("view.html").display()
        );
        println!(
            "  done in {:.1} s; open {} and {}",
            t0.elapsed().as_secs_f64(),
            report_dir.join("report.html").display(),
            out.join("grasp").join("view.html").display()
        );
    }
    Ok(())
}
