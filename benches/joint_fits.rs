//! The joint fits of the link model (section 3.4) one by one, on one 60 s trial at 100 fps
//! (6,000 frames, three child markers): the sphere fits (Gamage & Lasenby, and Halvorsen's
//! bias-compensated one with the noise estimated), the common plane normal and circle centre
//! of a hinge, and the functional SCoRE and SARA from both segments' poses. `benches/link.rs`
//! times the whole link model of a subject.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::geometry::{Point, Vec3};
use ergohand::link::axis_fit::common_plane_normal;
use ergohand::link::functional::{sara_axis, score_centre};
use ergohand::link::sphere_fit::{
    circle_centre_on_axis, common_sphere_centre, common_sphere_centre_bias_compensated,
};
use ergohand::rng::Rng;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::hint::black_box;

const FRAMES: usize = 6000;

/// Parent poses, child poses and the child markers' tracks in the parent's frame.
type Trial = (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>, Vec<Vec<Point>>);

/// Parent and child poses of a joint at (10, 20, 30) mm: the parent drifts, the child moves
/// about the joint by `motion(t)`; child markers 15-25 mm from the joint, 0.2 mm noise.
fn trial(motion: impl Fn(f64) -> UnitQuaternion<f64>, seed: u64) -> Trial {
    let mut rng = Rng::new(seed);
    let centre = Vec3::new(10.0, 20.0, 30.0);
    let markers = [
        Point::new(3.0, 14.0, 2.0),
        Point::new(-4.0, 16.0, 18.0),
        Point::new(2.0, 13.0, 24.0),
    ];
    let (mut parent, mut child) = (Vec::new(), Vec::new());
    let mut tracks = vec![Vec::new(); markers.len()];
    for i in 0..FRAMES {
        let t = i as f64 / FRAMES as f64;
        let p = Isometry3::from_parts(
            Translation3::new(5.0 * t, -3.0 * t, 2.0 * t),
            UnitQuaternion::from_euler_angles(0.1 * t, -0.05 * t, 0.2 * t),
        );
        // The child: rotate about the joint centre (in the parent's frame).
        let rel = Isometry3::from_parts(Translation3::from(centre), motion(t))
            * Isometry3::from_parts(Translation3::from(-centre), UnitQuaternion::identity());
        parent.push(p);
        child.push(p * rel);
        for (k, m) in markers.iter().enumerate() {
            let noise = Vec3::new(
                rng.gauss(0.0, 0.2),
                rng.gauss(0.0, 0.2),
                rng.gauss(0.0, 0.2),
            );
            tracks[k].push(rel * (m + centre) + noise);
        }
    }
    (parent, child, tracks)
}

fn joint_fits(c: &mut Criterion) {
    use std::f64::consts::TAU;
    // 3-DOF: circumduction, flexion 0-80 deg, abduction +-20 deg, as the synth's MCP motion.
    let (p3, c3, t3) = trial(
        |t| {
            let a = TAU * 4.0 * t;
            UnitQuaternion::from_euler_angles(
                (40.0 + 40.0 * a.sin()).to_radians(),
                (20.0 * a.cos()).to_radians(),
                0.0,
            )
        },
        1,
    );
    // 1-DOF: flexion 0-100 deg about x.
    let (p1, c1, t1) = trial(
        |t| {
            UnitQuaternion::from_euler_angles(
                (50.0 - 50.0 * (TAU * 5.0 * t).cos()).to_radians(),
                0.0,
                0.0,
            )
        },
        2,
    );
    let tracks3: Vec<&[Point]> = t3.iter().map(Vec::as_slice).collect();
    let tracks1: Vec<&[Point]> = t1.iter().map(Vec::as_slice).collect();
    let mut g = c.benchmark_group("joint_fits_6000_frames");
    g.bench_function("sphere_gamage_lasenby", |b| {
        b.iter(|| common_sphere_centre(black_box(&tracks3)).unwrap())
    });
    g.bench_function("sphere_bias_compensated_halvorsen", |b| {
        b.iter(|| common_sphere_centre_bias_compensated(black_box(&tracks3), None).unwrap())
    });
    g.bench_function("score_centre", |b| {
        b.iter(|| score_centre(black_box(&p3), black_box(&c3)).unwrap())
    });
    g.bench_function("plane_normal_axis", |b| {
        b.iter(|| common_plane_normal(black_box(&tracks1)).unwrap())
    });
    let axis = common_plane_normal(&tracks1).unwrap();
    g.bench_function("circle_centre_on_axis", |b| {
        b.iter(|| {
            circle_centre_on_axis(
                black_box(&tracks1),
                &axis.axis,
                &Point::new(10.0, 20.0, 30.0),
            )
            .unwrap()
        })
    });
    g.bench_function("sara_axis", |b| {
        b.iter(|| sara_axis(black_box(&p1), black_box(&c1)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, joint_fits);
criterion_main!(benches);
