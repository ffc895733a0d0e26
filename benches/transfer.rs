//! Deformation transfer (seed paper eq. 3) from a ~1,000-face simplified template to the
//! 18,514 vertices of the high-resolution template, and closest-point queries against the
//! ~1.7 M-face CT-like reference surface of a simulated subject (what validation does).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::closest_point::AabbTree;
use ergohand::skin::simplify::simplify_qem;
use ergohand::skin::transfer::{bind, transfer};
use ergohand::synth::voxel_scan::ct_surface;
use ergohand::template::load_template;
use std::hint::black_box;

fn transfer_bench(c: &mut Criterion) {
    let t = load_template(Side::Right).unwrap();
    let keep: Vec<usize> = t.spec.landmarks.values().copied().collect();
    let low = simplify_qem(&t.mesh, 1000, &keep).unwrap().mesh;
    let mut g = c.benchmark_group("transfer");
    g.sample_size(10);
    g.bench_function("bind_18514_points_to_1000_faces", |b| {
        b.iter(|| bind(black_box(&low), &t.mesh.vertices).unwrap())
    });
    let binding = bind(&low, &t.mesh.vertices).unwrap();
    let moved = low.scaled(1.05);
    g.bench_function("transfer_18514_points", |b| {
        b.iter(|| transfer(black_box(&binding), &moved).unwrap())
    });
    let reference = ct_surface(&t.mesh, 0.5).unwrap();
    g.bench_function("aabb_tree_build_ct_surface", |b| {
        b.iter(|| AabbTree::new(black_box(&reference)))
    });
    let tree = AabbTree::new(&reference);
    g.bench_function("closest_points_18514_to_ct_surface", |b| {
        b.iter(|| tree.distances(black_box(&t.mesh.vertices)))
    });
    g.finish();
}

criterion_group!(benches, transfer_bench);
criterion_main!(benches);
