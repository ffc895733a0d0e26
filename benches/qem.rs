//! QEM simplification of the high-resolution template (37,024 faces) to the paper's ~1,000
//! faces with every landmark kept (well under a second).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::skin::simplify::simplify_qem;
use ergohand::template::load_template;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let t = load_template(Side::Right).expect("embedded template");
    let mut keep: Vec<usize> = t.spec.landmarks.values().copied().collect();
    keep.extend(t.spec.dimensions.values().flatten());
    let mut g = c.benchmark_group("skin");
    g.sample_size(10);
    g.bench_function("simplify_qem/template_37024_to_1000", |b| {
        b.iter(|| simplify_qem(black_box(&t.mesh), 1000, &keep).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
