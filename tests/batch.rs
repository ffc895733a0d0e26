//! `ergohand batch` as a user meets it: two simulated subjects and a broken one; the good ones
//! are reconstructed, the broken one is named and skipped, the exit status says so; a rerun
//! skips what is up to date and redoes a subject whose input changed.

use std::collections::BTreeSet;
use std::path::Path;
mod common;
use common::{ergohand, stderr};

/// The status of each subject in `OUT/batch-summary.json`.
fn statuses(out: &Path) -> Vec<(String, String)> {
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("batch-summary.json")).unwrap())
            .unwrap();
    j["subjects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["subject"].as_str().unwrap().to_string(),
                s["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

fn mtime(p: &Path) -> std::time::SystemTime {
    std::fs::metadata(p).unwrap().modified().unwrap()
}

#[test]
fn batch_reconstructs_skips_failures_and_reruns_only_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let subjects = dir.path().join("subjects");
    let out = dir.path().join("out");
    let (sd, od) = (subjects.to_str().unwrap(), out.to_str().unwrap());
    for (name, seed, preset) in [("a", "11", "clean"), ("b", "12", "typical")] {
        let s = subjects.join(name);
        let o = ergohand(&[
            "synth",
            "--seed",
            seed,
            "--preset",
            preset,
            "--duration",
            "6",
            "--out",
            s.to_str().unwrap(),
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // "broken": a subject.toml naming trials that are not there.
    let broken = subjects.join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    std::fs::copy(subjects.join("a/subject.toml"), broken.join("subject.toml")).unwrap();
    // Not a subject folder: ignored.
    std::fs::create_dir_all(subjects.join("notes")).unwrap();

    let o = ergohand(&["batch", sd, "--out", od, "--jobs", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    let last = err.lines().last().unwrap();
    assert!(
        last.starts_with("error: ") && last.contains("broken") && last.contains("1 of 3"),
        "{err}"
    );
    // The failing subject's own one-line error names it and the missing trial.
    assert!(
        err.lines()
            .any(|l| l.contains("subject broken failed") && l.contains(".c3d")),
        "{err}"
    );
    let expected: BTreeSet<String> = ergohand::cli::batch::OUTPUTS
        .iter()
        .map(|s| s.to_string())
        .collect();
    for name in ["a", "b"] {
        let files: BTreeSet<String> = std::fs::read_dir(out.join(name))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(files, expected, "{name}: exactly what reconstruct writes");
    }
    assert!(!out.join("broken/report.json").exists());
    assert!(!out.join("notes").exists());
    assert_eq!(
        statuses(&out),
        [("a", "ok"), ("b", "ok"), ("broken", "failed")].map(|(a, b)| (a.into(), b.into()))
    );
    let md = std::fs::read_to_string(out.join("batch-summary.md")).unwrap();
    let row = md.lines().find(|l| l.starts_with("| broken |")).unwrap();
    assert!(row.contains("failed") && row.contains(".c3d"), "{row}");
    // The table is also printed on stderr.
    assert!(err.contains("| a | ok |"), "{err}");

    // Rerun: a and b are up to date and skipped (and said so), their files untouched.
    let before = mtime(&out.join("a/skin.obj"));
    let o = ergohand(&["batch", sd, "--out", od]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("up to date"), "{}", stderr(&o));
    assert_eq!(
        statuses(&out),
        [
            ("a", "skipped-up-to-date"),
            ("b", "skipped-up-to-date"),
            ("broken", "failed")
        ]
        .map(|(a, b)| (a.into(), b.into()))
    );
    assert_eq!(mtime(&out.join("a/skin.obj")), before);

    // A changed input (b's index trial rewritten as it was) redoes b only; without the broken
    // subject the batch succeeds, quietly.
    let trial = subjects.join("b/trials/index.c3d");
    let bytes = std::fs::read(&trial).unwrap();
    std::fs::write(&trial, bytes).unwrap();
    std::fs::remove_dir_all(&broken).unwrap();
    let o = ergohand(&["batch", sd, "--out", od, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stderr.is_empty(), "--quiet: {}", stderr(&o));
    assert_eq!(
        statuses(&out),
        [("a", "skipped-up-to-date"), ("b", "ok")].map(|(a, b)| (a.into(), b.into()))
    );
    assert!(mtime(&out.join("b/skin.obj")) > mtime(&trial));
    assert_eq!(mtime(&out.join("a/skin.obj")), before);

    // Tracking: every subject's motion, with the bottle scene for it, into
    // <subject>/motions/<motion>/; the reconstructions stay as they are (up to date), and each
    // motion.json is the very file `ergohand track` writes for that subject and motion.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
    let scene_arg = format!("grasp_bottle={}", scene.display());
    let o = ergohand(&["batch", sd, "--out", od, "--track", "--scene", &scene_arg]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("| b | grasp_bottle |"),
        "{}",
        stderr(&o)
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("batch-summary.json")).unwrap())
            .unwrap();
    for (k, name) in ["a", "b"].into_iter().enumerate() {
        let row = &j["subjects"][k];
        assert_eq!(row["status"], "skipped-up-to-date");
        let m = &row["motions"][0];
        assert_eq!(m["motion"], "grasp_bottle");
        assert!(m["error"].is_null(), "{m}");
        let truth: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(subjects.join(name).join("truth_motion/grasp_bottle.json"))
                .unwrap(),
        )
        .unwrap();
        assert_eq!(m["frames"], truth["frames"]);
        let direct = dir.path().join(format!("direct-{name}"));
        let o = ergohand(&[
            "track",
            subjects.join(name).to_str().unwrap(),
            "--model",
            out.join(name).to_str().unwrap(),
            "--motion",
            "grasp_bottle",
            "--scene",
            scene.to_str().unwrap(),
            "--out",
            direct.to_str().unwrap(),
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let tracked = out.join(name).join("motions/grasp_bottle");
        assert_eq!(
            std::fs::read(tracked.join("motion.json")).unwrap(),
            std::fs::read(direct.join("motion.json")).unwrap(),
            "{name}: batch and track disagree"
        );
        assert!(tracked.join("motion.glb").is_file());
    }
    assert_eq!(mtime(&out.join("a/skin.obj")), before);
    // --scene without --track, and a scene that is not there: usage errors before any work.
    let o = ergohand(&["batch", sd, "--out", od, "--scene", &scene_arg]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--track"), "{}", stderr(&o));
    let o = ergohand(&[
        "batch",
        sd,
        "--out",
        od,
        "--track",
        "--scene",
        "x=nope.toml",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("nope.toml"), "{}", stderr(&o));

    // The default fits with the shipped shape prior, and the report names it; another
    // choice (none) redoes every subject with it, and the report says none; a prior file that
    // is not there is an error naming it, before any work.
    let prior_of = |name: &str| -> serde_json::Value {
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(name).join("report.json")).unwrap(),
        )
        .unwrap();
        report["skin"]["shape_prior"].clone()
    };
    assert_eq!(
        prior_of("a").as_str(),
        Some(
            ergohand::skin::shape_prior::ShapePrior::builtin()
                .summary()
                .as_str()
        ),
    );
    let o = ergohand(&["batch", sd, "--out", od, "--shape-prior", "none", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        statuses(&out),
        [("a", "ok"), ("b", "ok")].map(|(a, b)| (a.into(), b.into()))
    );
    assert!(prior_of("a").is_null(), "{}", prior_of("a"));
    let o = ergohand(&[
        "batch",
        sd,
        "--out",
        od,
        "--shape-prior",
        "no-such-prior.json",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no-such-prior.json"), "{}", stderr(&o));
    assert!(mtime(&out.join("a/skin.obj")) > before);

    // Bad use: --jobs 0, and a folder without subjects; one-line errors.
    let o = ergohand(&["batch", sd, "--out", od, "--jobs", "0"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--jobs"), "{}", stderr(&o));
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = ergohand(&["batch", empty.to_str().unwrap(), "--out", od]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("subject.toml") && e.contains("empty"), "{e}");
}
