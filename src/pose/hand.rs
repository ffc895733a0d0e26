//! The individual hand as a posable object: its skin (homologous to the template), its
//! skeleton (the link model's joint centres and frames) and the skin's link weights.

use super::skinning::{SkinBinding, Skinning};
use super::weights::{bone_heat_weights, template_weights, HeatOptions, WeightMethod};
use crate::anatomy::{Finger, Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use crate::io::{obj, Units};
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::record::parse_link_model;
use crate::skeleton::{Pose, Skeleton};
use crate::template::{dominant_links, LinkWeights, TemplateHand};
use std::path::Path;

/// A reconstructed hand ready to pose.
#[derive(Clone, Debug)]
pub struct IndividualHand {
    /// Which hand.
    pub side: Side,
    /// The high-resolution skin in the reference posture, mm.
    pub skin: TriMesh,
    /// Joint centres and frames in the reference posture (the skin's frame).
    pub skeleton: Skeleton,
    /// Per skin vertex, (link index over [`Link::ALL`], weight), summing to 1.
    pub weights: LinkWeights,
}

impl IndividualHand {
    /// Assemble a hand from parts in memory (what `reconstruct` has after its stages). Errors
    /// when the weights do not cover every vertex, refer to a link outside [`Link::ALL`], or do
    /// not sum to 1, or when the skeleton does not have 16 joints.
    pub fn from_parts(
        side: Side,
        skin: TriMesh,
        skeleton: Skeleton,
        weights: LinkWeights,
    ) -> Result<Self> {
        if skeleton.joints.len() != Joint::ALL.len() {
            return Err(Error::invalid(format!(
                "skeleton has {} joints, expected {}",
                skeleton.joints.len(),
                Joint::ALL.len()
            )));
        }
        // The same checks the skinning runs, once, with their messages.
        SkinBinding::new(&skin.vertices, &weights, Link::ALL.len())?;
        Ok(IndividualHand {
            side,
            skin,
            skeleton,
            weights,
        })
    }

    /// A hand from a skin homologous to `template`, its skeleton, and weights by `method`.
    /// The skeleton's tips are replaced by those derived from the skin ([`tips_from_skin`]), as
    /// [`IndividualHand::load`] does, so a hand built in memory and one read back from the
    /// files `reconstruct` writes are the same.
    pub fn from_skin(
        template: &TemplateHand,
        skin: TriMesh,
        mut skeleton: Skeleton,
        method: WeightMethod,
    ) -> Result<Self> {
        template_weights(template, &skin)?;
        skeleton.tips = tips_from_skin(&skeleton, &skin, &template.weights);
        let weights = match method {
            WeightMethod::Template => template_weights(template, &skin)?,
            WeightMethod::BoneHeat => bone_heat_weights(&skin, &skeleton, &HeatOptions::default())?,
        };
        Self::from_parts(template.side, skin, skeleton, weights)
    }

    /// Read a `reconstruct` output folder: `OUT/link_model.json` (hand, joint centres and
    /// frames) and `OUT/skin.obj` (mm, homologous to the template of that hand), with weights
    /// by `method`.
    ///
    /// `link_model.json` has no fingertips; they are derived from the skin: each digit's tip is
    /// the point of its distal joint's long axis (frame z) level with the skin's farthest vertex
    /// along that axis among the vertices the template assigns to the distal link (dominant
    /// weight). It is the end of the distal bone segment, inside the fingertip.
    pub fn load(out_dir: &Path, method: WeightMethod) -> Result<Self> {
        let model_path = out_dir.join("link_model.json");
        let text = std::fs::read_to_string(&model_path).map_err(|e| Error::io(&model_path, e))?;
        let (skeleton, _) = parse_link_model(&text, &model_path)?;
        let side = skeleton.side;
        let skin_path = out_dir.join("skin.obj");
        let skin = obj::read_obj(&skin_path, Units::Millimetres)?;
        let template = crate::template::model_template(out_dir, side)?;
        if skin.n_vertices() != template.mesh.n_vertices() || skin.faces != template.mesh.faces {
            return Err(Error::input(
                &skin_path,
                format!(
                    "{} vertices / {} faces, not homologous to the {side} template ({} / {}); \
                     re-run reconstruct",
                    skin.n_vertices(),
                    skin.n_faces(),
                    template.mesh.n_vertices(),
                    template.mesh.n_faces()
                ),
            ));
        }
        Self::from_skin(&template, skin, skeleton, method).map_err(|e| e.in_file(&skin_path))
    }

    /// A binding of the skin for repeated posing.
    pub fn binding(&self) -> SkinBinding {
        SkinBinding::new(&self.skin.vertices, &self.weights, Link::ALL.len())
            .expect("checked in from_parts")
    }

    /// The skin in `pose` (angles as given: clamp them first if they come from a user).
    pub fn posed_skin(&self, pose: &Pose, method: Skinning) -> TriMesh {
        let t = link_transforms(&self.skeleton, pose);
        TriMesh {
            vertices: self.binding().apply(method, &t),
            faces: self.skin.faces.clone(),
        }
    }
}

/// Fingertips from a skin with (template) weights: see [`IndividualHand::load`].
pub(crate) fn tips_from_skin(sk: &Skeleton, skin: &TriMesh, weights: &LinkWeights) -> [Point; 5] {
    let dom = dominant_links(weights);
    let mut tips = [Point::origin(); 5];
    for f in Finger::ALL {
        let dip = f.joints()[2];
        let (c, z) = (sk.centre(dip), sk.joint(dip).z());
        let l = dip.child_link().index();
        let reach = skin
            .vertices
            .iter()
            .zip(&dom)
            .filter(|(_, &d)| d == l)
            .map(|(v, _)| (v - c).dot(&z))
            .fold(f64::NAN, f64::max);
        // A skin without a distal region (not a hand) keeps a nominal 15 mm phalanx.
        let reach = if reach.is_finite() && reach > 1.0 {
            reach
        } else {
            15.0
        };
        tips[f as usize] = c + z * reach;
    }
    tips
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::record::joint_records;
    use crate::template::load_template;

    /// Writes the template as a `reconstruct` folder and loads it back: the skeleton's frames
    /// and centres are the template's, the tips lie just inside the template's own tips.
    #[test]
    fn load_reads_a_reconstruct_folder() {
        let t = load_template(Side::Left).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let doc = serde_json::json!({
            "units": "mm", "frame": "reference", "hand": "left",
            "joints": joint_records(&t.skeleton),
        });
        std::fs::write(dir.path().join("link_model.json"), doc.to_string()).unwrap();
        obj::write_obj(
            &dir.path().join("skin.obj"),
            &t.mesh,
            Units::Millimetres,
            None,
        )
        .unwrap();
        let h = IndividualHand::load(dir.path(), WeightMethod::Template).unwrap();
        assert_eq!(h.side, Side::Left);
        assert_eq!(h.weights, t.weights);
        for j in Joint::ALL {
            assert!((h.skeleton.centre(j) - t.skeleton.centre(j)).norm() < 1e-9);
            assert!(
                (h.skeleton.joint(j).frame.matrix() - t.skeleton.joint(j).frame.matrix()).norm()
                    < 1e-9
            );
        }
        for f in Finger::ALL {
            let d = (h.skeleton.tips[f as usize] - t.skeleton.tips[f as usize]).norm();
            assert!(d < 12.0, "{f:?} tip {d:.1} mm from the template's");
        }
        // Errors name the file and the item.
        std::fs::write(dir.path().join("link_model.json"), r#"{"joints": {}}"#).unwrap();
        let e = IndividualHand::load(dir.path(), WeightMethod::Template)
            .unwrap_err()
            .to_string();
        assert!(e.contains("link_model.json") && e.contains("'hand'"), "{e}");
        std::fs::write(
            dir.path().join("link_model.json"),
            r#"{"hand": "left", "joints": {}}"#,
        )
        .unwrap();
        let e = IndividualHand::load(dir.path(), WeightMethod::Template)
            .unwrap_err()
            .to_string();
        assert!(e.contains("link_model.json") && e.contains("WRIST"), "{e}");
        std::fs::write(dir.path().join("link_model.json"), doc.to_string()).unwrap();
        obj::write_obj(
            &dir.path().join("skin.obj"),
            &crate::geometry::mesh::tests::icosphere(10.0, 1),
            Units::Millimetres,
            None,
        )
        .unwrap();
        let e = IndividualHand::load(dir.path(), WeightMethod::Template)
            .unwrap_err()
            .to_string();
        assert!(e.contains("skin.obj") && e.contains("homologous"), "{e}");
    }
}
