//! A hand as a skinned glTF scene (glTF 2.0 spec 3.7.3 "Skins"): one joint node per link of
//! the spec's tree ([`Link::ALL`], nested as the tree), each placed at its joint's centre with
//! its joint's frame (the forearm with the wrist's), inverse bind matrices the inverses of the
//! rest world transforms, and the per-vertex link weights.
//!
//! With a pose, each joint node's local rotation is the joint's rotation expressed in its own
//! frame, `Fᵀ · R_world(θ) · F` ([`joint_rotation`]), and the forearm node carries the pose's
//! root motion; the mesh stays in the bind pose, so a viewer shows the posed hand by linear
//! blend skinning (`Σ w_l · world_l · IBM_l`), which equals [`super::skinning`]'s LBS: since
//! `world_l(θ) = T_l(θ) · world_l(0)`, `world_l(θ) · IBM_l = T_l(θ)`.

use crate::anatomy::{Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::TriMesh;
use crate::io::gltf::{
    Animation, AnimationTarget, Channel, Keyframes, Scene, SceneMesh, Skin, SkinJoint,
};
use crate::skeleton::forward_kinematics::joint_rotation;
use crate::skeleton::{Pose, Skeleton};
use crate::template::LinkWeights;
use nalgebra::{Isometry3, Matrix4, Translation3, UnitQuaternion};

/// Rest frame of link `l`'s joint node: at its joint (the forearm: the wrist), axes of the
/// joint frame, re-orthonormalised (frames read from files are orthonormal only to ~1e-6).
fn rest_frame(sk: &Skeleton, l: Link) -> Isometry3<f64> {
    let j = l.joint().unwrap_or(Joint::Wrist);
    let jf = sk.joint(j);
    let q = UnitQuaternion::from_rotation_matrix(&jf.frame);
    Isometry3::from_parts(Translation3::from(jf.centre.coords), q)
}

/// The local transform (relative to its parent link's node; the forearm's: to the scene) of
/// every link's joint node, in [`Link::ALL`] order, for `pose` (`None`: the rest pose). At
/// rest a node is its joint's frame seen from its parent's; posed, a joint node adds the
/// joint's rotation in its own frame, `Fᵀ · R_world(θ) · F`, and the forearm node is moved by
/// the pose's root. Only rotations change below the forearm: each node's translation is its
/// rest one, so an animation needs a translation channel on the forearm alone.
pub fn joint_locals(sk: &Skeleton, pose: Option<&Pose>) -> Vec<Isometry3<f64>> {
    Link::ALL
        .iter()
        .map(|&l| {
            let rest = rest_frame(sk, l);
            let rest_local = match l.parent() {
                Some(p) => rest_frame(sk, p).inverse() * rest,
                None => rest,
            };
            match (pose, l.joint()) {
                (Some(pose), Some(j)) => {
                    let r = joint_rotation(sk, j, &pose.angles[j.index()]);
                    // Fᵀ R F: the world rotation about the joint seen in the joint's own frame.
                    rest_local * (rest.rotation.inverse() * r * rest.rotation)
                }
                (Some(pose), None) => pose.root * rest_local,
                (None, _) => rest_local,
            }
        })
        .collect()
}

/// The skinned scene of `mesh` (bind pose, mm) with per-vertex link `weights` over
/// [`Link::ALL`] and the joint centres and frames of `sk`; joint nodes posed by `pose` when
/// given (see the module documentation and [`joint_locals`]), else at rest.
pub fn skinned_scene(
    name: &str,
    mesh: &TriMesh,
    weights: &LinkWeights,
    sk: &Skeleton,
    pose: Option<&Pose>,
) -> Scene {
    let locals = joint_locals(sk, pose);
    let mut worlds: Vec<Isometry3<f64>> = Vec::with_capacity(Link::ALL.len());
    let mut joints = Vec::with_capacity(Link::ALL.len());
    for (&l, &local) in Link::ALL.iter().zip(&locals) {
        let rest = rest_frame(sk, l);
        let parent = l.parent();
        let world = match parent {
            Some(p) => worlds[p.index()] * local,
            None => local,
        };
        worlds.push(world);
        joints.push(SkinJoint {
            name: l.name().to_string(),
            parent: parent.map(|p| p.index()),
            local: local.to_homogeneous(),
            world: world.to_homogeneous(),
            inverse_bind: rest.inverse().to_homogeneous(),
        });
    }
    Scene {
        meshes: vec![SceneMesh {
            name: name.to_string(),
            mesh: mesh.clone(),
            normals: Some(mesh.vertex_normals()),
            colors: None,
            skin: Some(Skin {
                joints,
                weights: weights.clone(),
            }),
            attributes: Vec::new(),
            morph_targets: Vec::new(),
        }],
        animations: Vec::new(),
    }
}

/// Most keyframes [`animated_scene`] writes per channel: a viewer interpolates between them,
/// and at 100 Hz this is 20 s of motion at full rate while the file stays near a megabyte.
pub const MAX_KEYFRAMES: usize = 2000;

/// A rigid part moving with the hand in [`animated_scene`].
#[derive(Clone, Copy, Debug)]
pub struct MovingPart<'a> {
    /// The mesh node's name.
    pub name: &'a str,
    /// The part's mesh in its own frame, mm.
    pub mesh: &'a TriMesh,
    /// Per frame, the part's pose (part frame -> the hand's frame), `None` where unknown.
    pub poses: &'a [Option<Isometry3<f64>>],
}

/// The frames that get keyframes in a trial of `n` frames: all of them when `n <= max`, else
/// `max` frames spread evenly from the first to the last (rounded), so a very long trial
/// keeps its whole span at a lower rate rather than being cut short.
pub fn keyframe_frames(n: usize, max: usize) -> Vec<usize> {
    if n <= max {
        return (0..n).collect();
    }
    if max < 2 {
        return (0..max).collect();
    }
    (0..max)
        .map(|k| ((k as f64) * (n - 1) as f64 / (max - 1) as f64).round() as usize)
        .collect()
}

/// The hand of [`skinned_scene`] animated over a trial (glTF 2.0 spec 3.11 "Animations"),
/// with an optional rigid part: a viewer plays the motion by linear blend skinning, as the
/// spec defines skinning (3.7.3), which equals [`super::skinning`]'s LBS of each pose.
///
/// `poses` holds one entry per frame of a trial sampled at `rate` Hz; frame `f` is at
/// `f / rate` seconds. Every solved frame (`Some`) gives one keyframe: a rotation on every
/// joint node ([`joint_locals`]) and a translation on the forearm node, the only one whose
/// translation moves. A `None` frame gets no keyframe, so the viewer interpolates across it
/// (LINEAR: lerp of the forearm's translation, slerp of each joint's rotation). The part is a
/// second, unskinned mesh node with translation and rotation channels at the frames where its
/// pose is known. A trial longer than [`MAX_KEYFRAMES`] frames is resampled to that many
/// frames spread evenly over it ([`keyframe_frames`]); the unsolved ones among those are
/// skipped as above. The still scene (what a viewer shows without playing) is the hand in its
/// first solved pose (at rest if none) and the part in its own frame.
///
/// Errors ([`Error::Invalid`]): a rate that is not finite and positive, or part poses whose
/// count differs from `poses`.
pub fn animated_scene(
    name: &str,
    mesh: &TriMesh,
    weights: &LinkWeights,
    sk: &Skeleton,
    poses: &[Option<Pose>],
    rate: f64,
    part: Option<MovingPart>,
) -> Result<Scene> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(Error::invalid(format!(
            "frame rate {rate} Hz: an animation needs a finite positive rate"
        )));
    }
    if let Some(p) = &part {
        if p.poses.len() != poses.len() {
            return Err(Error::invalid(format!(
                "part '{}' has {} poses for {} frames of the hand",
                p.name,
                p.poses.len(),
                poses.len()
            )));
        }
    }
    let first = poses.iter().flatten().next();
    let mut scene = skinned_scene(name, mesh, weights, sk, first);
    let frames = keyframe_frames(poses.len(), MAX_KEYFRAMES);
    let time = |f: usize| f as f64 / rate;
    let mut channels = hand_channels(sk, &frames, poses, time);
    if let Some(p) = part {
        // A CAD part: smooth across its rounds, sharp at its edges.
        let split = crate::geometry::crease_normals(
            p.mesh,
            crate::geometry::crease_normals::DEFAULT_CREASE_DEG,
        );
        scene.meshes.push(SceneMesh {
            name: p.name.to_string(),
            mesh: split.mesh,
            normals: Some(split.normals),
            colors: None,
            skin: None,
            attributes: Vec::new(),
            morph_targets: Vec::new(),
        });
        channels.extend(part_channels(1, &frames, p.poses, time));
    }
    if !channels.is_empty() {
        scene.animations.push(Animation {
            name: name.to_string(),
            channels,
        });
    }
    Ok(scene)
}

/// Per joint node of mesh 0 a rotation channel, and on the forearm also a translation
/// channel, keyed at the `frames` whose pose is known; none when no such frame.
fn hand_channels(
    sk: &Skeleton,
    frames: &[usize],
    poses: &[Option<Pose>],
    time: impl Fn(usize) -> f64,
) -> Vec<Channel> {
    let keyed: Vec<(f64, Vec<Isometry3<f64>>)> = frames
        .iter()
        .filter_map(|&f| {
            poses[f]
                .as_ref()
                .map(|p| (time(f), joint_locals(sk, Some(p))))
        })
        .collect();
    if keyed.is_empty() {
        return Vec::new();
    }
    let times: Vec<f64> = keyed.iter().map(|k| k.0).collect();
    let mut channels = Vec::new();
    for (j, l) in Link::ALL.iter().enumerate() {
        let target = AnimationTarget::Joint { mesh: 0, joint: j };
        if l.parent().is_none() {
            channels.push(Channel {
                target,
                times: times.clone(),
                values: Keyframes::Translation(
                    keyed.iter().map(|k| k.1[j].translation.vector).collect(),
                ),
            });
        }
        channels.push(Channel {
            target,
            times: times.clone(),
            values: Keyframes::Rotation(keyed.iter().map(|k| k.1[j].rotation).collect()),
        });
    }
    channels
}

/// Translation and rotation channels of mesh node `mesh`, keyed at the `frames` whose pose is
/// known; none when no such frame.
fn part_channels(
    mesh: usize,
    frames: &[usize],
    poses: &[Option<Isometry3<f64>>],
    time: impl Fn(usize) -> f64,
) -> Vec<Channel> {
    let keyed: Vec<(f64, Isometry3<f64>)> = frames
        .iter()
        .filter_map(|&f| poses[f].map(|p| (time(f), p)))
        .collect();
    if keyed.is_empty() {
        return Vec::new();
    }
    let times: Vec<f64> = keyed.iter().map(|k| k.0).collect();
    let target = AnimationTarget::Mesh(mesh);
    vec![
        Channel {
            target,
            times: times.clone(),
            values: Keyframes::Translation(keyed.iter().map(|k| k.1.translation.vector).collect()),
        },
        Channel {
            target,
            times,
            values: Keyframes::Rotation(keyed.iter().map(|k| k.1.rotation).collect()),
        },
    ]
}

/// The glTF skinning of a scene's first skinned mesh as read back from a file: per vertex
/// `Σ w · world · IBM` applied to the bind position (glTF 2.0 spec 3.7.3.3), what a viewer
/// draws. Used to check that a written pose moves the hand as [`super::skinning`] does.
pub fn viewer_positions(m: &SceneMesh) -> Option<Vec<crate::geometry::Point>> {
    let skin = m.skin.as_ref()?;
    let mats: Vec<Matrix4<f64>> = skin
        .joints
        .iter()
        .map(|j| j.world * j.inverse_bind)
        .collect();
    Some(
        m.mesh
            .vertices
            .iter()
            .zip(&skin.weights)
            .map(|(p, w)| {
                let mut s = Matrix4::zeros();
                for &(k, a) in w {
                    s += mats[k] * a;
                }
                s.transform_point(p)
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::io::gltf::{glb_bytes, read_gltf_slice};
    use crate::io::Units;
    use crate::pose::named_pose;
    use crate::pose::skinning::{SkinBinding, Skinning};
    use crate::skeleton::forward_kinematics::link_transforms;
    use crate::template::load_template;
    use std::path::Path;

    /// Round trip through GLB bytes and the reader: joint names and tree, weights, inverse bind
    /// matrices (the inverse of each rest joint frame), and, for a posed scene, the viewer's
    /// skinning of the file equals this crate's LBS of the same pose.
    #[test]
    fn posed_hand_round_trips_and_moves_like_lbs() {
        let t = load_template(Side::Right).unwrap();
        let pose = named_pose("fist").unwrap();
        let scene = skinned_scene("hand", &t.mesh, &t.weights, &t.skeleton, Some(&pose));
        let back = read_gltf_slice(
            &glb_bytes(&scene, Units::Metres).unwrap(),
            Units::Metres,
            Path::new("hand.glb"),
        )
        .unwrap();
        let m = &back.meshes[0];
        let skin = m.skin.as_ref().unwrap();
        assert_eq!(skin.joints.len(), Link::ALL.len());
        for (k, (j, l)) in skin.joints.iter().zip(Link::ALL).enumerate() {
            assert_eq!(j.name, l.name());
            assert_eq!(j.parent, l.parent().map(|p| p.index()), "{l}");
            let rest = rest_frame(&t.skeleton, l).to_homogeneous();
            assert!(
                (j.inverse_bind * rest - Matrix4::identity()).norm() < 1e-4,
                "{k}"
            );
        }
        for (a, b) in t.weights.iter().zip(&skin.weights) {
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(b) {
                assert_eq!(x.0, y.0);
                assert!((x.1 - y.1).abs() < 1e-6);
            }
        }
        let viewer = viewer_positions(m).unwrap();
        let lbs = SkinBinding::new(&t.mesh.vertices, &t.weights, Link::ALL.len())
            .unwrap()
            .linear(&link_transforms(&t.skeleton, &pose));
        let worst = viewer
            .iter()
            .zip(&lbs)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        // f32 metres in the file: ~1e-4 mm per value, a few of them per vertex.
        assert!(worst < 5e-3, "viewer vs LBS: {worst} mm");
        let moved = lbs
            .iter()
            .zip(&t.mesh.vertices)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(moved > 30.0, "the fist moves the fingertips: {moved} mm");
    }

    /// Joint and mesh node locals of a read-back scene at keyframe `k` of every channel that
    /// has one at time `t`: the static local with the keyframe's translation or rotation
    /// replacing the node's (spec 3.11), then the joint worlds down the tree.
    fn sampled_at(scene: &Scene, t: f64) -> (Vec<Matrix4<f64>>, Option<Isometry3<f64>>) {
        let skin = scene.meshes[0].skin.as_ref().unwrap();
        let mut locals: Vec<(Translation3<f64>, UnitQuaternion<f64>)> = skin
            .joints
            .iter()
            .map(|j| {
                let m = j.local;
                let r = nalgebra::Rotation3::from_matrix_unchecked(
                    m.fixed_view::<3, 3>(0, 0).into_owned(),
                );
                (
                    Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
                    UnitQuaternion::from_rotation_matrix(&r),
                )
            })
            .collect();
        let mut part = (Translation3::identity(), UnitQuaternion::identity());
        let mut part_keyed = false;
        for ch in &scene.animations[0].channels {
            let Some(k) = ch.times.iter().position(|&s| (s - t).abs() < 1e-6) else {
                continue;
            };
            let slot = match ch.target {
                AnimationTarget::Joint { mesh: 0, joint } => &mut locals[joint],
                AnimationTarget::Mesh(1) => {
                    part_keyed = true;
                    &mut part
                }
                other => panic!("unexpected target {other:?}"),
            };
            match &ch.values {
                Keyframes::Translation(v) => slot.0 = Translation3::from(v[k]),
                Keyframes::Rotation(v) => slot.1 = v[k],
            }
        }
        let mut worlds: Vec<Matrix4<f64>> = Vec::with_capacity(locals.len());
        for (j, (tr, q)) in locals.iter().enumerate() {
            let local = Isometry3::from_parts(*tr, *q).to_homogeneous();
            worlds.push(match skin.joints[j].parent {
                Some(p) => worlds[p] * local,
                None => local,
            });
        }
        let part = part_keyed.then(|| Isometry3::from_parts(part.0, part.1));
        (worlds, part)
    }

    /// A hand moving from rest into a fist while its forearm travels and turns, one frame
    /// unsolved, and a part whose pose is unknown in another frame: written, read back, and
    /// sampled at each keyframe, the viewer's skinning of the file reproduces the hand's own
    /// LBS of that frame's pose (`IndividualHand::posed_skin`), and the part node moves the
    /// part's vertices by its pose. Keyframes sit at frame / rate for known frames only, and
    /// the stored rotations are sign-continuous.
    #[test]
    fn animated_hand_replays_every_solved_frame() {
        let t = load_template(Side::Right).unwrap();
        let hand = crate::pose::IndividualHand::from_parts(
            Side::Right,
            t.mesh.clone(),
            t.skeleton.clone(),
            t.weights.clone(),
        )
        .unwrap();
        let fist = named_pose("fist").unwrap();
        let n = 7;
        let rate = 50.0;
        let poses: Vec<Option<Pose>> = (0..n)
            .map(|f| {
                let s = f as f64 / (n - 1) as f64;
                let mut p = fist.clone();
                for a in p.angles.iter_mut().flatten() {
                    *a *= s;
                }
                p.root = Isometry3::new(
                    nalgebra::Vector3::new(30.0 * s, -10.0 * s, 5.0),
                    nalgebra::Vector3::new(0.2 * s, -0.9 * s, 1.4 * s),
                );
                (f != 2).then_some(p)
            })
            .collect();
        let part_mesh = TriMesh::new(
            vec![
                crate::geometry::Point::new(0.0, 0.0, 0.0),
                crate::geometry::Point::new(60.0, 0.0, 0.0),
                crate::geometry::Point::new(0.0, 60.0, 0.0),
                crate::geometry::Point::new(0.0, 0.0, 200.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap();
        let part_poses: Vec<Option<Isometry3<f64>>> = (0..n)
            .map(|f| {
                (f != 4).then(|| {
                    Isometry3::new(
                        nalgebra::Vector3::new(100.0, 20.0 * f as f64, -40.0),
                        nalgebra::Vector3::new(0.0, 0.0, 0.6 * f as f64),
                    )
                })
            })
            .collect();
        let scene = animated_scene(
            "hand",
            &hand.skin,
            &hand.weights,
            &hand.skeleton,
            &poses,
            rate,
            Some(MovingPart {
                name: "part",
                mesh: &part_mesh,
                poses: &part_poses,
            }),
        )
        .unwrap();
        let back = read_gltf_slice(
            &glb_bytes(&scene, Units::Metres).unwrap(),
            Units::Metres,
            Path::new("motion.glb"),
        )
        .unwrap();
        assert_eq!(back.meshes.len(), 2);
        // The part is a tetrahedron, all edges sharp: three copies of each corner, each with
        // its face's normal.
        let p = &back.meshes[1];
        assert_eq!(p.mesh.n_vertices(), 12);
        let face_n = p.mesh.face_normals();
        for (f, face) in p.mesh.faces.iter().enumerate() {
            for &v in face {
                assert!((p.normals.as_ref().unwrap()[v] - face_n[f]).norm() < 1e-6);
            }
        }
        assert_eq!(back.animations.len(), 1);
        let channels = &back.animations[0].channels;
        // A rotation per joint node, the forearm's translation, the part's two.
        assert_eq!(channels.len(), Link::ALL.len() + 1 + 2);
        let hand_times: Vec<f64> = [0, 1, 3, 4, 5, 6].map(|f| f as f64 / rate).to_vec();
        let part_times: Vec<f64> = [0, 1, 2, 3, 5, 6].map(|f| f as f64 / rate).to_vec();
        for ch in channels {
            let want = match ch.target {
                AnimationTarget::Mesh(_) => &part_times,
                AnimationTarget::Joint { .. } => &hand_times,
            };
            assert_eq!(ch.times.len(), want.len(), "{:?}", ch.target);
            for (a, b) in ch.times.iter().zip(want) {
                assert!((a - b).abs() < 1e-7, "{a} vs {b}");
            }
            if let Keyframes::Rotation(q) = &ch.values {
                for w in q.windows(2) {
                    assert!(w[0].coords.dot(&w[1].coords) >= 0.0, "{:?}", ch.target);
                }
            }
        }
        for f in 0..n {
            let (worlds, part) = sampled_at(&back, f as f64 / rate);
            if let Some(pose) = &poses[f] {
                let mut m = back.meshes[0].clone();
                for (j, w) in m.skin.as_mut().unwrap().joints.iter_mut().zip(&worlds) {
                    j.world = *w;
                }
                let viewer = viewer_positions(&m).unwrap();
                let lbs = hand.posed_skin(pose, Skinning::Linear);
                let worst = viewer
                    .iter()
                    .zip(&lbs.vertices)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                // 1e-6 m: f32 metres in the file, a few roundings per vertex.
                assert!(worst < 1e-3, "frame {f}: viewer vs LBS {worst} mm");
            }
            match (part_poses[f], part) {
                (Some(want), Some(got)) => {
                    for p in &part_mesh.vertices {
                        let d = (want * p - got * p).norm();
                        assert!(d < 1e-3, "frame {f}: part vertex {d} mm off");
                    }
                }
                (None, None) => {}
                (w, g) => panic!("frame {f}: part pose {w:?}, keyframe {g:?}"),
            }
        }
    }

    /// Long trials keep at most MAX_KEYFRAMES frames spread over the whole span; short ones
    /// keep every frame. An unknown rate and mismatched part poses are refused.
    #[test]
    fn keyframes_resample_long_trials_only() {
        assert_eq!(keyframe_frames(5, MAX_KEYFRAMES), vec![0, 1, 2, 3, 4]);
        let k = keyframe_frames(4321, MAX_KEYFRAMES);
        assert_eq!(k.len(), MAX_KEYFRAMES);
        assert_eq!((k[0], *k.last().unwrap()), (0, 4320));
        assert!(k.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] <= 3));
        let t = load_template(Side::Left).unwrap();
        let one = [Some(Pose::zero())];
        for rate in [0.0, f64::NAN] {
            assert!(
                animated_scene("h", &t.mesh, &t.weights, &t.skeleton, &one, rate, None).is_err()
            );
        }
        let part = MovingPart {
            name: "p",
            mesh: &t.mesh,
            poses: &[],
        };
        let e = animated_scene("h", &t.mesh, &t.weights, &t.skeleton, &one, 1.0, Some(part))
            .unwrap_err();
        assert!(e.to_string().contains("0 poses for 1 frames"), "{e}");
        // Nothing solved: a still scene without animation.
        let s = animated_scene("h", &t.mesh, &t.weights, &t.skeleton, &[None], 1.0, None).unwrap();
        assert!(s.animations.is_empty());
    }

    /// At rest every joint's world transform times its inverse bind matrix is the identity.
    #[test]
    fn rest_scene_is_the_bind_pose() {
        let t = load_template(Side::Left).unwrap();
        let scene = skinned_scene("hand", &t.mesh, &t.weights, &t.skeleton, None);
        for j in &scene.meshes[0].skin.as_ref().unwrap().joints {
            assert!(
                (j.world * j.inverse_bind - Matrix4::identity()).norm() < 1e-9,
                "{}",
                j.name
            );
        }
    }
}
