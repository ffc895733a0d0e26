//! Loop subdivision of the generic hand (2314 faces): one and two levels, with composed stencils.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::geometry::loop_subdivision::{loop_subdivide, loop_subdivide_n};
use ergohand::geometry::{Point, TriMesh};
use std::hint::black_box;

fn generic_hand() -> TriMesh {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/generic-hand/right.glb");
    let (doc, buffers, _) = gltf::import(path).expect("generic hand");
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for mesh in doc.meshes() {
        for prim in mesh.primitives() {
            let reader = prim.reader(|b| Some(&buffers[b.index()]));
            let base = vertices.len();
            vertices.extend(
                reader
                    .read_positions()
                    .expect("positions")
                    .map(|p| Point::new(p[0] as f64, p[1] as f64, p[2] as f64) * 1000.0),
            );
            let idx: Vec<usize> = reader
                .read_indices()
                .expect("indices")
                .into_u32()
                .map(|i| i as usize)
                .collect();
            faces.extend(
                idx.chunks(3)
                    .map(|c| [base + c[0], base + c[1], base + c[2]]),
            );
        }
    }
    TriMesh::new(vertices, faces)
        .expect("valid mesh")
        .weld(0.0)
        .0
}

fn bench(c: &mut Criterion) {
    let hand = generic_hand();
    c.bench_function("loop_subdivide/generic_hand/1", |b| {
        b.iter(|| loop_subdivide(black_box(&hand)))
    });
    c.bench_function("loop_subdivide_n/generic_hand/2", |b| {
        b.iter(|| loop_subdivide_n(black_box(&hand), 2))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
