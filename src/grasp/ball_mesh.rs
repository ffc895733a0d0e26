//! One contact per skin ball on the part's mesh, for the hold test's rapier world.
//!
//! rapier's own ball-against-triangle-mesh contact gives a ball a contact manifold with every
//! triangle within its reach, so a ball sunk into a finely triangulated part makes a dozen
//! or more contacts, each a spring of the world's contact stiffness: the grip then grows with
//! the part's tessellation, and the narrow phase and the solver spend their time on it.
//! [`OneContactPerBall`] is a narrow-phase dispatcher that answers the ball-mesh pairs itself
//! with the one contact a ball has with a solid: from the ball's centre to its closest point
//! on the mesh, inside or out (the mesh's pseudo-normals, so the mesh must be built with
//! `TriMeshFlags::ORIENTED`), the depth that of the ball's surface. Every other pair goes to
//! rapier's default dispatcher through a chain.
//!
//! Inputs and outputs are rapier's (SI units, poses of shape 2 in shape 1's frame).

use rapier3d_f64::geometry::{ContactData, ContactManifold, ContactManifoldData};
use rapier3d_f64::parry::query::details::NormalConstraints;
use rapier3d_f64::parry::query::{
    ClosestPoints, Contact, ContactManifoldsWorkspace, NonlinearRigidMotion,
    PersistentQueryDispatcher, PointQueryWithLocation, QueryDispatcher, ShapeCastHit,
    ShapeCastOptions, TrackedContact, Unsupported,
};
use rapier3d_f64::parry::shape::{PackedFeatureId, Shape};
use rapier3d_f64::prelude::{Pose, Real, Vector};

/// The narrow-phase dispatcher of one contact per ball against a triangle mesh (module doc).
/// A ball sunk deeper than `max_depth` (m) reports `max_depth`: compressed soft tissue
/// pushes as a pad does, not as a rigid body driven into the part.
#[derive(Clone, Copy, Debug)]
pub struct OneContactPerBall {
    /// Deepest penetration a contact reports, m.
    pub max_depth: Real,
}

/// The contact of a ball of radius `r` centred at `c` (in the mesh's frame) with the solid the
/// oriented `mesh` bounds, if closer than `prediction`: the closest point on the mesh, the
/// mesh's outward normal there (from the solid toward the ball's centre; the face's normal when
/// the centre lies on the surface) and the signed distance of the ball's surface (negative
/// inside). A centre deeper than the ball's diameter inside the solid has no contact (its
/// nearest surface may be the far side of a thin wall).
fn ball_on_mesh(
    c: Vector,
    r: Real,
    mesh: &rapier3d_f64::parry::shape::TriMesh,
    prediction: Real,
) -> Option<(Vector, Vector, Real)> {
    let (proj, (tri, _)) =
        mesh.project_local_point_and_get_location_with_max_dist(c, false, 3.0 * r + prediction)?;
    let d = c - proj.point;
    let len = d.length();
    let outward = if len > 1e-12 {
        if proj.is_inside {
            -d / len
        } else {
            d / len
        }
    } else {
        mesh.triangle(tri).normal()?
    };
    let dist = if proj.is_inside { -len - r } else { len - r };
    (dist < prediction).then_some((proj.point, outward, dist))
}

impl QueryDispatcher for OneContactPerBall {
    fn intersection_test(
        &self,
        _: &Pose,
        _: &dyn Shape,
        _: &dyn Shape,
    ) -> Result<rapier3d_f64::parry::query::ShapeIntersection, Unsupported> {
        Err(Unsupported)
    }

    fn distance(
        &self,
        _: &Pose,
        _: &dyn Shape,
        _: &dyn Shape,
    ) -> Result<rapier3d_f64::parry::query::ShapeDistance, Unsupported> {
        Err(Unsupported)
    }

    fn contact(
        &self,
        _: &Pose,
        _: &dyn Shape,
        _: &dyn Shape,
        _: Real,
    ) -> Result<Option<Contact>, Unsupported> {
        Err(Unsupported)
    }

    fn closest_points(
        &self,
        _: &Pose,
        _: &dyn Shape,
        _: &dyn Shape,
        _: Real,
    ) -> Result<ClosestPoints, Unsupported> {
        Err(Unsupported)
    }

    fn cast_shapes(
        &self,
        _: &Pose,
        _: Vector,
        _: &dyn Shape,
        _: &dyn Shape,
        _: ShapeCastOptions,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        Err(Unsupported)
    }

    fn cast_shapes_nonlinear(
        &self,
        _: &NonlinearRigidMotion,
        _: &dyn Shape,
        _: &NonlinearRigidMotion,
        _: &dyn Shape,
        _: Real,
        _: Real,
        _: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        Err(Unsupported)
    }
}

impl PersistentQueryDispatcher<ContactManifoldData, ContactData> for OneContactPerBall {
    fn contact_manifolds(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
        manifolds: &mut Vec<ContactManifold>,
        _workspace: &mut Option<ContactManifoldsWorkspace>,
    ) -> Result<(), Unsupported> {
        // Shape 1's frame is the ball's or the mesh's; `pos12` places shape 2 in it.
        let (ball, mesh, ball_first) = match (g1.as_ball(), g2.as_trimesh(), g2.as_ball()) {
            (Some(b), Some(m), _) => (b, m, true),
            (None, _, Some(b)) => match g1.as_trimesh() {
                Some(m) => (b, m, false),
                None => return Err(Unsupported),
            },
            _ => return Err(Unsupported),
        };
        if mesh.pseudo_normals_if_oriented().is_none() {
            return Err(Unsupported);
        }
        let centre = if ball_first {
            pos12.inverse_transform_point(Vector::ZERO)
        } else {
            pos12.translation
        };
        // The pair keeps its one manifold for its life, empty when the ball is clear (rapier's
        // solver graph refers to a pair's manifolds by their place in its list).
        if manifolds.is_empty() {
            manifolds.push(ContactManifold::with_data(
                0,
                0,
                ContactManifoldData::default(),
            ));
        }
        manifolds.truncate(1);
        let m = &mut manifolds[0];
        let Some((on_mesh, outward, dist)) = ball_on_mesh(centre, ball.radius, mesh, prediction)
        else {
            m.points.clear();
            return Ok(());
        };
        let dist = dist.max(-self.max_depth);
        // The ball's point at that depth, on the normal through the mesh's point, in the mesh's
        // frame; then both points and normals in their shapes' frames.
        let in_ball = on_mesh + outward * dist;
        let fid = PackedFeatureId::face(0);
        let (p1, p2, n1, n2) = if ball_first {
            let n = pos12.transform_vector(outward);
            (pos12.transform_point(in_ball), on_mesh, -n, outward)
        } else {
            let n = pos12.inverse_transform_vector(outward);
            (on_mesh, pos12.inverse_transform_point(in_ball), outward, -n)
        };
        let contact = TrackedContact::new(p1, p2, fid, fid, dist);
        // One contact that persists from step to step keeps its warm-start impulse.
        match m.points.first_mut() {
            Some(p) => p.copy_geometry_from(contact),
            None => m.points.push(contact),
        }
        m.points.truncate(1);
        m.local_n1 = n1;
        m.local_n2 = n2;
        Ok(())
    }

    fn contact_manifold_convex_convex(
        &self,
        _: &Pose,
        _: &dyn Shape,
        _: &dyn Shape,
        _: Option<&dyn NormalConstraints>,
        _: Option<&dyn NormalConstraints>,
        _: Real,
        _: &mut ContactManifold,
    ) -> Result<(), Unsupported> {
        Err(Unsupported)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d_f64::parry::shape::{Ball, TriMeshFlags};

    /// The 40 mm cube [0, 40]^3, in metres, oriented.
    fn cube() -> rapier3d_f64::parry::shape::TriMesh {
        let m = crate::geometry::mesh::tests::cuboid(40.0, 40.0, 40.0);
        let verts = m
            .vertices
            .iter()
            .map(|p| Vector::new(p.x, p.y, p.z) * 1e-3)
            .collect();
        let idx = m.faces.iter().map(|f| f.map(|i| i as u32)).collect();
        rapier3d_f64::parry::shape::TriMesh::with_flags(verts, idx, TriMeshFlags::ORIENTED).unwrap()
    }

    /// The one contact of a 1.5 mm ball over the middle of the cube's top face (z = 40 mm), its centre at
    /// height `z` mm, the mesh rotated about z by 30 degrees and shifted, either shape first:
    /// (distance mm, normal from shape 1 toward shape 2 in the world, world points).
    fn touch(z: f64, ball_first: bool, max_depth_mm: f64) -> Option<(f64, Vector, Vector, Vector)> {
        let mesh = cube();
        let ball = Ball::new(1.5e-3);
        let mesh_pose = Pose::from_parts(
            Vector::new(0.01, -0.02, 0.005),
            rapier3d_f64::prelude::Rotation::from_rotation_z(30f64.to_radians()),
        );
        let ball_pose = Pose::from_translation(mesh_pose.transform_point(Vector::new(
            20e-3,
            20e-3,
            (40.0 + z) * 1e-3,
        )));
        let d = OneContactPerBall {
            max_depth: max_depth_mm * 1e-3,
        };
        let mut manifolds = Vec::new();
        let (pose1, pose2, g1, g2): (Pose, Pose, &dyn Shape, &dyn Shape) = if ball_first {
            (ball_pose, mesh_pose, &ball, &mesh)
        } else {
            (mesh_pose, ball_pose, &mesh, &ball)
        };
        let pos12 = pose1.inverse() * pose2;
        d.contact_manifolds(&pos12, g1, g2, 2e-3, &mut manifolds, &mut None)
            .unwrap();
        assert_eq!(manifolds.len(), 1);
        let m = &manifolds[0];
        let p = m.points.first()?;
        assert_eq!(m.points.len(), 1);
        let n1 = pose1.transform_vector(m.local_n1);
        let n2 = pose2.transform_vector(m.local_n2);
        assert!((n1 + n2).length() < 1e-12, "{n1:?} {n2:?}");
        Some((
            p.dist * 1e3,
            n1,
            pose1.transform_point(p.local_p1),
            pose2.transform_point(p.local_p2),
        ))
    }

    /// Against closed forms: a ball above the face by 1 mm is 1 mm off it (less the radius),
    /// one sunk so that its centre lies 0.5 mm under the face is 2 mm in (the radius and the
    /// centre's depth), and the depth reported stops at the cap; the normal is the face's,
    /// pointing from shape 1 to shape 2 whichever is first; the points are the face's and the
    /// ball's at that depth; a ball out of reach (2 mm, the prediction distance here) has no contact.
    #[test]
    fn one_contact_per_ball_against_a_cube_face() {
        let up = rapier3d_f64::prelude::Rotation::from_rotation_z(30f64.to_radians()) * Vector::Z;
        for ball_first in [true, false] {
            // Normal from the ball to the mesh is down the face's normal.
            let toward_2 = if ball_first { -up } else { up };
            for (z, want, cap) in [
                (2.5, 1.0, 5.0),
                (1.5, 0.0, 5.0),
                (0.5, -1.0, 5.0),
                (-0.5, -2.0, 5.0),
                (-0.5, -1.5, 1.5),
            ] {
                let (dist, n, p1, p2) = touch(z, ball_first, cap).unwrap();
                assert!((dist - want).abs() < 1e-9, "{ball_first} {z}: {dist}");
                assert!((n - toward_2).length() < 1e-9, "{ball_first} {z}: {n:?}");
                // The mesh's point on the face, the ball's `dist` above it along the normal.
                let (on_mesh, on_ball) = if ball_first { (p2, p1) } else { (p1, p2) };
                assert!(((on_ball - on_mesh) - up * dist * 1e-3).length() < 1e-12);
                let face = rapier3d_f64::prelude::Rotation::from_rotation_z(30f64.to_radians())
                    .inverse()
                    * (on_mesh - Vector::new(0.01, -0.02, 0.005));
                assert!((face.z - 40e-3).abs() < 1e-12, "{face:?}");
            }
            assert!(touch(1.5 + 2.1, ball_first, 5.0).is_none());
        }
    }

    /// Where a free 40 mm cube (no gravity) has moved along z after 0.1 s, mm, when a fixed
    /// 1.5 mm ball's centre starts `z_mm` above the middle of its top face (negative: inside),
    /// in a rapier world that uses [`OneContactPerBall`].
    fn cube_moves(z_mm: f64) -> f64 {
        use rapier3d_f64::prelude::*;
        let mut w = PhysicsWorld::new();
        w.narrow_phase = NarrowPhase::with_query_dispatcher(QueryDispatcher::chain(
            OneContactPerBall { max_depth: 1.5e-3 },
            rapier3d_f64::parry::query::DefaultQueryDispatcher,
        ));
        w.integration_parameters.length_unit = 0.05;
        w.gravity = Vector::ZERO;
        let hand = w.insert_body(RigidBodyBuilder::kinematic_position_based());
        let centre = Vector::new(0.02, 0.02, 0.04 + z_mm * 1e-3);
        w.insert_collider(
            ColliderBuilder::ball(1.5e-3).translation(centre).build(),
            Some(hand),
        );
        let body = w.insert_body(RigidBodyBuilder::dynamic());
        w.insert_collider(
            ColliderBuilder::new(SharedShape::new(cube())).build(),
            Some(body),
        );
        for _ in 0..24 {
            w.step();
        }
        w.bodies[body].translation().z * 1e3
    }

    /// A ball pressed into the part pushes it away, whichever side of the surface its centre
    /// is on: the cube moves down, out of the ball, by about the ball's overlap (the ball's
    /// surface 0.5 and 1.0 mm in: 0.5 and 1.0 mm), or the capped 1.5 mm once the centre has
    /// passed the surface. (rapier's own ball-triangle contacts treat the face as two-sided:
    /// with the centre under it, they pull the cube up onto the ball.)
    #[test]
    fn a_ball_pressed_in_pushes_the_part_out_from_either_side_of_its_surface() {
        for (z, want) in [(1.0, 0.5), (0.5, 1.0), (-0.5, 1.5), (-1.0, 1.5)] {
            let moved = cube_moves(z);
            assert!(moved < 0.0, "centre {z} mm: the cube moved {moved} mm");
            assert!(
                (-moved - want).abs() < 0.1,
                "centre {z} mm: {moved} mm, want -{want}"
            );
        }
    }
}
