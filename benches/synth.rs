//! Generating one simulated subject: six 60 s calibration trials at 100 fps, the reference trial
//! and the CT-like reference surface at 0.5 mm (under 10 s on the 2-core machine).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::synth::{simulate, voxel_scan::ct_surface, Preset, SynthOptions};
use ergohand::template::load_template;
use std::hint::black_box;

fn synth(c: &mut Criterion) {
    let mut g = c.benchmark_group("synth");
    g.sample_size(10);
    let opts = SynthOptions {
        duration_s: Some(60.0),
        ..SynthOptions::new(1, Preset::Typical)
    };
    g.bench_function("subject_six_60s_trials_and_ct_surface", |b| {
        b.iter(|| simulate(black_box(&opts)).unwrap())
    });
    let mesh = load_template(ergohand::anatomy::Side::Right).unwrap().mesh;
    g.bench_function("ct_surface_template_0.5mm", |b| {
        b.iter(|| ct_surface(black_box(&mesh), 0.5).unwrap())
    });
    g.finish();
}

criterion_group!(benches, synth);
criterion_main!(benches);
