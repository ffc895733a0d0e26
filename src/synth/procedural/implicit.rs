//! The procedural hand's skin as an implicit surface: a signed distance (approximate, negative
//! inside, about unit gradient near the surface) built from simple anatomical solids, each
//! carried rigidly by its link, blended with a smooth minimum.
//!
//! Solids (after the surface anatomy of the hand, e.g. Kapandji vol. 1 and Tubiana, *The Hand*):
//! * every phalanx a tapered capsule with elliptic sections (breadth > thickness) whose centre
//!   lies a little palmar of the bone (joint centres at 45-55 % of the thickness from the dorsal
//!   skin); the distal phalanx ends in a palmar pulp reaching beyond the bone's tip and is
//!   flattened dorsally over its distal two thirds (the nail plate);
//! * knuckle bumps: small spheres over the dorsal side of every MCP, PIP and DIP (and the thumb's);
//! * the palm: a slab with rounded edges whose section widens from the wrist to the metacarpal
//!   heads and is bent into the transverse arch; the hypothenar eminence on its ulnar palmar side
//!   and the thenar eminence over the thumb's metacarpal;
//! * web spaces: thickened sheets between neighbouring proximal phalanges, on their palmar side,
//!   reaching a third of the way along them, and the first web space from the thumb's metacarpal
//!   and MCP to the index;
//! * a forearm stub with an elliptic section.
//!
//! Blending: the polynomial smooth minimum of Quilez (2013, "smooth minimum") within the palm's
//! solids, within each digit, and between each digit and the palm; digits are joined with each
//! other by a plain minimum, so fingers that do not touch stay apart.
//! Distances of ellipsoids and elliptic capsules use Quilez's ellipsoid bound `k0 (k0 - 1) / k1`.

use super::proportions::Proportions;
use super::skeleton::{pulp_length, BodySkeleton};
use crate::anatomy::{Finger, Joint, Link};
use crate::geometry::closest_point::closest_point_triangle;
use crate::geometry::{Point, Vec3};
use crate::skeleton::Skeleton;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};

/// Polynomial smooth minimum of Quilez: equals `min(a, b)` when they differ by more than `k`,
/// and rounds the crease within `k` of it.
pub fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// Smooth maximum (intersection), the mirror of [`smin`].
pub(crate) fn smax(a: f64, b: f64, k: f64) -> f64 {
    -smin(-a, -b, k)
}

/// Quilez's distance bound of an ellipsoid with semi-axes `r` at the origin, from `q`.
fn ellipsoid(q: &Vec3, r: &Vec3) -> f64 {
    let k0 = Vec3::new(q.x / r.x, q.y / r.y, q.z / r.z).norm();
    let k1 = Vec3::new(q.x / (r.x * r.x), q.y / (r.y * r.y), q.z / (r.z * r.z)).norm();
    if k1 < 1e-12 {
        return -r.min();
    }
    k0 * (k0 - 1.0) / k1
}

/// A tapered capsule along local +z from 0 to `len`: half-breadth (x) and half-thickness (y)
/// linear from `w0, h0` to `w1, h1`, the section centre at `v0 .. v1` along y, closed by
/// half-ellipsoids of length `cap0` (proximal) and `cap1` (distal); optionally flattened
/// dorsally (a nail plate) from `nail_from` along z at `nail` of the local half-thickness.
#[derive(Clone, Debug)]
pub struct Capsule {
    pub len: f64,
    pub w: [f64; 2],
    pub h: [f64; 2],
    pub v: [f64; 2],
    pub cap: [f64; 2],
    pub nail: Option<(f64, f64)>,
}

impl Capsule {
    fn distance(&self, q: &Vec3) -> f64 {
        let t = (q.z / self.len).clamp(0.0, 1.0);
        let lerp = |a: [f64; 2]| a[0] + (a[1] - a[0]) * t;
        let (w, h, v) = (lerp(self.w), lerp(self.h), lerp(self.v));
        let (ez, c) = if q.z < 0.0 {
            (q.z, self.cap[0])
        } else if q.z > self.len {
            (q.z - self.len, self.cap[1])
        } else {
            (0.0, 1.0)
        };
        let d = ellipsoid(&Vec3::new(q.x, q.y - v, ez), &Vec3::new(w, h, c));
        match self.nail {
            Some((from, level)) => {
                // The plate rises toward the proximal end so that it fades out there.
                let plane = q.y - v - level * h - (from - q.z).max(0.0) * 0.6;
                smax(d, plane, 1.5)
            }
            None => d,
        }
    }
}

/// The palm slab in the palm link's frame (the body frame; see [`super::skeleton`]).
#[derive(Clone, Debug)]
pub struct PalmSlab {
    /// Wrist (y = 0) and metacarpal-head (y = `y_heads`) sections: half-width, half-thickness,
    /// centre x and z.
    pub wrist: [f64; 4],
    pub heads: [f64; 4],
    pub y_heads: f64,
    /// Proximal end (inside the forearm).
    pub y_start: f64,
    /// Distal end: (x, y) breakpoints, increasing x; constant beyond the ends.
    pub distal: Vec<(f64, f64)>,
    /// Transverse arch: the section's mid-line drops by `arch * u²` at `u` from the centre.
    pub arch: f64,
    /// Radius of the rounding of the distal and proximal edges.
    pub end_round: f64,
}

impl PalmSlab {
    fn distal_end(&self, x: f64) -> f64 {
        let d = &self.distal;
        if x <= d[0].0 {
            return d[0].1;
        }
        for w in d.windows(2) {
            if x <= w[1].0 {
                let t = (x - w[0].0) / (w[1].0 - w[0].0);
                return w[0].1 + (w[1].1 - w[0].1) * t;
            }
        }
        d[d.len() - 1].1
    }

    fn distance(&self, q: &Vec3) -> f64 {
        let t = (q.y / self.y_heads).clamp(0.0, 1.0);
        // Widens quickly beyond the wrist, then evenly to the heads.
        let grow = 1.0 - (1.0 - t) * (1.0 - t);
        let mix = |k: usize, s: f64| self.wrist[k] + (self.heads[k] - self.wrist[k]) * s;
        let a = mix(0, grow);
        // The hollow of the palm: thinner in the middle.
        let b = mix(1, t) * (1.0 - 0.08 * (std::f64::consts::PI * t).sin());
        let (xc, zc) = (mix(2, grow), mix(3, t));
        let u = q.x - xc;
        let v = q.z - zc + self.arch * u * u;
        let r = 0.8 * b;
        let (qx, qy) = (u.abs() - (a - r), v.abs() - (b - r));
        let section = (qx.max(0.0).hypot(qy.max(0.0)) + qx.max(qy).min(0.0)) - r;
        let along = (self.y_start - q.y).max(q.y - self.distal_end(q.x));
        let rr = self.end_round;
        let (e0, e1) = (section + rr, along + rr);
        e0.max(0.0).hypot(e1.max(0.0)) + e0.max(e1).min(0.0) - rr
    }
}

/// One solid.
#[derive(Clone, Debug)]
pub enum Shape {
    Capsule(Capsule),
    /// Semi-axes along the local axes.
    Ellipsoid(Vec3),
    Palm(PalmSlab),
    /// Triangles (already posed) thickened by `radius`.
    Sheet(Vec<[Point; 3]>, f64),
}

/// A solid and the rigid map from the posed hand into its local frame.
#[derive(Clone, Debug)]
pub struct Solid {
    pub to_local: Isometry3<f64>,
    pub shape: Shape,
}

impl Solid {
    fn distance(&self, p: &Point) -> f64 {
        let q = (self.to_local * p).coords;
        match &self.shape {
            Shape::Capsule(c) => c.distance(&q),
            Shape::Ellipsoid(r) => ellipsoid(&q, r),
            Shape::Palm(s) => s.distance(&q),
            Shape::Sheet(tris, r) => {
                let p = Point::from(q);
                tris.iter()
                    .map(|[a, b, c]| (closest_point_triangle(&p, a, b, c).0 - p).norm())
                    .fold(f64::INFINITY, f64::min)
                    - r
            }
        }
    }
}

/// Smooth union of a group of solids.
fn group(solids: &[Solid], p: &Point, k: f64) -> f64 {
    solids
        .iter()
        .map(|s| s.distance(p))
        .fold(f64::INFINITY, |acc, d| {
            if acc.is_finite() {
                smin(acc, d, k)
            } else {
                d
            }
        })
}

/// The whole skin field of a posed hand.
#[derive(Clone, Debug)]
pub struct HandField {
    /// Forearm, palm, hypothenar, finger webs, knuckles of the metacarpal heads.
    pub core: Vec<Solid>,
    /// Thenar eminence and first web space (blended into the core).
    pub thumb_base: Vec<Solid>,
    /// Per digit (thumb first): phalanges and their knuckles.
    pub digits: [Vec<Solid>; 5],
}

/// Blend radii, mm: within the palm, of the thumb's base into it, within a digit, of a finger
/// (and the thumb) into the palm.
const K_CORE: f64 = 9.0;
const K_THUMB_BASE: f64 = 7.0;
const K_DIGIT: f64 = 1.5;
const K_FINGER: f64 = 5.0;
const K_THUMB: f64 = 7.0;

impl HandField {
    /// Signed distance (approximate) of the skin at `p`: negative inside.
    pub fn distance(&self, p: &Point) -> f64 {
        self.distance_with(p, true)
    }

    /// The field without the thumb, its thenar eminence and first web space: what a caliper
    /// across the metacarpal heads or the wrist touches.
    pub fn distance_without_thumb(&self, p: &Point) -> f64 {
        self.distance_with(p, false)
    }

    fn distance_with(&self, p: &Point, thumb: bool) -> f64 {
        let mut core = group(&self.core, p, K_CORE);
        if thumb {
            core = smin(core, group(&self.thumb_base, p, K_CORE), K_THUMB_BASE);
        }
        let mut d = core;
        for (i, digit) in self.digits.iter().enumerate() {
            if i == 0 && !thumb {
                continue;
            }
            let k = if i == 0 { K_THUMB } else { K_FINGER };
            d = d.min(smin(core, group(digit, p, K_DIGIT), k));
        }
        d
    }

    /// One digit's own solids alone (no palm): negative inside that digit.
    pub fn digit_distance(&self, f: Finger, p: &Point) -> f64 {
        group(&self.digits[f as usize], p, K_DIGIT)
    }

    /// Outward unit normal: the normalised gradient by central differences.
    pub fn normal(&self, p: &Point) -> Vec3 {
        let e = 0.02;
        let g = Vec3::new(
            self.distance(&(p + Vec3::x() * e)) - self.distance(&(p - Vec3::x() * e)),
            self.distance(&(p + Vec3::y() * e)) - self.distance(&(p - Vec3::y() * e)),
            self.distance(&(p + Vec3::z() * e)) - self.distance(&(p - Vec3::z() * e)),
        );
        g.try_normalize(1e-12).unwrap_or_else(Vec3::z)
    }
}

/// Isometry from a local frame (columns x, y, z at `origin`) of the neutral hand, carried by the
/// link motion `link`, back into that local frame.
fn local_frame(link: &Isometry3<f64>, origin: &Point, frame: &Rotation3<f64>) -> Isometry3<f64> {
    let local_to_neutral = Isometry3::from_parts(
        Translation3::from(origin.coords),
        UnitQuaternion::from_rotation_matrix(frame),
    );
    (link * local_to_neutral).inverse()
}

/// A right-handed frame with z along `long` and y toward `dorsal`.
fn frame(long: &Vec3, dorsal: &Vec3) -> Rotation3<f64> {
    let z = long.normalize();
    let y = (dorsal - z * dorsal.dot(&z)).normalize();
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[y.cross(&z), y, z]))
}

/// Build the skin field of the right hand `bs` with proportions `p`, posed by the link motions
/// `tf` (from [`crate::skeleton::forward_kinematics::link_transforms`] on the neutral skeleton);
/// `posed` is the posed skeleton (for the webs, which span two links).
pub fn build_field(
    p: &Proportions,
    bs: &BodySkeleton,
    tf: &[Isometry3<f64>],
    posed: &Skeleton,
) -> HandField {
    let sk = &bs.skeleton;
    let (hl, hb) = (p.hand_length, p.hand_breadth);
    let palm_tf = tf[Link::Palm.index()];
    let arm_tf = tf[Link::Arm.index()];
    let mut core = Vec::new();

    // Forearm stub: an elliptic cylinder widening a little proximally, ending 0.3 hand lengths
    // before the wrist.
    let fa_len = 0.3 * hl;
    let fa_frame = frame(&-Vec3::y(), &Vec3::z());
    core.push(Solid {
        to_local: local_frame(&arm_tf, &Point::new(0.0, 4.0, 0.0), &fa_frame),
        shape: Shape::Capsule(Capsule {
            len: fa_len + 4.0,
            w: [0.5 * p.wrist_breadth, 0.54 * p.wrist_breadth],
            h: [0.5 * p.wrist_thickness, 0.53 * p.wrist_thickness],
            v: [0.0, 0.0],
            cap: [0.5 * p.wrist_thickness, 8.0],
            nail: None,
        }),
    });

    // Palm.
    let heads: Vec<Point> = Finger::ALL[1..]
        .iter()
        .map(|f| sk.centre(f.joints()[0]))
        .collect();
    let pt = p.palm_thickness;
    let y_heads = sk.centre(Joint::MMcp).y;
    // The slab ends a rounding radius beyond the heads, so that its rounded end does not narrow
    // the palm across the heads (the hand breadth).
    let end_round = 0.35 * pt;
    let mut distal: Vec<(f64, f64)> = heads.iter().map(|c| (c.x, c.y + end_round)).collect();
    distal.sort_by(|a, b| a.0.total_cmp(&b.0));
    core.push(Solid {
        to_local: palm_tf.inverse(),
        shape: Shape::Palm(PalmSlab {
            wrist: [0.5 * p.wrist_breadth, 0.5 * p.wrist_thickness, 0.0, 0.0],
            heads: [0.5 * hb, 0.5 * pt, 0.10 * hb, -0.08 * pt],
            y_heads,
            y_start: -6.0,
            distal,
            arch: 0.0035 * 90.0 / hb,
            end_round,
        }),
    });
    // Hypothenar eminence: ulnar, palmar, over the 5th metacarpal's proximal two thirds.
    core.push(Solid {
        to_local: local_frame(
            &palm_tf,
            &Point::new(0.36 * hb, 0.20 * hl, -0.32 * pt),
            &Rotation3::identity(),
        ),
        shape: Shape::Ellipsoid(Vec3::new(0.12 * hb, 0.15 * hl, 0.30 * pt)),
    });
    // Knuckles over the metacarpal heads.
    for f in &Finger::ALL[1..] {
        let i = *f as usize;
        let r = 0.36 * p.sections[i][0];
        let c = sk.centre(f.joints()[0]) + Vec3::z() * (0.42 * pt + 1.0 - r);
        core.push(Solid {
            to_local: local_frame(&palm_tf, &c, &Rotation3::identity()),
            shape: Shape::Ellipsoid(Vec3::new(r, r, r * 1.1)),
        });
    }
    // Finger webs: palmar sheets between neighbouring proximal phalanges, to a third of them.
    let palmar_point = |f: Finger, along: f64| -> Point {
        let [mcp, pip, _] = f.joints();
        let (a, b) = (posed.centre(mcp), posed.centre(pip));
        let t = p.sections[f as usize][1];
        a + (b - a) * along - posed.joint(mcp).y() * (0.18 * t)
    };
    for pair in Finger::ALL[1..].windows(2) {
        let (fa, fb) = (pair[0], pair[1]);
        let r = 0.28 * (p.sections[fa as usize][1] + p.sections[fb as usize][1]) * 0.5;
        let third =
            |f: Finger| (p.segments[f as usize][1] / 3.0 - 0.5 * r) / p.segments[f as usize][1];
        let (a0, a1) = (palmar_point(fa, 0.0), palmar_point(fa, third(fa)));
        let (b0, b1) = (palmar_point(fb, 0.0), palmar_point(fb, third(fb)));
        core.push(Solid {
            to_local: Isometry3::identity(),
            shape: Shape::Sheet(vec![[a0, a1, b1], [a0, b1, b0]], r),
        });
    }

    // Thumb base: thenar eminence over the metacarpal, palmar and toward the palm.
    let mut thumb_base = Vec::new();
    let meta_tf = tf[Link::TMeta.index()];
    let (cmc, tmcp) = (sk.centre(Joint::TCmc), sk.centre(Joint::TMcp));
    let mc = tmcp - cmc;
    let thenar_c = cmc + mc * 0.40 + Vec3::x() * (0.10 * hb) - Vec3::z() * (0.06 * hb);
    thumb_base.push(Solid {
        to_local: local_frame(&meta_tf, &thenar_c, &frame(&mc, &Vec3::z())),
        shape: Shape::Ellipsoid(Vec3::new(0.17 * hb, 0.12 * hb, 0.55 * mc.norm())),
    });
    // First web space: a sheet from the thumb's metacarpal and MCP to the index's base.
    {
        let t_ip = posed.centre(Joint::TIp);
        let (pc, pm) = (posed.centre(Joint::TCmc), posed.centre(Joint::TMcp));
        let (im, ip) = (posed.centre(Joint::IMcp), posed.centre(Joint::IPip));
        let ibase = palm_tf * bs.metacarpal_bases[0];
        let a = pc + (pm - pc) * 0.55;
        let b = pm + (t_ip - pm) * 0.15;
        let c = im + (ip - im) * 0.12 - posed.joint(Joint::IMcp).y() * (0.15 * p.sections[1][1]);
        let d = ibase + (im - ibase) * 0.5;
        let r = 0.22 * p.sections[0][1];
        thumb_base.push(Solid {
            to_local: Isometry3::identity(),
            shape: Shape::Sheet(vec![[a, b, c], [a, c, d]], r),
        });
    }

    // Digits.
    let digits: [Vec<Solid>; 5] = std::array::from_fn(|i| {
        let f = Finger::ALL[i];
        let s = p.sections[i];
        let seg = p.segments[i];
        let joints = f.joints();
        let mut out = Vec::new();
        // Half-breadth / half-thickness at the proximal joint, the middle joint, the distal one
        // and the tip, in the order of the digit's three links.
        let (b_mid, t_mid) = (0.5 * s[0], 0.5 * s[1]);
        let (b_dist, t_dist) = (0.5 * s[2], 0.5 * s[3]);
        let sections: [([f64; 2], [f64; 2]); 3] = if f == Finger::Thumb {
            [
                ([1.05 * b_mid, 1.02 * b_mid], [1.05 * t_mid, t_mid]),
                ([1.02 * b_mid, b_mid], [t_mid, 0.98 * t_mid]),
                ([0.97 * b_mid, 0.92 * b_mid], [0.92 * t_mid, 0.72 * t_mid]),
            ]
        } else {
            [
                ([0.98 * b_mid, b_mid], [1.04 * t_mid, t_mid]),
                ([b_mid, b_dist], [t_mid, t_dist]),
                ([b_dist, 0.93 * b_dist], [t_dist, 0.8 * t_dist]),
            ]
        };
        for (k, &j) in joints.iter().enumerate() {
            let link_tf = tf[j.child_link().index()];
            let a = sk.centre(j);
            let b = sk.distal_end(j);
            let long = b - a;
            let fr = frame(&long, &sk.joint(j).y());
            let (w, h) = sections[k];
            let is_dist = k == 2;
            // The thumb's metacarpal is a bone inside the thenar: a plain round capsule.
            let (w, h) = if f == Finger::Thumb && k == 0 {
                ([0.55 * s[0], 0.5 * s[0]], [0.5 * s[1], 0.48 * s[1]])
            } else {
                (w, h)
            };
            let palmar = if is_dist {
                [-0.04, -0.16]
            } else {
                [-0.04, -0.04]
            };
            let cap_end = if is_dist {
                pulp_length(p, f) + 0.15 * h[1]
            } else {
                h[1]
            };
            out.push(Solid {
                to_local: local_frame(&link_tf, &a, &fr),
                shape: Shape::Capsule(Capsule {
                    len: long.norm(),
                    w,
                    h,
                    v: [palmar[0] * 2.0 * h[0], palmar[1] * 2.0 * h[1]],
                    cap: [h[0], cap_end],
                    nail: is_dist.then_some((0.3 * seg[3], 0.8)),
                }),
            });
            // Knuckle bump over the next joint, on this link (thumb: over MCP and IP).
            if k < 2 {
                let next = joints[k + 1];
                let (nb, nt) = (sections[k + 1].0[0], sections[k + 1].1[0]);
                let r = 0.55 * nb.min(nt);
                let c = sk.centre(next) + sk.joint(next).y() * (0.92 * nt + 0.7 - r);
                out.push(Solid {
                    to_local: local_frame(&link_tf, &c, &fr),
                    shape: Shape::Ellipsoid(Vec3::new(r * 1.1, r, r * 1.2)),
                });
            }
        }
        out
    });
    HandField {
        core,
        thumb_base,
        digits,
    }
}
