//! Benches of the foundation: Horn's registration (run once per frame per joint by the link
//! model), welding, topology and template loading (Loop subdivision: benches/subdivision.rs).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::{absolute_orientation, Point};
use ergohand::template::load_template;
use std::hint::black_box;

fn horn(c: &mut Criterion) {
    // Four palm markers, as registered in every frame of every trial.
    let src = [
        Point::new(0.0, 0.0, 0.0),
        Point::new(60.0, 5.0, 2.0),
        Point::new(3.0, 55.0, -4.0),
        Point::new(58.0, 50.0, 8.0),
    ];
    let q = nalgebra::UnitQuaternion::from_euler_angles(0.2, -0.4, 1.1);
    let dst: Vec<Point> = src
        .iter()
        .map(|p| q * p + nalgebra::Vector3::new(5.0, 6.0, 7.0))
        .collect();
    c.bench_function("horn_4_points", |b| {
        b.iter(|| absolute_orientation(black_box(&src), black_box(&dst), None, false).unwrap())
    });
}

fn meshes(c: &mut Criterion) {
    let high = load_template(Side::Right).unwrap().mesh;
    c.bench_function("weld_37k_faces", |b| b.iter(|| black_box(&high).weld(0.01)));
    c.bench_function("topology_37k_faces", |b| {
        b.iter(|| black_box(&high).topology())
    });
    let mut g = c.benchmark_group("template");
    g.sample_size(10);
    g.bench_function("load_template_right", |b| {
        b.iter(|| load_template(Side::Right).unwrap())
    });
    g.finish();
}

criterion_group!(benches, horn, meshes);
criterion_main!(benches);
