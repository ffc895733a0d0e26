//! The hand that grasps: anything that can pose its skin for a [`Pose`].
//!
//! The grasp stage needs the skeleton (for forward kinematics and limits), the rest mesh, each
//! vertex's dominant link (to split the skin into links for contacts per link and colliders per
//! link) and a way to pose the skin, whole or one link's vertices at a time (the autograsp
//! moves one digit per step and poses only its links).
//!
//! * [`SkinnedHand`]: the individual hand of the pose stage ([`crate::pose::IndividualHand`]),
//!   deformed by linear blend skinning through [`crate::pose::SkinBinding`] (the pose stage's
//!   fast path), so contacts are measured on the skin as it bends at the joints. The default
//!   hand is the template as an individual hand ([`SkinnedHand::template`]).
//! * [`RigidHand`]: every vertex follows its dominant link rigidly (a simpler reference, used by
//!   tests that need a hand without blending).

use crate::anatomy::{Link, Side};
use crate::error::Result;
use crate::geometry::{Point, TriMesh};
use crate::pose::{IndividualHand, SkinBinding, WeightMethod};
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::{Pose, Skeleton};
use crate::template::{dominant_links, load_template};
use nalgebra::Isometry3;

/// A hand that can be posed.
pub trait PosableHand: Sync {
    /// The kinematic skeleton in the rest posture.
    fn skeleton(&self) -> &Skeleton;
    /// The skin in the rest posture, mm.
    fn rest_mesh(&self) -> &TriMesh;
    /// Per rest vertex, the [`Link::index`] that dominates its weights.
    fn vertex_link(&self) -> &[usize];
    /// Per [`Link::index`], the rest vertices it dominates (ascending).
    fn link_vertices(&self) -> &[Vec<usize>];
    /// The whole posed skin for link transforms
    /// ([`crate::skeleton::forward_kinematics::link_transforms`]), in rest vertex order.
    fn pose_all(&self, transforms: &[Isometry3<f64>], out: &mut Vec<Point>);
    /// The posed vertices of one link, in the order of [`PosableHand::link_vertices`]; the
    /// same positions [`PosableHand::pose_all`] gives them.
    fn pose_link(&self, link: usize, transforms: &[Isometry3<f64>], out: &mut Vec<Point>);
    /// Every `stride`-th of the posed vertices of one link (the first, the `stride`-th, ... of
    /// [`PosableHand::pose_link`]'s order), at the same positions: a thinned check need not
    /// pose the vertices it skips.
    fn pose_link_every(
        &self,
        link: usize,
        stride: usize,
        transforms: &[Isometry3<f64>],
        out: &mut Vec<Point>,
    ) {
        self.pose_link(link, transforms, out);
        keep_every(out, stride);
    }
    /// Write the posed skin vertices (same order as [`PosableHand::rest_mesh`]) into `out`.
    fn pose_vertices(&self, pose: &Pose, out: &mut Vec<Point>) {
        let t = link_transforms(self.skeleton(), pose);
        self.pose_all(&t, out);
    }
}

/// Keep every `stride`-th point of `out` (the first, the `stride`-th, ...).
fn keep_every(out: &mut Vec<Point>, stride: usize) {
    if stride > 1 {
        let kept: Vec<Point> = out.iter().step_by(stride).copied().collect();
        *out = kept;
    }
}

/// Rest vertices grouped by dominant link.
fn group_by_link(links: &[usize]) -> Vec<Vec<usize>> {
    let mut by = vec![Vec::new(); Link::ALL.len()];
    for (i, &l) in links.iter().enumerate() {
        by[l].push(i);
    }
    by
}

/// Rigid posing: each vertex follows its dominant link.
#[derive(Clone, Debug)]
pub struct RigidHand {
    /// Skeleton.
    pub skeleton: Skeleton,
    /// Rest skin.
    pub mesh: TriMesh,
    /// Dominant link per vertex.
    pub links: Vec<usize>,
    by_link: Vec<Vec<usize>>,
}

impl RigidHand {
    /// The template of `side`, posed rigidly.
    pub fn template(side: Side) -> Result<RigidHand> {
        let t = load_template(side)?;
        RigidHand::new(t.skeleton, t.mesh, dominant_links(&t.weights))
    }

    /// A hand from its parts; `links` must have one valid link index per vertex.
    pub fn new(skeleton: Skeleton, mesh: TriMesh, links: Vec<usize>) -> Result<RigidHand> {
        if links.len() != mesh.n_vertices() || links.iter().any(|&l| l >= Link::ALL.len()) {
            return Err(crate::Error::invalid(format!(
                "hand: {} link labels for {} vertices (or a label out of range)",
                links.len(),
                mesh.n_vertices()
            )));
        }
        Ok(RigidHand {
            by_link: group_by_link(&links),
            skeleton,
            mesh,
            links,
        })
    }
}

/// Pose `rest` rigidly: vertex `i` moves by `transforms[links[i]]`.
pub(crate) fn pose_rigid(
    rest: &[Point],
    links: &[usize],
    transforms: &[Isometry3<f64>],
    out: &mut Vec<Point>,
) {
    out.clear();
    out.extend(rest.iter().zip(links).map(|(p, &l)| transforms[l] * p));
}

impl PosableHand for RigidHand {
    fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }
    fn rest_mesh(&self) -> &TriMesh {
        &self.mesh
    }
    fn vertex_link(&self) -> &[usize] {
        &self.links
    }
    fn link_vertices(&self) -> &[Vec<usize>] {
        &self.by_link
    }
    fn pose_all(&self, transforms: &[Isometry3<f64>], out: &mut Vec<Point>) {
        pose_rigid(&self.mesh.vertices, &self.links, transforms, out);
    }
    fn pose_link(&self, link: usize, transforms: &[Isometry3<f64>], out: &mut Vec<Point>) {
        let t = transforms[link];
        out.clear();
        out.extend(
            self.by_link[link]
                .iter()
                .map(|&i| t * self.mesh.vertices[i]),
        );
    }
}

/// The pose stage's individual hand, posed by linear blend skinning (the fast path,
/// [`SkinBinding::linear_into`]): the whole skin through one binding, and one binding per
/// link over the vertices it dominates (with their full weights, so a link's vertices land
/// exactly where the whole-skin posing puts them).
#[derive(Clone, Debug)]
pub struct SkinnedHand {
    /// The individual hand.
    pub hand: IndividualHand,
    binding: SkinBinding,
    links: Vec<usize>,
    by_link: Vec<Vec<usize>>,
    link_bindings: Vec<SkinBinding>,
    /// Per stride 2 to [`STRIDED_UP_TO`], one binding per link over its every stride-th vertex,
    /// made the first time that stride is asked for (the screening uses one).
    strided: [std::sync::OnceLock<Option<Vec<SkinBinding>>>; STRIDED_UP_TO - 1],
}

/// Largest stride [`SkinnedHand`] keeps thinned link bindings for (larger ones pose the whole
/// link and thin it).
const STRIDED_UP_TO: usize = 8;

/// One binding per link over every `stride`-th vertex it dominates.
fn link_bindings(
    hand: &IndividualHand,
    by_link: &[Vec<usize>],
    stride: usize,
) -> Result<Vec<SkinBinding>> {
    by_link
        .iter()
        .map(|vs| {
            let vs: Vec<usize> = vs.iter().step_by(stride).copied().collect();
            let rest: Vec<Point> = vs.iter().map(|&i| hand.skin.vertices[i]).collect();
            let w: Vec<Vec<(usize, f64)>> = vs.iter().map(|&i| hand.weights[i].clone()).collect();
            SkinBinding::new(&rest, &w, Link::ALL.len())
        })
        .collect()
}

impl SkinnedHand {
    /// Bind `hand` for posing.
    pub fn new(hand: IndividualHand) -> Result<SkinnedHand> {
        let links = dominant_links(&hand.weights);
        let by_link = group_by_link(&links);
        let per_link = link_bindings(&hand, &by_link, 1)?;
        Ok(SkinnedHand {
            binding: SkinBinding::new(&hand.skin.vertices, &hand.weights, Link::ALL.len())?,
            hand,
            links,
            by_link,
            link_bindings: per_link,
            strided: Default::default(),
        })
    }

    /// The default hand: the template of `side` as an individual hand (its own skin, skeleton
    /// and weights).
    pub fn template(side: Side) -> Result<SkinnedHand> {
        let t = load_template(side)?;
        let h = IndividualHand::from_skin(
            &t,
            t.mesh.clone(),
            t.skeleton.clone(),
            WeightMethod::Template,
        )?;
        SkinnedHand::new(h)
    }

    /// The hand of a `reconstruct` output folder (template weights by homology).
    pub fn load(dir: &std::path::Path) -> Result<SkinnedHand> {
        SkinnedHand::new(IndividualHand::load(dir, WeightMethod::Template)?)
    }
}

impl PosableHand for SkinnedHand {
    fn skeleton(&self) -> &Skeleton {
        &self.hand.skeleton
    }
    fn rest_mesh(&self) -> &TriMesh {
        &self.hand.skin
    }
    fn vertex_link(&self) -> &[usize] {
        &self.links
    }
    fn link_vertices(&self) -> &[Vec<usize>] {
        &self.by_link
    }
    fn pose_all(&self, transforms: &[Isometry3<f64>], out: &mut Vec<Point>) {
        self.binding.linear_into(transforms, out);
    }
    fn pose_link(&self, link: usize, transforms: &[Isometry3<f64>], out: &mut Vec<Point>) {
        self.link_bindings[link].linear_into(transforms, out);
    }
    fn pose_link_every(
        &self,
        link: usize,
        stride: usize,
        transforms: &[Isometry3<f64>],
        out: &mut Vec<Point>,
    ) {
        // A subset of the bindings `new` made, so it binds as they did; were it to fail, the
        // whole link is posed and thinned instead.
        let thinned = stride
            .checked_sub(2)
            .and_then(|k| self.strided.get(k))
            .and_then(|c| {
                c.get_or_init(|| link_bindings(&self.hand, &self.by_link, stride).ok())
                    .as_ref()
            });
        match thinned {
            Some(bindings) => bindings[link].linear_into(transforms, out),
            None => {
                self.pose_link(link, transforms, out);
                keep_every(out, stride);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Joint;

    #[test]
    fn skinned_hand_poses_like_the_pose_stage_and_per_link_like_whole_thinned_or_not() {
        let h = SkinnedHand::template(Side::Right).unwrap();
        let mut pose = Pose::zero();
        pose.angles[Joint::IMcp.index()] = [60f64.to_radians(), 0.0, 0.0];
        pose.angles[Joint::TCmc.index()] = [20f64.to_radians(), 30f64.to_radians(), 0.0];
        let mut all = Vec::new();
        h.pose_vertices(&pose, &mut all);
        // The pose stage's own LBS of the same hand.
        let want = h
            .hand
            .posed_skin(&pose, crate::pose::Skinning::Linear)
            .vertices;
        assert_eq!(all.len(), want.len());
        assert!(all.iter().zip(&want).all(|(a, b)| (a - b).norm() < 1e-9));
        let t = link_transforms(h.skeleton(), &pose);
        let mut part = Vec::new();
        for l in 0..Link::ALL.len() {
            h.pose_link(l, &t, &mut part);
            assert_eq!(part.len(), h.link_vertices()[l].len());
            for (p, &i) in part.iter().zip(&h.link_vertices()[l]) {
                assert!((p - all[i]).norm() < 1e-9);
            }
            // Thinned, through its own bindings or by thinning the whole link (stride 9):
            // the same vertices at the same places.
            for stride in 1..=STRIDED_UP_TO + 1 {
                let mut thin = Vec::new();
                h.pose_link_every(l, stride, &t, &mut thin);
                let want: Vec<usize> = h.link_vertices()[l]
                    .iter()
                    .step_by(stride)
                    .copied()
                    .collect();
                assert_eq!(thin.len(), want.len(), "link {l} stride {stride}");
                for (p, &i) in thin.iter().zip(&want) {
                    assert!((p - all[i]).norm() < 1e-9, "link {l} stride {stride}");
                }
            }
        }
        // The blend differs from rigid posing near the flexed joint, not far from it.
        let r =
            RigidHand::new(h.skeleton().clone(), h.rest_mesh().clone(), h.links.clone()).unwrap();
        let mut rigid = Vec::new();
        r.pose_vertices(&pose, &mut rigid);
        let moved = all
            .iter()
            .zip(&rigid)
            .filter(|(a, b)| (*a - *b).norm() > 0.5)
            .count();
        assert!(moved > 50, "{moved}");
        let little = &h.link_vertices()[Link::LDist.index()];
        assert!(little.iter().all(|&i| (all[i] - rigid[i]).norm() < 1e-9));
    }
}
