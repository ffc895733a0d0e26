//! The template as a skinned glTF: the general skinned-hand scene of
//! [`crate::pose::gltf::skinned_scene`] (one joint node per link of the spec's tree at its joint
//! centre and frame, inverse bind matrices, the link weights) for the template's mesh, weights
//! and skeleton, in the rest pose. Posing it in a viewer rotates each link about its joint
//! centre, as [`crate::skeleton::forward_kinematics`] does.

use crate::io::gltf::Scene;
use crate::template::TemplateHand;

/// The scene of the skinned template `hand` at rest.
pub fn skinned_scene(name: &str, hand: &TemplateHand) -> Scene {
    super::gltf::skinned_scene(name, &hand.mesh, &hand.weights, &hand.skeleton, None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::io::gltf::{glb_bytes, read_gltf_slice};
    use crate::io::Units;
    use crate::template::load_template;
    use nalgebra::Matrix4;
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
