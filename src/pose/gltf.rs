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
use crate::geometry::TriMesh;
use crate::io::gltf::{Scene, SceneMesh, Skin, SkinJoint};
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

/// The skinned scene of `mesh` (bind pose, mm) with per-vertex link `weights` over
/// [`Link::ALL`] and the joint centres and frames of `sk`; joint nodes posed by `pose` when
/// given (see the module documentation), else at rest.
pub fn skinned_scene(
    name: &str,
    mesh: &TriMesh,
    weights: &LinkWeights,
    sk: &Skeleton,
    pose: Option<&Pose>,
) -> Scene {
    let mut worlds: Vec<Isometry3<f64>> = Vec::with_capacity(Link::ALL.len());
    let mut joints = Vec::with_capacity(Link::ALL.len());
    for &l in &Link::ALL {
        let rest = rest_frame(sk, l);
        let parent = l.parent();
        let rest_local = match parent {
            Some(p) => rest_frame(sk, p).inverse() * rest,
            None => rest,
        };
        let local = match (pose, l.joint()) {
            (Some(pose), Some(j)) => {
                let r = joint_rotation(sk, j, &pose.angles[j.index()]);
                // Fᵀ R F: the world rotation about the joint seen in the joint's own frame.
                rest_local * (rest.rotation.inverse() * r * rest.rotation)
            }
            (Some(pose), None) => pose.root * rest_local,
            (None, _) => rest_local,
        };
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
        }],
    }
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
    use crate::pose::skinning::SkinBinding;
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
