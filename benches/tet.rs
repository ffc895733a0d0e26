//! Tetrahedral hand mesh (seed paper section 3.7): isosurface stuffing of the 37,024-face
//! template (goal < 5 s) and the deformation of its tet mesh to a subject's skin: boundary
//! binding, Cholesky factorisation and the ARAP solve (goal < 1 s).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::{Point, TriMesh};
use ergohand::template::load_template;
use ergohand::tet::{
    bind_boundary, isosurface_stuffing, place_boundary, subject_tet_mesh, untangle, ArapOptions,
    ElasticSolver, StuffingParams, UntangleOptions,
};
use std::hint::black_box;

#[path = "../tests/common/crease_fold.rs"]
mod crease_fold;

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
    // Its parts.
    g.bench_function("bind_boundary", |b| {
        b.iter(|| bind_boundary(black_box(&tet), &t.mesh).unwrap())
    });
    let binding = bind_boundary(&tet, &t.mesh).unwrap();
    g.bench_function("factorise", |b| {
        b.iter(|| ElasticSolver::new(black_box(&tet), &binding.nodes).unwrap())
    });
    let solver = ElasticSolver::new(&tet, &binding.nodes).unwrap();
    let held = place_boundary(&binding, &skin).unwrap();
    let (_, stats) = solver.solve(&held, &ArapOptions::default()).unwrap();
    eprintln!("ARAP: {stats:?}");
    g.bench_function("arap_solve", |b| {
        b.iter(|| {
            solver
                .solve(black_box(&held), &ArapOptions::default())
                .unwrap()
        })
    });
    g.bench_function("quality", |b| b.iter(|| black_box(&tet).quality()));
    // A fist's palmar crease that the penalty sweeps leave one element inverted in: what
    // untangling costs where the Winslow step has to finish it.
    let crease_fold::CreaseFold {
        nodes,
        tets,
        held,
        reference,
    } = crease_fold::crease_fold();
    let opts = UntangleOptions {
        max_boundary_move_mm: 0.0,
        ..Default::default()
    };
    g.bench_function("untangle_crease_fold", |b| {
        b.iter(|| {
            let mut n = nodes.clone();
            untangle(&mut n, black_box(&tets), &held, &reference, &opts)
        })
    });
    g.finish();
}

criterion_group!(benches, tet_bench);
criterion_main!(benches);
