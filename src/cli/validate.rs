//! `ergohand validate`: one reconstruction against its subject, or the whole validation suite.

use super::reconstruct::reconstruct_job;
use super::{create_dir, Voice};
use crate::error::{Error, Result};
use crate::io::atomic;
use crate::skin::pipeline::SkinOptions;
use crate::synth;
use std::path::Path;
use std::time::Instant;

/// What `validate` measured (see [`crate::validate::SubjectValidation`]).
pub type Validation = crate::validate::SubjectValidation;

/// `ergohand validate SUBJECT_DIR --model OUT [--report DIR]`: the link model against
/// `truth.json` (per-joint centre and axis errors, link lengths), `skin.obj` against
/// `reference.ply` both ways, the caliper dimensions measured on `skin.obj` and the joint fits
/// of the seed paper's Figures 8-9, into `DIR/metrics.json`, `DIR/report.html` (self-contained)
/// and `DIR/report.md` with the pictures and charts beside them; tables on stdout. Both
/// references are optional (a real subject has no `truth.json`): what needs a missing one is
/// skipped, and the report says so.
pub fn validate(subject_dir: &Path, model: &Path, report: &Path) -> Result<Validation> {
    validate_job(subject_dir, model, report, &[], &[], Voice::Command)
}

/// [`validate`], with the tracked motions of the `track` output folders `motions` scored
/// against the subject's motion truths (besides those found in `MODEL/motions/NAME/`), and the
/// `grasp` output folders `grasps` in the report's grasp section.
pub fn validate_with(
    subject_dir: &Path,
    model: &Path,
    report: &Path,
    motions: &[std::path::PathBuf],
    grasps: &[std::path::PathBuf],
) -> Result<Validation> {
    validate_job(subject_dir, model, report, motions, grasps, Voice::Command)
}

/// [`validate_with`], speaking with `voice`: the tables on stdout only for the command's own
/// job.
pub(crate) fn validate_job(
    subject_dir: &Path,
    model: &Path,
    report: &Path,
    motions: &[std::path::PathBuf],
    grasps: &[std::path::PathBuf],
    voice: Voice,
) -> Result<Validation> {
    let spinner = match voice {
        Voice::Command => super::progress(1, "validate"),
        Voice::Nested => indicatif::ProgressBar::hidden(),
    };
    let (v, _) =
        crate::validate::validate_subject_with(subject_dir, model, report, motions, grasps)?;
    spinner.finish_and_clear();
    let dims = &v.dimensions;
    if voice == Voice::Command && super::show_summaries() {
        if let Some(acc) = &v.link {
            println!("joint    centre error (mm)   axis error (deg)");
            for e in &acc.joints {
                let axis = e
                    .axis_deg
                    .map(|a| format!("{a:.2}"))
                    .unwrap_or_else(|| "-".into());
                println!("{:8} {:>10.2}          {:>8}", e.joint, e.centre_mm, axis);
            }
        }
        if let (Some(surface), Some(r)) = (&v.surface, &v.surface_reverse) {
            println!(
                "skin.obj to reference.ply: mean {:.2} mm, SD {:.2}, 95th percentile {:.2}, max {:.2} mm over {} vertices",
                surface.mean_mm, surface.sd_mm, surface.p95_mm, surface.max_mm, surface.n
            );
            println!(
                "reference.ply to skin.obj: mean {:.2} mm, SD {:.2}, 95th percentile {:.2}, max {:.2} mm over {} vertices",
                r.mean_mm, r.sd_mm, r.p95_mm, r.max_mm, r.n
            );
        }
        if let Some(regions) = &v.surface_regions {
            println!("region                     vertices  mean  95th pct   max (mm)");
            for e in regions
                .regions
                .iter()
                .chain(std::iter::once(&regions.hand_distal_of_wrist))
            {
                println!(
                    "{:26} {:>8} {:>5.2} {:>9.2} {:>10.2}",
                    e.region, e.vertices, e.mean_mm, e.p95_mm, e.max_mm
                );
            }
        }
        if let Some(acc) = &v.link {
            println!("link         estimated    true (mm)");
            for (k, (m, t)) in &acc.link_lengths {
                println!("{k:12} {m:>8.2} {t:>10.2}");
            }
        } else {
            println!("link         estimated (mm)");
            for (k, m) in &v.link_lengths_mm {
                println!("{k:12} {m:>8.2}");
            }
        }
        // The true column only when truth.json gave true values.
        let with_true = dims.vs_true_mm.is_some();
        println!(
            "dimension                     on skin    given{}",
            if with_true { "     true (mm)" } else { " (mm)" }
        );
        for e in &dims.dimensions {
            let t = match (with_true, e.true_mm) {
                (false, _) => String::new(),
                (true, Some(t)) => format!(" {t:>8.2}"),
                (true, None) => format!(" {:>8}", "-"),
            };
            println!("{:28} {:>8.3} {:>8.3}{t}", e.name, e.skin_mm, e.given_mm);
        }
        println!(
            "dimensions on skin - given: mean {:+.3} mm, SD {:.3} mm",
            dims.mean_vs_given_mm, dims.sd_vs_given_mm
        );
        if let Some(r) = crate::validate::report_tables::references_sentence(&v) {
            println!("{r}");
        }
        for m in &v.motions {
            let mm = |r: &Option<crate::validate::motion_accuracy::Rms>| {
                r.map(|r| format!("{:.2} mm", r.rms_mm))
                    .unwrap_or_else(|| "-".into())
            };
            println!(
                "motion {}: centre RMS {}, fingertip RMS {}, marker residual RMS {}, {} of {} \
                 frames unsolved ({} lost)",
                m.motion,
                mm(&m.centre),
                mm(&m.tip),
                mm(&m.marker_residual),
                m.unsolved_frames,
                m.frames,
                m.lost_frames
                    .as_ref()
                    .map_or("?".to_string(), |l| l.len().to_string())
            );
            if let Some(h) = &m.hold_contacts {
                println!("link      hold area tracked   true (mm²)  ratio");
                for l in &h.links {
                    let r = l.ratio.map_or("-".to_string(), |r| format!("{r:.2}"));
                    println!(
                        "{:8} {:>12.1} {:>12.1} {:>6}",
                        l.link, l.tracked_mm2, l.true_mm2, r
                    );
                }
            }
        }
        let secs: f64 = v.validate_timings_s.iter().map(|x| x.1).sum();
        log::info!(
            "validate: {:.1} s; open {}",
            secs,
            report.join("report.html").display()
        );
    }
    Ok(v)
}

/// `ergohand validate --suite DIR`: every subject of `DIR/suite.toml` is generated (when its
/// folder is missing), reconstructed and compared with its truth; `REPORT/link-accuracy.md` and
/// `REPORT/suite-metrics.json` summarise the suite (medians per joint class, per preset).
pub fn validate_suite(dir: &Path, report: &Path) -> Result<()> {
    use crate::anatomy::Joint;
    let suite = synth::suite::read_suite_subjects(&dir.join("suite.toml"))?;
    let pb = super::progress(suite.len() as u64, "suite");
    let (mut rows, mut figures) = (Vec::new(), Vec::new());
    for s in &suite {
        let (name, opts) = (&s.name, &s.opts);
        pb.set_message(name.clone());
        let sdir = dir.join("subjects").join(name);
        if !synth::stamp::is_current(&sdir, opts) {
            // A simulation error names no file: the suite entry is the input at fault.
            let subject = synth::simulate(opts).map_err(|e| match e {
                Error::Invalid(m) => {
                    Error::input(dir.join("suite.toml"), format!("subject '{name}': {m}"))
                }
                other => other,
            })?;
            synth::write_subject(&sdir, &subject, true)?;
            synth::stamp::write(&sdir, opts)?;
        }
        let out = sdir.join("out");
        let t0 = Instant::now();
        reconstruct_job(
            &sdir,
            &out,
            &SkinOptions::default(),
            None,
            None,
            Voice::Nested,
        )?;
        let secs = t0.elapsed().as_secs_f64();
        let (v, _) = crate::validate::validate_subject(&sdir, &out, &out.join("report"))?;
        let (link, surface) = v.against_references(&sdir)?;
        let f = crate::validate::thresholds::Figures::measure(link, surface, &v.dimensions, &out)?;
        figures.push((name.clone(), f));
        rows.push((name.clone(), opts.clone(), s.held_out, v, secs));
        pb.inc(1);
    }
    pb.finish_and_clear();
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let class = |j: &str| -> &'static str {
        match Joint::from_name(j) {
            Some(j) if j.dof() == 3 => "MCP/CMC/WRIST",
            _ => "PIP/DIP/IP/T_MCP",
        }
    };
    let mut md = String::from(
        "# Link model and skin accuracy on the validation suite\n\nGenerated by `ergohand validate --suite validation/`. Errors against each simulated subject's truth.json, one table per body: the template body is the template deformed by its own skeleton (the template can always reach it), the procedural body is independent of the template. Subjects marked *held out* are never used to choose a method or a default.\n",
    );
    let mut summary = serde_json::Map::new();
    for body in synth::Body::ALL {
        if !rows.iter().any(|r| r.1.body == body) {
            continue;
        }
        md.push_str(&format!(
            "\n## {} body\n\n| subject | preset | hand | posture | median centre error 3-DOF (mm) | median centre error 1-DOF (mm) | median axis error (deg) | max centre error (mm) | skin to reference mean / max (mm) | dimensions on skin − given, mean ± SD (mm) | reconstruct time (s) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
            body.name()
        ));
        for (name, o, held_out, v, secs) in rows.iter().filter(|r| r.1.body == body) {
            let (acc, surf) = v.against_references(&dir.join("subjects").join(name))?;
            let dims = &v.dimensions;
            let c3: Vec<f64> = acc
                .joints
                .iter()
                .filter(|e| class(&e.joint) == "MCP/CMC/WRIST")
                .map(|e| e.centre_mm)
                .collect();
            let c1: Vec<f64> = acc
                .joints
                .iter()
                .filter(|e| class(&e.joint) != "MCP/CMC/WRIST")
                .map(|e| e.centre_mm)
                .collect();
            let ax: Vec<f64> = acc.joints.iter().filter_map(|e| e.axis_deg).collect();
            let max = acc.joints.iter().map(|e| e.centre_mm).fold(0.0, f64::max);
            md.push_str(&format!(
                "| {name}{} | {} | {} | {:?} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} / {:.2} | {:+.3} ± {:.3} | {:.2} |\n",
                if *held_out { " (held out)" } else { "" },
                o.preset.name(),
                o.hand,
                o.posture,
                median(c3.clone()),
                median(c1.clone()),
                median(ax.clone()),
                max,
                surf.mean_mm,
                surf.max_mm,
                dims.mean_vs_given_mm,
                dims.sd_vs_given_mm,
                secs
            ));
            summary.insert(
                name.clone(),
                serde_json::json!({"body": o.body.name(), "preset": o.preset.name(), "held_out": held_out, "median_centre_3dof_mm": median(c3), "median_centre_1dof_mm": median(c1), "median_axis_deg": median(ax), "max_centre_mm": max, "skin": surf, "surface_regions": v.surface_regions, "dimensions": dims, "seconds": secs, "joints": acc.joints}),
            );
        }
    }
    let region_groups: Vec<(String, Vec<&crate::validate::SubjectValidation>)> = synth::Body::ALL
        .iter()
        .map(|b| {
            let g = rows
                .iter()
                .filter(|r| r.1.body == *b)
                .map(|r| &r.3)
                .collect();
            (b.name().to_string(), g)
        })
        .filter(|g: &(String, Vec<&crate::validate::SubjectValidation>)| !g.1.is_empty())
        .collect();
    md.push_str("\n## Skin to reference per region\n\n");
    md.push_str(&crate::validate::report_md::table_markdown(
        &crate::validate::suite_index::region_summary_table(&region_groups),
    ));
    let mut tets = Vec::new();
    for (name, ..) in &rows {
        let q = crate::validate::tet_quality::read_tet_quality(
            &dir.join("subjects").join(name).join("out"),
        )?;
        if let Some(serde_json::Value::Object(m)) = summary.get_mut(name) {
            m.insert("tet".into(), serde_json::json!(q));
        }
        tets.push((name.clone(), q));
    }
    md.push_str(&crate::validate::tet_quality::tet_quality_markdown(&tets));
    create_dir(report)?;
    atomic::write_bytes_atomic(&report.join("link-accuracy.md"), md.as_bytes())?;
    let json =
        serde_json::to_string_pretty(&serde_json::Value::Object(summary)).expect("serialisable");
    atomic::write_bytes_atomic(&report.join("suite-metrics.json"), json.as_bytes())?;
    let index_rows: Vec<crate::validate::suite_index::SuiteRow> = rows
        .iter()
        .map(
            |(name, o, held_out, v, _)| crate::validate::suite_index::SuiteRow {
                name: name.clone(),
                opts: o.clone(),
                held_out: *held_out,
                validation: v,
                report: dir
                    .join("subjects")
                    .join(name)
                    .join("out/report/report.html"),
            },
        )
        .collect();
    let html = crate::validate::suite_index::suite_index_html(&index_rows, report);
    atomic::write_bytes_atomic(&report.join("index.html"), html.as_bytes())?;
    if super::show_summaries() {
        print!("{md}");
        log::info!("open {}", report.join("index.html").display());
    }
    // The regression check: an error naming each figure worse than its threshold.
    crate::validate::thresholds::check_suite(&dir.join(crate::validate::thresholds::FILE), &figures)
}
