//! Tracking a grasp trial: the whole per-frame inverse kinematics of a 400-frame, 100 Hz trial
//! with 0.5 mm marker noise (the speed goal: far faster than capture, at least 2,000 frames per
//! second), the same trial with a fifth of the samples missing (holds and readmissions), and
//! one frame's solve from a fresh start (the three-flexion multi-start); and the contacts of
//! that tracked trial with the bottle of `scenes/bottle.toml` cutting through the palm and
//! moving with it (the replay against the inverse kinematics: their ratio is printed).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use ergohand::anatomy::{Link, Side};
use ergohand::grasp::hand::{PosableHand, SkinnedHand};
use ergohand::track::fixture::{grasp_setup, motion_trial};
use ergohand::track::{replay_contacts, track_trial, IkOptions, ReplayOptions};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::hint::black_box;
use std::time::{Duration, Instant};

fn track_bench(c: &mut Criterion) {
    let frames = 400;
    let (kin, st, att, truth) = grasp_setup(Side::Right, frames);
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.5, 7);
    let mut gappy = motion.clone();
    let mut rng = ergohand::rng::Rng::new(3);
    for track in &mut gappy.positions {
        for sample in track.iter_mut() {
            if rng.uniform() < 0.2 {
                *sample = None;
            }
        }
    }
    let opts = IkOptions::default();

    let mut g = c.benchmark_group("track");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(frames as u64));
    g.bench_function("grasp_400_frames_noise_0_5mm", |b| {
        b.iter(|| track_trial(&kin, &st, black_box(&motion), None, &opts).unwrap())
    });
    g.bench_function("grasp_400_frames_a_fifth_missing", |b| {
        b.iter(|| track_trial(&kin, &st, black_box(&gappy), None, &opts).unwrap())
    });
    g.throughput(Throughput::Elements(1));
    let first = motion_trial(&kin, &att, &truth[..1], 100.0, 0.5, 7);
    g.bench_function("one_frame_fresh_start", |b| {
        b.iter(|| track_trial(&kin, &st, black_box(&first), None, &opts).unwrap())
    });

    // The bottle's side 1 mm off the palm's centroid at rest, tilted, carried by the true palm.
    let hand = SkinnedHand::template(Side::Right).unwrap();
    let rest = &hand.rest_mesh().vertices;
    let palm = &hand.link_vertices()[Link::Palm.index()];
    let centre = palm
        .iter()
        .fold(Vector3::zeros(), |a, &i| a + rest[i].coords)
        / palm.len() as f64;
    let opts_c = ReplayOptions::default();
    let scene = ergohand::grasp::scene::read_scene(std::path::Path::new("scenes/bottle.toml"))
        .expect("the shipped bottle scene reads");
    let (part, _) =
        ergohand::grasp::scene_part_with_band(&scene, &Isometry3::identity(), opts_c.tolerance_mm)
            .expect("the shipped bottle loads");
    let cut = Isometry3::from_parts(
        Translation3::from(centre),
        UnitQuaternion::from_euler_angles(0.3, -0.5, 0.2),
    ) * Isometry3::translation(-31.0, 0.0, -100.0);
    let mut tracked = track_trial(&kin, &st, &motion, None, &opts).unwrap();
    tracked.part = Some((
        truth.iter().map(|s| Some(s.palm * cut)).collect(),
        vec![None; frames],
    ));
    let replay = replay_contacts(&hand, &kin, &tracked, &part, &opts_c);
    let touching = replay
        .frames
        .iter()
        .flatten()
        .filter(|f| f.total_area_mm2() > 0.0);
    assert!(touching.count() > frames / 2, "the bottle touches the palm");
    g.throughput(Throughput::Elements(frames as u64));
    g.bench_function("contacts_400_frames_bottle", |b| {
        b.iter(|| replay_contacts(&hand, &kin, black_box(&tracked), &part, &opts_c))
    });
    g.finish();

    // The replay's cost against the inverse kinematics', on the same trial.
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        for _ in 0..5 {
            f();
        }
        t.elapsed().as_secs_f64() / 5.0
    };
    let ik = time(&mut || {
        black_box(track_trial(&kin, &st, &motion, None, &opts).unwrap());
    });
    let contacts = time(&mut || {
        black_box(replay_contacts(&hand, &kin, &tracked, &part, &opts_c));
    });
    eprintln!(
        "track: contacts {:.1} ms, inverse kinematics {:.1} ms, ratio {:.2}",
        contacts * 1e3,
        ik * 1e3,
        contacts / ik
    );
}

criterion_group!(benches, track_bench);
criterion_main!(benches);
