//! The hand that grasps: anything that can pose its skin for a [`Pose`].
//!
//! The grasp stage needs only the skeleton (for forward kinematics and limits), the rest mesh,
//! each vertex's dominant link (to split the skin into rigid-ish links for contacts per link and
//! colliders per link) and a way to pose the skin. [`RigidHand`] poses rigidly: every vertex
//! moves with its dominant link ([`link_transforms`]); the integrator implements
//! [`PosableHand`] for the skinned individual hand (issue 7).

use crate::anatomy::{Link, Side};
use crate::error::Result;
use crate::geometry::{Point, TriMesh};
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
    /// Write the posed skin vertices (same order as [`PosableHand::rest_mesh`]) into `out`.
    fn pose_vertices(&self, pose: &Pose, out: &mut Vec<Point>);
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
}

impl RigidHand {
    /// The default hand: the template of `side`, posed rigidly.
    pub fn template(side: Side) -> Result<RigidHand> {
        let t = load_template(side)?;
        Ok(RigidHand {
            links: dominant_links(&t.weights),
            skeleton: t.skeleton,
            mesh: t.mesh,
        })
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
            skeleton,
            mesh,
            links,
        })
    }
}

/// Pose `rest` rigidly: vertex `i` moves by `transforms[links[i]]`.
pub fn pose_rigid(
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
    fn pose_vertices(&self, pose: &Pose, out: &mut Vec<Point>) {
        let t = link_transforms(&self.skeleton, pose);
        pose_rigid(&self.mesh.vertices, &self.links, &t, out);
    }
}
