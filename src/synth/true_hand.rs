//! The true hand of a simulated subject, before it is put in the lab: a closed skin surface in
//! the subject's reference posture, the skeleton under it and the anatomical landmark points.
//! Everything downstream (the lab placement, the calipers, the markers, the CT-like scan) reads
//! only this, so any body that can fill it can be captured.

use super::anthropometry::{shape_hand, ShapeParams};
use super::surface_field;
use crate::anatomy::{landmark_names, tip_marker_names};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::rng::Rng;
use crate::skeleton::forward_kinematics::{linear_blend, link_transforms, posed_skeleton};
use crate::skeleton::{Pose, Skeleton};
use crate::template::TemplateHand;
use std::collections::BTreeMap;

/// A true hand in its reference posture (the body's own frame; the template's axis conventions,
/// see [`crate::skeleton`]).
#[derive(Clone, Debug)]
pub struct TrueHand {
    /// Closed, 2-manifold skin surface, mm.
    pub skin: TriMesh,
    /// Joint centres and frames under that skin.
    pub skeleton: Skeleton,
    /// Every landmark of the spec (section 2): the anatomical point on the skin and the outward
    /// unit normal there. A lab's marker sits `marker_offset_mm` off that point along the normal.
    pub landmarks: BTreeMap<String, (Point, Vec3)>,
    /// The reference posture relative to the body's own neutral posture.
    pub posture: Pose,
    /// `skin` is homologous to the template (same vertices and faces), so vertex-to-vertex
    /// checks against a reconstruction are meaningful (`truth_skin.ply`).
    pub homologous_to_template: bool,
}

impl TrueHand {
    /// The same hand moved rigidly by `iso` (normals turned with it).
    pub fn transformed(&self, iso: &nalgebra::Isometry3<f64>) -> TrueHand {
        let skeleton = posed_skeleton(&self.skeleton, &vec![*iso; crate::anatomy::Link::ALL.len()]);
        TrueHand {
            skin: self.skin.transformed(iso),
            skeleton,
            landmarks: self
                .landmarks
                .iter()
                .map(|(k, (p, n))| (k.clone(), (iso * p, iso.rotation * n)))
                .collect(),
            posture: self.posture.clone(),
            homologous_to_template: self.homologous_to_template,
        }
    }

    /// The landmark `name`'s skin point and normal.
    pub fn landmark(&self, name: &str) -> Result<(Point, Vec3)> {
        self.landmarks
            .get(name)
            .copied()
            .ok_or_else(|| Error::invalid(format!("true hand has no landmark {name}")))
    }
}

/// The template body: the template changed the way hands differ ([`super::anthropometry`]),
/// roughened by a smooth surface field, posed in `posture` by the template's own skin weights.
/// The template can always reach this hand (same topology, same skinning), which is why a second,
/// independent body exists ([`super::procedural`]).
pub fn template_body(template: &TemplateHand, root: &Rng, posture: Pose) -> Result<TrueHand> {
    let shape = ShapeParams::sample(&mut root.fork("shape"), 1.0);
    let shaped = shape_hand(
        &template.mesh,
        &template.weights,
        &template.skeleton,
        &shape,
    );
    let mut skin = shaped.mesh;
    let mut field_rng = root.fork("field");
    let field = surface_field::FieldParams {
        amplitude_mm: field_rng.range(0.5, 2.0),
        ..Default::default()
    };
    surface_field::displace_along_normals(&mut skin, &field, &mut field_rng);

    let tf = link_transforms(&shaped.skeleton, &posture);
    skin.vertices = linear_blend(&skin.vertices, &template.weights, &tf);
    let skeleton = posed_skeleton(&shaped.skeleton, &tf);
    let normals = skin.vertex_normals();
    let mut landmarks = BTreeMap::new();
    for name in landmark_names().into_iter().chain(tip_marker_names()) {
        let v = template
            .spec
            .landmark(name)
            .ok_or_else(|| Error::invalid(format!("template spec has no landmark {name}")))?;
        landmarks.insert(name.to_string(), (skin.vertices[v], normals[v]));
    }
    Ok(TrueHand {
        skin,
        skeleton,
        landmarks,
        posture,
        homologous_to_template: true,
    })
}
