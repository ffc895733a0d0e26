//! The link model of a subject: seven trials of 60 s at 100 fps (all joints under
//! 0.5 s), and the per-frame registration alone.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::{palm_markers, Side};
use ergohand::link::estimate::estimate_link_model_from;
use ergohand::link::registration::register_parent;
use ergohand::synth::{simulate, Preset, SynthOptions};
use std::hint::black_box;

fn link(c: &mut Criterion) {
    let s = simulate(&SynthOptions {
        duration_s: Some(60.0),
        voxel_mm: 2.0,
        ..SynthOptions::new(7, Preset::Typical)
    })
    .expect("simulated subject");
    let mut g = c.benchmark_group("link");
    g.sample_size(10);
    g.bench_function("link_model_7_trials_60s", |b| {
        b.iter(|| estimate_link_model_from(Side::Right, 0, black_box(&s.trials)).unwrap())
    });
    let index = &s.trials["index"];
    g.bench_function("register_palm_6000_frames", |b| {
        b.iter(|| register_parent(black_box(index), &palm_markers(), 0))
    });
    g.finish();
}

criterion_group!(benches, link);
criterion_main!(benches);
