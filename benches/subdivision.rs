//! Loop subdivision of the generic hand (2314 faces): one and two levels, with composed stencils.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::loop_subdivision::{loop_subdivide, loop_subdivide_n};
use ergohand::template::load_base_hand;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let hand = load_base_hand(Side::Right).expect("embedded template").mesh;
    c.bench_function("loop_subdivide/generic_hand/1", |b| {
        b.iter(|| loop_subdivide(black_box(&hand)))
    });
    c.bench_function("loop_subdivide_n/generic_hand/2", |b| {
        b.iter(|| loop_subdivide_n(black_box(&hand), 2))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
