//! The link model as the tracker moves it: the palm as the root (its rigid pose in the lab),
//! the wrist and every digit joint by its angles, each joint with the degrees of freedom the
//! link model gives it.
//!
//! The palm, not the forearm, is the root because every motion trial carries palm markers
//! (`PALM_n`, the MCP knuckles), while forearm markers are optional: the forearm follows the
//! palm through the inverse of the wrist's rotation, so the wrist's angles are only asked of
//! the data when forearm markers are seen. Angles are those of
//! [`crate::skeleton::forward_kinematics`] (radians, zero in the reference posture, the
//! Grood-Suntay order `[flexion, abduction, axial]`), so a [`HandState`] is a
//! [`Pose`] ([`Kinematics::pose`]) and poses the skin as any other.
//!
//! [`Kinematics::evaluate`] gives every link's transform and, for the Jacobian, every
//! rotational degree of freedom as a world axis through a world centre: the derivative of a
//! point `p` moved by angle `a` is `axis × (p - centre)` (analytic, no differencing).

use crate::anatomy::{Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use crate::skeleton::record::parse_link_model;
use crate::skeleton::{Pose, Skeleton};
use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion};
use std::path::Path;

/// Most parameters of a hand: the palm's 6, the wrist's 3, five digits of 3 + 1 + 1.
pub const MAX_PARAMS: usize = 34;

/// The tracked quantities of one frame: the palm's rigid motion from the reference posture
/// (lab frame) and every joint's angles, radians.
#[derive(Clone, Debug, PartialEq)]
pub struct HandState {
    /// Palm link transform: reference posture -> lab.
    pub palm: Isometry3<f64>,
    /// Per joint ([`Joint::index`]): `[flexion, abduction, axial]`.
    pub angles: [[f64; 3]; 16],
}

impl HandState {
    /// The reference posture with the palm at `palm`.
    pub fn at(palm: Isometry3<f64>) -> HandState {
        HandState {
            palm,
            angles: [[0.0; 3]; 16],
        }
    }
}

/// The link model, ready to move: skeleton, degrees of freedom and parameter layout.
#[derive(Clone, Debug)]
pub struct Kinematics {
    /// Joint centres and frames in the reference posture.
    pub skeleton: Skeleton,
    /// Degrees of freedom per joint as the link model says (3: flexion, abduction, axial; 2:
    /// flexion and abduction; 1: the hinge), never more than the joint has.
    pub dof: [usize; 16],
    /// Per joint and DOF, the parameter index (after the palm's 6), `None` for a fixed DOF.
    pub param: [[Option<usize>; 3]; 16],
    /// Number of parameters.
    pub n_params: usize,
    signs: [[f64; 3]; 16],
    /// Per link, the joints between the palm and it, proximal first (the wrist for the arm).
    chains: Vec<Vec<Joint>>,
}

/// Read `OUT/link_model.json` (spec section 3): the skeleton and each joint's `dof`. Errors
/// name the file and the joint or field.
pub fn load_link_model(model_dir: &Path) -> Result<Kinematics> {
    let path = model_dir.join("link_model.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::input(
                &path,
                "file not found: --model must be a reconstruct output folder",
            ))
        }
        Err(e) => return Err(Error::io(&path, e)),
    };
    let (skeleton, joints) = parse_link_model(&text, &path)?;
    let mut dof = [0usize; 16];
    for j in Joint::ALL {
        let r = &joints[j.name()];
        if !(1..=3).contains(&r.dof) {
            return Err(Error::input(
                &path,
                format!("joint {j}: 'dof' is {} (expected 1, 2 or 3)", r.dof),
            ));
        }
        dof[j.index()] = r.dof.min(j.dof());
    }
    Ok(Kinematics::new(skeleton, dof))
}

impl Kinematics {
    /// A model of `skeleton` whose joints have `dof` degrees of freedom each (clamped to the
    /// joint's own: a hinge never gains any).
    pub fn new(skeleton: Skeleton, dof: [usize; 16]) -> Kinematics {
        let mut param = [[None; 3]; 16];
        let mut n = 6;
        let mut dofs = [0; 16];
        let mut signs = [[0.0; 3]; 16];
        for j in Joint::ALL {
            let d = dof[j.index()].clamp(1, j.dof());
            dofs[j.index()] = d;
            for slot in param[j.index()].iter_mut().take(d) {
                *slot = Some(n);
                n += 1;
            }
            signs[j.index()] = skeleton.signs(j);
        }
        let chains = Link::ALL
            .iter()
            .map(|&l| {
                let mut c = Vec::new();
                let mut cur = l;
                if l == Link::Arm {
                    return vec![Joint::Wrist];
                }
                while cur != Link::Palm {
                    let j = cur.joint().expect("below the palm");
                    c.push(j);
                    cur = j.parent_link();
                }
                c.reverse();
                c
            })
            .collect();
        Kinematics {
            skeleton,
            dof: dofs,
            param,
            n_params: n,
            signs,
            chains,
        }
    }

    /// A model with every joint's own DOF ([`Joint::dof`]).
    pub fn full(skeleton: Skeleton) -> Kinematics {
        let dof = Joint::ALL.map(|j| j.dof());
        Kinematics::new(skeleton, dof)
    }

    /// The joints between the palm and `link`, proximal first (`[WRIST]` for the forearm,
    /// whose markers move by the wrist's inverse).
    pub fn chain(&self, link: Link) -> &[Joint] {
        &self.chains[link.index()]
    }

    /// `state` as a [`Pose`]: the forearm's motion is the palm's with the wrist undone.
    pub fn pose(&self, state: &HandState) -> Pose {
        let t = self.evaluate(state);
        Pose {
            angles: state.angles,
            root: t.links[Link::Arm.index()],
        }
    }

    /// Link transforms and the world axes of every degree of freedom in `state`.
    pub fn evaluate(&self, state: &HandState) -> Evaluated {
        let sk = &self.skeleton;
        let mut links = [Isometry3::identity(); 17];
        let mut axes = [[Vec3::zeros(); 3]; 16];
        let mut centres = [Point::origin(); 16];
        links[Link::Palm.index()] = state.palm;
        let rot =
            |axis: Vec3, a: f64| UnitQuaternion::from_axis_angle(&Unit::new_unchecked(axis), a);
        for j in Joint::ALL {
            let jf = sk.joint(j);
            let s = self.signs[j.index()];
            let a = state.angles[j.index()];
            let (x, y, z) = (jf.x(), jf.y(), jf.z());
            let q0 = rot(x, s[0] * a[0]);
            let q1 = rot(y, s[1] * a[1]);
            let q2 = rot(z, s[2] * a[2]);
            let r = q0 * q1 * q2;
            let c = jf.centre.coords;
            let about = Isometry3::from_parts(Translation3::from(c - r * c), r);
            if j == Joint::Wrist {
                // The forearm: palm with the wrist undone. Derivatives of p = G (c + Rᵀ v):
                // -s_k (R_G M_k e_k) × (p - G c) with M = [Rzᵀ Ryᵀ, Rzᵀ, I].
                let g = state.palm;
                links[Link::Arm.index()] = g * about.inverse();
                let rg = g.rotation;
                let (i1, i2) = (q1.inverse(), q2.inverse());
                axes[0] = [
                    -(rg * (i2 * (i1 * x))) * s[0],
                    -(rg * (i2 * y)) * s[1],
                    -(rg * z) * s[2],
                ];
                centres[0] = g * jf.centre;
                continue;
            }
            let tp = links[j.parent_link().index()];
            links[j.child_link().index()] = tp * about;
            let rp = tp.rotation;
            axes[j.index()] = [
                rp * x * s[0],
                rp * (q0 * y) * s[1],
                rp * (q0 * (q1 * z)) * s[2],
            ];
            centres[j.index()] = tp * jf.centre;
        }
        Evaluated {
            links,
            axes,
            centres,
        }
    }

    /// Posed joint centres of `state`, lab frame (each moves with the link on its parent
    /// side, about which it turns).
    pub fn centres(&self, state: &HandState) -> [Point; 16] {
        let e = self.evaluate(state);
        Joint::ALL.map(|j| {
            if j == Joint::Wrist {
                state.palm * self.skeleton.centre(j)
            } else {
                e.centres[j.index()]
            }
        })
    }

    /// Apply a parameter step: the palm turns by `delta[0..3]` (rotation vector) about its
    /// posed wrist centre and moves by `delta[3..6]`; angles add.
    pub fn step(&self, state: &HandState, delta: &[f64]) -> HandState {
        let mut out = state.clone();
        let cw = state.palm * self.skeleton.centre(Joint::Wrist);
        let w = Vec3::new(delta[0], delta[1], delta[2]);
        let t = Vec3::new(delta[3], delta[4], delta[5]);
        let q = UnitQuaternion::from_scaled_axis(w);
        let about = Isometry3::from_parts(Translation3::from(cw.coords + t - q * cw.coords), q);
        out.palm = about * state.palm;
        // Keep the rotation unit: products of many steps drift, and scale the hand.
        out.palm.rotation.renormalize();
        for j in Joint::ALL {
            for d in 0..3 {
                if let Some(k) = self.param[j.index()][d] {
                    out.angles[j.index()][d] += delta[k];
                }
            }
        }
        out
    }
}

/// A state evaluated: link transforms and, per joint and DOF, the world axis of its
/// derivative (sign included) and the world centre it turns about.
#[derive(Clone, Debug)]
pub struct Evaluated {
    /// Link transforms, reference posture -> lab, by [`Link::index`].
    pub links: [Isometry3<f64>; 17],
    /// Per joint and DOF: `dp/da = axis × (p - centre)`.
    pub axes: [[Vec3; 3]; 16],
    /// Per joint: the posed centre (the wrist's: its centre on the palm).
    pub centres: [Point; 16],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::forward_kinematics::link_transforms;

    fn state() -> HandState {
        let mut s = HandState::at(Isometry3::from_parts(
            Translation3::new(10.0, -20.0, 30.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.5),
        ));
        for (k, a) in s.angles.iter_mut().enumerate() {
            *a = [0.1 + 0.03 * k as f64, -0.05 * (k % 3 + 1) as f64, 0.07];
            if Joint::ALL[k].dof() == 1 {
                *a = [a[0], 0.0, 0.0];
            }
        }
        s
    }

    /// The pose of a state moves every link as the skeleton's own forward kinematics does,
    /// and the analytic derivatives match central differences.
    #[test]
    fn transforms_and_derivatives_agree_with_the_skeleton() {
        let sk = crate::template::load_template(crate::anatomy::Side::Right)
            .unwrap()
            .skeleton;
        let k = Kinematics::full(sk.clone());
        let s1 = state();
        let e = k.evaluate(&s1);
        let pose = k.pose(&s1);
        let t = link_transforms(&sk, &pose);
        for l in Link::ALL {
            let d = (t[l.index()].to_homogeneous() - e.links[l.index()].to_homogeneous()).norm();
            assert!(d < 1e-9, "{l}: {d}");
        }
        // Derivatives of a point on every link by every DOF of its chain.
        let h = 1e-6;
        for l in Link::ALL {
            let p_ref = sk.centre(Joint::MMcp) + Vec3::new(3.0, 5.0, -7.0);
            for &j in k.chain(l) {
                for d in 0..k.dof[j.index()] {
                    let mut a = s1.clone();
                    let mut b = s1.clone();
                    a.angles[j.index()][d] += h;
                    b.angles[j.index()][d] -= h;
                    let num = (k.evaluate(&a).links[l.index()] * p_ref
                        - k.evaluate(&b).links[l.index()] * p_ref)
                        / (2.0 * h);
                    let p = e.links[l.index()] * p_ref;
                    let ana = e.axes[j.index()][d].cross(&(p - e.centres[j.index()]));
                    assert!((num - ana).norm() < 1e-5, "{l} {j} {d}: {num} vs {ana}");
                }
            }
        }
        // The palm step: a rotation about the posed wrist centre.
        let delta = [1e-6, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut full = vec![0.0; k.n_params];
        full[..6].copy_from_slice(&delta);
        let moved = k.step(&s1, &full);
        let cw = s1.palm * sk.centre(Joint::Wrist);
        assert!((moved.palm * sk.centre(Joint::Wrist) - cw).norm() < 1e-9);
        assert_eq!(k.n_params, MAX_PARAMS);
    }
}
