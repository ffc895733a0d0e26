//! The command line as a user meets it: exit codes, one-line errors naming the file and item,
//! outputs that exist only when complete.

use ergohand::io::Units;
use std::path::Path;
mod common;
use common::{ergohand, error_line, stderr};

#[test]
fn synth_writes_a_subject_and_refuses_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("S");
    let out_s = out.to_str().unwrap();

    let o = ergohand(&["synth", "--seed", "3", "--out", out_s, "--preset", "typcal"]);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("--preset") && line.contains("typcal"),
        "{line}"
    );
    assert!(!out.exists(), "nothing written on bad input");

    let o = ergohand(&["synth", "--seed", "3", "--out", out_s, "--hand", "middle"]);
    assert!(error_line(&o).contains("--hand"));

    // A percentile hand: only of the procedural body, only strictly between 0 and 100.
    let pct = |extra: &[&str]| {
        let mut a = vec!["synth", "--seed", "3", "--out", out_s, "--sex", "female"];
        a.extend_from_slice(extra);
        ergohand(&a)
    };
    let line = error_line(&pct(&["--percentile", "5"]));
    assert!(
        line.contains("--percentile") && line.contains("--body procedural"),
        "{line}"
    );
    let line = error_line(&pct(&["--percentile", "100", "--body", "procedural"]));
    assert!(line.contains("--percentile 100"), "{line}");
    assert!(!out.exists(), "nothing written on bad input");

    let args = [
        "synth",
        "--seed",
        "3",
        "--out",
        out_s,
        "--duration",
        "2",
        "--quiet",
    ];
    let o = ergohand(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        o.stderr.is_empty(),
        "--quiet prints nothing: {}",
        stderr(&o)
    );
    for f in [
        "subject.toml",
        "truth.json",
        "reference.ply",
        "trials/index.c3d",
        "trials/reference.c3d",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }

    // An existing, non-empty folder needs --force.
    let o = ergohand(&args);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(line.contains(out_s) && line.contains("--force"), "{line}");
    let mut forced = args.to_vec();
    forced.push("--force");
    assert!(ergohand(&forced).status.success());

    // An unwritable place: the error names it.
    let blocked = dir.path().join("file");
    std::fs::write(&blocked, b"x").unwrap();
    let target = blocked.join("S");
    let o = ergohand(&[
        "synth",
        "--seed",
        "3",
        "--out",
        target.to_str().unwrap(),
        "--duration",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(error_line(&o).contains(blocked.to_str().unwrap()));
}

/// `ergohand validate SUBJECT --model MODEL --report REPORT -q`, which must succeed.
fn validate(subject: &Path, model: &Path, report: &Path) {
    let v = ergohand(&[
        "validate",
        subject.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "-q",
    ]);
    assert!(v.status.success(), "{}", stderr(&v));
}

/// The subject folder `subj` with only subject.toml and the trials, plus `reference.ply` and
/// `truth.json` as asked (hard links, nothing copied): a lab subject without simulation.
fn partial_subject(subj: &Path, to: &Path, with_reference: bool, with_truth: bool) {
    std::fs::create_dir_all(to.join("trials")).unwrap();
    let mut files = vec![std::path::PathBuf::from("subject.toml")];
    if with_reference {
        files.push("reference.ply".into());
    }
    if with_truth {
        files.push("truth.json".into());
    }
    for e in std::fs::read_dir(subj.join("trials")).unwrap() {
        files.push(Path::new("trials").join(e.unwrap().file_name()));
    }
    for f in files {
        std::fs::hard_link(subj.join(&f), to.join(&f)).unwrap();
    }
}

/// `validate` with a `truth.json` holding only the spec's fields (section 3: `joints` with
/// `centre` and `axis`, `dimensions`), as another simulator would write it, written by hand from
/// the full truth's values: it reports the very joint and dimension errors of the full truth.
fn validate_with_a_spec_only_truth(
    subj: &Path,
    model: &Path,
    full: &serde_json::Value,
    tmp: &Path,
) {
    partial_subject(subj, tmp, true, false);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(subj.join("truth.json")).unwrap()).unwrap();
    let mut joints = String::new();
    for (name, j) in truth["joints"].as_object().unwrap() {
        let c = &j["centre"];
        let axis = if j["axis"].is_null() {
            String::new()
        } else {
            format!(", \"axis\": {}", j["axis"])
        };
        if !joints.is_empty() {
            joints.push_str(",\n");
        }
        joints.push_str(&format!("    \"{name}\": {{ \"centre\": {c}{axis} }}"));
    }
    let text = format!(
        "{{ \"joints\": {{\n{joints}\n  }},\n  \"dimensions\": {} }}\n",
        truth["dimensions"]
    );
    assert!(!text.contains("frame") && !text.contains("reference_posture_deg"));
    std::fs::write(tmp.join("truth.json"), text).unwrap();
    let rep = tmp.join("rep");
    validate(tmp, model, &rep);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(rep.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["references"]["truth_json"], true);
    assert_eq!(m["link"], full["link"]);
    assert_eq!(m["link"]["joints"].as_array().unwrap().len(), 16);
    assert_eq!(m["dimensions"], full["dimensions"]);
    assert!(!m["dimensions"]["vs_true_mm"].is_null());
    // A truth.json without a 1-DOF joint's axis is refused, naming the file and the joint.
    let broken = std::fs::read_to_string(tmp.join("truth.json"))
        .unwrap()
        .replacen("\"axis\"", "\"axle\"", 1);
    std::fs::write(tmp.join("truth.json"), broken).unwrap();
    let o = ergohand(&[
        "validate",
        tmp.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
        "--report",
        rep.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("truth.json") && line.contains("axis"),
        "{line}"
    );
}

/// `validate` on the same reconstruction without `truth.json`, without both references, and
/// without `reference.ply` alone succeeds, writes `null` for what needs the missing file, the
/// very numbers of the full validation (`full`, its metrics.json) for everything else, and
/// says what it skipped.
fn validate_like_a_real_subject(subj: &Path, model: &Path, full: &serde_json::Value, tmp: &Path) {
    for (with_reference, with_truth) in [(true, false), (false, false), (false, true)] {
        let sdir = tmp.join(format!("S-{with_reference}-{with_truth}"));
        let rep = tmp.join(format!("rep-{with_reference}-{with_truth}"));
        partial_subject(subj, &sdir, with_reference, with_truth);
        validate(&sdir, model, &rep);
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(rep.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["references"]["truth_json"], with_truth);
        assert_eq!(m["references"]["reference_ply"], with_reference);
        if with_truth {
            assert_eq!(m["link"], full["link"]);
        } else {
            assert!(m["link"].is_null(), "{}", m["link"]);
        }
        // The model's own link lengths are the estimated ones of the full validation.
        let lengths = m["link_lengths_mm"].as_object().unwrap();
        let full_lengths = full["link"]["link_lengths"].as_object().unwrap();
        assert_eq!(lengths.len(), full_lengths.len());
        for (k, l) in lengths {
            assert_eq!(l, &full_lengths[k][0], "{k}");
        }
        // Dimensions against the calipers: the same numbers, with true values only with truth.
        let (d, fd) = (&m["dimensions"], &full["dimensions"]);
        assert_eq!(d["mean_vs_given_mm"], fd["mean_vs_given_mm"]);
        assert_eq!(d["sd_vs_given_mm"], fd["sd_vs_given_mm"]);
        if with_truth {
            assert_eq!(d, fd);
        } else {
            assert!(d["vs_true_mm"].is_null());
        }
        let rows = d["dimensions"].as_array().unwrap();
        assert_eq!(rows.len(), 22);
        for (a, b) in rows.iter().zip(fd["dimensions"].as_array().unwrap()) {
            assert_eq!(a["skin_mm"], b["skin_mm"]);
            assert_eq!(a["given_mm"], b["given_mm"]);
            assert_eq!(a["true_mm"].is_null(), !with_truth);
        }
        assert_eq!(m["joint_fits"], full["joint_fits"]);
        for key in [
            "surface",
            "surface_regions",
            "surface_reverse",
            "reference_vertices",
            "reference_stride",
            "colour_scale_top_mm",
        ] {
            if with_reference {
                assert_eq!(m[key], full[key], "{key}");
            } else {
                assert!(m[key].is_null(), "{key}: {}", m[key]);
            }
        }
        assert_eq!(rep.join("error-map.glb").is_file(), with_reference);
        assert_eq!(rep.join("joint-errors.png").is_file(), with_truth);
        // The reports say what was skipped and why, are self-contained and link only files
        // that exist.
        let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
        let md = std::fs::read_to_string(rep.join("report.md")).unwrap();
        ergohand::validate::report_html::check_self_contained(&html).unwrap();
        for text in [&html, &md] {
            assert_eq!(
                text.contains("no truth.json") && text.contains("truth.json absent"),
                !with_truth,
                "truth skip"
            );
            assert_eq!(
                text.contains("no reference.ply") && text.contains("reference.ply absent"),
                !with_reference,
                "reference skip"
            );
        }
        for id in [
            "error-map",
            "joint-fits",
            "joint-centres",
            "dimensions",
            "link-lengths",
        ] {
            assert!(html.contains(&format!("<section id=\"{id}\">")), "{id}");
        }
        for l in md.split("](").skip(1).map(|s| s.split(')').next().unwrap()) {
            assert!(rep.join(l).is_file(), "report.md links {l}");
        }
    }
}

/// `ergohand track` on the grasp trial synth wrote beside the calibration trials, scored
/// against synth's own record of the motion (`truth_motion/`): the subject is clean, so what
/// remains is the reconstructed link model's own error (its 1-DOF centres), not the tracker's.
/// The distance between two points, mm.
fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn track_the_grasp_trial(subj: &Path, model: &Path, out: &Path) {
    let (s, m, o) = (
        subj.to_str().unwrap(),
        model.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
    let scene = scene.to_str().unwrap();

    // A motion the subject does not have: the error names subject.toml and the motions there are.
    let r = ergohand(&["track", s, "--model", m, "--motion", "pour", "--out", o]);
    assert_eq!(r.status.code(), Some(1));
    let line = error_line(&r);
    assert!(
        line.contains("subject.toml") && line.contains("pour") && line.contains("grasp_bottle"),
        "{line}"
    );
    assert!(!out.exists());

    // The grasp trial tracked into `dir` with the bottle's scene, and `extra` options.
    let track_grasp = |dir: &str, extra: &[&str]| {
        let mut args = vec![
            "track",
            s,
            "--model",
            m,
            "--motion",
            "grasp_bottle",
            "--scene",
            scene,
            "--out",
            dir,
            "-q",
        ];
        args.extend_from_slice(extra);
        let r = ergohand(&args);
        assert!(r.status.success(), "{}", stderr(&r));
    };
    track_grasp(o, &[]);
    track_pages_hold_the_trial(out);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let got = read(&out.join("motion.json"));
    let truth = read(&subj.join("truth_motion/grasp_bottle.json"));
    let frames = truth["frames"].as_u64().unwrap() as usize;
    assert_eq!(got["frames"].as_u64(), Some(frames as u64));
    assert_eq!(got["units"], "mm");
    assert!(got["unsolved_frames"].as_array().unwrap().is_empty());
    let point = |v: &serde_json::Value| -> [f64; 3] {
        let a = v.as_array().unwrap();
        [0, 1, 2].map(|k| a[k].as_f64().unwrap())
    };
    // A tracked motion's joint centres against the truth's: (count, RMS, worst), mm.
    let centre_errors = |m: &serde_json::Value| -> (usize, f64, f64) {
        let (mut ss, mut n, mut worst) = (0.0, 0usize, 0.0f64);
        for (joint, t) in truth["joints"].as_object().unwrap() {
            for f in 0..frames {
                let d = distance(
                    point(&m["joints"][joint]["centre"][f]),
                    point(&t["centre"][f]),
                );
                ss += d * d;
                n += 1;
                worst = worst.max(d);
            }
        }
        (n, (ss / n as f64).sqrt(), worst)
    };
    let (n, rms, worst) = centre_errors(&got);
    assert!(
        n == 16 * frames && rms < 1.0 && worst < 3.0,
        "RMS {rms} mm, worst {worst} mm"
    );
    // The bottle follows its markers (Horn, exact without noise).
    let part = &got["part"]["pose"];
    for f in (0..frames).step_by(37) {
        let d = distance(
            point(&part[f]["translation_mm"]),
            point(&truth["part"]["position"][f]),
        );
        assert!(d < 1e-3, "frame {f}: part {d} mm off");
    }

    // Contacts: none while the hand is still far in the reach; in the hold, the thumb on the
    // bottle; in the lift the hand carries the bottle rigidly, so every frame's contact area
    // equals the hold's (the same relative pose, tracked afresh in each frame).
    let phase = |name: &str| -> (usize, usize) {
        let p = truth["phases"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap();
        (
            p["first"].as_u64().unwrap() as usize,
            p["last"].as_u64().unwrap() as usize,
        )
    };
    let mut area = vec![0.0; frames];
    let mut thumb = vec![false; frames];
    for c in got["contacts"].as_array().unwrap() {
        let f = c["frame"].as_u64().unwrap() as usize;
        area[f] += c["area_mm2"].as_f64().unwrap();
        thumb[f] |= c["link"].as_str().unwrap().starts_with("T_");
    }
    let (reach, _) = phase("reach");
    assert!(area[reach..reach + 40].iter().all(|&a| a == 0.0));
    let (h0, h1) = phase("hold");
    let (l0, l1) = phase("lift");
    let held = area[h0];
    assert!(
        held > 100.0 && (h0..=h1).all(|f| thumb[f]),
        "hold area {held} mm²"
    );
    for f in (h0..=h1).chain(l0..=l1) {
        assert!(
            (area[f] - held).abs() <= 0.01 * held,
            "frame {f}: {} mm² against {held} at the hold's start",
            area[f]
        );
    }

    // motion.glb: the skinned hand and the bottle, one keyframe per frame (all solved) at
    // frame / rate, the bottle's translation keyframes where motion.json puts it.
    let glb = ergohand::io::gltf::read_gltf(&out.join("motion.glb"), Units::Metres).unwrap();
    assert_eq!(glb.meshes.len(), 2);
    assert!(glb.meshes[0].skin.is_some() && glb.meshes[1].skin.is_none());
    assert_eq!(glb.animations.len(), 1);
    let rate = got["rate"].as_f64().unwrap();
    let channels = &glb.animations[0].channels;
    assert_eq!(channels.len(), 17 + 1 + 2);
    for ch in channels {
        assert_eq!(ch.times.len(), frames);
        assert!((ch.times[frames - 1] - (frames - 1) as f64 / rate).abs() < 1e-6);
    }
    let part_t = channels
        .iter()
        .find_map(|c| match (&c.target, &c.values) {
            (
                ergohand::io::gltf::AnimationTarget::Mesh(1),
                ergohand::io::gltf::Keyframes::Translation(v),
            ) => Some(v),
            _ => None,
        })
        .unwrap();
    for f in (0..frames).step_by(37) {
        let t = part_t[f];
        let d = distance(point(&part[f]["translation_mm"]), [t.x, t.y, t.z]);
        assert!(d < 1e-3, "frame {f}: glb part {d} mm from motion.json");
    }

    // The contact map, the charts and the page: the map's GLB carries one colour per vertex
    // of the hand and of the bottle, the hand's thumb touched (not grey) in the hold; the
    // pictures decode; the page needs nothing outside itself.
    let map = ergohand::io::gltf::read_gltf(&out.join("contact_map.glb"), Units::Metres).unwrap();
    assert_eq!(map.meshes.len(), 2);
    for m in &map.meshes {
        assert_eq!(m.colors.as_ref().unwrap().len(), m.mesh.n_vertices());
    }
    assert_eq!(
        map.meshes[0].mesh.n_vertices(),
        glb.meshes[0].mesh.n_vertices()
    );
    // The same counts through an independent reader: COLOR_0 as long as POSITION.
    let peer = gltf::Gltf::open(out.join("contact_map.glb")).unwrap();
    for mesh in peer.meshes() {
        for p in mesh.primitives() {
            let n = p.get(&gltf::Semantic::Positions).unwrap().count();
            assert_eq!(p.get(&gltf::Semantic::Colors(0)).unwrap().count(), n);
        }
    }
    let grey = |c: &[f32; 4]| c[0] == c[1] && c[1] == c[2];
    for m in &map.meshes {
        let touched = m
            .colors
            .as_ref()
            .unwrap()
            .iter()
            .filter(|c| !grey(c))
            .count();
        assert!(touched > 100, "{}: {touched} vertices coloured", m.name);
    }
    for (name, size) in [
        ("contact_map.png", None),
        (
            "angles.png",
            Some(ergohand::validate::motion_plots::ANGLES_SIZE),
        ),
        (
            "contact_area.png",
            Some(ergohand::validate::motion_plots::CONTACT_AREA_SIZE),
        ),
    ] {
        let img = image::open(out.join(name)).unwrap();
        if let Some((w, h)) = size {
            assert_eq!((img.width(), img.height()), (w, h), "{name}");
        }
    }
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(
        ergohand::validate::report_html::check_self_contained(&page),
        Ok(3)
    );
    assert!(page.contains("T_DIST") && page.contains("grasp_bottle"));

    // validate finds the tracked motion (given by --motion) and scores it against the
    // truth: the centres as measured above, the tips of every digit, the hold's contacts per
    // link against the true skin's, in metrics.json and both reports.
    let rep = out.with_file_name("TRACK_REPORT");
    let r = ergohand(&[
        "validate",
        s,
        "--model",
        m,
        "--report",
        rep.to_str().unwrap(),
        "--motion",
        o,
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let metrics = read(&rep.join("metrics.json"));
    let motions = metrics["motions"].as_array().unwrap();
    assert_eq!(motions.len(), 1);
    let mo = &motions[0];
    assert_eq!(mo["motion"], "grasp_bottle");
    assert!((mo["centre"]["rms_mm"].as_f64().unwrap() - rms).abs() < 1e-9);
    assert_eq!(mo["centre"]["samples"].as_u64(), Some(16 * frames as u64));
    assert_eq!(mo["tips"].as_object().unwrap().len(), 5);
    assert_eq!(mo["lost_frames"].as_array().map(Vec::len), Some(0));
    let hold = &mo["hold_contacts"];
    let (h0, h1) = phase("hold");
    assert_eq!(hold["frames"].as_u64(), Some((h1 - h0 + 1) as u64));
    let total = hold["links"].as_array().unwrap().last().unwrap();
    assert_eq!(total["link"], "TOTAL");
    assert!((total["tracked_mm2"].as_f64().unwrap() - held).abs() <= 0.01 * held);
    assert!(total["true_mm2"].as_f64().unwrap() > 0.0);
    for f in ["report.md", "report.html"] {
        let text = std::fs::read_to_string(rep.join(f)).unwrap();
        assert!(text.contains("Tracked motions against the truth"), "{f}");
    }

    // --keep-out 1 (the true skin is pressed 1 mm into the bottle in the hold): the frames
    // whose skin reaches deeper are solved again with the skin held out where the markers
    // allow. Measured the way the contacts are (every skin vertex, not the keep-out's sample),
    // the deepest penetration over the trial comes to within 1.5 mm of the allowance and never
    // grows, and the joint centres stay within the tracking goal (2 mm RMS; the keep-out costs
    // some of their accuracy, see the README). Without it the plain track follows the truth
    // deeper where synth's withdrawing thumb still grazes the bottle.
    let deepest = |m: &serde_json::Value| -> f64 {
        m["contacts"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["depth_mm"].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    let kept = out.with_file_name("TRACK_KEEP_OUT");
    track_grasp(kept.to_str().unwrap(), &["--keep-out", "1"]);
    let k = read(&kept.join("motion.json"));
    let (before, after) = (deepest(&got), deepest(&k));
    assert!(after < 2.5 && after <= before, "{before} -> {after} mm");
    let (_, kept_rms, _) = centre_errors(&k);
    assert!(kept_rms < 2.0, "centres {rms} -> {kept_rms} mm RMS");

    // A model folder without skin.obj: motion.json still, no motion.glb, a warning naming it.
    let bare = out.with_file_name("BARE_MODEL");
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::copy(model.join("link_model.json"), bare.join("link_model.json")).unwrap();
    let out2 = out.with_file_name("TRACK_BARE");
    let r = ergohand(&[
        "track",
        s,
        "--model",
        bare.to_str().unwrap(),
        "--motion",
        "grasp_bottle",
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(out2.join("motion.json").is_file() && !out2.join("motion.glb").exists());
    // No map without the skin, but the charts and the page (with the two charts).
    assert!(!out2.join("contact_map.png").exists() && !out2.join("contact_map.glb").exists());
    assert!(out2.join("angles.png").is_file() && out2.join("contact_area.png").is_file());
    let page = std::fs::read_to_string(out2.join("report.html")).unwrap();
    assert_eq!(
        ergohand::validate::report_html::check_self_contained(&page),
        Ok(2)
    );
    let warned = stderr(&r);
    assert!(
        warned
            .lines()
            .any(|l| l.contains("skin.obj") && l.contains("motion.glb")),
        "{warned}"
    );
}

#[test]
fn reconstruct_and_validate_a_simulated_subject() {
    let dir = tempfile::tempdir().unwrap();
    let subj = dir.path().join("S");
    let out = dir.path().join("OUT");
    let (s, o) = (subj.to_str().unwrap(), out.to_str().unwrap());

    // A folder without subject.toml: the error names the file.
    let o1 = ergohand(&["reconstruct", s, "--out", o]);
    assert_eq!(o1.status.code(), Some(1));
    assert!(error_line(&o1).contains("subject.toml"));
    assert!(!out.exists());

    let gen = ergohand(&[
        "synth",
        "--seed",
        "5",
        "--preset",
        "clean",
        "--out",
        s,
        "--duration",
        "8",
        "-q",
    ]);
    assert!(gen.status.success(), "{}", stderr(&gen));
    let r = ergohand(&["reconstruct", s, "--out", o, "-q"]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(out.join("link_model.json").is_file() && out.join("report.json").is_file());
    validate(&subj, &out, &out.join("rep"));
    validate_page_holds_the_error_map(&out.join("rep"));
    track_the_grasp_trial(&subj, &out, &dir.path().join("TRACK"));
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rep/metrics.json")).unwrap())
            .unwrap();
    // Every given dimension is measured on the skin by its definition. The skin fit's caliper
    // rounds read the same calipers on its own skin: a caliper on skin.obj meets the given
    // value (this subject is clean: no caliper noise) about within the fingers' slack, and the skin
    // stage's own readings (report.json) agree with validate's, taken from the written files.
    let dims = &metrics["dimensions"];
    assert_eq!(dims["dimensions"].as_array().unwrap().len(), 22, "{dims}");
    assert!(
        dims["not_measured"].as_object().unwrap().is_empty(),
        "{dims}"
    );
    let report = read_report(&out);
    let own = report["skin"]["caliper_residuals_mm"].as_object().unwrap();
    assert_eq!(own.len(), 22, "{own:?}");
    let slack = ergohand::skin::pipeline::FINGER_CALIPER_SLACK_MM;
    for d in dims["dimensions"].as_array().unwrap() {
        let name = d["name"].as_str().unwrap();
        let e = d["skin_mm"].as_f64().unwrap() - d["given_mm"].as_f64().unwrap();
        assert!(e.abs() <= slack + 0.5, "{d}");
        let r = own[name].as_f64().unwrap();
        assert!((r - e).abs() < 0.02, "{name}: skin stage {r}, validate {e}");
    }
    let pairs = report["skin"]["caliper_pair_residuals_mm"]
        .as_object()
        .unwrap();
    assert_eq!(pairs.len(), 22);
    // The report a person reads, self-contained, with every section and picture.
    let rep = out.join("rep");
    let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
    let images = ergohand::validate::report_html::check_self_contained(&html).unwrap();
    assert!(images >= 9, "{images} images");
    for id in [
        "error-map",
        "joint-fits",
        "joint-centres",
        "dimensions",
        "link-lengths",
        "runtime",
    ] {
        assert!(html.contains(&format!("<section id=\"{id}\">")), "{id}");
    }
    assert!(!html.contains(ergohand::validate::report_html::RUNTIME_PLACEHOLDER));
    // report.md links only files that exist beside it.
    let md = std::fs::read_to_string(rep.join("report.md")).unwrap();
    let links: Vec<&str> = md
        .split("](")
        .skip(1)
        .map(|s| s.split(')').next().unwrap())
        .collect();
    assert!(links.len() >= 17, "{links:?}");
    for l in links {
        assert!(rep.join(l).is_file(), "report.md links {l}");
    }
    // The error map's GLB: the skin with one colour per vertex.
    let glb =
        ergohand::io::gltf::read_gltf(&rep.join("error-map.glb"), ergohand::io::Units::Metres)
            .unwrap();
    let skin = ergohand::io::obj::read_obj(&out.join("skin.obj"), ergohand::io::Units::Millimetres)
        .unwrap();
    assert_eq!(glb.meshes.len(), 1);
    assert_eq!(glb.meshes[0].mesh.n_vertices(), skin.n_vertices());
    assert_eq!(
        glb.meshes[0].colors.as_ref().unwrap().len(),
        skin.n_vertices()
    );
    assert!(metrics["surface_reverse"]["mean_mm"].as_f64().unwrap() < 1.0);
    // The regions partition the skin's vertices, and their statistics recombine into the
    // whole skin's mean.
    let regions = metrics["surface_regions"]["regions"].as_array().unwrap();
    let n: u64 = regions
        .iter()
        .map(|r| r["vertices"].as_u64().unwrap())
        .sum();
    assert_eq!(n as usize, skin.n_vertices());
    let weighted: f64 = regions
        .iter()
        .map(|r| r["vertices"].as_f64().unwrap() * r["mean_mm"].as_f64().unwrap())
        .sum();
    let mean = metrics["surface"]["mean_mm"].as_f64().unwrap();
    assert!(
        (weighted / n as f64 - mean).abs() < 1e-9,
        "{weighted} {mean}"
    );
    let wrist = regions.iter().find(|r| r["region"] == "wrist").unwrap();
    assert_eq!(
        metrics["surface_regions"]["hand_distal_of_wrist"]["vertices"]
            .as_u64()
            .unwrap(),
        n - wrist["vertices"].as_u64().unwrap()
    );
    assert!(md.contains("per region") && html.contains("per region"));
    assert_eq!(metrics["joint_fits"].as_array().unwrap().len(), 16);
    // A real lab subject has no truth.json, and may have no reference.ply either.
    validate_like_a_real_subject(&subj, &out, &metrics, &dir.path().join("real"));
    // Another simulator writes only what the spec names in truth.json.
    validate_with_a_spec_only_truth(&subj, &out, &metrics, &dir.path().join("spec-only"));
    assert_eq!(report["skin"]["inverted_faces"], 0);
    // Section 3.7 and posing: the tetrahedral mesh and the skinned hand.
    assert_eq!(report["tet"]["inverted"], 0);
    assert!(
        report["tet"]["volume_error_percent"]
            .as_f64()
            .unwrap()
            .abs()
            < 1.0
    );
    for f in ["tet.vtk", "tet.msh", "hand.glb"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The hand poses from the reconstruction folder: a built-in pose into a GLB.
    let fist = dir.path().join("fist.glb");
    let p = ergohand(&[
        "pose",
        o,
        "--pose",
        "fist",
        "--out",
        fist.to_str().unwrap(),
        "-q",
    ]);
    assert!(p.status.success(), "{}", stderr(&p));
    assert!(fist.is_file());
    // ... and its tetrahedral mesh in the same pose: same nodes and elements as
    // tet.vtk, moved, with the same volume to a few percent.
    let rest = ergohand::io::vtk::read_vtk(&out.join("tet.vtk"), Units::Millimetres).unwrap();
    for ext in ["vtk", "msh"] {
        let posed_path = dir.path().join(format!("power.{ext}"));
        let p = ergohand(&[
            "pose",
            o,
            "--pose",
            "power-grasp",
            "--out",
            posed_path.to_str().unwrap(),
            "-q",
        ]);
        assert!(p.status.success(), "{}", stderr(&p));
        assert!(posed_path.is_file());
    }
    every_builtin_pose_keeps_its_elements_positive(&out, dir.path());
    let posed =
        ergohand::io::vtk::read_vtk(&dir.path().join("power.vtk"), Units::Millimetres).unwrap();
    assert_eq!(posed.tets, rest.tets);
    assert!(posed
        .nodes
        .iter()
        .zip(&rest.nodes)
        .any(|(a, b)| (a - b).norm() > 5.0));
    assert!((posed.volume() / rest.volume() - 1.0).abs() < 0.03);
    assert_eq!(posed.inverted_count(), 0);
    // In a fist, dual-quaternion skinning alone loses finger tissue; the default correction
    // gives it back (the segment-volume goal, checked per segment in the library's
    // tests), so the whole mesh's volume is closer to the rest volume with it.
    let mut change = Vec::new();
    for plain in [false, true] {
        let path = dir.path().join(format!("fist-{plain}.vtk"));
        let mut args = vec![
            "pose",
            o,
            "--pose",
            "fist",
            "--out",
            path.to_str().unwrap(),
            "-q",
        ];
        if plain {
            args.push("--plain-skinning");
        }
        let p = ergohand(&args);
        assert!(p.status.success(), "{}", stderr(&p));
        let m = ergohand::io::vtk::read_vtk(&path, Units::Millimetres).unwrap();
        change.push(m.volume() / rest.volume() - 1.0);
    }
    eprintln!(
        "fist volume change: corrected {:+.4}, plain {:+.4}",
        change[0], change[1]
    );
    assert!(change[0].abs() < change[1].abs(), "{change:?}");
    let p = ergohand(&[
        "pose",
        o,
        "--pose",
        "no-such-pose",
        "--out",
        fist.to_str().unwrap(),
    ]);
    assert_eq!(p.status.code(), Some(1));
    assert!(error_line(&p).contains("no-such-pose"), "{}", stderr(&p));
    assert!(report["skin"]["posture_deg"]["I_MCP"].is_array());
    assert!(report["skin"]["section_3_6_shift_mm"]["I_PIP"].is_f64());

    // Bad skin options are refused before anything is written.
    let o2 = dir.path().join("OUT2");
    for (flag, needle) in [
        ("--fit-resolution=medium", "medium"),
        ("--centre-weight=-1", "--centre-weight"),
    ] {
        let r = ergohand(&["reconstruct", s, "--out", o2.to_str().unwrap(), flag]);
        assert_eq!(r.status.code(), Some(1), "{flag}");
        assert!(error_line(&r).contains(needle), "{}", stderr(&r));
        assert!(!o2.exists());
    }
    // The full-resolution fit: a skin as close to the CT-like reference as the default's.
    let r = ergohand(&[
        "reconstruct",
        s,
        "--out",
        o2.to_str().unwrap(),
        "--fit-resolution=full",
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let rep2 = o2.join("rep");
    validate(&subj, &o2, &rep2);
    let surface = |p: &Path| -> f64 {
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p.join("metrics.json")).unwrap())
                .unwrap();
        m["surface"]["mean_mm"].as_f64().unwrap()
    };
    let (low, full) = (surface(&out.join("rep")), surface(&rep2));
    assert!(low < 1.0 && full < 1.0, "low {low} full {full}");
    grasp_and_pose_in_the_report(&subj, &out, dir.path());

    // A trial whose palm marker is unlabelled: the error names the trial and the marker.
    let toml = std::fs::read_to_string(subj.join("subject.toml")).unwrap();
    let relabelled = toml.replace("[labels]", "[labels]\n\"PALM_3\" = \"SOMETHING_ELSE\"");
    std::fs::write(subj.join("subject.toml"), relabelled).unwrap();
    let r = ergohand(&["reconstruct", s, "--out", o]);
    assert_eq!(r.status.code(), Some(1));
    let line = error_line(&r);
    assert!(line.contains(".c3d") && line.contains("PALM_3"), "{line}");
}

#[test]
fn template_writes_mesh_spec_and_picture() {
    let dir = tempfile::tempdir().unwrap();
    let o = ergohand(&["template", "--out", dir.path().to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "template-right.obj",
        "template-left.obj",
        "template-right.png",
        "template-left.png",
        "template-spec.toml",
    ] {
        let p = dir.path().join(f);
        assert!(
            p.is_file() && std::fs::metadata(&p).unwrap().len() > 1000,
            "{f}"
        );
    }
    // The spec written is the one shipped.
    let shipped =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/generic-hand/template-spec.toml");
    assert_eq!(
        std::fs::read_to_string(dir.path().join("template-spec.toml")).unwrap(),
        std::fs::read_to_string(shipped).unwrap()
    );
    // The OBJ reads back as the closed high-resolution template.
    let m = ergohand::io::obj::read_obj(
        &dir.path().join("template-right.obj"),
        ergohand::io::Units::Millimetres,
    )
    .unwrap();
    assert_eq!(m.n_faces(), 37_024);
    m.check_closed_manifold().unwrap();
}

/// `view.html` beside a grasp's files: its data (read as the page reads it) gives the grasp's
/// own figures and areas, its GLB is `grasp.glb` byte for byte, and the hand's frame is a
/// right-handed set of unit vectors.
fn view_page_holds_the_grasp(out: &Path, r: &serde_json::Value) {
    let html = std::fs::read_to_string(out.join("view.html")).unwrap();
    let between = |start: &str| {
        let a = html.find(start).unwrap() + start.len();
        &html[a..a + html[a..].find("</script>").unwrap()]
    };
    let data: serde_json::Value = serde_json::from_str(between(
        "<script id=\"ergohand-view-data\" type=\"application/json\">",
    ))
    .unwrap();
    let fact = |k: &str| {
        data["facts"]
            .as_array()
            .unwrap()
            .iter()
            .find(|f| f[0] == k)
            .unwrap_or_else(|| panic!("fact {k}"))[1]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(fact("force closure"), "yes");
    let eps: f64 = fact("epsilon").parse().unwrap();
    assert!((eps - r["epsilon"].as_f64().unwrap()).abs() < 1e-4);
    assert!(fact("holds").starts_with("yes: 6 of 6"));
    let rows = data["tables"][0]["rows"].as_array().unwrap();
    for row in rows {
        let a: f64 = row[1].as_str().unwrap().parse().unwrap();
        let want = r["contact_area_mm2"][row[0].as_str().unwrap()]
            .as_f64()
            .unwrap();
        assert!((a - want).abs() <= 0.05, "{row}");
    }
    assert_eq!(data["part_nodes"][0], "part");
    assert_eq!(
        data["meshes"][0]["value"],
        serde_json::json!({"attribute": "_DISTANCE_MM", "label": "distance to the part", "unit": "mm"})
    );
    let glb = between("<script id=\"ergohand-glb-0\" type=\"application/octet-stream\">");
    // The reference crate decodes it (an independent reader of the page's GLB).
    let decoded = base64::decode(glb).unwrap();
    assert_eq!(decoded, std::fs::read(out.join("grasp.glb")).unwrap());
    let f = &data["frame"];
    let v = |k: &str| -> [f64; 3] { std::array::from_fn(|i| f[k][i].as_f64().unwrap()) };
    let (d, ra, di) = (v("dorsal"), v("radial"), v("distal"));
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for (a, b) in [(d, ra), (d, di), (ra, di)] {
        assert!(dot(a, b).abs() < 1e-9);
    }
    for a in [d, ra, di] {
        assert!((dot(a, a) - 1.0).abs() < 1e-9);
    }
}

/// A caliper round may not buy its calipers with the markers: on this procedural left hand
/// (varied posture, typical capture, 20-s trials) the rounds kept shortening pairs whose
/// calipers did not follow them, and the last round left the wrist's markers 6.3 mm off their
/// offset from the skin (sections unscaled, so the skin written is the kept round's). The rounds
/// still run, and the kept round's markers stand within the warning level and its slack.
#[test]
fn caliper_rounds_keep_the_markers_where_they_stand() {
    let dir = tempfile::tempdir().unwrap();
    let (subj, out) = (dir.path().join("S"), dir.path().join("OUT"));
    let (s, o) = (subj.to_str().unwrap(), out.to_str().unwrap());
    let gen = ergohand(&[
        "synth",
        "--seed",
        "8007",
        "--body",
        "procedural",
        "--hand",
        "left",
        "--posture",
        "varied",
        "--preset",
        "typical",
        "--duration",
        "20",
        "--out",
        s,
        "-q",
    ]);
    assert!(gen.status.success(), "{}", stderr(&gen));
    let r = ergohand(&["reconstruct", s, "--out", o, "--no-section-scaling", "-q"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let skin = &read_report(&out)["skin"];
    let worst = skin["landmark_residuals_mm"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_f64().unwrap().abs())
        .fold(0.0, f64::max);
    eprintln!(
        "rounds kept {}; worst marker {worst:.2} mm",
        skin["caliper_rounds"]
    );
    assert!(skin["caliper_rounds"].as_u64().unwrap() > 0);
    let limit = ergohand::skin::pipeline::LANDMARK_WARN_MM
        + ergohand::skin::pipeline::ROUND_MARKER_SLACK_MM;
    assert!(worst <= limit, "a marker {worst:.2} mm off its offset");
}

/// The `report.json` of the model folder `model`, parsed.
fn read_report(model: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(model.join("report.json")).unwrap()).unwrap()
}

/// A `view.html` page's data and its embedded GLBs, decoded by the `base64` crate (an
/// independent reader of the page).
fn read_view_page(page: &Path) -> (serde_json::Value, Vec<Vec<u8>>) {
    let html = std::fs::read_to_string(page).unwrap();
    let between = |start: &str| -> Option<&str> {
        let a = html.find(start)? + start.len();
        Some(&html[a..a + html[a..].find("</script>").unwrap()])
    };
    let data: serde_json::Value = serde_json::from_str(
        between("<script id=\"ergohand-view-data\" type=\"application/json\">").unwrap(),
    )
    .unwrap();
    let glbs = (0..)
        .map_while(|i| {
            between(&format!(
                "<script id=\"ergohand-glb-{i}\" type=\"application/octet-stream\">"
            ))
            .map(|b| base64::decode(b).unwrap())
        })
        .collect();
    (data, glbs)
}

/// The value of the fact `label` of a page's data.
fn view_fact(data: &serde_json::Value, label: &str) -> String {
    data["facts"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f[0] == label)
        .unwrap_or_else(|| panic!("fact {label}: {data}"))[1]
        .as_str()
        .unwrap()
        .to_string()
}

/// The numbers of a text that stand as words, in order ("mean 1.49 mm, 95th pct 2.05" ->
/// [1.49, 2.05]).
fn numbers_in(text: &str) -> Vec<f64> {
    text.split([' ', ',', '(', ')'])
        .filter_map(|w| w.trim_start_matches('+').parse().ok())
        .collect()
}

/// `validate`'s `view.html` beside `report.html`: kind validate, `error-map.glb` byte for byte,
/// the legend's ramp the report's colour scale, the surface figures and the per-region table
/// those of `metrics.json`, and a right-handed unit frame for the presets.
fn validate_page_holds_the_error_map(report: &Path) {
    let metrics: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report.join("metrics.json")).unwrap()).unwrap();
    let (data, glbs) = read_view_page(&report.join("view.html"));
    assert_eq!(data["kind"], "validate");
    assert_eq!(
        glbs,
        vec![std::fs::read(report.join("error-map.glb")).unwrap()]
    );
    assert_eq!(data["legend"]["unit"], "mm");
    assert_eq!(data["legend"]["gradient"]["min"], 0.0);
    assert_eq!(
        data["legend"]["gradient"]["max"],
        metrics["colour_scale_top_mm"]
    );
    let s = &metrics["surface"];
    let got = numbers_in(&view_fact(&data, "skin to reference"));
    for (g, k) in got
        .iter()
        .zip(["mean_mm", "sd_mm", "p95_mm", "max_mm", "n"])
    {
        assert!(
            (g - s[k].as_f64().unwrap()).abs() <= 0.005,
            "{k}: {got:?} {s}"
        );
    }
    let regions = metrics["surface_regions"]["regions"].as_array().unwrap();
    let rows = data["tables"][0]["rows"].as_array().unwrap();
    assert_eq!(
        rows.len(),
        regions.len() + 1,
        "the regions and the whole hand"
    );
    for (row, r) in rows.iter().zip(regions) {
        assert_eq!(row[0], r["region"]);
        let mean: f64 = row[2].as_str().unwrap().parse().unwrap();
        assert!(
            (mean - r["mean_mm"].as_f64().unwrap()).abs() <= 0.005,
            "{row}"
        );
    }
    // A click reads the distance out: the GLB carries it per vertex, the surface's own
    // figures (the largest of the skin's distances to the reference).
    assert_eq!(data["meshes"][0]["value"]["attribute"], "_ERROR_MM");
    let scene =
        ergohand::io::gltf::read_gltf_slice(&glbs[0], Units::Metres, Path::new("glb")).unwrap();
    let errors = &scene.meshes[0].attributes[0];
    assert_eq!(errors.name, "_ERROR_MM");
    assert_eq!(errors.values.len(), scene.meshes[0].mesh.n_vertices());
    let max = errors.values.iter().copied().fold(0.0f32, f32::max) as f64;
    eprintln!("_ERROR_MM max {max} mm, metrics {}", s["max_mm"]);
    assert!(
        (max - s["max_mm"].as_f64().unwrap()).abs() < 1e-3,
        "{max} {s}"
    );
    let f = &data["frame"];
    let v = |k: &str| -> [f64; 3] { std::array::from_fn(|i| f[k][i].as_f64().unwrap()) };
    let (d, r, di) = (v("dorsal"), v("radial"), v("distal"));
    let cross = [
        d[1] * r[2] - d[2] * r[1],
        d[2] * r[0] - d[0] * r[2],
        d[0] * r[1] - d[1] * r[0],
    ];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    assert!((dot(cross, di).abs() - 1.0).abs() < 1e-9, "orthonormal");
    assert!(metrics["files"]
        .as_array()
        .unwrap()
        .iter()
        .any(|f| f == "view.html"));
}

/// `track`'s two pages: `view.html` holds `motion.glb` and `contact_map.view.html` holds
/// `contact_map.glb`, byte for byte; both give the trial's frames, and their contact table is
/// `motion.json`'s contacts summed per link here.
fn track_pages_hold_the_trial(out: &Path) {
    let motion: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("motion.json")).unwrap()).unwrap();
    let mut per: std::collections::BTreeMap<String, (usize, f64, f64)> = Default::default();
    for c in motion["contacts"].as_array().unwrap() {
        let e = per
            .entry(c["link"].as_str().unwrap().to_string())
            .or_default();
        let a = c["area_mm2"].as_f64().unwrap();
        e.0 += 1;
        e.1 += a;
        e.2 = e.2.max(a);
    }
    assert!(!per.is_empty(), "the grasp touches the bottle");
    for (page, glb, legend) in [
        ("view.html", "motion.glb", false),
        ("contact_map.view.html", "contact_map.glb", true),
    ] {
        let (data, glbs) = read_view_page(&out.join(page));
        assert_eq!(data["kind"], "track", "{page}");
        assert_eq!(glbs, vec![std::fs::read(out.join(glb)).unwrap()], "{page}");
        assert_eq!(data.get("legend").is_some(), legend, "{page}");
        let frames = numbers_in(&view_fact(&data, "frames"))[0];
        assert_eq!(frames, motion["frames"].as_f64().unwrap(), "{page}");
        let rows = data["tables"][0]["rows"].as_array().unwrap();
        assert_eq!(rows.len(), per.len(), "{page}");
        for row in rows {
            let (n, sum, max) = per[row[0].as_str().unwrap()];
            let cell = |k: usize| -> f64 { row[k].as_str().unwrap().parse().unwrap() };
            assert_eq!(cell(1), n as f64, "{row}");
            assert!((cell(2) - sum / n as f64).abs() <= 0.05, "{row}");
            assert!((cell(3) - max).abs() <= 0.05, "{row}");
        }
    }
    let (data, _) = read_view_page(&out.join("contact_map.view.html"));
    assert_eq!(data["legend"]["unit"], "%");
    assert_eq!(data["legend"]["gradient"]["max"], 100.0);
}

/// `validate --grasp DIR` and a pose in the model folder: the report's grasp section is the
/// grasp's `grasp.json`, its pose section the pose's `fist.pose.json`, both in `metrics.json`
/// and in the page (with the contact picture and the link to the grasp's 3-D page); a folder
/// without `grasp.json` is refused naming it, before anything is written.
fn grasp_and_pose_in_the_report(subj: &Path, model: &Path, tmp: &Path) {
    let (s, m) = (subj.to_str().unwrap(), model.to_str().unwrap());
    let fist = model.join("fist.glb");
    let p = ergohand(&[
        "pose",
        m,
        "--pose",
        "fist",
        "--out",
        fist.to_str().unwrap(),
        "-q",
    ]);
    assert!(p.status.success(), "{}", stderr(&p));
    let pose: serde_json::Value =
        serde_json::from_slice(&std::fs::read(model.join("fist.pose.json")).unwrap()).unwrap();
    assert_eq!(pose["file"], "fist.glb");
    let g = tmp.join("G");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
    let r = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--model",
        m,
        "--out",
        g.to_str().unwrap(),
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let rep = tmp.join("REP-G");
    let bad = ergohand(&[
        "validate",
        s,
        "--model",
        m,
        "--report",
        rep.to_str().unwrap(),
        "--grasp",
        tmp.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(
        error_line(&bad).contains("grasp.json"),
        "{}",
        error_line(&bad)
    );
    assert!(!rep.join("metrics.json").exists());
    let v = ergohand(&[
        "validate",
        s,
        "--model",
        m,
        "--report",
        rep.to_str().unwrap(),
        "--grasp",
        g.to_str().unwrap(),
        "-q",
    ]);
    assert!(v.status.success(), "{}", stderr(&v));
    let metrics: serde_json::Value =
        serde_json::from_slice(&std::fs::read(rep.join("metrics.json")).unwrap()).unwrap();
    let grasp: serde_json::Value =
        serde_json::from_slice(&std::fs::read(g.join("grasp.json")).unwrap()).unwrap();
    let section = &metrics["grasps"][0];
    for k in [
        "force_closure",
        "epsilon",
        "holds",
        "total_contact_area_mm2",
        "max_penetration_mm",
    ] {
        assert_eq!(section[k], grasp[k], "{k}");
    }
    let touching: serde_json::Map<String, serde_json::Value> = grasp["contact_area_mm2"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(_, a)| a.as_f64().unwrap() > 0.0)
        .map(|(k, a)| (k.clone(), a.clone()))
        .collect();
    assert_eq!(
        section["contact_area_mm2"],
        serde_json::Value::Object(touching)
    );
    assert_eq!(metrics["poses"][0], pose);
    let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
    assert!(html.contains("9 · Grasps") && html.contains("10 · Posed hands"));
    assert!(
        html.contains("../G/view.html"),
        "a relative link to the grasp's page"
    );
    // The contact picture is the grasp's own PNG, embedded.
    let png = std::fs::read(g.join("contact_map.png")).unwrap();
    assert!(html.contains(&base64::encode(&png)));
    // The model folder as it was, for the checks after this one.
    for f in ["fist.glb", "fist.pose.json"] {
        std::fs::remove_file(model.join(f)).unwrap();
    }
}

/// Closest point of triangle `abc` to `p` (Ericson, "Real-Time Collision Detection" 5.1.5):
/// written here so the check does not share the crate's AABB-tree code.
fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let sub = |u: [f64; 3], v: [f64; 3]| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
    let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let at = |o: [f64; 3], u: [f64; 3], t: f64| [o[0] + t * u[0], o[1] + t * u[1], o[2] + t * u[2]];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return at(a, ab, d1 / (d1 - d3));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return at(a, ac, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return at(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [
        a[0] + ab[0] * v + ac[0] * w,
        a[1] + ab[1] * v + ac[1] * w,
        a[2] + ab[2] * v + ac[2] * w,
    ]
}

/// Winding number of a closed triangle mesh about `p` (sum of the triangles' solid angles over
/// 4π, Van Oosterom & Strackee 1983): 1 inside, 0 outside.
fn winding_number(p: [f64; 3], tris: &[[[f64; 3]; 3]]) -> f64 {
    let mut total = 0.0;
    for t in tris {
        let r = t.map(|q| [q[0] - p[0], q[1] - p[1], q[2] - p[2]]);
        let len = |u: [f64; 3]| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let (a, b, c) = (r[0], r[1], r[2]);
        let cross = [
            b[1] * c[2] - b[2] * c[1],
            b[2] * c[0] - b[0] * c[2],
            b[0] * c[1] - b[1] * c[0],
        ];
        let (la, lb, lc) = (len(a), len(b), len(c));
        let num = dot(a, cross);
        let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// `grasp.glb` read back: both meshes carry unit normals, and the hand's `_DISTANCE_MM` equals each vertex's signed distance to the part computed here by
/// brute force (closest point over every part triangle; inside by the winding number).
fn grasp_glb_carries_normals_and_distances(path: &Path) {
    let scene = ergohand::io::gltf::read_gltf(path, Units::Metres).unwrap();
    let hand = scene.meshes.iter().find(|m| m.name == "hand").unwrap();
    let part = scene.meshes.iter().find(|m| m.name == "part").unwrap();
    for m in [hand, part] {
        let n = m.normals.as_ref().expect("normals");
        assert_eq!(n.len(), m.mesh.n_vertices());
        assert!(
            n.iter().all(|v| (v.norm() - 1.0).abs() < 1e-6),
            "{}",
            m.name
        );
    }
    let dist = &hand
        .attributes
        .iter()
        .find(|a| a.name == "_DISTANCE_MM")
        .expect("_DISTANCE_MM")
        .values;
    assert_eq!(dist.len(), hand.mesh.n_vertices());
    let tris: Vec<[[f64; 3]; 3]> = part
        .mesh
        .faces
        .iter()
        .map(|f| f.map(|v| part.mesh.vertices[v].coords.into()))
        .collect();
    let nearest = (0..dist.len())
        .min_by(|&a, &b| dist[a].total_cmp(&dist[b]))
        .unwrap();
    let farthest = (0..dist.len())
        .max_by(|&a, &b| dist[a].total_cmp(&dist[b]))
        .unwrap();
    assert!(dist[nearest] <= 1.0, "the hand touches the part");
    let mut checked = vec![nearest, farthest];
    checked.extend((0..dist.len()).step_by(dist.len() / 12));
    for v in checked {
        let p: [f64; 3] = hand.mesh.vertices[v].coords.into();
        let unsigned = tris
            .iter()
            .map(|t| distance(p, closest_on_triangle(p, t[0], t[1], t[2])))
            .fold(f64::INFINITY, f64::min);
        let inside = winding_number(p, &tris) > 0.5;
        let want = if inside { -unsigned } else { unsigned };
        let got = f64::from(dist[v]);
        assert!(
            (got - want).abs() < 1e-3,
            "vertex {v}: _DISTANCE_MM {got} mm, recomputed {want} mm"
        );
    }
}

/// `ergohand grasp` as a product designer runs it: the shipped bottle scene (placement search)
/// writes `grasp.json` with the keys, a GLB whose hand and part carry the contact map
/// as vertex colours, and a PNG; a scene with an unknown grasp type or a part in metres gets a
/// one-line error or a warning naming the scene, the field and the value, and writes nothing.
#[test]
fn grasp_writes_report_glb_and_map_and_refuses_bad_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bottle");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stderr.is_empty(), "--quiet: {}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("grasp.json")).unwrap()).unwrap();
    assert_eq!(r["force_closure"], true);
    assert_eq!(r["holds"], true);
    assert!(r["epsilon"].as_f64().unwrap() > 0.0 && r["volume"].as_f64().unwrap() > 0.0);
    let contacts = r["contacts"].as_array().unwrap();
    let areas = r["contact_area_mm2"].as_object().unwrap();
    assert!(contacts.len() >= 3);
    // Every contact's link has an area, and the areas add up to the total.
    for c in contacts {
        assert!(areas.contains_key(c["link"].as_str().unwrap()), "{c}");
    }
    let sum: f64 = areas.values().map(|a| a.as_f64().unwrap()).sum();
    let total = r["total_contact_area_mm2"].as_f64().unwrap();
    assert!(
        (sum - total).abs() < 1e-6 * total.max(1.0),
        "{sum} vs {total}"
    );
    // The GLB: every mesh primitive has one colour per vertex.
    let glb = gltf::Gltf::open(out.join("grasp.glb")).unwrap();
    let mut coloured = 0;
    for mesh in glb.meshes() {
        for p in mesh.primitives() {
            let n = p.get(&gltf::Semantic::Positions).unwrap().count();
            let c = p.get(&gltf::Semantic::Colors(0)).expect("COLOR_0");
            assert_eq!(c.count(), n);
            coloured += 1;
        }
    }
    assert!(coloured >= 2, "hand and part");
    grasp_glb_carries_normals_and_distances(&out.join("grasp.glb"));
    let png = std::fs::read(out.join("contact_map.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    view_page_holds_the_grasp(&out, &r);

    // An unknown grasp type: the scene, the field and the value, nothing written.
    let stl = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.stl");
    let bad = dir.path().join("bad.toml");
    let text = |units: &str, kind: &str| {
        format!(
            "[part]\nfile = {:?}\nunits = \"{units}\"\nfriction = 0.5\nmass_g = 500\n\n\
             [grasp]\ntype = \"{kind}\"\napproach = {{ translation_mm = [-35, -42, 90], rotation_deg = [-90, -90, 0] }}\n",
            stl.to_str().unwrap()
        )
    };
    std::fs::write(&bad, text("mm", "grip")).unwrap();
    let out_bad = dir.path().join("bad-out");
    let args = [
        "grasp",
        bad.to_str().unwrap(),
        "--out",
        out_bad.to_str().unwrap(),
    ];
    let o = ergohand(&args);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("bad.toml") && line.contains("type") && line.contains("grip"),
        "{line}"
    );
    assert!(!out_bad.exists(), "nothing written on bad input");
    // The bottle read as metres is 1000 times a hand: a warning naming its size.
    std::fs::write(&bad, text("m", "power")).unwrap();
    let o = ergohand(&args);
    let e = stderr(&o);
    assert!(
        e.lines()
            .any(|l| l.contains("warning") && l.contains("bad.toml") && l.contains(" m")),
        "{e}"
    );
}

/// The procedural body is not the template deformed: the whole pipeline on a clean subject,
/// with the paper's skin fit (no shape prior), leaves the reconstructed skin well over a
/// millimetre from the CT-like reference on average (the template body gives about 0.5 mm), so
/// the simulator's figures can no longer come from a hand the template reaches by
/// construction; the default's shipped shape prior brings it measurably closer.
#[test]
fn the_template_cannot_reach_the_procedural_body() {
    use ergohand::cli;
    use ergohand::validate::thresholds::Figures;
    let tmp = tempfile::tempdir().unwrap();
    let mut opts = cli::synth_options(
        5,
        ergohand::synth::Preset::Clean,
        ergohand::anatomy::Side::Right,
        ergohand::synth::Posture::Template,
        ergohand::synth::Body::Procedural,
        Some(15.0),
        None,
    );
    opts.voxel_mm = 0.7;
    let sdir = tmp.path().join("P");
    let model = sdir.join("out");
    cli::synth(&opts, &sdir, false).unwrap();
    assert!(!sdir.join("truth_skin.ply").exists());
    // The paper's fit: no shape prior, the caliper rounds' sections as they are.
    let r = ergohand(&[
        "reconstruct",
        sdir.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
        "--shape-prior",
        "none",
        "--no-section-scaling",
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let both = ergohand(&[
        "reconstruct",
        sdir.to_str().unwrap(),
        "--out",
        tmp.path().join("both").to_str().unwrap(),
        "--section-scaling",
        "--no-section-scaling",
    ]);
    assert!(!both.status.success());
    assert!(
        stderr(&both).contains("--no-section-scaling"),
        "{}",
        stderr(&both)
    );
    let v = cli::validate(&sdir, &model, &model.join("report")).unwrap();
    let (link, surface) = v.against_references(&sdir).unwrap();
    let figures = Figures::measure(link, surface, &v.dimensions, &model).unwrap();
    eprintln!("procedural seed 5: {:?}", figures.0);
    assert!(
        surface.mean_mm > 1.5,
        "skin to reference mean {} mm: the template reaches the procedural body",
        surface.mean_mm
    );
    every_builtin_pose_keeps_its_elements_positive(&model, tmp.path());
    pose_page_and_baked_glb(&model, tmp.path());
    grasp_a_population(&model, tmp.path());
    // The default, with the shipped shape prior: closer to the reference. Its fuller creases
    // skinning turns over more: relaxing them in the fist took the little finger's middle
    // phalanx well past 5 % before the bulge field was solved again for what the relaxation
    // moved.
    let prior = sdir.join("out-prior");
    let r = ergohand(&[
        "reconstruct",
        sdir.to_str().unwrap(),
        "--out",
        prior.to_str().unwrap(),
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let v = cli::validate(&sdir, &prior, &prior.join("report")).unwrap();
    let (_, with_prior) = v.against_references(&sdir).unwrap();
    eprintln!(
        "skin to reference: {:.2} mm with the prior, {:.2} without",
        with_prior.mean_mm, surface.mean_mm
    );
    assert!(with_prior.mean_mm < 0.8 * surface.mean_mm);
    // The features a prior reads are the subject's, not the fit's: the same with the prior as
    // without (a prior is trained on fits without one), and every one the shipped prior reads.
    let features = |model: &Path| read_report(model)["skin"]["shape_prior_features"].clone();
    assert_eq!(features(&model), features(&prior));
    let shipped = ergohand::skin::shape_prior::ShapePrior::builtin();
    let recorded = features(&prior);
    for name in &shipped.features {
        assert!(
            recorded[name].as_f64().is_some_and(f64::is_finite),
            "{name}: {recorded}"
        );
    }
    let fist = tmp.path().join("prior-fist.vtk");
    let p = ergohand(&[
        "pose",
        prior.to_str().unwrap(),
        "--pose",
        "fist",
        "--out",
        fist.to_str().unwrap(),
        "-q",
    ]);
    assert!(p.status.success(), "{}", stderr(&p));
    finger_segments_keep_their_volume(&prior, &fist, "prior fist");
    // With the sections scaled to their calipers (the default), a caliper on the fingers reads
    // the given values where the caliper rounds left them up to their slack off; on the
    // paper's fit, whose scaled creases fold deepest in the tripod, every built-in pose stays
    // positive.
    let scaled_model = sdir.join("out-scaled");
    let r = ergohand(&[
        "reconstruct",
        sdir.to_str().unwrap(),
        "--out",
        scaled_model.to_str().unwrap(),
        "--shape-prior",
        "none",
        "-q",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let (scaled_report, plain_report) = (read_report(&scaled_model), read_report(&model));
    let finger_worst = |report: &serde_json::Value| -> f64 {
        let own = report["skin"]["caliper_residuals_mm"].as_object().unwrap();
        assert_eq!(own.len(), 22, "{own:?}");
        own.iter()
            .filter(|(n, _)| n.starts_with("finger"))
            .map(|(_, r)| r.as_f64().unwrap().abs())
            .fold(0.0, f64::max)
    };
    let (scaled, plain) = (finger_worst(&scaled_report), finger_worst(&plain_report));
    eprintln!("finger calipers, worst miss: {plain:.2} mm unscaled, {scaled:.2} scaled");
    assert!(scaled <= 0.3 && scaled < plain, "{scaled} vs {plain}");
    assert_eq!(
        scaled_report["skin"]["section_scaling"],
        serde_json::json!(true)
    );
    assert_eq!(
        plain_report["skin"]["section_scaling"],
        serde_json::json!(false)
    );
    let scaled_poses = tmp.path().join("scaled-poses");
    std::fs::create_dir_all(&scaled_poses).unwrap();
    every_builtin_pose_keeps_its_elements_positive(&scaled_model, &scaled_poses);
}

/// Every finger segment of the posed tetrahedral mesh `posed` (written by `pose` from the model
/// folder `model`) within 5 % of its volume in the model's `tet.vtk`, read from the files: the
/// tissue of each segment (its tetrahedra, labelled by the template's weights) summed.
fn finger_segments_keep_their_volume(model: &Path, posed: &Path, what: &str) {
    use ergohand::pose::quality::{finger_volume_changes, segment_volumes};
    let hand = ergohand::pose::IndividualHand::load(model, ergohand::pose::WeightMethod::default())
        .unwrap();
    let rig = ergohand::pose::volume_rig(&hand, model).unwrap();
    let nodes = ergohand::io::vtk::read_vtk(posed, Units::Millimetres)
        .unwrap()
        .nodes;
    let n = ergohand::anatomy::Link::ALL.len();
    let changes = finger_volume_changes(
        &rig.rest_volumes,
        &segment_volumes(&nodes, &rig.tets, &rig.labels, n),
    );
    let worst = changes
        .iter()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap();
    eprintln!(
        "{what}: worst finger segment {:?} {:+.1} %",
        worst.0,
        100.0 * worst.1
    );
    assert!(worst.1.abs() <= 0.05, "{what}: {changes:?}");
}

/// The page data of a view page, and the bytes of its binary element `id`.
fn view_page_data(page: &Path, id: &str) -> (serde_json::Value, Vec<u8>) {
    let html = std::fs::read_to_string(page).unwrap();
    let between = |start: &str| {
        let a = html.find(start).unwrap() + start.len();
        html[a..a + html[a..].find("</script>").unwrap()].to_string()
    };
    let data = serde_json::from_str(&between(
        "<script id=\"ergohand-view-data\" type=\"application/json\">",
    ))
    .unwrap();
    let bin = base64::decode(between(&format!(
        "<script id=\"{id}\" type=\"application/octet-stream\">"
    )))
    .unwrap();
    (data, bin)
}

/// `pose` writes a page beside its output whose hand is the written skin, whose rig describes
/// the toolkit's own forward kinematics (every vertex that follows one link rigidly is where
/// the rig's joints, composed here from the page's data alone, put it), and a skinned `.glb`
/// gets the kept-volume skin baked beside it (what `.obj` writes at the same angles).
fn pose_page_and_baked_glb(model: &Path, tmp: &Path) {
    use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
    let dir = tmp.join("pose-page");
    std::fs::create_dir_all(&dir).unwrap();
    let run = |out: &str| {
        let p = ergohand(&[
            "pose",
            model.to_str().unwrap(),
            "--pose",
            "fist",
            "--keep-angles",
            "--out",
            dir.join(out).to_str().unwrap(),
        ]);
        assert!(p.status.success(), "{out}: {}", stderr(&p));
    };
    run("fist.obj");
    run("fistg.glb");
    let obj = ergohand::io::obj::read_obj(&dir.join("fist.obj"), Units::Millimetres).unwrap();
    let (data, bin) = view_page_data(&dir.join("fist.view.html"), "ergohand-bin-0");
    assert_eq!(data["kind"], "pose");
    let rig = &data["rig"];
    let n = rig["vertices"].as_u64().unwrap() as usize;
    assert_eq!(n, obj.n_vertices());
    let f32s = |k: &str| -> Vec<f64> {
        let (at, count) = (
            rig[k][0].as_u64().unwrap() as usize,
            rig[k][1].as_u64().unwrap() as usize,
        );
        (0..count)
            .map(|i| f32::from_le_bytes(bin[at + 4 * i..at + 4 * i + 4].try_into().unwrap()) as f64)
            .collect()
    };
    let u32s = |k: &str| -> Vec<usize> {
        let (at, count) = (
            rig[k][0].as_u64().unwrap() as usize,
            rig[k][1].as_u64().unwrap() as usize,
        );
        (0..count)
            .map(|i| {
                u32::from_le_bytes(bin[at + 4 * i..at + 4 * i + 4].try_into().unwrap()) as usize
            })
            .collect()
    };
    let (rest, shown, weights) = (f32s("rest"), f32s("shown"), f32s("weights"));
    let offsets = u32s("offsets");
    let links_at = rig["links"][0].as_u64().unwrap() as usize;
    let p = |xs: &[f64], i: usize| Point3::new(xs[3 * i], xs[3 * i + 1], xs[3 * i + 2]);
    // The page shows what was written.
    for (i, v) in obj.vertices.iter().enumerate() {
        assert!((p(&shown, i) - v).norm() < 1e-3, "vertex {i}");
    }
    let skin = ergohand::io::obj::read_obj(&model.join("skin.obj"), Units::Millimetres).unwrap();
    for (i, v) in skin.vertices.iter().enumerate() {
        assert!((p(&rest, i) - v).norm() < 1e-3, "rest vertex {i}");
    }
    // The rig's forward kinematics, from the page's data alone.
    let v3 = |x: &serde_json::Value| {
        Vector3::new(
            x[0].as_f64().unwrap(),
            x[1].as_f64().unwrap(),
            x[2].as_f64().unwrap(),
        )
    };
    let root = &rig["root"]["rotation"];
    let q = nalgebra::Quaternion::new(
        root[0].as_f64().unwrap(),
        root[1].as_f64().unwrap(),
        root[2].as_f64().unwrap(),
        root[3].as_f64().unwrap(),
    );
    let mut t = vec![Isometry3::identity(); rig["link_names"].as_array().unwrap().len()];
    t[0] = Isometry3::from_parts(
        Translation3::from(v3(&rig["root"]["translation"])),
        UnitQuaternion::from_quaternion(q),
    );
    let fist = ergohand::pose::named_pose("fist").unwrap();
    for (k, j) in rig["joints"].as_array().unwrap().iter().enumerate() {
        let mut r = UnitQuaternion::identity();
        for (d, axis) in j["axes"].as_array().unwrap().iter().enumerate() {
            let deg = j["deg"][d].as_f64().unwrap();
            assert!((deg - fist.angles[k][d].to_degrees()).abs() < 1e-9, "{j}");
            r *= UnitQuaternion::from_axis_angle(&Unit::new_normalize(v3(axis)), deg.to_radians());
        }
        let c = v3(&j["centre"]);
        let about = Isometry3::from_parts(Translation3::from(c - r * c), r);
        let (parent, child) = (
            j["parent"].as_u64().unwrap() as usize,
            j["child"].as_u64().unwrap() as usize,
        );
        t[child] = t[parent] * about;
    }
    let mut rigid = 0;
    for i in 0..n {
        let (a, b) = (offsets[i], offsets[i + 1]);
        if b - a == 1 && (weights[a] - 1.0).abs() < 1e-6 {
            let link = bin[links_at + a] as usize;
            let want = t[link] * p(&rest, i);
            assert!(
                (want - obj.vertices[i]).norm() < 2e-3,
                "vertex {i} on link {link}"
            );
            rigid += 1;
        }
    }
    eprintln!("{rigid} of {n} vertices follow one link rigidly");
    assert!(rigid > n / 20, "{rigid} of {n} vertices follow one link");
    // The skinned GLB's baked twin is the kept-volume skin of the same angles.
    let baked = ergohand::io::gltf::read_gltf(&dir.join("fistg.baked.glb"), Units::Metres).unwrap();
    assert_eq!(baked.meshes.len(), 1);
    for (a, b) in baked.meshes[0].mesh.vertices.iter().zip(&obj.vertices) {
        assert!((a - b).norm() < 1e-3);
    }
    assert!(dir.join("fistg.view.html").exists());
}

/// Every built-in pose of the model folder `model` as a tetrahedral mesh: every finger segment
/// within 5 % of its rest volume, no element inverted
/// (the skinned skin unfolded, then untangled from hundreds in a fist; node by node alone left
/// a sliver in procedural seed 5's fist, where two nodes had collapsed onto each other at a
/// palmar crease), counted on the nodes read back and in the file's own signed-volume field
/// alike, and no warning of inverted elements.
fn every_builtin_pose_keeps_its_elements_positive(model: &Path, tmp: &Path) {
    let rest = ergohand::io::vtk::read_vtk(&model.join("tet.vtk"), Units::Millimetres)
        .unwrap()
        .inverted_count();
    for name in ergohand::pose::NAMED_POSES {
        let path = tmp.join(format!("builtin-{name}.vtk"));
        let p = ergohand(&[
            "pose",
            model.to_str().unwrap(),
            "--pose",
            name,
            "--out",
            path.to_str().unwrap(),
        ]);
        assert!(p.status.success(), "{name}: {}", stderr(&p));
        let m = ergohand::io::vtk::read_vtk(&path, Units::Millimetres).unwrap();
        let inverted = m.inverted_count();
        eprintln!("{name}: {inverted} inverted (the model's tet.vtk: {rest})");
        assert!(inverted == 0, "{name}: {inverted} inverted, tet.vtk {rest}");
        assert_eq!(
            stderr(&p).contains(&format!(
                "{inverted} of {} tetrahedra are inverted",
                m.n_tets()
            )),
            inverted > 0,
            "{name}: {}",
            stderr(&p)
        );
        let text = std::fs::read_to_string(&path).unwrap();
        let at = text.find("SCALARS signed_volume double 1").unwrap();
        let field: Vec<f64> = text[at..]
            .lines()
            .skip(2)
            .take(m.n_tets())
            .map(|l| l.parse().unwrap())
            .collect();
        assert_eq!(field.len(), m.n_tets());
        assert_eq!(
            field.iter().filter(|v| **v <= 0.0).count(),
            inverted,
            "{name}"
        );
        finger_segments_keep_their_volume(model, &path, name);
    }
}

/// `grasp --models` on a population of two copies of the procedural hand (named A and B, given
/// as the folder holding them): each hand's files in OUT/NAME/ and the same outcome for both
/// (the same hand, the same seeded search); `population.json` counts them, the page needs
/// nothing outside itself and shows both pictures and the chart; one hand's grasp.json is the
/// single-hand command's (timings apart, and the wrench space's volume, which a population
/// leaves out). Two models of one name, or a folder without models,
/// are refused before any work, naming the folder.
fn grasp_a_population(model: &Path, tmp: &Path) {
    let hands = tmp.join("hands");
    for name in ["A", "B"] {
        let to = hands.join(name);
        std::fs::create_dir_all(&to).unwrap();
        for f in ["link_model.json", "skin.obj"] {
            std::fs::copy(model.join(f), to.join(f)).unwrap();
        }
    }
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pen.toml");
    let out = tmp.join("POP");
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--models",
        hands.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let pop: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("population.json")).unwrap()).unwrap();
    assert_eq!(pop["hands"], 2);
    let outcomes = pop["outcomes"].as_array().unwrap();
    assert_eq!(outcomes[0]["name"], "A");
    assert_eq!(outcomes[1]["name"], "B");
    for k in [
        "holds",
        "force_closure",
        "epsilon",
        "contact_area_mm2",
        "hand_length_mm",
    ] {
        assert_eq!(outcomes[0][k], outcomes[1][k], "{k}");
    }
    let holding = outcomes.iter().filter(|o| o["holds"] == true).count();
    assert_eq!(pop["holding"], holding);
    let html = std::fs::read_to_string(out.join("population.html")).unwrap();
    assert_eq!(
        ergohand::validate::report_html::check_self_contained(&html),
        Ok(3),
        "two contact pictures and the chart"
    );
    assert!(html.contains("<a href=\"view.html\">") && html.contains("<a href=\"A/view.html\">"));
    // The population's 3-D page: the part coloured by the share of hands touching it, written
    // as contact_frequency.glb too, and every hand's row as population.json has it.
    let (data, glbs) = read_view_page(&out.join("view.html"));
    assert_eq!(data["kind"], "population");
    assert_eq!(
        glbs,
        vec![std::fs::read(out.join("contact_frequency.glb")).unwrap()]
    );
    assert_eq!(data["legend"]["unit"], "%");
    let rows = data["tables"][0]["rows"].as_array().unwrap();
    for (row, o) in rows.iter().zip(outcomes) {
        assert_eq!(row[0], o["name"]);
        assert_eq!(row[1], if o["holds"] == true { "yes" } else { "no" });
        let eps: f64 = row[3].as_str().unwrap().parse().unwrap();
        assert!((eps - o["epsilon"].as_f64().unwrap()).abs() < 1e-4, "{row}");
    }
    // Two copies of one hand touch the same places: every part vertex is touched by none or
    // by both (two colours, both present when the hand touches the part at all).
    let (doc, buffers, _) = gltf::import_slice(&glbs[0]).unwrap();
    let mut colours = std::collections::BTreeSet::new();
    for mesh in doc.meshes() {
        for p in mesh.primitives() {
            let reader = p.reader(|b| Some(&buffers[b.index()]));
            for c in reader.read_colors(0).unwrap().into_rgba_f32() {
                colours.insert(c.map(|x| (x * 1e4).round() as i64));
            }
        }
    }
    let touched = outcomes[0]["contact_area_mm2"].as_f64().unwrap() > 0.0;
    assert_eq!(colours.len(), 1 + touched as usize, "{colours:?}");
    // ... and a click reads the share: 0 or 100 % alike.
    assert_eq!(data["meshes"][0]["value"]["attribute"], "_HAND_SHARE_PCT");
    let part =
        ergohand::io::gltf::read_gltf_slice(&glbs[0], Units::Metres, Path::new("glb")).unwrap();
    let share = &part.meshes[0].attributes[0];
    assert_eq!(share.name, "_HAND_SHARE_PCT");
    assert!(share.values.iter().all(|&v| v == 0.0 || v == 100.0));
    assert_eq!(share.values.contains(&100.0), touched);
    // One hand alone, through the single-hand command: the same grasp.
    let single = tmp.join("SINGLE");
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--model",
        hands.join("A").to_str().unwrap(),
        "--out",
        single.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let read = |p: &Path| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(p.join("grasp.json")).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("timings_s");
        let volume = v.as_object_mut().unwrap().remove("volume").unwrap();
        (v, volume)
    };
    let ((pop_a, pop_volume), (alone, volume)) = (read(&out.join("A")), read(&single));
    assert_eq!(pop_a, alone);
    assert!(
        pop_volume.is_null() && volume.as_f64().unwrap() > 0.0,
        "{volume}"
    );
    // Refused before any work: two models named A; a folder without any model.
    let other = tmp.join("other/A");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::copy(model.join("link_model.json"), other.join("link_model.json")).unwrap();
    let out2 = tmp.join("POP2");
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--models",
        hands.join("A").to_str().unwrap(),
        other.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(error_line(&o).contains("named A"), "{}", error_line(&o));
    let empty = tmp.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--models",
        empty.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("empty") && line.contains("link_model.json"),
        "{line}"
    );
    assert!(!out2.exists(), "nothing written on bad input");
}

/// The library's one-call reconstruction is what the command writes: the same link model
/// (section 3.6 applied once, on the final skin: the report's shifts are the ones the link
/// model records), the same skin and the same report, and a template of the other hand is
/// refused naming the subject.
#[test]
fn the_library_reconstruction_is_what_the_command_writes() {
    use ergohand::mocap::subject::Subject;
    let dir = tempfile::tempdir().unwrap();
    let subj = dir.path().join("S");
    let out = dir.path().join("OUT");
    let mut opts = ergohand::cli::synth_options(
        6,
        ergohand::synth::Preset::Typical,
        ergohand::anatomy::Side::Left,
        ergohand::synth::Posture::Template,
        ergohand::synth::Body::Template,
        Some(8.0),
        None,
    );
    opts.voxel_mm = 2.0;
    ergohand::cli::synth(&opts, &subj, false).unwrap();
    ergohand::cli::reconstruct(&subj, &out).unwrap();

    let subject = Subject::load(&subj).unwrap();
    let template = ergohand::template::load_template(subject.hand).unwrap();
    let skin_opts = ergohand::skin::pipeline::SkinOptions::default();
    let r = ergohand::reconstruct::reconstruct(&subject, &template, &skin_opts, None).unwrap();

    let written = std::fs::read_to_string(out.join("link_model.json")).unwrap();
    assert_eq!(written, r.link_model.to_json());
    let skin = ergohand::io::obj::read_obj(&out.join("skin.obj"), Units::Millimetres).unwrap();
    assert_eq!(skin.faces, r.skin.high.faces);
    let worst = skin
        .vertices
        .iter()
        .zip(&r.skin.high.vertices)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "skin.obj differs by {worst} mm");
    let mut report = read_report(&out);
    let mut own = serde_json::to_value(&r.report).unwrap();
    for v in [&mut report, &mut own] {
        v.as_object_mut().unwrap().remove("timings_s");
    }
    // serde_json reads a float back to within an ulp, not always exactly.
    fn same(a: &serde_json::Value, b: &serde_json::Value) -> bool {
        use serde_json::Value::*;
        match (a, b) {
            (Number(x), Number(y)) => {
                let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
                (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1.0)
            }
            (Array(x), Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y)),
            (Object(x), Object(y)) => {
                x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
            }
            _ => a == b,
        }
    }
    assert!(same(&report, &own), "report.json: {report}\nlibrary: {own}");

    let shifts = &r.report.skin.section_3_6_shift_mm;
    let hinges: Vec<_> = r
        .link_model
        .joints
        .iter()
        .filter(|e| e.axis.is_some())
        .collect();
    assert!(!hinges.is_empty());
    for e in hinges {
        assert_eq!(
            e.diagnostics.centre_shift_on_skin_mm,
            shifts.get(e.joint.name()).copied(),
            "{}",
            e.joint.name()
        );
    }

    // The same hand given as data (a template folder holding the shipped surface, subdivided
    // as the embedded one is, its spec derived by the landmark rule) gives the same skin.
    let folder = dir.path().join("T");
    std::fs::create_dir(&folder).unwrap();
    let glb = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/generic-hand/left.glb");
    std::fs::copy(&glb, folder.join("left.glb")).unwrap();
    std::fs::write(folder.join("template.toml"), "subdivisions = 2\n").unwrap();
    let data = ergohand::template::load_folder_template(&folder, subject.hand).unwrap();
    assert_eq!(data.spec, template.spec);
    let r2 = ergohand::reconstruct::reconstruct(&subject, &data, &skin_opts, None).unwrap();
    assert_eq!(r2.skin.high.vertices, r.skin.high.vertices);
    assert_eq!(r2.link_model.to_json(), r.link_model.to_json());
    assert!(matches!(
        r2.report.template,
        ergohand::template::TemplateSource::Folder { .. }
    ));
    assert_ne!(r2.report.inputs_fnv1a, r.report.inputs_fnv1a);

    let right = ergohand::template::load_template(ergohand::anatomy::Side::Right).unwrap();
    let err = ergohand::reconstruct::reconstruct(&subject, &right, &skin_opts, None)
        .err()
        .expect("a right template for a left hand is refused")
        .to_string();
    assert!(
        err.contains(subj.to_str().unwrap()) && err.contains("template"),
        "{err}"
    );
}

/// A template folder of another resolution: `template` describes it (spec derived by the
/// landmark rule, written for review and read back unchanged), `reconstruct --template` builds
/// the hand on it, `pose` and `validate` find it through the model folder, and a template folder
/// changed after the model was made is refused naming report.json; a folder without the hand's
/// surface or with a bad setting is an error naming the file.
#[test]
fn a_template_folder_is_used_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let subj = dir.path().join("S");
    let (s, tdir) = (subj.to_str().unwrap(), dir.path().join("T"));
    let t = tdir.to_str().unwrap();
    let gen = ergohand(&[
        "synth",
        "--seed",
        "8",
        "--preset",
        "clean",
        "--out",
        s,
        "--duration",
        "8",
        "-q",
    ]);
    assert!(gen.status.success(), "{}", stderr(&gen));
    std::fs::create_dir(&tdir).unwrap();

    // No surface for the subject's (right) hand: the error names the file to provide.
    let out = dir.path().join("OUT");
    let o = out.to_str().unwrap();
    let r = ergohand(&["reconstruct", s, "--out", o, "--template", t]);
    assert_eq!(r.status.code(), Some(1));
    let line = error_line(&r);
    assert!(line.contains("right.glb"), "{line}");
    assert!(!out.exists());

    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/generic-hand");
    std::fs::copy(assets.join("right.glb"), tdir.join("right.glb")).unwrap();
    std::fs::write(tdir.join("template.toml"), "subdivisons = 1\n").unwrap();
    let r = ergohand(&["reconstruct", s, "--out", o, "--template", t]);
    assert_eq!(r.status.code(), Some(1));
    let line = error_line(&r);
    assert!(
        line.contains("template.toml") && line.contains("subdivisons"),
        "{line}"
    );
    std::fs::write(tdir.join("template.toml"), "subdivisions = 1\n").unwrap();

    // The spec for review, read back as the folder's own: the same hand.
    let review = dir.path().join("review");
    let w = ergohand(&[
        "template",
        "--template",
        t,
        "--out",
        review.to_str().unwrap(),
        "-q",
    ]);
    assert!(w.status.success(), "{}", stderr(&w));
    let derived =
        ergohand::template::load_folder_template(&tdir, ergohand::anatomy::Side::Right).unwrap();
    std::fs::copy(
        review.join("template-spec.toml"),
        tdir.join("template-spec.toml"),
    )
    .unwrap();
    let given =
        ergohand::template::load_folder_template(&tdir, ergohand::anatomy::Side::Right).unwrap();
    assert_eq!(given.spec, derived.spec);
    assert_eq!(given.mesh.n_faces(), 9_256);
    assert!(review.join("template-right.png").is_file());

    // The shipped shape prior belongs to the generic hand: asked for on another, refused.
    let r = ergohand(&[
        "reconstruct",
        s,
        "--out",
        o,
        "--template",
        t,
        "--shape-prior",
        "builtin",
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        error_line(&r).contains("--shape-prior"),
        "{}",
        error_line(&r)
    );
    assert!(!out.exists());

    // Without the option the shipped prior is left out on another template, and said so.
    let r = ergohand(&["reconstruct", s, "--out", o, "--template", t, "-q"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let skin = ergohand::io::obj::read_obj(&out.join("skin.obj"), Units::Millimetres).unwrap();
    assert_eq!(
        skin.faces, given.mesh.faces,
        "homologous to the folder's template"
    );
    let report = read_report(&out);
    assert!(
        report["skin"]["shape_prior"].is_null(),
        "{}",
        report["skin"]
    );
    validate(&subj, &out, &out.join("rep"));
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rep/metrics.json")).unwrap())
            .unwrap();
    let regions = metrics["surface_regions"]["regions"].as_array().unwrap();
    let n: u64 = regions
        .iter()
        .map(|r| r["vertices"].as_u64().unwrap())
        .sum();
    assert_eq!(n as usize, skin.n_vertices());
    assert!(
        metrics["surface"]["mean_mm"].as_f64().unwrap() < 2.0,
        "{}",
        metrics["surface"]
    );
    let fist = dir.path().join("fist.obj");
    let p = ergohand(&[
        "pose",
        o,
        "--pose",
        "fist",
        "--out",
        fist.to_str().unwrap(),
        "-q",
    ]);
    assert!(p.status.success(), "{}", stderr(&p));
    let posed = ergohand::io::obj::read_obj(&fist, Units::Millimetres).unwrap();
    assert_eq!(posed.faces, given.mesh.faces);

    // The folder changes under the model: pose refuses, naming report.json and the folder.
    std::fs::write(tdir.join("template.toml"), "subdivisions = 0\n").unwrap();
    let p = ergohand(&[
        "pose",
        o,
        "--pose",
        "fist",
        "--out",
        fist.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(p.status.code(), Some(1));
    let line = error_line(&p);
    assert!(line.contains("report.json") && line.contains(t), "{line}");
}

/// The optional fingertip markers through the commands: `synth --tip-markers` writes them into
/// the static trial, `reconstruct --shape-prior none` fits the skin's fingertips to them (their
/// residuals in `report.json`) and aims every digit's last joint at them (in
/// `link_model.json`), and the same subject without the flag has neither. (With the default
/// shape prior they only aim the joints; the skin test of the pipeline checks that.)
#[test]
fn fingertip_markers_go_from_synth_to_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, tips: bool| -> (serde_json::Value, serde_json::Value) {
        let (subj, out) = (
            dir.path().join(name),
            dir.path().join(format!("{name}-out")),
        );
        let mut a = vec![
            "synth",
            "--seed",
            "9",
            "--out",
            subj.to_str().unwrap(),
            "--duration",
            "6",
            "--no-motions",
            "-q",
        ];
        if tips {
            a.push("--tip-markers");
        }
        let g = ergohand(&a);
        assert!(g.status.success(), "{}", stderr(&g));
        let r = ergohand(&[
            "reconstruct",
            subj.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--shape-prior",
            "none",
            "-q",
        ]);
        assert!(r.status.success(), "{}", stderr(&r));
        let read = |f: &str| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(out.join(f)).unwrap()).unwrap()
        };
        (read("report.json"), read("link_model.json"))
    };
    let (plain, plain_model) = run("plain", false);
    let (tipped, tipped_model) = run("tipped", true);
    let tips = |r: &serde_json::Value| -> Vec<String> {
        r["skin"]["landmark_residuals_mm"]
            .as_object()
            .unwrap()
            .keys()
            .filter(|k| k.ends_with("_TIP"))
            .cloned()
            .collect()
    };
    assert!(tips(&plain).is_empty());
    assert_eq!(tips(&tipped), ["I_TIP", "L_TIP", "M_TIP", "R_TIP", "T_TIP"]);
    for k in tips(&tipped) {
        let r = tipped["skin"]["landmark_residuals_mm"][&k]
            .as_f64()
            .unwrap();
        // As near as the sections' scaling to the calipers leaves them (0.57 mm at most
        // here), within the 1.5 mm at which a landmark is warned.
        assert!(r < 1.0, "{k}: {r} mm from its marker");
    }
    // The distal joints' long axes (third row of each frame) turn toward the markers.
    let z = |m: &serde_json::Value, j: &str| -> [f64; 3] {
        let r = &m["joints"][j]["frame"][2];
        [0, 1, 2].map(|k| r[k].as_f64().unwrap())
    };
    let angle = |a: [f64; 3], b: [f64; 3]| {
        let d: f64 = (0..3).map(|k| a[k] * b[k]).sum();
        d.clamp(-1.0, 1.0).acos().to_degrees()
    };
    let turned = ["T_IP", "I_DIP", "M_DIP", "R_DIP", "L_DIP"]
        .iter()
        .filter(|j| angle(z(&plain_model, j), z(&tipped_model, j)) > 0.5)
        .count();
    assert!(turned >= 3, "{turned} distal frames turned");
}

/// Fingertip markers worn through a grasp trial (an extension of the spec): `track` attaches
/// them from the static trial and fits the distal links to them. The same trial without them
/// (synth draws them from streams of their own, so every other marker is the same) is tracked
/// beside it on the same model; against synth's record of the motion the fingertips come
/// nearer with the markers worn.
#[test]
fn fingertip_markers_worn_in_a_grasp_are_tracked() {
    let dir = tempfile::tempdir().unwrap();
    let synth = |name: &str, tips: bool| {
        let subj = dir.path().join(name);
        let mut a = vec![
            "synth",
            "--seed",
            "9",
            "--out",
            subj.to_str().unwrap(),
            "--duration",
            "6",
            "--motion-s",
            "3",
            "-q",
        ];
        if tips {
            a.push("--tip-markers-worn");
        }
        let g = ergohand(&a);
        assert!(g.status.success(), "{}", stderr(&g));
        subj
    };
    let (plain, tipped) = (synth("plain", false), synth("tipped", true));
    // The plain trial beside the worn one, in the tipped subject's folder.
    std::fs::copy(
        plain.join("trials/grasp_bottle.c3d"),
        tipped.join("trials/grasp_plain.c3d"),
    )
    .unwrap();
    let toml = tipped.join("subject.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(
        &toml,
        text + "\"grasp_plain\" = \"trials/grasp_plain.c3d\"\n",
    )
    .unwrap();
    let model = dir.path().join("model");
    let (s, m) = (tipped.to_str().unwrap(), model.to_str().unwrap());
    let r = ergohand(&["reconstruct", s, "--out", m, "-q"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let truth = read(&tipped.join("truth_motion/grasp_bottle.json"));
    let frames = truth["frames"].as_u64().unwrap() as usize;
    let point = |v: &serde_json::Value| -> [f64; 3] { [0, 1, 2].map(|k| v[k].as_f64().unwrap()) };
    let track = |motion: &str| -> serde_json::Value {
        let out = dir.path().join(motion);
        let r = ergohand(&[
            "track",
            s,
            "--model",
            m,
            "--motion",
            motion,
            "--out",
            out.to_str().unwrap(),
            "-q",
        ]);
        assert!(r.status.success(), "{}", stderr(&r));
        read(&out.join("motion.json"))
    };
    // RMS of the tracked fingertips against the truth's over every frame and digit, mm.
    let tip_rms = |got: &serde_json::Value| -> f64 {
        let (mut ss, mut n) = (0.0, 0);
        for (f, t) in truth["tips"].as_object().unwrap() {
            for k in 0..frames {
                let d = distance(point(&got["tips"][f][k]), point(&t[k]));
                ss += d * d;
                n += 1;
            }
        }
        (ss / n as f64).sqrt()
    };
    let worn = track("grasp_bottle");
    let bare = track("grasp_plain");
    // Worn markers are fitted: each one's median residual is of the order of the noise and its
    // slide (the mean is not: swapped labels and outliers are in it).
    for f in ["T", "I", "M", "R", "L"] {
        let name = format!("{f}_TIP");
        let mut res: Vec<f64> = worn["marker_residual_mm"][&name]
            .as_array()
            .unwrap_or_else(|| panic!("{name} not tracked"))
            .iter()
            .filter_map(|v| v.as_f64())
            .collect();
        assert!(res.len() > frames / 2, "{name}: {} samples", res.len());
        res.sort_by(f64::total_cmp);
        let median = res[res.len() / 2];
        assert!(median < 1.0, "{name}: median residual {median:.2} mm");
        // Attached from the static trial but never seen in the bare trial: no residual.
        let none = bare["marker_residual_mm"][&name]
            .as_array()
            .is_none_or(|a| a.iter().all(|v| v.is_null()));
        assert!(none, "{name} has residuals in a trial without it");
    }
    let (with, without) = (tip_rms(&worn), tip_rms(&bare));

    assert!(
        with < without,
        "fingertips {with:.2} mm with the markers worn, {without:.2} without"
    );
}
