//! The template as a skinned glTF: one joint node per link of the spec's tree, placed at the
//! link's joint centre (the forearm at the wrist centre), each node's rotation the identity in
//! the rest pose, inverse bind matrices the inverse translations, and the template's link
//! weights. Posing it in a viewer rotates each link about its joint centre, as
//! [`crate::skeleton::forward_kinematics`] does.

use super::TemplateHand;
use crate::anatomy::{Joint, Link};
use crate::geometry::Point;
use crate::io::gltf::{Scene, SceneMesh, Skin, SkinJoint};
use nalgebra::Matrix4;

/// The scene of a skinned hand: `mesh` with per-vertex link `weights` over [`Link::ALL`] and the
/// joint centres of `skeleton`.
pub fn skinned_scene(name: &str, hand: &TemplateHand) -> Scene {
    let sk = &hand.skeleton;
    let origin = |l: Link| -> Point {
        match l.joint() {
            Some(j) => sk.centre(j),
            None => sk.centre(Joint::Wrist),
        }
    };
    let joints = Link::ALL
        .iter()
        .map(|&l| {
            let world = Matrix4::new_translation(&origin(l).coords);
            let parent = l.parent();
            let local = match parent {
                Some(p) => Matrix4::new_translation(&(origin(l) - origin(p))),
                None => world,
            };
            SkinJoint {
                name: l.name().to_string(),
                parent: parent.map(|p| p.index()),
                local,
                world,
                inverse_bind: Matrix4::new_translation(&-origin(l).coords),
            }
        })
        .collect();
    Scene {
        meshes: vec![SceneMesh {
            name: name.to_string(),
            mesh: hand.mesh.clone(),
            normals: Some(hand.mesh.vertex_normals()),
            colors: None,
            skin: Some(Skin {
                joints,
                weights: hand.weights.clone(),
            }),
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::io::gltf::{glb_bytes, read_gltf_slice};
    use crate::io::Units;
    use crate::template::load_template;
    use std::path::Path;

    /// The skinned template survives a GLB round trip: same vertices, faces, joint tree and
    /// weights, and every joint's inverse bind matrix undoes its rest world transform.
    #[test]
    fn skinned_template_round_trips() {
        let t = load_template(Side::Left).unwrap();
        let scene = skinned_scene("hand", &t);
        let back = read_gltf_slice(
            &glb_bytes(&scene, Units::Metres).unwrap(),
            Units::Metres,
            Path::new("t.glb"),
        )
        .unwrap();
        let (a, b) = (&scene.meshes[0], &back.meshes[0]);
        assert_eq!(a.mesh.faces, b.mesh.faces);
        for (p, q) in a.mesh.vertices.iter().zip(&b.mesh.vertices) {
            assert!((p - q).norm() < 1e-3, "f32 precision in metres");
        }
        let (sa, sb) = (a.skin.as_ref().unwrap(), b.skin.as_ref().unwrap());
        for (ja, jb) in sa.joints.iter().zip(&sb.joints) {
            assert_eq!((ja.name.as_str(), ja.parent), (jb.name.as_str(), jb.parent));
            // Translations travel as f32 metres: 1e-4 mm is their round-off at hand scale.
            assert!((jb.inverse_bind * jb.world - Matrix4::identity()).norm() < 1e-4);
        }
        for (wa, wb) in sa.weights.iter().zip(&sb.weights) {
            let sum: f64 = wb.iter().map(|x| x.1).sum();
            assert!((sum - 1.0).abs() < 1e-6);
            assert_eq!(wa[0].0, wb[0].0, "dominant link kept");
        }
    }
}
