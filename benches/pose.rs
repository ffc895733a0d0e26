//! Posing the 18,514-vertex / 37,024-face skin (the speed goal: at least 2,000 poses per
//! second on one core with linear blend skinning): forward kinematics plus skinning per pose,
//! into a reused buffer as grasp search does; dual-quaternion skinning for comparison; and the
//! one-off bone heat weights; and a baked pose with the segment-volume correction (DQS of skin
//! and the 157k-tet mesh's nodes, Newton on the segment volumes, boundary placement); and
//! writing the pose's 3-D page (the rig's arrays as base64, the data as JSON, the viewer
//! inlined).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::pose::{
    bone_heat_weights, named_pose, HeatOptions, IndividualHand, VolumeOptions, VolumeRig,
    WeightMethod,
};
use ergohand::skeleton::forward_kinematics::link_transforms;
use ergohand::template::load_template;
use std::hint::black_box;

fn pose_bench(c: &mut Criterion) {
    let t = load_template(Side::Right).unwrap();
    let h = IndividualHand::from_skin(
        &t,
        t.mesh.clone(),
        t.skeleton.clone(),
        WeightMethod::Template,
    )
    .unwrap();
    let binding = h.binding();
    let pose = named_pose("fist").unwrap();
    let mut out = Vec::new();
    let mut g = c.benchmark_group("pose");
    g.bench_function("lbs_fk_plus_18514_vertices", |b| {
        b.iter(|| {
            let tr = link_transforms(&h.skeleton, black_box(&pose));
            binding.linear_into(&tr, &mut out);
            black_box(out.len())
        })
    });
    g.bench_function("dqs_fk_plus_18514_vertices", |b| {
        b.iter(|| {
            let tr = link_transforms(&h.skeleton, black_box(&pose));
            black_box(binding.dual_quaternion(&tr).len())
        })
    });
    g.bench_function("view_page_html_with_rig_18514_vertices", |b| {
        use ergohand::validate::view_page::{view_html, ViewPage, ViewRig};
        let shown = binding.dual_quaternion(&link_transforms(&h.skeleton, &pose));
        let page = ViewPage {
            title: "pose: fist".into(),
            kind: "pose",
            glbs: vec![],
            part_nodes: vec![],
            legend: None,
            facts: vec![],
            tables: vec![],
            frame: None,
            view: None,
            part_opacity: None,
            rig: Some(ViewRig {
                rest: h.skin.clone(),
                weights: h.weights.clone(),
                skeleton: h.skeleton.clone(),
                root: pose.root,
                angles_deg: pose.angles.map(|a| a.map(f64::to_degrees)),
                shown,
                shown_label: "as written".into(),
                live_label: "live".into(),
            }),
        };
        b.iter(|| black_box(view_html(black_box(&page)).len()))
    });
    g.sample_size(10);
    g.bench_function("bone_heat_weights_18514_vertices", |b| {
        b.iter(|| {
            bone_heat_weights(black_box(&h.skin), &h.skeleton, &HeatOptions::default()).unwrap()
        })
    });
    let prepared = ergohand::tet::TemplateTet::prepare(&t, None).unwrap();
    let rig = VolumeRig::new(&t, &prepared, prepared.tet.nodes.clone()).unwrap();
    g.bench_function("fist_dqs_volume_corrected_skin_and_tet", |b| {
        b.iter(|| {
            rig.pose(&h, black_box(&pose), true, &VolumeOptions::default())
                .unwrap()
                .correction
                .iterations
        })
    });
    g.finish();
}

criterion_group!(benches, pose_bench);
criterion_main!(benches);
