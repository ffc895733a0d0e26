//! Physical hold test in rapier (issue 8, "Grasp stability"): the hand's links are kinematic
//! convex hulls of the skin vertices each link dominates, fixed in the grasp posture; the part is
//! a dynamic triangle mesh with its mass (inertia of its bounding box as a solid); gravity is
//! applied along ±x, ±y, ±z of the world in turn, in a fresh world each time. The grasp holds when
//! the part's centre of mass moves less than 2 mm over 1 s in every direction.
//!
//! rapier works in SI units: lengths are converted from mm to m at this boundary.

use super::contact::PartShape;
use crate::error::{Error, Result};
use crate::geometry::Point;
use rapier3d_f64::prelude::*;
use serde::Serialize;

/// Displacement over which the part counts as dropped, mm.
pub const HOLD_LIMIT_MM: f64 = 2.0;

/// One direction of gravity.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HoldTrial {
    /// Direction of gravity (unit, world).
    pub gravity_dir: [f64; 3],
    /// Displacement of the centre of mass after `duration_s`, mm.
    pub displacement_mm: f64,
    /// Whether it stayed within [`HOLD_LIMIT_MM`].
    pub holds: bool,
}

/// Result of [`hold_test`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HoldReport {
    /// Whether every direction held.
    pub holds: bool,
    /// Simulated time per direction, s.
    pub duration_s: f64,
    /// Per direction.
    pub trials: Vec<HoldTrial>,
}

fn v(p: &Point) -> Vector {
    Vector::new(p.x * 1e-3, p.y * 1e-3, p.z * 1e-3)
}

/// Run the hold test: `link_points` are the posed skin vertices of each link (mm; links with
/// fewer than 4 points are skipped), `part` the part, `mass_kg` its mass, `mu` the friction.
pub fn hold_test(
    link_points: &[Vec<Point>],
    part: &PartShape,
    mass_kg: f64,
    mu: f64,
) -> Result<HoldReport> {
    let duration_s = 1.0;
    let hulls: Vec<Collider> = link_points
        .iter()
        .filter(|p| p.len() >= 4)
        .filter_map(|p| {
            let pts: Vec<Vector> = p.iter().map(v).collect();
            ColliderBuilder::convex_hull(&pts).map(|b| b.friction(mu).build())
        })
        .collect();
    let verts: Vec<Vector> = part.mesh.vertices.iter().map(v).collect();
    let idx: Vec<[u32; 3]> = part
        .mesh
        .faces
        .iter()
        .map(|f| [f[0] as u32, f[1] as u32, f[2] as u32])
        .collect();
    let size = (part.hi - part.lo) * 1e-3;
    let inertia = Vector::new(
        mass_kg * (size.y * size.y + size.z * size.z) / 12.0,
        mass_kg * (size.x * size.x + size.z * size.z) / 12.0,
        mass_kg * (size.x * size.x + size.y * size.y) / 12.0,
    );
    let com = v(&part.centre_of_mass);
    let mut trials = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let mut g = [0.0; 3];
            g[axis] = sign;
            let mut world = PhysicsWorld::new();
            world.gravity = Vector::new(g[0], g[1], g[2]) * 9.81;
            world.integration_parameters.dt = 1.0 / 240.0;
            let hand = world.insert_body(RigidBodyBuilder::kinematic_position_based());
            for h in &hulls {
                world.insert_collider(h.clone(), Some(hand));
            }
            let shape = ColliderBuilder::trimesh(verts.clone(), idx.clone())
                .map_err(|e| {
                    Error::invalid(format!("hold test: rapier cannot use the part mesh: {e:?}"))
                })?
                .friction(mu)
                .mass_properties(MassProperties::new(com, mass_kg, inertia))
                .build();
            let body = world.insert_body(RigidBodyBuilder::dynamic().can_sleep(false));
            world.insert_collider(shape, Some(body));
            let steps = (duration_s / world.integration_parameters.dt).round() as usize;
            for _ in 0..steps {
                world.step();
            }
            let pose = world.bodies[body].position();
            let moved = pose.transform_point(com) - com;
            let d = moved.length() * 1e3;
            let d = if d.is_finite() { d } else { f64::MAX };
            trials.push(HoldTrial {
                gravity_dir: g,
                displacement_mm: d,
                holds: d < HOLD_LIMIT_MM,
            });
        }
    }
    Ok(HoldReport {
        holds: trials.iter().all(|t| t.holds),
        duration_s,
        trials,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    fn cylinder() -> PartShape {
        let m = super::super::parts::mesh_sdf(
            |p| (p.x.hypot(p.y) - 30.0).max(-p.z).max(p.z - 120.0),
            Point::new(-30.0, -30.0, 0.0),
            Point::new(30.0, 30.0, 120.0),
            3.0,
        )
        .unwrap();
        PartShape::new(m).unwrap().0
    }

    /// A pad: a box of points 20 x 20 x 10 mm whose inner face is at `r` from the axis,
    /// facing the axis at angle `a`, height `z`.
    fn pad(a: f64, r: f64, z: f64) -> Vec<Point> {
        let (c, s) = (a.cos(), a.sin());
        let radial = Vec3::new(c, s, 0.0);
        let tangent = Vec3::new(-s, c, 0.0);
        let mut out = Vec::new();
        for &dr in &[0.0, 10.0] {
            for &dt in &[-10.0, 10.0] {
                for &dz in &[-10.0, 10.0] {
                    out.push(
                        Point::new(0.0, 0.0, z) + radial * (r + dr) + tangent * dt + Vec3::z() * dz,
                    );
                }
            }
        }
        out
    }

    #[test]
    fn wrapped_cylinder_holds_and_a_touch_does_not() {
        let part = cylinder();
        // Power grasp: two rings of eight pads pressed 0.5 mm into the surface.
        let mut wrap = Vec::new();
        for z in [40.0, 80.0] {
            for k in 0..8 {
                wrap.push(pad(k as f64 * std::f64::consts::PI / 4.0, 29.5, z));
            }
        }
        let r = hold_test(&wrap, &part, 0.3, 0.8).unwrap();
        assert!(r.holds, "{r:?}");
        // One fingertip touching the side.
        let r = hold_test(&[pad(0.0, 29.9, 60.0)], &part, 0.3, 0.8).unwrap();
        assert!(!r.holds, "{r:?}");
    }
}
