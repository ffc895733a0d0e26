//! The template hand M_temp^temp of the seed paper (section 3.5): the vendored `generic-hand`
//! surface, welded and in millimetres, refined by two Loop subdivisions to 37,024 faces, with
//! its skin weights per link, its skeleton and its spec (landmarks, dimension vertex pairs,
//! palm landmarks, joint centres).

pub mod folder;
pub mod generic_hand;
pub mod landmark_rule;
pub mod picture;
pub mod spec;

pub use folder::{load_folder_template, model_template, template_source, TemplateSource};
pub use generic_hand::{load_base_hand, BaseHand, LinkWeights};
pub use spec::{HandSpec, TemplateSpec};

use crate::anatomy::Side;
use crate::error::Result;
use crate::geometry::loop_subdivision::loop_subdivide_n;
use crate::geometry::TriMesh;
use crate::skeleton::Skeleton;
use std::path::Path;

/// Loop subdivision levels from the base asset to the high-resolution template
/// (2314 -> 9256 -> 37,024 faces; the seed paper's template had 59,904).
pub(crate) const SUBDIVISION_LEVELS: usize = 2;

/// The high-resolution template of one hand with everything later stages need.
#[derive(Clone, Debug)]
pub struct TemplateHand {
    /// Which hand.
    pub side: Side,
    /// High-resolution surface, mm; the first `base.mesh.n_vertices()` vertices are the base
    /// vertices (Loop subdivision keeps their indices).
    pub mesh: TriMesh,
    /// Skinning weights per vertex of `mesh` over [`crate::anatomy::Link::ALL`], carried
    /// through the subdivision stencils and renormalised.
    pub weights: LinkWeights,
    /// Joint centres and frames of the template.
    pub skeleton: Skeleton,
    /// The base asset (welded, unsubdivided) it was made from.
    pub base: BaseHand,
    /// Landmarks, dimension pairs, palm landmarks and joint centres on `mesh`.
    pub spec: HandSpec,
    /// Where it was read from.
    pub source: TemplateSource,
}

impl TemplateHand {
    /// Every landmark of the spec at its vertex of `mesh`, by name: the template read as if
    /// each landmark were the skin point under its marker.
    pub fn landmark_points(&self) -> std::collections::BTreeMap<String, crate::geometry::Point> {
        self.spec
            .landmarks
            .iter()
            .map(|(name, &v)| (name.clone(), self.mesh.vertices[v]))
            .collect()
    }
}

/// The link that dominates each vertex's weights.
pub fn dominant_links(weights: &LinkWeights) -> Vec<usize> {
    weights
        .iter()
        .map(|w| {
            w.iter()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|x| x.0)
                .unwrap_or(0)
        })
        .collect()
}

/// The high-resolution mesh, weights and skeleton of `side`, without a spec. The right hand is
/// the refined left one mirrored ([`generic_hand::mirror_base_hand`]): subdividing the mirrored
/// base would number the new vertices in another order, and the two hands share their vertex
/// numbering so that a landmark, a caliper pair or a field per vertex means the same on both.
fn refine(side: Side) -> Result<(BaseHand, TriMesh, LinkWeights)> {
    let left = load_base_hand(Side::Left)?;
    let (mesh, weights) = refine_base(&left, SUBDIVISION_LEVELS);
    Ok(match side {
        Side::Left => (left, mesh, weights),
        Side::Right => (
            generic_hand::mirror_base_hand(&left)?,
            generic_hand::mirror_mesh(&mesh),
            weights,
        ),
    })
}

/// `base`'s surface after `levels` Loop subdivisions, with its weights carried through the
/// stencils (at most four links per vertex, renormalised).
fn refine_base(base: &BaseHand, levels: usize) -> (TriMesh, LinkWeights) {
    let sub = loop_subdivide_n(&base.mesh, levels);
    let weights = sub.apply_sparse(&base.weights, 4);
    (sub.mesh, weights)
}

/// Load the template of `side` with the spec shipped in the toolkit, checked against the mesh.
pub fn load_template(side: Side) -> Result<TemplateHand> {
    let (base, mesh, weights) = refine(side)?;
    let spec = TemplateSpec::embedded()?.hand(side).clone();
    spec.check(&mesh, Path::new("assets/generic-hand/template-spec.toml"))?;
    Ok(TemplateHand {
        side,
        skeleton: base.skeleton.clone(),
        mesh,
        weights,
        base,
        spec,
        source: TemplateSource::GenericHand,
    })
}

/// The template of `side` from the folder `dir` ([`folder`]), or the embedded generic hand.
pub fn load_template_from(dir: Option<&Path>, side: Side) -> Result<TemplateHand> {
    match dir {
        Some(d) => load_folder_template(d, side),
        None => load_template(side),
    }
}

/// Derive the spec of both hands from the rule of [`landmark_rule`] (what the shipped file holds).
pub fn derive_template_spec() -> Result<TemplateSpec> {
    let hand = |side| -> Result<HandSpec> {
        let (base, mesh, weights) = refine(side)?;
        landmark_rule::derive_hand_spec(
            &mesh,
            &base.skeleton,
            side,
            &dominant_links(&weights),
            &base.metacarpal_bases,
        )
    };
    Ok(TemplateSpec {
        right: hand(Side::Right)?,
        left: hand(Side::Left)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{Dimension, Joint};
    use crate::skeleton::forward_kinematics::{link_transforms, posed_centres};
    use crate::skeleton::Pose;

    #[test]
    fn high_resolution_template_is_closed_manifold_with_weights() {
        for side in [Side::Right, Side::Left] {
            let t = load_template(side).unwrap();
            assert_eq!(t.mesh.n_faces(), 37_024, "{side}");
            t.mesh.check_closed_manifold().unwrap();
            t.base.mesh.check_closed_manifold().unwrap();
            assert_eq!(t.mesh.topology().euler_characteristic(), 2);
            // Loop subdivision shrinks a surface slightly but not by much.
            let (v0, v1) = (t.base.mesh.signed_volume(), t.mesh.signed_volume());
            assert!(v1 < v0 && v1 > 0.9 * v0, "{side}: {v0} -> {v1}");
            assert_eq!(t.weights.len(), t.mesh.n_vertices());
            for w in &t.weights {
                assert!(!w.is_empty() && w.len() <= 4);
                assert!((w.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-9);
            }
            // The base vertices keep their indices: their weights are unchanged in support.
            assert_eq!(&t.mesh.faces.len(), &(t.base.mesh.n_faces() * 16));
        }
    }

    #[test]
    fn zero_pose_reproduces_template_joint_centres() {
        for side in [Side::Right, Side::Left] {
            let t = load_template(side).unwrap();
            let c = posed_centres(&t.skeleton, &link_transforms(&t.skeleton, &Pose::zero()));
            for j in Joint::ALL {
                let want = t.spec.joint_centres[j.name()];
                let got = c[j.index()];
                for k in 0..3 {
                    assert!((got[k] - want[k]).abs() < 1e-9, "{side} {j}");
                }
            }
        }
    }

    /// The shipped spec is exactly what the documented rule derives: every index has a provenance.
    #[test]
    fn shipped_spec_is_reproduced_by_the_rule() {
        let derived = derive_template_spec().unwrap();
        let shipped = TemplateSpec::embedded().unwrap();
        for side in [Side::Right, Side::Left] {
            let (d, s) = (derived.hand(side), shipped.hand(side));
            assert_eq!(d.landmarks, s.landmarks, "{side}: run `ergohand template --out DIR` and copy template-spec.toml to assets/generic-hand/");
            assert_eq!(d.dimensions, s.dimensions, "{side}");
            assert_eq!(d.palm, s.palm, "{side}");
            for (k, c) in &d.joint_centres {
                let o = s.joint_centres[k];
                assert!((0..3).all(|i| (c[i] - o[i]).abs() < 1e-9), "{side} {k}");
            }
        }
    }

    /// The rule is anatomical (dorsal, distal, radial) and the left template is the right one
    /// mirrored vertex for vertex, so each landmark and each caliper pair is the same vertex on
    /// both hands: a left subject is fitted as the mirror image of a right one.
    #[test]
    fn the_rule_picks_the_same_vertices_on_mirror_image_hands() {
        let spec = TemplateSpec::embedded().unwrap();
        let (r, l) = (spec.hand(Side::Right), spec.hand(Side::Left));
        assert_eq!(r.landmarks, l.landmarks);
        assert_eq!(r.palm, l.palm);
        for (d, [a, b]) in &r.dimensions {
            let [c, e] = l.dimensions[d];
            assert!((a, b) == (&c, &e) || (a, b) == (&e, &c), "{d}");
        }
    }

    #[test]
    fn landmarks_sit_where_the_spec_says() {
        for side in [Side::Right, Side::Left] {
            let t = load_template(side).unwrap();
            let sk = &t.skeleton;
            let v = |name: &str| t.mesh.vertices[t.spec.landmarks[name]];
            for j in Joint::ALL {
                // Over the dorsal side of the joint, a few mm to a couple of cm from its centre.
                let r = v(j.name()) - sk.centre(j);
                assert!(r.dot(&sk.joint(j).y()) > 0.8 * r.norm(), "{side} {j}");
                assert!((2.0..25.0).contains(&r.norm()), "{side} {j}: {}", r.norm());
            }
            // Fingertip markers: the apex of the distal link, on the line of its bone and
            // within a millimetre of the link's farthest vertex along it.
            let owners = dominant_links(&t.weights);
            for f in crate::anatomy::Finger::ALL {
                let j = f.joints()[2];
                let c = sk.centre(j);
                let bone = (sk.tips[f as usize] - c).normalize();
                let tip = v(f.tip_marker()) - c;
                let link = f.links()[2].index();
                let reach = (0..t.mesh.n_vertices())
                    .filter(|&k| owners[k] == link)
                    .map(|k| (t.mesh.vertices[k] - c).dot(&bone))
                    .fold(f64::MIN, f64::max);
                assert!(tip.dot(&bone) > reach - 1.0, "{side} {f:?}");
                let off_line = (tip - bone * tip.dot(&bone)).norm();
                assert!(
                    off_line < 1.5,
                    "{side} {f:?}: {off_line:.2} mm off the bone's line"
                );
                // Nail markers over the middle of the nail plate: on the back of the distal
                // segment, 40-60 % of the way from the joint to the apex (the plate covers the
                // distal half to two thirds of the segment's back), not over the joint.
                let nail = v(f.nail_marker()) - c;
                let along = nail.dot(&bone) / tip.dot(&bone);
                assert!(
                    (0.4..0.6).contains(&along),
                    "{side} {f:?}: nail {along:.2} of the way to the apex"
                );
                assert!(
                    nail.dot(&sk.joint(j).y()) > 0.0,
                    "{side} {f:?}: nail palmar"
                );
            }
            // Radial landmarks lie radially of ulnar ones.
            let radial = sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp);
            assert!((v("I_MCP_LAT") - v("L_MCP_LAT")).dot(&radial) > 0.0);
            assert!((v("WRIST_RAD") - v("WRIST_ULN")).dot(&radial) > 0.0);
            // Every dimension of the template is a plausible adult hand dimension.
            for d in Dimension::all() {
                let [a, b] = t.spec.dimension(d).unwrap();
                let len = (t.mesh.vertices[a] - t.mesh.vertices[b]).norm();
                let (lo, hi) = d.plausible_range_mm();
                assert!((lo..hi).contains(&len), "{side} {d}: {len:.1} mm");
            }
        }
    }
}
