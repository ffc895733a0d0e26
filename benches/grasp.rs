//! Grasp stage (the speed goals): one evaluation (pose by linear blend skinning +
//! contacts + force closure and epsilon) of the 37k-face template hand against a
//! ~100k-triangle bottle (< 5 ms), its contact query and its epsilon alone (the nearest-facet
//! search) against the whole hull's epsilon and volume, the distance from force closure
//! (Wolfe's nearest point) on the same wrenches, one autograsp (< 100 ms), the hold test
//! and the part's simplification for it, a precision
//! plan fitted to the hand (once per scene), and a placement search of 1,000 candidates
//! (< 15 s).

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::geometry::Point;
use ergohand::grasp::autograsp::{autograsp, root_for, squeeze, AutograspOptions};
use ergohand::grasp::contact::{contacts, vertex_areas, ContactOptions, PartShape};
use ergohand::grasp::hold::{hold_test_hand, HoldRun};
use ergohand::grasp::parts::{mesh_sdf, Part};
use ergohand::grasp::placement::placement_search;
use ergohand::grasp::plan::{fit_thumb_to_pads, grasp_plan};
use ergohand::grasp::quality::{
    closure_distance, cone_wrenches, grasp_epsilon, grasp_quality, CONE_EDGES,
};
use ergohand::grasp::scene::{pose_from, GraspType};
use ergohand::grasp::{evaluate, PosableHand, SkinnedHand};
use nalgebra::Isometry3;
use std::hint::black_box;

fn grasp_bench(c: &mut Criterion) {
    let hand = SkinnedHand::template(Side::Right).unwrap();
    let mesh = mesh_sdf(
        |p| Part::Bottle.sdf(p),
        Point::new(-30.0, -30.0, 0.0),
        Point::new(30.0, 30.0, 200.0),
        1.85,
    )
    .unwrap();
    eprintln!(
        "bottle: {} triangles, hand: {} faces",
        mesh.n_faces(),
        hand.rest_mesh().n_faces()
    );
    let part = PartShape::new(mesh).unwrap().0;
    let plan = grasp_plan(GraspType::Power);
    let approach = pose_from([-25.0, -36.0, 90.0], [-90.0, -90.0, 0.0]);
    let root = root_for(&hand, &Isometry3::identity(), &approach);
    let opts = AutograspOptions::default();
    let g = autograsp(&hand, &part, &plan, root, &opts).unwrap();
    let areas = vertex_areas(hand.rest_mesh());
    let mut gr = c.benchmark_group("grasp");
    gr.sample_size(10);
    gr.bench_function("evaluate_pose_contacts_epsilon", |b| {
        let mut pts = Vec::new();
        b.iter(|| evaluate(&hand, &part, black_box(&g.pose), 0.5, &areas, &mut pts))
    });
    // Its two parts apart (the "contact query" and "epsilon" benches).
    let mut posed = Vec::new();
    hand.pose_vertices(&g.pose, &mut posed);
    gr.bench_function("contact_query", |b| {
        b.iter(|| {
            contacts(
                &part,
                black_box(&posed),
                hand.vertex_link(),
                &areas,
                &ContactOptions::default(),
            )
        })
    });
    let cs = contacts(
        &part,
        &posed,
        hand.vertex_link(),
        &areas,
        &ContactOptions::default(),
    );
    eprintln!("epsilon bench: {} contacts", cs.contacts.len());
    gr.bench_function("epsilon_nearest_facet", |b| {
        b.iter(|| {
            grasp_epsilon(
                black_box(&cs.contacts),
                0.5,
                &part.centre_of_mass,
                part.max_radius,
            )
        })
    });
    gr.bench_function("epsilon_volume_whole_hull", |b| {
        b.iter(|| {
            grasp_quality(
                black_box(&cs.contacts),
                0.5,
                &part.centre_of_mass,
                part.max_radius,
            )
        })
    });
    // What ranks the placement search's grasps without force closure: the distance from the
    // origin to the same hull (Wolfe's nearest point), without building it.
    let wrenches = cone_wrenches(
        &cs.contacts,
        0.5,
        &part.centre_of_mass,
        part.max_radius,
        CONE_EDGES,
    );
    gr.bench_function("closure_distance_nearest_point", |b| {
        b.iter(|| closure_distance(black_box(&wrenches)))
    });
    gr.bench_function("autograsp_power_bottle", |b| {
        b.iter(|| autograsp(&hand, &part, &plan, black_box(root), &opts).unwrap())
    });
    // The hold test of the squeezed power grasp (six gravity directions, two at a time on two
    // cores).
    let squeezed = squeeze(&hand, &part, &plan, &g, &opts).0;
    let mut held = Vec::new();
    hand.pose_vertices(&squeezed, &mut held);
    gr.bench_function("hold_test_power_bottle", |b| {
        b.iter(|| hold_test_hand(&hand, black_box(&held), &part, 0.3, 0.5, HoldRun::Whole).unwrap())
    });
    // The precision plan fitted to the hand, once per scene: a fraction of one autograsp.
    let tripod = grasp_plan(GraspType::Tripod);
    gr.bench_function("fit_thumb_to_pads_tripod", |b| {
        b.iter(|| fit_thumb_to_pads(black_box(&tripod), &hand))
    });
    gr.measurement_time(std::time::Duration::from_secs(110));
    gr.bench_function("placement_search_1000", |b| {
        b.iter(|| placement_search(&hand, &part, &plan, 0.5, 1, 1000, 1e9).unwrap())
    });
    gr.finish();
}

criterion_group!(benches, grasp_bench);
criterion_main!(benches);
