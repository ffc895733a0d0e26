//! Physical hold test in rapier: the hand's skin in contact is a set of kinematic balls fixed
//! in the grasp posture ([`hold_test_hand`]); the part is a dynamic body colliding through its
//! own triangle mesh, with its mass (inertia of its bounding box as a solid); gravity is
//! applied along ±x, ±y, ±z of the world in turn, each in its own copy of the world. The grasp
//! holds when the part's centre of mass stays within 2 mm of where it started for 1 s in every
//! direction (it starts where it settled in 0.4 s without gravity, once for all six: the squeeze
//! after the autograsp ([`super::autograsp::squeeze`]) leaves the skin up to 1.5 mm inside the
//! part, and the solver's push-out is not a drop; the part is damped while it settles,
//! [`SETTLE_DAMPING_PER_S`]). That overlap is what makes a grasp hold: rapier turns it into the
//! contacts' normal force (critically damped contact springs of [`CONTACT_HZ`]), and friction
//! bounded by it holds the part; a grasp that only touches holds nothing. Each ball has one
//! contact with the part, as a ball has with a solid ([`super::ball_mesh`]), whatever the
//! part's triangulation, its depth capped at the squeeze's. A direction ends early when the
//! part passes the limit, or when it has come to rest well inside it ([`comes_to_rest`]).
//!
//! rapier works in SI units: lengths are converted from mm to m at this boundary.

use super::contact::PartShape;
use super::hand::PosableHand;
use crate::anatomy::Link;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use rapier3d_f64::parry::query::{DefaultQueryDispatcher, QueryDispatcher};
use rapier3d_f64::prelude::*;
use serde::Serialize;

/// Displacement over which the part counts as dropped, mm.
pub(crate) const HOLD_LIMIT_MM: f64 = 2.0;

/// Steps (1/240 s, so 0.4 s) without gravity before the trials, to let the solver resolve
/// the initial overlap of skin and part. The squeezed part needs this long to come to rest
/// between the fingers (after 0.1 s the demo hand's bottle was still moving: it passed 2 mm
/// within 0.2 s of the trial in two directions and stayed within 0.25 mm after a 0.4 s
/// settle).
pub(crate) const SETTLE_STEPS: usize = 96;

/// One direction of gravity.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HoldTrial {
    /// Direction of gravity (unit, world).
    pub gravity_dir: [f64; 3],
    /// Displacement of the centre of mass at the end of the trial (after its duration, when
    /// it passed the limit, or when the part came to rest), mm.
    pub displacement_mm: f64,
    /// Whether it stayed within [`HOLD_LIMIT_MM`].
    pub holds: bool,
    /// When the part came to rest under gravity and the trial ended early, s after gravity
    /// came on ([`comes_to_rest`]); `None` when the trial ran its whole duration or the part
    /// passed the limit.
    pub at_rest_s: Option<f64>,
    /// Stopped because the part had dropped in another direction ([`HoldRun::UntilDrop`]): the
    /// displacement is where it had got to, and `holds` says only that it had not dropped yet.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub cut_short: bool,
}

/// How far [`hold_test_hand`] runs its six directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HoldRun {
    /// Every direction to its end: the whole report.
    Whole,
    /// For a caller that needs only whether the grasp holds (a placement dropped when it does
    /// not): the directions still running stop as soon as the part drops in one of them
    /// ([`HoldTrial::cut_short`]). `holds` is the same as [`HoldRun::Whole`]'s; the
    /// displacements of the directions cut short are not.
    UntilDrop,
}

/// Result of [`hold_test`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HoldReport {
    /// Whether every direction held.
    pub holds: bool,
    /// Simulated time per direction at most (a trial ends early when the part passes the
    /// limit or comes to rest), s.
    pub duration_s: f64,
    /// How far the part's centre of mass moved while the squeeze settled, before any gravity
    /// (the trials' displacements are measured from where it settled), mm.
    pub settle_mm: f64,
    /// Per direction.
    pub trials: Vec<HoldTrial>,
    /// The part's rigid motion while the squeeze settled it, in the world, mm (its centre of
    /// mass moved [`HoldReport::settle_mm`]).
    #[serde(skip)]
    pub settle_motion: nalgebra::Isometry3<f64>,
}

fn v(p: &Point) -> Vector {
    Vector::new(p.x * 1e-3, p.y * 1e-3, p.z * 1e-3)
}

/// rapier's length unit for hand-sized scenes, m (scales its contact tolerances).
pub(crate) const LENGTH_UNIT_M: f64 = 0.05;

/// Natural frequency of rapier's contact springs in the hold test, Hz (critically damped).
pub(crate) const CONTACT_HZ: f64 = 60.0;

/// rapier's solver iterations per step in the hold test (its default is 4): with friction in
/// the biased pass too, four do not converge on a part pressed from every side, and it creeps
/// under gravity where its friction could hold it.
pub(crate) const SOLVER_ITERATIONS: usize = 12;

/// Linear and angular damping of the part while it settles, 1/s (a time constant of 10 ms,
/// two and a half steps): the squeeze's overlap is pushed out at up to rapier's corrective
/// velocity, and an undamped part kept that speed and coasted out of a grip whose forces
/// balance a millimetre further on. The settling is the grasp's preparation, not its test:
/// the trials run undamped.
pub(crate) const SETTLE_DAMPING_PER_S: f64 = 100.0;

/// Radius of the balls that stand for the skin in [`hold_test_hand`], mm.
pub(crate) const SKIN_BALL_MM: f64 = 1.5;

/// Skin within this distance of the part gets balls, mm (the contact tolerance and a half).
pub(crate) const BALL_BAND_MM: f64 = 1.5;

/// One ball per link per cell of this size, mm.
pub(crate) const BALL_CELL_MM: f64 = 3.0;

/// The hold test of a posed hand (`posed`: the skin in rest vertex order, faces of the rest
/// mesh). The skin in contact (vertices within [`BALL_BAND_MM`] of the part or inside it, one
/// per [`BALL_CELL_MM`] cell per link) is a set of
/// kinematic balls of [`SKIN_BALL_MM`] radius, each sunk by its radius along the skin's
/// inward normal so that its surface is the skin's. Unlike a convex hull per link, balls keep
/// the palm's and the finger's concave shape: a hull would fill the cup of the palm, which
/// the part occupies. The forearm has no collider. `run`: every direction to its end, or only
/// until the part drops in one ([`HoldRun`]).
pub fn hold_test_hand(
    hand: &dyn PosableHand,
    posed: &[Point],
    part: &PartShape,
    mass_kg: f64,
    mu: f64,
    run: HoldRun,
) -> Result<HoldReport> {
    let mesh = TriMesh {
        vertices: posed.to_vec(),
        faces: hand.rest_mesh().faces.clone(),
    };
    let normals = mesh.vertex_normals();
    let mut seen = std::collections::HashSet::new();
    let mut centres = Vec::new();
    for (l, vs) in hand.link_vertices().iter().enumerate() {
        if l == Link::Arm.index() {
            continue;
        }
        let cell = BALL_CELL_MM;
        for &i in vs {
            let p = posed[i];
            let near = match part.probe(&p, BALL_BAND_MM) {
                super::contact::Probe::Hit(d, _, _) => d <= BALL_BAND_MM,
                super::contact::Probe::Deep => true,
                super::contact::Probe::Far => false,
            };
            if !near {
                continue;
            }
            let key = (
                l,
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            );
            if seen.insert(key) {
                centres.push(p - normals[i] * SKIN_BALL_MM);
            }
        }
    }
    let colliders: Vec<Collider> = centres
        .iter()
        .map(|c| {
            ColliderBuilder::ball(SKIN_BALL_MM * 1e-3)
                .translation(v(c))
                .friction(mu)
                .build()
        })
        .collect();
    run_trials(colliders, &centres, part, mass_kg, mu, run)
}

/// Run the hold test: `link_points` are the posed skin vertices of each link (mm; links with
/// fewer than 4 points are skipped), `part` the part, `mass_kg` its mass, `mu` the friction.
/// The part's collider keeps only the triangles within 10 mm of the hand's links (a part that
/// moves that far has long failed: each trial stops as soon as the part has moved
/// [`HOLD_LIMIT_MM`]); the six directions run in parallel, each in its own world.
pub fn hold_test(
    link_points: &[Vec<Point>],
    part: &PartShape,
    mass_kg: f64,
    mu: f64,
) -> Result<HoldReport> {
    let used: Vec<&Vec<Point>> = link_points.iter().filter(|p| p.len() >= 4).collect();
    let hulls: Vec<Collider> = used
        .iter()
        .filter_map(|p| {
            let pts: Vec<Vector> = p.iter().map(v).collect();
            ColliderBuilder::convex_hull(&pts).map(|b| b.friction(mu).build())
        })
        .collect();
    let pts: Vec<Point> = used.iter().flat_map(|p| p.iter().copied()).collect();
    run_trials(hulls, &pts, part, mass_kg, mu, HoldRun::Whole)
}

/// The six trials with the hand's `colliders` (mm points `pts` on them locate the part's
/// triangles to keep), as `run` says.
fn run_trials(
    hulls: Vec<Collider>,
    pts: &[Point],
    part: &PartShape,
    mass_kg: f64,
    mu: f64,
    run: HoldRun,
) -> Result<HoldReport> {
    use rayon::prelude::*;
    let duration_s = 1.0;
    // Part triangles within TRIM_MM of a collider point: everything the part can touch
    // before it has moved HOLD_LIMIT_MM (the hull's faces span points at most a 4 mm cell
    // apart), found through a hash grid of the points.
    const TRIM_MM: f64 = 8.0;
    let mut cells: std::collections::HashSet<[i64; 3]> = std::collections::HashSet::new();
    for p in pts {
        cells.insert(std::array::from_fn(|a| (p[a] / TRIM_MM).floor() as i64));
    }
    let near = |q: &Point| {
        let c: [i64; 3] = std::array::from_fn(|a| (q[a] / TRIM_MM).floor() as i64);
        (-1..=1).any(|i| {
            (-1..=1).any(|j| (-1..=1).any(|k| cells.contains(&[c[0] + i, c[1] + j, c[2] + k])))
        })
    };
    let clock = std::time::Instant::now();
    let mesh = &part.mesh;
    let keep: Vec<bool> = mesh.vertices.iter().map(near).collect();
    let mut remap = vec![u32::MAX; mesh.n_vertices()];
    let mut verts: Vec<Vector> = Vec::new();
    let mut idx: Vec<[u32; 3]> = Vec::new();
    for f in &mesh.faces {
        if f.iter().any(|&i| keep[i]) {
            let t = f.map(|i| {
                if remap[i] == u32::MAX {
                    remap[i] = verts.len() as u32;
                    verts.push(v(&mesh.vertices[i]));
                }
                remap[i]
            });
            idx.push(t);
        }
    }
    let size = (part.hi - part.lo) * 1e-3;
    let inertia = Vector::new(
        mass_kg * (size.y * size.y + size.z * size.z) / 12.0,
        mass_kg * (size.x * size.x + size.z * size.z) / 12.0,
        mass_kg * (size.x * size.x + size.y * size.y) / 12.0,
    );
    let com = v(&part.centre_of_mass);
    let shape = if idx.is_empty() {
        None
    } else {
        Some(
            ColliderBuilder::trimesh_with_flags(verts, idx, TriMeshFlags::ORIENTED)
                .map_err(|e| {
                    Error::invalid(format!("hold test: rapier cannot use the part mesh: {e:?}"))
                })?
                .friction(mu)
                .mass_properties(MassProperties::new(com, mass_kg, inertia))
                .build(),
        )
    };
    let dirs: Vec<[f64; 3]> = (0..3)
        .flat_map(|axis| {
            [-1.0, 1.0].map(|sign| {
                let mut g = [0.0; 3];
                g[axis] = sign;
                g
            })
        })
        .collect();
    let Some(shape) = shape else {
        // Nothing of the hand near the part: it falls freely.
        let trials = dirs
            .iter()
            .map(|g| HoldTrial {
                gravity_dir: *g,
                displacement_mm: 0.5 * 9.81 * duration_s * duration_s * 1e3,
                holds: false,
                at_rest_s: None,
                cut_short: false,
            })
            .collect();
        return Ok(HoldReport {
            holds: false,
            duration_s,
            settle_mm: 0.0,
            trials,
            settle_motion: nalgebra::Isometry3::identity(),
        });
    };
    let mut world = PhysicsWorld::new();
    // One contact per skin ball (see `ball_mesh`), its depth capped at the squeeze's: skin
    // pressed deeper (the thenar, which the approach lets give way) pushes as a squeezed pad.
    world.narrow_phase = NarrowPhase::with_query_dispatcher(QueryDispatcher::chain(
        super::ball_mesh::OneContactPerBall {
            max_depth: super::autograsp::SQUEEZE_MM * 1e-3,
        },
        DefaultQueryDispatcher,
    ));
    world.integration_parameters.dt = 1.0 / 240.0;
    // Hand-sized bodies: rapier's tolerances are tuned for metre-sized ones (20 mm of
    // predictive contacts, 5 mm of slop), so its length unit is set to 5 cm.
    world.integration_parameters.length_unit = LENGTH_UNIT_M;
    // The squeeze's overlap is pushed out in rapier's biased pass; by default friction acts only
    // in the unbiased one, so that push met no friction and a squeezed part slid out sideways
    // along faces pressed hard enough to hold it (a slab between two rows of pressed balls,
    // pushed at its edge, slid the whole of the edge's overlap: see the tests). Friction in
    // both passes, and the solver iterations it needs to converge on a part pressed from
    // every side.
    world.integration_parameters.friction_in_bias_pass = true;
    world.integration_parameters.num_solver_iterations = SOLVER_ITERATIONS;
    // rapier reuses a pair's contacts until it has moved ten times its slop, which at this
    // length unit is more than the hold limit: every step's contacts are measured afresh.
    world.integration_parameters.contact_recycling = false;
    // Contacts as critically damped springs of 60 Hz (rapier's default, 30 Hz with a
    // damping ratio of 10, is made for piles of bodies: so overdamped that a squeezed
    // part creeps out of the grip at about 2 mm/s). The skin's compliance is the
    // squeeze's overlap; the solver should hold that overlap, not add a softer second
    // spring. 60 Hz is a quarter of the step rate, well inside what the soft
    // constraints resolve in one step, and the push-out stays capped at rapier's
    // corrective velocity (3 length units/s = 0.15 m/s), so an overlapping part is
    // pushed to rest, never launched.
    let soft = SpringCoefficients::new(CONTACT_HZ, 1.0);
    world.integration_parameters.contact_softness = soft;
    world.integration_parameters.static_contact_softness = soft;
    let hand = world.insert_body(RigidBodyBuilder::kinematic_position_based());
    for h in &hulls {
        world.insert_collider(h.clone(), Some(hand));
    }
    // Damped while it settles, free in the trials.
    let body = world.insert_body(
        RigidBodyBuilder::dynamic()
            .can_sleep(false)
            .linear_damping(SETTLE_DAMPING_PER_S)
            .angular_damping(SETTLE_DAMPING_PER_S),
    );
    world.insert_collider(shape, Some(body));
    // Settle without gravity first: the skin may overlap the part by up to the autograsp's
    // depth bound, and the solver's push-out is not a drop. Every direction starts from the
    // same settled state (settling is the same in each: no gravity), at rest.
    world.gravity = Vector::ZERO;
    let built_s = clock.elapsed().as_secs_f64();
    for _ in 0..SETTLE_STEPS {
        world.step();
    }
    let settle_motion = {
        let p = world.bodies[body].position();
        let (t, q) = (p.translation * 1e3, p.rotation);
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(t.x, t.y, t.z),
            nalgebra::UnitQuaternion::new_normalize(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)),
        )
    };
    let settle_mm = (settle_motion * part.centre_of_mass - part.centre_of_mass).norm();
    let rb = &mut world.bodies[body];
    rb.set_linear_damping(0.0);
    rb.set_angular_damping(0.0);
    rb.set_linvel(Vector::ZERO, true);
    rb.set_angvel(Vector::ZERO, true);
    let start = rb.position().transform_point(com);
    let steps = (duration_s / world.integration_parameters.dt).round() as usize;
    let settled = Settled::of(&world);
    let settled_s = clock.elapsed().as_secs_f64();
    let params = world.integration_parameters;
    drop(world);
    let dropped = std::sync::atomic::AtomicBool::new(false);
    let trials: Vec<HoldTrial> = dirs
        .par_iter()
        .map(|g| {
            let mut world = settled.world(&params);
            world.gravity = Vector::new(g[0], g[1], g[2]) * 9.81;
            let mut d = 0.0f64;
            let mut path = Vec::with_capacity(steps);
            let mut at_rest = None;
            let mut cut_short = false;
            for k in 0..steps {
                if run == HoldRun::UntilDrop && dropped.load(std::sync::atomic::Ordering::Relaxed) {
                    cut_short = true;
                    break;
                }
                world.step();
                let c = world.bodies[body].position().transform_point(com);
                let moved = (c - start).length() * 1e3;
                d = if moved.is_finite() { moved } else { f64::MAX };
                path.push(c);
                if d >= HOLD_LIMIT_MM {
                    dropped.store(true, std::sync::atomic::Ordering::Relaxed);
                    break;
                }
                if comes_to_rest(&path, &start, steps - 1 - k, params.dt) {
                    at_rest = Some((k + 1) as f64 * params.dt);
                    break;
                }
            }
            HoldTrial {
                gravity_dir: *g,
                displacement_mm: d,
                holds: d < HOLD_LIMIT_MM,
                at_rest_s: at_rest,
                cut_short,
            }
        })
        .collect();
    log::debug!(
        "hold test: {} balls, world built {built_s:.2} s, settled {:.2} s ({settle_mm:.2} mm), six directions {:.2} s",
        hulls.len(),
        settled_s - built_s,
        clock.elapsed().as_secs_f64() - settled_s
    );
    Ok(HoldReport {
        holds: trials.iter().all(|t| t.holds),
        duration_s,
        settle_mm,
        trials,
        settle_motion,
    })
}

/// Steps (1/240 s, so 0.1 s) of each window over which [`comes_to_rest`] measures the part's
/// creep.
pub(crate) const REST_WINDOW_STEPS: usize = 24;

/// Whether a trial may end as held before its duration: `path` is the part's centre of mass
/// after each step under gravity (m), `start` where it started, `left` the steps the trial
/// still has, `dt` the step. Over the last two [`REST_WINDOW_STEPS`] windows the part moved
/// `before` then `recent`; its speed is the larger over a window and its acceleration the
/// growth from one window to the next. The trial ends when the displacement so far, carried on
/// at that speed and acceleration for the rest of the trial, stays under half of
/// [`HOLD_LIMIT_MM`]. A part held by static friction under a constant load stays where it
/// stopped (the hand does not move); the factor two leaves room for a creep that the windows
/// underestimate (checked against trials run to the end: see the README's grasp section).
pub(crate) fn comes_to_rest(path: &[Vector], start: &Vector, left: usize, dt: f64) -> bool {
    let w = REST_WINDOW_STEPS;
    let n = path.len();
    if n < 2 * w + 1 {
        return false;
    }
    let now = path[n - 1];
    let recent = (now - path[n - 1 - w]).length();
    let before = (path[n - 1 - w] - path[n - 1 - 2 * w]).length();
    let window_s = w as f64 * dt;
    let speed = recent.max(before) / window_s;
    let acceleration = (recent - before).max(0.0) / (window_s * window_s);
    let rest_s = left as f64 * dt;
    let predicted = (now - *start).length() + speed * rest_s + 0.5 * acceleration * rest_s * rest_s;
    predicted * 1e3 < 0.5 * HOLD_LIMIT_MM
}

/// A settled world's state, from which each direction of the hold test starts (rapier's
/// `PhysicsWorld` is not `Clone`; its sets are, and its pipelines are workspaces).
struct Settled {
    islands: IslandManager,
    broad_phase: BroadPhaseBvh,
    narrow_phase: NarrowPhase,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    impulse_joints: ImpulseJointSet,
    multibody_joints: MultibodyJointSet,
    ccd_solver: CCDSolver,
}

impl Settled {
    fn of(w: &PhysicsWorld) -> Self {
        Settled {
            islands: w.islands.clone(),
            broad_phase: w.broad_phase.clone(),
            narrow_phase: w.narrow_phase.clone(),
            bodies: w.bodies.clone(),
            colliders: w.colliders.clone(),
            impulse_joints: w.impulse_joints.clone(),
            multibody_joints: w.multibody_joints.clone(),
            ccd_solver: w.ccd_solver.clone(),
        }
    }

    /// A world in this state, stepping with `params`.
    fn world(&self, params: &IntegrationParameters) -> PhysicsWorld {
        let mut w = PhysicsWorld::new();
        w.integration_parameters = *params;
        w.islands = self.islands.clone();
        w.broad_phase = self.broad_phase.clone();
        w.narrow_phase = self.narrow_phase.clone();
        w.bodies = self.bodies.clone();
        w.colliders = self.colliders.clone();
        w.impulse_joints = self.impulse_joints.clone();
        w.multibody_joints = self.multibody_joints.clone();
        w.ccd_solver = self.ccd_solver.clone();
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    /// The 60 mm cylinder, 200 mm tall, base at z = 0, moved by `pose`.
    fn cylinder_at(pose: &nalgebra::Isometry3<f64>) -> PartShape {
        let m = super::super::parts::mesh_sdf(
            |p| (p.x.hypot(p.y) - 30.0).max(-p.z).max(p.z - 200.0),
            Point::new(-30.0, -30.0, 0.0),
            Point::new(30.0, 30.0, 200.0),
            3.0,
        )
        .unwrap();
        PartShape::new(m.transformed(pose)).unwrap().0
    }

    /// The rest check on paths with a known end: a part that stopped ends its trial once two
    /// windows are seen; a steady creep that would end at 1.5 mm (a hold, but not well inside
    /// the limit) and a slip accelerating from rest that would end at 2.5 mm (a drop) never
    /// end early; a creep that would end at 0.2 mm does.
    #[test]
    fn a_part_at_rest_ends_its_trial_early_and_a_moving_one_does_not() {
        let dt = 1.0 / 240.0;
        let steps = 240;
        let start = Vector::ZERO;
        // Position after step k (k = 1..=steps) for a path x(t), mm.
        let run = |x: &dyn Fn(f64) -> f64| -> Option<usize> {
            let mut path = Vec::new();
            for k in 1..=steps {
                path.push(Vector::new(x(k as f64 * dt) * 1e-3, 0.0, 0.0));
                if comes_to_rest(&path, &start, steps - k, dt) {
                    return Some(k);
                }
            }
            None
        };
        let w = REST_WINDOW_STEPS;
        // Pushed 0.1 mm by the load at once, then still.
        assert_eq!(run(&|_| 0.1), Some(2 * w + 1));
        // Creeping at 1.5 mm/s, and at 0.2 mm/s.
        assert_eq!(run(&|t| 1.5 * t), None);
        assert!(run(&|t| 0.2 * t).is_some());
        // Accelerating at 5 mm/s² from rest: 2.5 mm after 1 s.
        assert_eq!(run(&|t| 0.5 * 5.0 * t * t), None);
    }

    /// A slab (40 x 60 x 8 mm, 180 g) squeezed between two rows of skin balls pressed 1.5 mm
    /// into its faces (49 a face) and pushed at one edge by 21 balls pressed as deep: each
    /// contact's normal force grows alike with its overlap, so the faces' friction (mu 0.5, on
    /// 98 contacts) can bear four times the edge's push (21): a solid slab stays where it is
    /// and holds. Friction acting only in rapier's unbiased pass let the edge's push slide it
    /// the whole 1.5 mm while settling.
    /// A 40 x 60 x 8 mm slab centred on the origin, thin along z.
    fn slab() -> PartShape {
        let m = super::super::parts::mesh_sdf(
            |p| {
                (p.x.abs() - 20.0)
                    .max(p.y.abs() - 30.0)
                    .max(p.z.abs() - 4.0)
            },
            Point::new(-21.0, -31.0, -5.0),
            Point::new(21.0, 31.0, 5.0),
            1.0,
        )
        .unwrap();
        PartShape::new(m).unwrap().0
    }

    /// Balls of the skin's radius centred at `centres` (each one's surface its radius inside a
    /// surface the centre lies on).
    fn balls_at(centres: &[Point]) -> Vec<Collider> {
        centres
            .iter()
            .map(|c| {
                ColliderBuilder::ball(SKIN_BALL_MM * 1e-3)
                    .translation(v(c))
                    .friction(0.5)
                    .build()
            })
            .collect()
    }

    /// The whole hold test of a 180 g `part` (mu 0.5) against balls at `centres`.
    fn slab_trials(part: &PartShape, centres: &[Point]) -> HoldReport {
        run_trials(balls_at(centres), centres, part, 0.18, 0.5, HoldRun::Whole).unwrap()
    }

    /// 21 ball centres on the slab's +x edge.
    fn edge_centres() -> Vec<Point> {
        let mut centres = Vec::new();
        for j in -3..=3 {
            for z in [-2.0, 0.0, 2.0] {
                centres.push(Point::new(20.0, j as f64 * 3.0, z));
            }
        }
        centres
    }

    #[test]
    fn a_slab_pressed_at_its_edge_between_pressed_faces_stays_put() {
        let part = slab();
        // Ball centres on the surface: each ball's surface its radius (1.5 mm) inside.
        let mut centres = Vec::new();
        for i in -3..=3 {
            for j in -3..=3 {
                let (x, y) = (i as f64 * 3.0, j as f64 * 3.0);
                centres.push(Point::new(x, y, 4.0));
                centres.push(Point::new(x, y, -4.0));
            }
        }
        centres.extend(edge_centres());
        let r = slab_trials(&part, &centres);
        assert!(r.settle_mm < 0.3, "{r:?}");
        assert!(r.holds, "{r:?}");
        assert!(r.trials.iter().all(|t| t.displacement_mm < 0.1), "{r:?}");
    }

    /// Pressed at its edge alone, the slab is pushed straight off the balls while it settles:
    /// the settle motion is a translation along the edge's inward normal (-x) by about the
    /// balls' overlap (1.5 mm), and the report's settle distance is its length.
    #[test]
    fn a_slab_pressed_at_its_edge_alone_settles_away_from_the_push() {
        let part = slab();
        let centres = edge_centres();
        let r = slab_trials(&part, &centres);
        let c = part.centre_of_mass;
        let moved = r.settle_motion * c - c;
        assert!(
            moved.x < 0.0 && moved.x.abs() > 0.95 * moved.norm(),
            "{moved:?}"
        );
        assert!((1.0..2.5).contains(&moved.norm()), "{moved:?}");
        assert!((moved.norm() - r.settle_mm).abs() < 1e-9, "{moved:?} {r:?}");
        assert!(
            r.settle_motion.rotation.angle() < 1f64.to_radians(),
            "{r:?}"
        );
        assert!(!r.holds, "{r:?}");
    }

    fn cylinder() -> PartShape {
        cylinder_at(&nalgebra::Isometry3::identity())
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
        // Held this firmly, the part comes to rest and no direction runs its whole second.
        assert!(r.trials.iter().all(|t| t.at_rest_s.is_some()), "{r:?}");
        // One fingertip touching the side.
        let r = hold_test(&[pad(0.0, 29.9, 60.0)], &part, 0.3, 0.8).unwrap();
        assert!(!r.holds, "{r:?}");
    }

    /// The hold check with the hand: the template hand's power grasp of the 60 mm cylinder
    /// (approach to contact, autograsp, squeeze) holds in all six directions, and the same
    /// hand's index fingertip pressed as deep into the cylinder (the squeeze depth) with
    /// nothing else touching does not: holding needs opposing contacts, not only pressure.
    #[test]
    fn hand_power_grasp_of_the_cylinder_holds_and_a_fingertip_touch_does_not() {
        use crate::anatomy::{Finger, Joint, Side};
        use crate::grasp::autograsp::{autograsp, root_for, squeeze, AutograspOptions, SQUEEZE_MM};
        use crate::grasp::contact::{contacts, vertex_areas};
        use crate::grasp::plan::grasp_plan;
        use crate::grasp::scene::GraspType;
        use crate::grasp::SkinnedHand;
        use crate::skeleton::forward_kinematics::link_transforms;
        use crate::skeleton::Pose;
        use nalgebra::{Isometry3, Translation3, UnitQuaternion};
        let h = SkinnedHand::template(Side::Right).unwrap();
        let (mass, mu) = (0.5, 0.5);
        // The bottle grasp of synth's grasp trials (the shipped scene's given approach until it
        // searched).
        let part = cylinder();
        let approach = crate::grasp::scene::pose_from(
            crate::grasp::parts::BOTTLE_SIDE_APPROACH.0,
            crate::grasp::parts::BOTTLE_SIDE_APPROACH.1,
        );
        let plan = grasp_plan(GraspType::Power);
        let opts = AutograspOptions::default();
        let root = root_for(&h, &Isometry3::identity(), &approach);
        let g = autograsp(&h, &part, &plan, root, &opts).unwrap();
        assert!(g.approach_mm > 0.0, "{}", g.approach_mm);
        let (pose, _, sq) = squeeze(&h, &part, &plan, &g, &opts);
        // The squeeze presses, and never deeper than the phalanges a closing joint carries may
        // sink (the thenar, pressed by the approach, aside).
        let deepest = sq
            .depth_mm
            .iter()
            .filter(|(l, _)| Link::from_name(l).is_some_and(|l| plan.give(l.index()) == 0.0))
            .map(|(_, &d)| d)
            .fold(0.0, f64::max);
        assert!(
            deepest > SQUEEZE_MM - 0.5 && deepest <= opts.wrap_carried_mm + 1e-9,
            "{sq:?}"
        );
        let mut pts = Vec::new();
        h.pose_vertices(&pose, &mut pts);
        let r = hold_test_hand(&h, &pts, &part, mass, mu, HoldRun::Whole).unwrap();
        assert!(r.holds, "{r:?}");
        // Nothing drops, so a run until a drop runs every direction to its end.
        assert_eq!(
            hold_test_hand(&h, &pts, &part, mass, mu, HoldRun::UntilDrop).unwrap(),
            r
        );

        // The index fingertip of the pinch preshape: the skin vertex furthest along the distal
        // phalanx, and a cylinder across that direction sunk SQUEEZE_MM into it.
        let pose = Pose {
            angles: grasp_plan(GraspType::Pinch).preshape,
            root: Isometry3::identity(),
        };
        h.pose_vertices(&pose, &mut pts);
        let tr = link_transforms(h.skeleton(), &pose);
        let dist = Link::IDist.index();
        let tip = tr[dist] * h.skeleton().tips[Finger::Index as usize];
        let dip = tr[dist] * h.skeleton().centre(Joint::IDip);
        let along = (tip - dip).normalize();
        let end = h.link_vertices()[dist]
            .iter()
            .map(|&i| pts[i])
            .max_by(|a, b| along.dot(&a.coords).total_cmp(&along.dot(&b.coords)))
            .unwrap();
        let axis = along.cross(&Vec3::x()).normalize();
        let centre = end + along * (30.0 - SQUEEZE_MM);
        let rot = UnitQuaternion::rotation_between(&Vec3::z(), &axis).unwrap();
        let part = cylinder_at(&Isometry3::from_parts(
            Translation3::from((centre - axis * 100.0).coords),
            rot,
        ));
        let c = contacts(
            &part,
            &pts,
            h.vertex_link(),
            &vertex_areas(h.rest_mesh()),
            &Default::default(),
        );
        let touching: Vec<&str> = Link::ALL
            .iter()
            .filter(|l| c.touches(l.index()))
            .map(|l| l.name())
            .collect();
        assert_eq!(touching, ["I_DIST"]);
        assert!(
            (c.max_depth_mm() - SQUEEZE_MM).abs() < 0.3,
            "{}",
            c.max_depth_mm()
        );
        let r = hold_test_hand(&h, &pts, &part, mass, mu, HoldRun::Whole).unwrap();
        assert!(!r.holds, "{r:?}");
        // A run until a drop agrees; each direction it ran to its end is the full test's (every
        // direction is a world of its own), the others stopped short of it.
        let v = hold_test_hand(&h, &pts, &part, mass, mu, HoldRun::UntilDrop).unwrap();
        assert!(!v.holds, "{v:?}");
        assert!(v.trials.iter().any(|t| !t.holds && !t.cut_short), "{v:?}");
        for (a, b) in v.trials.iter().zip(&r.trials) {
            if a.cut_short {
                // Stopped before it had dropped itself.
                assert!(a.holds && a.at_rest_s.is_none(), "{a:?}");
            } else {
                assert_eq!(a, b);
            }
        }
    }
}
