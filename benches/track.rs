//! Tracking a grasp trial: the whole per-frame inverse kinematics of a 400-frame, 100 Hz trial
//! with 0.5 mm marker noise (the speed goal: far faster than capture, at least 2,000 frames per
//! second), the same trial with a fifth of the samples missing (holds and readmissions), and
//! one frame's solve from a fresh start (the three-flexion multi-start).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use ergohand::anatomy::Side;
use ergohand::track::fixture::{grasp_setup, motion_trial};
use ergohand::track::{track_trial, IkOptions};
use std::hint::black_box;

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
    g.sample_size(20);
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
    g.finish();
}

criterion_group!(benches, track_bench);
criterion_main!(benches);
