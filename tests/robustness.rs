//! Wrong input must never give a confident wrong hand: each case feeds one realistic mistake to
//! a command and checks the exit status (or `Err`), that the one-line error names the file and
//! the item, that nothing half-written stays in the output folder, and that no input changed.

use ergohand::io::fingerprint::Fnv1a;
use ergohand::mocap::c3d::{read_c3d, write_c3d};
use ergohand::synth::{self, Preset, SynthOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
mod common;
use common::{ergohand, error_line, stderr};

/// A short simulated right-hand subject, made once; tests copy it.
fn base() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = tempfile::tempdir().unwrap();
        let mut o = SynthOptions::new(21, Preset::Typical);
        o.duration_s = Some(4.0);
        o.voxel_mm = 1.0;
        let s = synth::simulate(&o).unwrap();
        synth::write_subject(&d.path().join("S"), &s, false).unwrap();
        d
    })
    .path()
    .join("S")
    .leak()
}

/// A copy of the base subject at `dir/name`.
fn subject_copy(dir: &Path, name: &str) -> PathBuf {
    let to = dir.join(name);
    copy_tree(base(), &to);
    to
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let t = to.join(e.file_name());
        if e.path().is_dir() {
            copy_tree(&e.path(), &t);
        } else {
            std::fs::copy(e.path(), t).unwrap();
        }
    }
}

/// Every file under `dir` with the FNV-1a hash of its bytes.
fn tree_hash(dir: &Path) -> BTreeMap<PathBuf, u64> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let mut h = Fnv1a::default();
                h.update(&std::fs::read(&p).unwrap());
                out.insert(p, h.finish());
            }
        }
    }
    out
}

/// Nothing at `out`, or an empty folder.
fn nothing_written(out: &Path) -> bool {
    !out.exists() || std::fs::read_dir(out).unwrap().next().is_none()
}

/// `reconstruct S --out OUT` must fail with a line naming every one of `names`, write nothing
/// and change no input.
fn reconstruct_refuses(subject: &Path, names: &[&str]) -> String {
    let out = subject.parent().unwrap().join("out");
    let before = tree_hash(subject);
    let o = ergohand(&[
        "reconstruct",
        subject.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let line = error_line(&o);
    for n in names {
        assert!(line.contains(n), "'{n}' not in: {line}");
    }
    assert!(nothing_written(&out));
    assert_eq!(tree_hash(subject), before, "an input changed");
    line
}

/// Replace the `POINT:UNITS` text "mm" of a C3D file written here by `units` (same length).
fn set_point_units(path: &Path, units: &[u8; 2]) {
    let mut b = std::fs::read(path).unwrap();
    let at = b.windows(5).position(|w| w == b"UNITS").unwrap();
    let mm = at + b[at..].windows(2).position(|w| w == b"mm").unwrap();
    b[mm..mm + 2].copy_from_slice(units);
    std::fs::write(path, b).unwrap();
}

#[test]
fn trial_in_mm_labelled_metres_is_refused_naming_file_and_units() {
    let d = tempfile::tempdir().unwrap();
    let s = subject_copy(d.path(), "S");
    set_point_units(&s.join("trials/index.c3d"), b"m ");
    let line = reconstruct_refuses(&s, &["index.c3d", "POINT:UNITS", "'m'", "like mm"]);
    assert!(!line.contains('\n'));
}

#[test]
fn declared_hand_against_the_landmarks_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let s = subject_copy(d.path(), "S");
    let toml = s.join("subject.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(text.contains("hand = \"right\""));
    std::fs::write(&toml, text.replace("hand = \"right\"", "hand = \"left\"")).unwrap();
    reconstruct_refuses(&s, &["subject.toml", "hand", "right hand"]);
}

#[test]
fn a_landmark_metres_off_is_named() {
    let d = tempfile::tempdir().unwrap();
    let s = subject_copy(d.path(), "S");
    let path = s.join("trials/reference.c3d");
    let mut t = read_c3d(&path, &BTreeMap::new()).unwrap();
    let m = t.index_of("I_NAIL").unwrap();
    for p in t.positions[m].iter_mut().flatten() {
        p.x += 5000.0;
    }
    write_c3d(&path, &t).unwrap();
    reconstruct_refuses(&s, &["reference.c3d", "I_NAIL"]);
}

/// One sample of 1e8 mm is dropped and counted, and the link model is the one without it.
#[test]
fn a_single_absurd_sample_is_dropped_with_a_warning() {
    let d = tempfile::tempdir().unwrap();
    let s = subject_copy(d.path(), "S");
    let path = s.join("trials/index.c3d");
    let mut t = read_c3d(&path, &BTreeMap::new()).unwrap();
    let m = t.index_of("I_PROX_1").unwrap();
    let f = t.positions[m].iter().position(Option::is_some).unwrap() + 50;
    let clean =
        ergohand::link::estimate_link_model(&ergohand::mocap::subject::Subject::load(&s).unwrap())
            .unwrap();
    let was = t.positions[m][f];
    t.positions[m][f] = Some(ergohand::geometry::Point::new(1e8, 0.0, 0.0));
    write_c3d(&path, &t).unwrap();
    let subject = ergohand::mocap::subject::Subject::load(&s).unwrap();
    let model = ergohand::link::estimate_link_model(&subject).unwrap();
    let w = model
        .warnings
        .iter()
        .find(|w| w.contains("I_PROX_1"))
        .expect("a warning names the marker");
    assert!(w.contains("index.c3d") && w.contains("1 samples"), "{w}");
    // Dropped, it moves no joint centre by more than a fraction of a millimetre (one frame
    // of hundreds; undropped, a 1e8 mm sample would wreck the registration of its frame).
    assert!(was.is_some());
    for (a, b) in clean.joints.iter().zip(&model.joints) {
        let dist = (a.centre - b.centre).norm();
        assert!(dist < 0.5, "{} moved {dist} mm", a.joint);
    }
}

#[test]
fn pose_out_onto_the_models_own_skin_is_refused_before_any_work() {
    let d = tempfile::tempdir().unwrap();
    let model = d.path().join("OUT");
    std::fs::create_dir_all(&model).unwrap();
    // Not a real model: the refusal must come before anything is read.
    std::fs::write(model.join("skin.obj"), "v 0 0 0\n").unwrap();
    let before = tree_hash(&model);
    let target = model.join("skin.obj");
    let o = ergohand(&[
        "pose",
        model.to_str().unwrap(),
        "--pose",
        "fist",
        "--out",
        target.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("skin.obj") && line.contains("--out"),
        "{line}"
    );
    assert_eq!(tree_hash(&model), before);
}

#[test]
fn grasp_out_naming_a_file_is_refused_before_any_work() {
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("results.txt");
    std::fs::write(&file, "keep me").unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
    let o = ergohand(&[
        "grasp",
        scene.to_str().unwrap(),
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let line = error_line(&o);
    assert!(
        line.contains("results.txt") && line.contains("--out"),
        "{line}"
    );
    assert!(
        !line.contains("grasp.json"),
        "refused as a folder, not when writing"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
}

/// Batch: a huge --jobs finishes (lowered, with a warning); a stale temporary file of a killed
/// run is removed; a subject replaced with preserved timestamps is redone; and the same model,
/// validated against a reference written in metres, is refused naming the file and the unit.
#[test]
fn batch_reruns_by_content_clamps_jobs_and_cleans_up() {
    let d = tempfile::tempdir().unwrap();
    let subjects = d.path().join("subjects");
    let out = d.path().join("out");
    let s = subject_copy(&subjects, "A");
    let (sd, od) = (subjects.to_str().unwrap(), out.to_str().unwrap());
    let o = ergohand(&["batch", sd, "--out", od, "--jobs", "100000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--jobs 100000 lowered to 1"),
        "{}",
        stderr(&o)
    );

    // A temporary file a killed run left an hour ago, and a replaced trial whose times are
    // kept (`cp -p`): one sample moved by 1 mm.
    let stale = out.join("A/.tet.vtk.999.0.1.tmp");
    std::fs::write(&stale, "half").unwrap();
    let hour_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    let set_mtime = |p: &Path, t| {
        std::fs::File::options()
            .write(true)
            .open(p)
            .unwrap()
            .set_modified(t)
            .unwrap()
    };
    set_mtime(&stale, hour_ago);
    let trial = s.join("trials/ring.c3d");
    let mtime = std::fs::metadata(&trial).unwrap().modified().unwrap();
    let mut t = read_c3d(&trial, &BTreeMap::new()).unwrap();
    let sample = t.positions[0].iter_mut().flatten().nth(10).unwrap();
    sample.x += 1.0;
    write_c3d(&trial, &t).unwrap();
    set_mtime(&trial, mtime);

    let o = ergohand(&["batch", sd, "--out", od]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("batch-summary.json")).unwrap())
            .unwrap();
    assert_eq!(
        summary["subjects"][0]["status"], "ok",
        "redone, not skipped"
    );
    assert!(!stale.exists());
    assert!(stderr(&o).contains("removed 1 temporary"), "{}", stderr(&o));
    // A third run skips it.
    let o = ergohand(&["batch", sd, "--out", od, "-q"]);
    assert!(o.status.success());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("batch-summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["subjects"][0]["status"], "skipped-up-to-date");

    // reference.ply exported in metres.
    let reference = s.join("reference.ply");
    let mesh = ergohand::io::ply::read_ply(&reference, ergohand::io::Units::Millimetres)
        .unwrap()
        .mesh;
    ergohand::io::ply::write_ply(&reference, &mesh, ergohand::io::Units::Metres, None).unwrap();
    let before = tree_hash(&s);
    let report = d.path().join("report");
    let o = ergohand(&[
        "validate",
        s.to_str().unwrap(),
        "--model",
        out.join("A").to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let line = error_line(&o);
    assert!(
        line.contains("reference.ply") && line.contains("look like m"),
        "{line}"
    );
    assert!(nothing_written(&report));
    assert_eq!(tree_hash(&s), before);
}

/// The files of a model folder but `report.json` (which holds timings) with their hashes, and
/// the report's input fingerprint.
fn model_files(out: &Path) -> (BTreeMap<PathBuf, u64>, String) {
    let mut files: BTreeMap<PathBuf, u64> = tree_hash(out)
        .into_iter()
        .map(|(p, h)| (p.strip_prefix(out).unwrap().to_path_buf(), h))
        .collect();
    files.remove(Path::new("report.json"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    (files, report["inputs_fnv1a"].as_str().unwrap().to_string())
}

fn reconstruct_args<'a>(s: &'a Path, out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec![
        "reconstruct",
        s.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(extra);
    a.push("-q");
    a
}

/// A run killed while it writes leaves no file that a rerun keeps: the rerun removes the dead
/// run's temporaries and gives the same model as a run never killed. Two runs into one folder
/// at once (different options) leave one run's files, never a mix.
#[test]
fn killed_and_concurrent_runs_leave_one_runs_files_and_nothing_else() {
    let d = tempfile::tempdir().unwrap();
    let s = subject_copy(d.path(), "S");
    let inputs = tree_hash(&s);
    let (solo_a, solo_b) = (d.path().join("solo-a"), d.path().join("solo-b"));
    const B: &[&str] = &["--caliper-rounds", "0"];
    for (out, extra) in [(&solo_a, &[][..]), (&solo_b, B)] {
        let o = ergohand(&reconstruct_args(&s, out, extra));
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let (a, b) = (model_files(&solo_a), model_files(&solo_b));
    assert_ne!(a.0, b.0, "the two option sets give different models");

    // Killed as soon as its first output appears (mid-way through writing the model).
    let out = d.path().join("killed");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_ergohand"))
        .args(reconstruct_args(&s, &out, &[]))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let written = |out: &Path| std::fs::read_dir(out).map_or(0, |r| r.count());
    while written(&out) == 0 && child.try_wait().unwrap().is_none() {
        assert!(started.elapsed().as_secs() < 120, "no output after 120 s");
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // Whatever it left is whole files or hidden temporaries, never a half-written output.
    for e in std::fs::read_dir(&out).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        if !name.starts_with('.') {
            let h = tree_hash(&out)[&out.join(&name)];
            let whole = name == "report.json" || a.0.get(Path::new(&name)) == Some(&h);
            assert!(whole, "{name} half-written");
        }
    }
    let o = ergohand(&reconstruct_args(&s, &out, &[]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        model_files(&out),
        a,
        "the rerun's model is the unkilled run's"
    );
    for e in std::fs::read_dir(&out).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "{name} left behind");
    }

    // Two runs into one folder at once.
    let out = d.path().join("both");
    let spawn = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_ergohand"))
            .args(reconstruct_args(&s, &out, extra))
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap()
    };
    let (mut first, mut second) = (spawn(&[]), spawn(B));
    assert!(first.wait().unwrap().success() && second.wait().unwrap().success());
    let both = model_files(&out);
    assert!(both == a || both == b, "a mix of the two runs' files");
    assert_eq!(tree_hash(&s), inputs, "an input changed");
}

/// How one hostile case ended.
enum Outcome {
    /// Exit 1 with this one-line error.
    Refused(String),
    /// Exit 0.
    Done,
}

/// Run `reconstruct subject --out out -q` with a 60 s limit and check what every case must
/// hold whatever it is: no panic, no other exit status, no hang, no temporary file left, no
/// input changed; a refusal is one `error:` line naming `file`, and writes nothing.
fn hostile_reconstruct(subject: &Path, out: &Path, file: &str, case: &str) -> Outcome {
    let before = tree_hash(subject);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_ergohand"))
        .args([
            "reconstruct",
            subject.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if started.elapsed().as_secs() > 60 {
            child.kill().unwrap();
            panic!("{case}: still running after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!err.contains("panicked"), "{case}: {err}");
    assert_eq!(tree_hash(subject), before, "{case}: an input changed");
    if out.exists() {
        for e in std::fs::read_dir(out).unwrap() {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            assert!(!name.ends_with(".tmp"), "{case}: {name} left behind");
        }
    }
    match status.code() {
        Some(0) => Outcome::Done,
        Some(1) => {
            let line = err.lines().last().unwrap_or_default().to_string();
            assert!(line.starts_with("error: "), "{case}: {err}");
            assert!(line.contains(file), "{case}: '{file}' not in {line}");
            assert!(nothing_written(out), "{case}: refused but wrote");
            Outcome::Refused(line)
        }
        other => panic!("{case}: exit {other:?}: {err}"),
    }
}

/// The diagonal of the box around a model's skin, mm.
fn skin_diagonal(model: &Path) -> f64 {
    ergohand::io::obj::read_obj(&model.join("skin.obj"), ergohand::io::Units::Millimetres)
        .unwrap()
        .diagonal()
}

/// Over three hundred generated mistakes in a subject folder, each fed to `reconstruct`:
/// every value of subject.toml made negative, zero, not a number, infinite, huge, or of the
/// wrong type; every trial path pointing nowhere, at a non-C3D file, or empty; every line
/// deleted; every trial cut short at eight places; bytes of the reference trial's header and
/// parameters changed. Each case ends in a refusal naming the file (and, for a value of
/// subject.toml, the key), or in a hand whose size is within 20 % of the unharmed subject's.
#[test]
fn hostile_subject_folders_are_refused_or_give_a_plausible_hand() {
    let d = tempfile::tempdir().unwrap();
    let clean = subject_copy(d.path(), "clean");
    let clean_out = d.path().join("clean-out");
    assert!(matches!(
        hostile_reconstruct(&clean, &clean_out, "", "unharmed"),
        Outcome::Done
    ));
    let size = skin_diagonal(&clean_out);
    let toml_text = std::fs::read_to_string(clean.join("subject.toml")).unwrap();
    let s = subject_copy(d.path(), "S");
    let out = d.path().join("out");
    let (mut refused, mut done, mut cases) = (0, 0, 0);
    let mut check = |file: &str, case: String, key: Option<&str>| {
        if out.exists() {
            std::fs::remove_dir_all(&out).unwrap();
        }
        cases += 1;
        match hostile_reconstruct(&s, &out, file, &case) {
            Outcome::Refused(line) => {
                if let Some(k) = key {
                    assert!(line.contains(k), "{case}: '{k}' not in {line}");
                }
                refused += 1;
            }
            Outcome::Done => {
                let ratio = skin_diagonal(&out) / size;
                assert!(
                    (0.8..1.25).contains(&ratio),
                    "{case}: hand size x{ratio:.2}"
                );
                done += 1;
            }
        }
    };

    // subject.toml: every value replaced, every line deleted.
    let lines: Vec<&str> = toml_text.lines().collect();
    for (i, line) in lines.iter().enumerate() {
        let restore = || std::fs::write(s.join("subject.toml"), &toml_text).unwrap();
        let with_line = |new: &str| {
            let mut l: Vec<String> = lines.iter().map(|x| x.to_string()).collect();
            l[i] = new.to_string();
            std::fs::write(s.join("subject.toml"), l.join("\n")).unwrap();
        };
        if !line.trim().is_empty() {
            with_line("");
            check(
                "subject.toml",
                format!("line {} deleted: {line}", i + 1),
                None,
            );
        }
        let Some((key, value)) = line.split_once(" = ") else {
            restore();
            continue;
        };
        let key = key.trim().trim_matches('"');
        let variants: &[&str] = if value.starts_with('"') && value.contains(".c3d") {
            &["\"trials/missing.c3d\"", "\"subject.toml\"", "\"\"", "42"]
        } else if value.starts_with('"') {
            &["\"\"", "5", "\"up\""]
        } else {
            &["-5", "0", "nan", "inf", "1e9", "\"12\""]
        };
        for v in variants {
            with_line(&format!("{key} = {v}"));
            check("subject.toml", format!("{key} = {v}"), Some(key));
        }
        restore();
    }

    // Every trial cut short.
    let trials: Vec<PathBuf> = std::fs::read_dir(s.join("trials"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    for t in &trials {
        let bytes = std::fs::read(t).unwrap();
        let name = t.file_name().unwrap().to_str().unwrap().to_string();
        for cut in [
            0,
            1,
            100,
            512,
            513,
            1024,
            2048,
            bytes.len() / 2,
            bytes.len() - 1,
        ] {
            std::fs::write(t, &bytes[..cut.min(bytes.len())]).unwrap();
            check(&name, format!("{name} cut at {cut}"), None);
        }
        std::fs::write(t, &bytes).unwrap();
    }

    // Bytes of the reference trial's header and parameter section changed (seeded).
    let reference = s.join("trials/reference.c3d");
    let bytes = std::fs::read(&reference).unwrap();
    let data_start = 512 * (usize::from(u16::from_le_bytes([bytes[16], bytes[17]])) - 1);
    let mut rng = ergohand::rng::Rng::new(24);
    for k in 0..40 {
        let mut b = bytes.clone();
        let at = (rng.uniform() * data_start as f64) as usize;
        let to = (rng.uniform() * 256.0) as u8;
        if b[at] == to {
            continue;
        }
        b[at] = to;
        std::fs::write(&reference, &b).unwrap();
        check(
            "reference.c3d",
            format!("reference.c3d byte {at} set to {to} (mutation {k})"),
            None,
        );
    }
    std::fs::write(&reference, &bytes).unwrap();
    eprintln!("{cases} hostile cases: {refused} refused, {done} gave a plausible hand");
    assert!(cases >= 300, "{cases} cases");
}
