//! The C3D codec against ezc3d, a reader and writer that shares no code with it
//! (`validation/tools/c3d_peer.py`): ezc3d reads what `write_c3d` writes, and `read_c3d` reads
//! what ezc3d (float data, analog channels, 300 markers) and the Python `c3d` package (integer
//! data, which ezc3d does not write) write, with the same labels, rate, units, frame count and
//! values to float precision. ezc3d refuses more than 65,535 frames written the standard way (a
//! float `POINT:FRAMES`); the script checks such a file with the `c3d` package instead.
//!
//! Needs python3 with ezc3d and the c3d package (`pip install ezc3d c3d`); without either the
//! test prints a note and passes, so that a machine without them is not held to a check it
//! cannot run.

use ergohand::geometry::Point;
use ergohand::mocap::c3d::{read_c3d, write_c3d};
use ergohand::mocap::trajectories::Trajectories;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn python_imports(module: &str) -> bool {
    Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn peer_script(command: &str, dir: &Path) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("validation/tools/c3d_peer.py");
    let o = Command::new("python3")
        .arg(script)
        .arg(command)
        .arg(dir)
        .output()
        .unwrap();
    print!("{}", String::from_utf8_lossy(&o.stdout));
    assert!(
        o.status.success(),
        "c3d_peer.py {command} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Distinct smooth tracks with gaps: marker m misses frames where (f + 3m) % 11 == 4.
fn trajectories(labels: &[String], frames: usize, rate: f64) -> Trajectories {
    let positions = (0..labels.len())
        .map(|m| {
            (0..frames)
                .map(|f| {
                    let t = f as f64 * 0.01 + m as f64;
                    ((f + 3 * m) % 11 != 4).then(|| {
                        Point::new(
                            200.0 * t.sin() + f as f64 * 1e-3,
                            -650.0 + 40.0 * t.cos(),
                            900.0 + m as f64,
                        )
                    })
                })
                .collect()
        })
        .collect();
    Trajectories::new(rate, labels.to_vec(), positions, "peer.c3d").unwrap()
}

/// What the peer must read: the values as written (f32), in mm.
fn expected(t: &Trajectories) -> Value {
    let positions: Vec<Vec<Value>> = t
        .positions
        .iter()
        .map(|track| {
            track
                .iter()
                .map(|p| match p {
                    Some(p) => json!([p.x as f32, p.y as f32, p.z as f32]),
                    None => Value::Null,
                })
                .collect()
        })
        .collect();
    json!({
        "labels": t.labels,
        "rate": t.frame_rate,
        "units": "mm",
        "frames": t.n_frames(),
        "tolerance_mm": 1e-6,
        "positions": positions,
    })
}

fn labels(prefix: &str, n: usize) -> Vec<String> {
    (0..n).map(|k| format!("{prefix}{k}")).collect()
}

#[test]
fn ezc3d_reads_what_we_write_and_we_read_what_it_writes() {
    // The file of more than 65,535 frames can be checked only with the c3d package, so a
    // machine with ezc3d alone cannot run the whole check either.
    if let Some(missing) = ["ezc3d", "c3d"].into_iter().find(|m| !python_imports(m)) {
        println!(
            "note: python3 cannot import {missing}; the C3D peer check is skipped (pip install ezc3d c3d)"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();

    // Ours, read by ezc3d (and by the c3d package when it is installed).
    let ours = dir.path().join("ours");
    std::fs::create_dir(&ours).unwrap();
    let cases = [
        ("gaps", trajectories(&labels("PALM_", 5), 400, 120.0)),
        ("markers_300", trajectories(&labels("M", 300), 7, 100.0)),
        ("frames_70000", trajectories(&labels("L", 2), 70_000, 250.0)),
    ];
    for (name, t) in &cases {
        write_c3d(&ours.join(format!("{name}.c3d")), t).unwrap();
        std::fs::write(ours.join(format!("{name}.json")), expected(t).to_string()).unwrap();
    }
    peer_script("check", &ours);

    // Theirs, read by us.
    let theirs = dir.path().join("theirs");
    peer_script("write", &theirs);
    let mut read = 0;
    for entry in std::fs::read_dir(&theirs).unwrap() {
        let want_path = entry.unwrap().path();
        if want_path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let c3d = want_path.with_extension("c3d");
        let want: Value =
            serde_json::from_str(&std::fs::read_to_string(&want_path).unwrap()).unwrap();
        let t =
            read_c3d(&c3d, &BTreeMap::new()).unwrap_or_else(|e| panic!("{}: {e}", c3d.display()));
        let name = c3d.display().to_string();
        assert_eq!(
            t.labels,
            want["labels"]
                .as_array()
                .unwrap()
                .iter()
                .map(|l| l.as_str().unwrap())
                .collect::<Vec<_>>(),
            "{name}"
        );
        assert_eq!(t.frame_rate, want["rate"].as_f64().unwrap(), "{name}");
        assert_eq!(
            t.n_frames() as u64,
            want["frames"].as_u64().unwrap(),
            "{name}"
        );
        let tolerance = want["tolerance_mm"].as_f64().unwrap();
        for (m, track) in want["positions"].as_array().unwrap().iter().enumerate() {
            for (f, p) in track.as_array().unwrap().iter().enumerate() {
                let got = t.positions[m][f];
                match (p.as_array(), got) {
                    (None, None) => {}
                    (Some(w), Some(g)) => {
                        for k in 0..3 {
                            let w = w[k].as_f64().unwrap();
                            assert!(
                                (g[k] - w).abs() <= tolerance * w.abs().max(1.0),
                                "{name}: marker {m} frame {f}: {g} where {w} (axis {k})"
                            );
                        }
                    }
                    _ => panic!("{name}: marker {m} frame {f}: {got:?} where {p} was expected"),
                }
            }
        }
        read += 1;
    }
    assert!(read >= 2, "the peer wrote {read} files");
    println!("read {read} peer files");
}
