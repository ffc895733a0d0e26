//! How hands differ: random, correlated anthropometric variation of the template, applied as a
//! skeleton-driven deformation so that joint centres and axes move with the bones.
//!
//! Model. Hand dimensions are strongly correlated through overall size (hand length and breadth
//! correlate at r ≈ 0.6-0.7, finger segment lengths with hand length at r ≈ 0.7-0.9; Garrett
//! 1971, Kouchi's AIST/HQL hand database, Greiner 1991). We draw log-normal factors as
//! `size × (1 + partial)` with a common size factor (CV 5 %), a length and a breadth factor
//! shared by all links (CV 3 % each), and per-link factors (CV 3-4 %), which gives coefficients
//! of variation of 4-8 % per dimension and correlations of about 0.5-0.8 between them.
//! The thumb's placement varies by a rotation of the thumb ray about its CMC joint
//! (SD 4° per axis), and the 1-DOF joint axes are tilted from the template's (SD 3° about the
//! link's y and z axes), as real flexion axes are not exactly perpendicular to the bones.

use crate::anatomy::{Finger, Joint, Link};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::rng::Rng;
use crate::skeleton::{frame_from_axis, JointFrame, Skeleton};
use crate::template::LinkWeights;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

/// The drawn variation of one subject.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeParams {
    /// Overall size factor.
    pub size: f64,
    /// Per link (index into [`Link::ALL`]): factors on breadth (local x), thickness (local y)
    /// and length (local z), overall size excluded.
    pub link_scale: Vec<[f64; 3]>,
    /// Rotation of the thumb ray about T_CMC, degrees about the CMC frame's x, y, z.
    pub thumb_rotation_deg: [f64; 3],
    /// Tilt of each joint's flexion axis, degrees about its frame's y and z (1-DOF joints only).
    pub axis_tilt_deg: Vec<[f64; 2]>,
}

impl ShapeParams {
    /// The template itself: every factor 1, nothing rotated.
    pub fn identity() -> Self {
        ShapeParams {
            size: 1.0,
            link_scale: vec![[1.0; 3]; Link::ALL.len()],
            thumb_rotation_deg: [0.0; 3],
            axis_tilt_deg: vec![[0.0; 2]; Joint::ALL.len()],
        }
    }

    /// Draw a subject; `spread` scales every standard deviation (1 = the model above).
    pub fn sample(rng: &mut Rng, spread: f64) -> Self {
        let g = |rng: &mut Rng, cv: f64| (rng.normal() * cv * spread).exp();
        let size = g(rng, 0.05);
        let length = g(rng, 0.03);
        let breadth = g(rng, 0.03);
        let mut link_scale = vec![[1.0; 3]; Link::ALL.len()];
        for l in Link::ALL {
            if l == Link::Arm {
                continue;
            }
            // Breadth and thickness of a link co-vary (a fleshy finger is both); length apart.
            let girth = g(rng, 0.03);
            link_scale[l.index()] = [
                breadth * girth * g(rng, 0.015),
                breadth * girth * g(rng, 0.015),
                length * g(rng, 0.035),
            ];
        }
        let thumb_rotation_deg = [0, 1, 2].map(|_| rng.normal() * 4.0 * spread);
        let axis_tilt_deg = Joint::ALL
            .iter()
            .map(|j| {
                if j.dof() == 1 {
                    [rng.normal() * 3.0 * spread, rng.normal() * 3.0 * spread]
                } else {
                    [0.0, 0.0]
                }
            })
            .collect();
        ShapeParams {
            size,
            link_scale,
            thumb_rotation_deg,
            axis_tilt_deg,
        }
    }
}

/// The template deformed to a subject's shape: surface, skeleton and the per-link affine maps.
#[derive(Clone, Debug)]
pub struct ShapedHand {
    /// The deformed surface (same vertices and faces as the template).
    pub mesh: TriMesh,
    /// The subject's skeleton in the template's posture, with tilted 1-DOF axes.
    pub skeleton: Skeleton,
}

/// Deform the template: every link `l` (proximal joint `j`, frame `F`) gets the affine map
/// `A_l(p) = c'_j + R_l F S_l Fᵀ (p - c_j)` with `S_l = size · diag(breadth, thickness, length)`,
/// where the new joint centre `c'_j = A_parent(c_j)` so children follow their parents' growth,
/// and vertices blend the maps of their links with the template's skin weights (linear blend).
pub fn shape_hand(
    mesh: &TriMesh,
    weights: &LinkWeights,
    sk: &Skeleton,
    p: &ShapeParams,
) -> ShapedHand {
    let n = Link::ALL.len();
    let mut lin = vec![Matrix3::identity() * p.size; n];
    let mut origin = vec![sk.centre(Joint::Wrist); n]; // c_j for each link
    let mut new_origin = vec![sk.centre(Joint::Wrist); n]; // c'_j
    let thumb_rot = UnitQuaternion::from_euler_angles(
        p.thumb_rotation_deg[0].to_radians(),
        p.thumb_rotation_deg[1].to_radians(),
        p.thumb_rotation_deg[2].to_radians(),
    );
    for j in Joint::ALL {
        let l = j.child_link().index();
        let parent = j.parent_link().index();
        let f = sk.joint(j).frame.matrix();
        let s = p.link_scale[l];
        let mut m =
            f * Matrix3::from_diagonal(&Vec3::new(s[0], s[1], s[2])) * f.transpose() * p.size;
        if j == Joint::TCmc {
            let fr = UnitQuaternion::from_rotation_matrix(&sk.joint(j).frame);
            m = (fr * thumb_rot * fr.inverse())
                .to_rotation_matrix()
                .matrix()
                * m;
        }
        let c = sk.centre(j);
        lin[l] = m;
        origin[l] = c;
        new_origin[l] = new_origin[parent] + lin[parent] * (c - origin[parent]);
    }
    let apply = |l: usize, q: &Point| -> Point { new_origin[l] + lin[l] * (q - origin[l]) };
    let vertices = mesh
        .vertices
        .iter()
        .zip(weights)
        .map(|(q, w)| {
            let mut acc = Vec3::zeros();
            for &(l, wl) in w {
                acc += apply(l, q).coords * wl;
            }
            Point::from(acc)
        })
        .collect();

    // The new skeleton: centres c'_j, tips carried by their distal links; frames rebuilt from the
    // transformed link axes, 1-DOF axes then tilted.
    let mut centres = [Point::origin(); 16];
    let mut dorsal = [Vec3::zeros(); 16];
    for j in Joint::ALL {
        let l = j.child_link().index();
        centres[j.index()] = new_origin[l];
        dorsal[j.index()] = lin[l] * sk.joint(j).y();
    }
    let mut tips = sk.tips;
    for f in Finger::ALL {
        tips[f as usize] = apply(f.links()[2].index(), &sk.tips[f as usize]);
    }
    let mut skeleton = Skeleton::from_centres(sk.side, &centres, tips, &dorsal)
        .expect("an affine deformation of a valid skeleton stays valid");
    for j in Joint::ALL {
        if j.dof() != 1 {
            continue;
        }
        let jf = *skeleton.joint(j);
        let [ty, tz] = p.axis_tilt_deg[j.index()];
        let tilt =
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(jf.y()), ty.to_radians())
                * Rotation3::from_axis_angle(
                    &nalgebra::Unit::new_normalize(jf.z()),
                    tz.to_radians(),
                );
        let axis = tilt * jf.x();
        skeleton.joints[j.index()] = JointFrame {
            centre: jf.centre,
            frame: frame_from_axis(&axis, &jf.z())
                .expect("a small tilt keeps the axis off the link"),
        };
    }
    ShapedHand {
        mesh: TriMesh {
            vertices,
            faces: mesh.faces.clone(),
        },
        skeleton,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::template::load_template;

    #[test]
    fn identity_params_reproduce_the_template() {
        let t = load_template(Side::Right).unwrap();
        let h = shape_hand(&t.mesh, &t.weights, &t.skeleton, &ShapeParams::identity());
        for (a, b) in h.mesh.vertices.iter().zip(&t.mesh.vertices) {
            assert!((a - b).norm() < 1e-9);
        }
        for j in Joint::ALL {
            assert!((h.skeleton.centre(j) - t.skeleton.centre(j)).norm() < 1e-9);
        }
    }

    #[test]
    fn uniform_size_scales_about_the_wrist() {
        let t = load_template(Side::Right).unwrap();
        let mut p = ShapeParams::identity();
        p.size = 1.1;
        let h = shape_hand(&t.mesh, &t.weights, &t.skeleton, &p);
        let w = t.skeleton.centre(Joint::Wrist);
        for (a, b) in h.mesh.vertices.iter().zip(&t.mesh.vertices) {
            assert!((a - (w + (b - w) * 1.1)).norm() < 1e-9);
        }
        let v0 = t.mesh.signed_volume();
        assert!((h.mesh.signed_volume() / v0 - 1.1f64.powi(3)).abs() < 1e-9);
    }

    #[test]
    fn longer_proximal_phalanx_moves_the_distal_joints() {
        let t = load_template(Side::Right).unwrap();
        let mut p = ShapeParams::identity();
        p.link_scale[Link::IProx.index()][2] = 1.2;
        let h = shape_hand(&t.mesh, &t.weights, &t.skeleton, &p);
        let len = |sk: &Skeleton| (sk.centre(Joint::IPip) - sk.centre(Joint::IMcp)).norm();
        assert!((len(&h.skeleton) / len(&t.skeleton) - 1.2).abs() < 1e-9);
        let dip_shift = h.skeleton.centre(Joint::IDip) - t.skeleton.centre(Joint::IDip);
        let pip_shift = h.skeleton.centre(Joint::IPip) - t.skeleton.centre(Joint::IPip);
        assert!((dip_shift - pip_shift).norm() < 1e-9);
        assert!(pip_shift.norm() > 5.0);
        // Other fingers untouched.
        assert!((h.skeleton.centre(Joint::MPip) - t.skeleton.centre(Joint::MPip)).norm() < 1e-12);
    }

    #[test]
    fn sampled_variation_has_the_intended_spread() {
        let mut rng = Rng::new(5);
        let n = 2000;
        let samples: Vec<ShapeParams> =
            (0..n).map(|_| ShapeParams::sample(&mut rng, 1.0)).collect();
        // Coefficient of variation of a finger segment's length, size included: about
        // sqrt(0.05² + 0.03² + 0.035²) = 6.8 %.
        let lens: Vec<f64> = samples
            .iter()
            .map(|p| p.size * p.link_scale[Link::MProx.index()][2])
            .collect();
        let mean = lens.iter().sum::<f64>() / n as f64;
        let sd = (lens.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let cv = sd / mean;
        assert!((0.055..0.08).contains(&cv), "{cv}");
    }
}
