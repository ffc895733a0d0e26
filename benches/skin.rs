//! The landmark fit (Sumner & Popović energy with the seed paper's constraints) on
//! the base hand (2314 faces), on the QEM mesh of ~1,000 faces the skin stage fits by default
//! (low resolution) and on the full template (37,024 faces), the template's 31
//! landmarks and 22 dimension pairs, toward a smooth non-affine deformation of the template.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::{TriMesh, Vec3};
use ergohand::skin::correspondence::{
    fit_landmarks, DistanceConstraint, FitParams, LandmarkConstraint,
};
use ergohand::template::load_template;
use std::hint::black_box;

/// Targets: the mesh scaled by 7 % and bent by a 2 mm sine, landmarks 4 mm off along the normals.
fn problem(
    mesh: &TriMesh,
    idx: &[usize],
    pairs: &[[usize; 2]],
) -> (Vec<LandmarkConstraint>, Vec<DistanceConstraint>) {
    let c = mesh.vertex_centroid();
    let goal = TriMesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|p| c + 1.07 * (p - c) + Vec3::new(0.0, 2.0 * ((p.x - c.x) / 40.0).sin(), 0.0))
            .collect(),
        faces: mesh.faces.clone(),
    };
    let n = goal.vertex_normals();
    let lms = idx
        .iter()
        .map(|&v| LandmarkConstraint {
            vertex: v,
            target: goal.vertices[v] + n[v] * 4.0,
            offset_mm: 4.0,
        })
        .collect();
    let ds = pairs
        .iter()
        .map(|&[a, b]| DistanceConstraint {
            a,
            b,
            length_mm: (goal.vertices[a] - goal.vertices[b]).norm(),
            name: format!("{a}-{b}"),
        })
        .collect();
    (lms, ds)
}

fn skin(c: &mut Criterion) {
    let t = load_template(Side::Right).unwrap();
    let idx: Vec<usize> = t.spec.landmarks.values().copied().collect();
    let pairs: Vec<[usize; 2]> = t.spec.dimensions.values().copied().collect();
    let mut g = c.benchmark_group("skin_fit");
    g.sample_size(10);
    // The base hand's first 1159 vertices are the template's base vertices (Loop keeps indices);
    // its landmarks: the template's that are base vertices, else a spread of base vertices.
    let base = t.base.mesh.clone();
    let nb = base.n_vertices();
    let mut bidx: Vec<usize> = idx.iter().copied().filter(|&v| v < nb).collect();
    bidx.extend(
        (0..nb)
            .step_by(nb / 25)
            .take(25usize.saturating_sub(bidx.len())),
    );
    let bpairs: Vec<[usize; 2]> = pairs
        .iter()
        .copied()
        .filter(|p| p[0] < nb && p[1] < nb)
        .collect();
    let (lb, db) = problem(&base, &bidx, &bpairs);
    g.bench_function("base_hand_2314_faces", |b| {
        b.iter(|| fit_landmarks(black_box(&base), &lb, &db, &FitParams::default()).unwrap())
    });
    // The paper's low resolution: the QEM mesh of ~1,000 faces keeping every landmark and
    // dimension vertex, as the skin stage fits it by default.
    let mut keep: Vec<usize> = idx
        .iter()
        .copied()
        .chain(pairs.iter().flatten().copied())
        .collect();
    keep.sort_unstable();
    keep.dedup();
    let low = ergohand::skin::simplify::simplify_qem(&t.mesh, 1000, &keep).unwrap();
    let at = |v: usize| low.index_of[v].expect("kept vertices survive");
    let lidx: Vec<usize> = idx.iter().map(|&v| at(v)).collect();
    let lpairs: Vec<[usize; 2]> = pairs.iter().map(|&[a, b]| [at(a), at(b)]).collect();
    let (ll, dl) = problem(&low.mesh, &lidx, &lpairs);
    g.bench_function(
        format!("qem_low_resolution_{}_faces", low.mesh.n_faces()),
        |b| {
            b.iter(|| fit_landmarks(black_box(&low.mesh), &ll, &dl, &FitParams::default()).unwrap())
        },
    );
    let (lf, df) = problem(&t.mesh, &idx, &pairs);
    g.bench_function("full_template_37k_faces", |b| {
        b.iter(|| fit_landmarks(black_box(&t.mesh), &lf, &df, &FitParams::default()).unwrap())
    });
    g.finish();
}

/// The whole skin stage on a simulated subject in a varied posture (the goal: under
/// 1 s at the default resolution): pre-alignment, posture fit, posing, QEM, landmark fit,
/// transfer; the posture fit alone; and the stage at full resolution (fit under 3 s).
fn skin_stage(c: &mut Criterion) {
    use ergohand::skin::pipeline::{fit_skin, FitResolution, PriorChoice, SkinOptions};
    use ergohand::synth::{simulate, Posture, Preset, SynthOptions};
    let s = simulate(&SynthOptions {
        duration_s: Some(20.0),
        voxel_mm: 2.0,
        posture: Posture::Varied,
        ..SynthOptions::new(104, Preset::Typical)
    })
    .unwrap();
    let t = load_template(s.subject.hand).unwrap();
    let model = ergohand::link::estimate::estimate_link_model_from(
        s.subject.hand,
        s.subject.reference_frame,
        &s.trials,
    )
    .unwrap();
    let run = |opts: &SkinOptions| {
        fit_skin(
            &t,
            &s.trials["reference"],
            &s.subject.dimensions,
            s.subject.marker_offset_mm,
            Some(&model),
            opts,
        )
        .unwrap()
    };
    let mut g = c.benchmark_group("skin_stage");
    g.sample_size(10);
    g.bench_function("default_low_resolution", |b| {
        b.iter(|| run(black_box(&SkinOptions::default())))
    });
    // The default adds the shipped shape prior; the paper's fit leaves it out.
    g.bench_function("default_low_resolution_without_shape_prior", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                shape_prior: PriorChoice::None,
                ..SkinOptions::default()
            }))
        })
    });
    // The default pulls each digit joint's section towards the link model's centre; the
    // paper's fit has no such terms.
    g.bench_function("default_low_resolution_without_centre_terms", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                centre_weight: 0.0,
                ..SkinOptions::default()
            }))
        })
    });
    // The default scales the fingers' and the wrist's sections to their calipers after the
    // rounds; the rounds' skin alone is what it costs on top of.
    g.bench_function("default_low_resolution_without_section_scaling", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                section_scaling: false,
                ..SkinOptions::default()
            }))
        })
    });
    // The default keeps the thumb metacarpal's vertices at their spacing through the
    // simplification (and grows the face budget by as many); the quadrics alone are the paper's.
    g.bench_function("default_low_resolution_without_thumb_spacing", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                thumb_spacing_mm: 0.0,
                ..SkinOptions::default()
            }))
        })
    });
    g.bench_function("full_resolution", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                resolution: FitResolution::Full,
                ..SkinOptions::default()
            }))
        })
    });
    g.bench_function("without_posing", |b| {
        b.iter(|| {
            run(black_box(&SkinOptions {
                pose_template: false,
                ..SkinOptions::default()
            }))
        })
    });
    g.finish();
}

criterion_group!(benches, skin, skin_stage);
criterion_main!(benches);
