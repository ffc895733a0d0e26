//! Tetrahedral hand mesh (seed paper section 3.7): isosurface stuffing of the 37,024-face
//! template (goal < 5 s) and the deformation of its tet mesh to a subject's skin: boundary
//! binding, Cholesky factorisation and the ARAP solve (goal < 1 s).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::{Point, TriMesh};
use ergohand::template::load_template;
use ergohand::tet::{isosurface_stuffing, subject_tet_mesh, StuffingParams};
use std::hint::black_box;

fn tet_bench(c: &mut Criterion) {
    faer::set_global_parallelism(faer::Par::Seq);
    let t = load_template(Side::Right).unwrap();
    let mut g = c.benchmark_group("tet");
    g.sample_size(10);
    g.bench_function("stuff_template_default_spacing", |b| {
        b.iter(|| isosurface_stuffing(black_box(&t.mesh), &StuffingParams::default()).unwrap())
    });
    let tet = isosurface_stuffing(&t.mesh, &StuffingParams::default()).unwrap();
    // A smooth non-affine "subject": 5 % larger, with a gentle bend about the z axis.
    let c0 = t.mesh.vertex_centroid();
    let skin = TriMesh {
        vertices: t
            .mesh
            .vertices
            .iter()
            .map(|p| {
                let d = (p - c0) * 1.05;
                let a = 0.002 * d.y;
                let (s, co) = a.sin_cos();
                c0 + nalgebra::Vector3::new(co * d.x - s * d.y, s * d.x + co * d.y, d.z)
            })
            .collect::<Vec<Point>>(),
        faces: t.mesh.faces.clone(),
    };
    g.bench_function("deform_to_subject", |b| {
        b.iter(|| subject_tet_mesh(&t, black_box(&tet), &skin).unwrap())
    });
    g.finish();
}

criterion_group!(benches, tet_bench);
criterion_main!(benches);
