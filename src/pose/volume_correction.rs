//! Segment-volume preservation for dual-quaternion skinning.
//!
//! # Why DQS alone loses volume at the finger joints
//! Where one joint rotates by θ about axis `a` through its centre and the skinning blends two
//! links, DQS moves a point `x` (relative to the centre) by the rotation `R(φ(x)θ)`, with `φ`
//! the blended weight. The Jacobian of `x ↦ R(φθ)x` is `R(I + θ (a × x) ∇φᵀ)`, so
//! `det J = 1 + θ ∇φ · (a × x)` exactly, and by the divergence theorem the volume change of a
//! region `Ω` is `θ ∫_Ω ∇φ · (a × x) dV = θ ∫ φ′(s) A(s) r̄(s) ds` for weights that vary along
//! the bone only (`s` along the bone, `A` the cross-section's area, `r̄` the distance from the
//! joint axis to the cross-section's centroid, signed toward the dorsal side). The finger
//! joints' axes lie dorsal of the centroid of the finger's cross-section (the palmar pad and
//! flexor tendons are palmar of the bone), so flexion loses `θ A r̄`: in `fist` (MCP 90°,
//! PIP 100°) the proximal phalanges of the template lose 7-18 % of their tissue, measured on
//! the tetrahedral mesh ([`super::quality::segment_volumes`]).
//!
//! # The correction
//! As in volume-preserving skinning with a deformer (Rohmer, Hahmann & Cani 2009, "Exact volume
//! preserving skinning with shape control"), each finger link `l` gets a bulge amplitude `δ_l`
//! and the DQS position `p` of a point with weights `w` moves by
//! `u(p) = (1 − max w) Σ_l w_l δ_l r_l(p)`, with `r_l(p)` the vector from link `l`'s posed bone
//! segment to `p`: a radial swelling of the finger around its bone, zero where a point follows
//! one link rigidly (`max w = 1`), largest in the blended band at the joint, and continuous
//! everywhere (the weights, their maximum and `r_l` are). The amplitudes solve
//! `V_l(δ) = V_l(rest)` for every finger segment by Newton's method on the tetrahedral mesh's
//! segment volumes, with the Jacobian by forward differences (neighbouring segments share the
//! blended band at their joint) and a backtracking line search; a few iterations bring every
//! segment within 0.5 %.
//! The same field then moves the skin's vertices, and the mesh's boundary nodes are placed on
//! that skin ([`super::pose_tet_nodes`]). Where skinning turned the skin of a crease over, the
//! skin is relaxed there first ([`crate::skin::unfold`]), which moves the boundary of the
//! segments on either side; the targets are then corrected by what that moved and the field
//! solved again ([`VolumeRig::pose`]).

use super::quality::{
    finger_volume_changes, inverted_by_link, is_finger_segment, segment_volumes, tet_segments,
};
use super::skinning::{SkinBinding, Skinning};
use super::IndividualHand;
use crate::anatomy::Link;
use crate::error::{Error, Result};
use crate::geometry::tet_mesh::tet_signed_volume;
use crate::geometry::{Point, Topology, TriMesh, Vec3};
use crate::io::Units;
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::{Pose, Skeleton};
use crate::skin::unfold::{bone_carried_normals, unfold_skin, UNFOLD_PASSES};
use crate::template::dominant_links;
use crate::template::{LinkWeights, TemplateHand};
use crate::tet::{
    place_boundary_nodes, untangle, SurfaceBinding, TemplateTet, UntangleOptions, UntangleStats,
};
use nalgebra::{DMatrix, DVector, Isometry3};
use std::path::Path;
use std::sync::OnceLock;

/// Options of [`preserve_segment_volumes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeOptions {
    /// Stop when every finger segment's volume is within this fraction of its rest volume.
    pub tolerance: f64,
    /// At most this many Newton steps.
    pub max_iterations: usize,
}

impl Default for VolumeOptions {
    fn default() -> Self {
        VolumeOptions {
            tolerance: 0.005,
            max_iterations: 8,
        }
    }
}

/// What [`preserve_segment_volumes`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeCorrection {
    /// Bulge amplitude per link over [`Link::ALL`] (0 for links that are not finger segments),
    /// dimensionless (a fraction of the distance from the bone).
    pub amplitude: Vec<f64>,
    /// Newton steps taken.
    pub iterations: usize,
    /// Largest |relative volume change| of a finger segment before the correction (at the
    /// starting amplitudes; zeros: DQS alone).
    pub worst_before: f64,
    /// And after.
    pub worst_after: f64,
}

/// Per point, the bulge basis of the module's field: the mixedness `1 − max w` and, per finger
/// link it is weighted to, `w_l r_l(p)` (the weighted vector from the link's posed bone segment,
/// from its joint centre to the distal end, to the posed point `p`).
pub(crate) struct BulgeBasis {
    mixed: Vec<f64>,
    terms: Vec<Vec<(usize, Vec3)>>,
}

impl BulgeBasis {
    /// The basis at the posed points `posed` with `weights`, for the skeleton `sk` in the rest
    /// posture and the links' `transforms` (from
    /// [`crate::skeleton::forward_kinematics::link_transforms`]).
    pub fn new(
        posed: &[Point],
        weights: &LinkWeights,
        sk: &Skeleton,
        transforms: &[Isometry3<f64>],
    ) -> BulgeBasis {
        let bones: Vec<Option<(Point, Vec3)>> = Link::ALL
            .iter()
            .map(|l| {
                let j = l.joint()?;
                if !is_finger_segment(l.index()) {
                    return None;
                }
                let a = transforms[l.index()] * sk.centre(j);
                let b = transforms[l.index()] * sk.distal_end(j);
                Some((a, b - a))
            })
            .collect();
        let mut mixed = Vec::with_capacity(posed.len());
        let mut terms = Vec::with_capacity(posed.len());
        for (p, w) in posed.iter().zip(weights) {
            let top = w.iter().map(|x| x.1).fold(0.0, f64::max);
            mixed.push(1.0 - top);
            terms.push(
                w.iter()
                    .filter_map(|&(l, wl)| {
                        let (a, ab) = bones.get(l).copied().flatten()?;
                        let s = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                        Some((l, (p - (a + ab * s)) * wl))
                    })
                    .collect(),
            );
        }
        BulgeBasis { mixed, terms }
    }

    /// The points moved by the field with amplitudes `amplitude` (per link).
    pub fn apply(&self, posed: &[Point], amplitude: &[f64]) -> Vec<Point> {
        posed
            .iter()
            .zip(self.mixed.iter().zip(&self.terms))
            .map(|(p, (g, t))| {
                let mut q = *p;
                for (l, r) in t {
                    q += r * (amplitude[*l] * g);
                }
                q
            })
            .collect()
    }
}

/// Amplitudes of the bulge field (see the module documentation) that give every finger segment
/// of a tetrahedral mesh the volume `target` (its rest volume, [`segment_volumes`] of the rest
/// nodes, or that corrected for what follows the field, see [`VolumeRig::pose`]): `posed` are
/// the mesh's DQS-skinned nodes, `basis` the [`BulgeBasis`] at them, `tets` and `labels` the
/// mesh's tetrahedra and their segments ([`super::quality::tet_segments`]). Newton starts from
/// the amplitudes `start` (per link; zeros, or a solve for nearby targets).
pub(crate) fn preserve_segment_volumes(
    posed: &[Point],
    basis: &BulgeBasis,
    tets: &[[usize; 4]],
    labels: &[usize],
    target: &[f64],
    start: &[f64],
    opts: &VolumeOptions,
) -> VolumeCorrection {
    let n = target.len();
    let kept: Vec<usize> = (0..n)
        .filter(|&l| is_finger_segment(l) && target[l] > 0.0)
        .collect();
    let worst = |v: &[f64]| {
        kept.iter()
            .map(|&l| (v[l] / target[l] - 1.0).abs())
            .fold(0.0, f64::max)
    };
    let mut amplitude = start.to_vec();
    let mut v = segment_volumes(&basis.apply(posed, &amplitude), tets, labels, n);
    let worst_before = worst(&v);
    let mut worst_after = worst_before;
    let mut iterations = 0;
    // The forward-difference step: a 2 % swelling of the blended band, small against the
    // amplitudes found (0.2-0.8) and large against rounding.
    const H: f64 = 0.02;
    // Largest change of an amplitude per step: a doubling of the distance from the bone in the
    // blended band, far beyond any swelling that keeps tissue (0.2-0.8 in `fist`).
    const MAX_STEP: f64 = 1.0;
    'newton: while worst_after > opts.tolerance && iterations < opts.max_iterations {
        // Jacobian by forward differences, one amplitude at a time: a segment's volume also
        // depends on its neighbours' amplitudes (the blended band at a joint is shared).
        let m = kept.len();
        let mut jac = DMatrix::<f64>::zeros(m, m);
        for (c, &k) in kept.iter().enumerate() {
            let mut probe = amplitude.clone();
            probe[k] += H;
            let vh = segment_volumes(&basis.apply(posed, &probe), tets, labels, n);
            for (r, &l) in kept.iter().enumerate() {
                jac[(r, c)] = (vh[l] - v[l]) / H;
            }
        }
        let rhs = DVector::from_iterator(m, kept.iter().map(|&l| target[l] - v[l]));
        // A segment without a blended band has a zero row; the least-squares solve (SVD) then
        // leaves its amplitude alone.
        let Ok(sol) = jac
            .svd(true, true)
            .solve(&rhs, 1e-9 * target.iter().fold(0.0, |a: f64, b| a.max(*b)))
        else {
            break;
        };
        let mut step = vec![0.0; n];
        for (c, &k) in kept.iter().enumerate() {
            step[k] = sol[c].clamp(-MAX_STEP, MAX_STEP);
        }
        iterations += 1;
        // Backtrack: a step that makes the worst segment worse is halved (a pose that folds
        // tissue through itself has no swelling that restores it).
        let mut scale = 1.0;
        loop {
            let trial: Vec<f64> = amplitude
                .iter()
                .zip(&step)
                .map(|(a, d)| a + scale * d)
                .collect();
            let vt = segment_volumes(&basis.apply(posed, &trial), tets, labels, n);
            let wt = worst(&vt);
            if wt < worst_after {
                amplitude = trial;
                v = vt;
                worst_after = wt;
                break;
            }
            scale *= 0.5;
            if scale < 0.1 {
                break 'newton;
            }
        }
    }
    VolumeCorrection {
        amplitude,
        iterations,
        worst_before,
        worst_after,
    }
}

/// A hand's tetrahedral mesh ready to pose with [`preserve_segment_volumes`]: its nodes in the
/// reference posture, the template's tetrahedra, boundary binding and node weights (carried to
/// a subject by homology, like the skin's weights), and the segments with their rest volumes.
pub struct VolumeRig {
    /// Nodes in the reference posture (the subject's `tet.vtk`, or the template's), mm.
    pub rest_nodes: Vec<Point>,
    /// Tetrahedra.
    pub tets: Vec<[usize; 4]>,
    /// The boundary nodes' faces and barycentric coordinates on the skin.
    pub binding: SurfaceBinding,
    /// Per node, its link weights ([`super::tet_node_weights`]).
    pub node_weights: LinkWeights,
    /// Per tetrahedron, its segment ([`tet_segments`]).
    pub labels: Vec<usize>,
    /// Per link over [`Link::ALL`], the rest volume of its segment, mm³.
    pub rest_volumes: Vec<f64>,
    /// The skin's topology for relaxing its folds, made once on first use: the contact
    /// resolver asks for the posed skin every round, and every skin posed with this rig has the
    /// template's faces.
    skin_topology: OnceLock<Topology>,
}

/// At most this many times the bulge field is solved again for what relaxing the posed skin's
/// folds took from a segment ([`VolumeRig::pose`]): a second solve brings the segments the
/// relaxation moved within a per cent or so, a third rarely changes anything.
const RELAX_ROUNDS: usize = 2;

/// The posed skin relaxed and the nodes placed on it, before the interior is untangled.
struct Relaxed {
    skin: TriMesh,
    nodes: Vec<Point>,
    correction: VolumeCorrection,
    skin_unfolded: (usize, usize),
}

/// A pose of [`VolumeRig::pose`].
#[derive(Clone, Debug)]
pub struct VolumePose {
    /// The posed skin (DQS, then the bulge field unless it was off).
    pub skin: TriMesh,
    /// The posed tetrahedral mesh's nodes, its boundary on `skin`.
    pub nodes: Vec<Point>,
    /// The amplitudes found (all 0 when the correction was off).
    pub correction: VolumeCorrection,
    /// Relative volume change of each finger segment of the result, as (link, change).
    pub volume_changes: Vec<(Link, f64)>,
    /// What untangling the posed mesh's interior did ([`crate::tet::untangle`]).
    pub untangle: UntangleStats,
    /// Elements still inverted after it, counted per segment, as (link, count), most first.
    pub inverted_by_link: Vec<(Link, usize)>,
    /// Faces of the skinned skin that turned over from their bones' (a joint's weights reaching
    /// across a crease), relaxed before the mesh's boundary was placed on the skin, and those
    /// left turned over ([`crate::skin::unfold::unfold_skin`]).
    pub skin_unfolded: (usize, usize),
}

impl VolumeRig {
    /// The rig of a tet mesh with nodes `rest_nodes` homologous to `prepared`'s (the template's
    /// own or a subject's from [`TemplateTet::deform`]), with the node weights of `template`'s
    /// skin weights ([`super::tet_node_weights`]).
    pub fn new(
        template: &TemplateHand,
        prepared: &TemplateTet,
        rest_nodes: Vec<Point>,
    ) -> Result<VolumeRig> {
        let node_weights = super::tet_node_weights(template, prepared)?;
        Self::from_parts(
            prepared.tet.tets.clone(),
            prepared.binding.clone(),
            node_weights,
            rest_nodes,
        )
    }

    /// The rig of the tetrahedra `tets` with nodes `rest_nodes`, the boundary `binding` on the
    /// skin and the `node_weights` of [`super::tet_node_weights`], all homologous to the
    /// template's.
    pub fn from_parts(
        tets: Vec<[usize; 4]>,
        binding: SurfaceBinding,
        node_weights: LinkWeights,
        rest_nodes: Vec<Point>,
    ) -> Result<VolumeRig> {
        if rest_nodes.len() != node_weights.len() {
            return Err(Error::invalid(format!(
                "tet mesh has {} nodes, the template's {}: not homologous",
                rest_nodes.len(),
                node_weights.len()
            )));
        }
        let labels = tet_segments(&tets, &node_weights);
        let rest_volumes = segment_volumes(&rest_nodes, &tets, &labels, Link::ALL.len());
        Ok(VolumeRig {
            rest_nodes,
            tets,
            binding,
            node_weights,
            labels,
            rest_volumes,
            skin_topology: OnceLock::new(),
        })
    }

    /// `hand` in `pose`: skin and tet nodes dual-quaternion skinned, then (if `correct`) the
    /// bulge field that keeps every finger segment's volume ([`preserve_segment_volumes`])
    /// applied to both; the skin's folds relaxed and the mesh's boundary nodes placed on it, the
    /// interior untangled.
    pub fn pose(
        &self,
        hand: &IndividualHand,
        pose: &Pose,
        correct: bool,
        opts: &VolumeOptions,
    ) -> Result<VolumePose> {
        let n = Link::ALL.len();
        let Relaxed {
            skin,
            mut nodes,
            mut correction,
            skin_unfolded,
        } = self.relaxed(hand, pose, correct, opts)?;
        // Skinning keeps no element positive where a joint bends hard (the palmar creases of a
        // fist): the interior nodes give way where that happens.
        let reference: Vec<f64> = self
            .tets
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.map(|i| self.rest_nodes[i]);
                tet_signed_volume(&a, &b, &c, &d)
            })
            .collect();
        let untangled = untangle(
            &mut nodes,
            &self.tets,
            &self.binding.nodes,
            &reference,
            &UntangleOptions::default(),
        );
        let inverted_by_link = if untangled.inverted_after > 0 {
            inverted_by_link(&nodes, &self.tets, &self.labels)
        } else {
            Vec::new()
        };
        let volume_changes = finger_volume_changes(
            &self.rest_volumes,
            &segment_volumes(&nodes, &self.tets, &self.labels, n),
        );
        // What the result has, boundary placed on the skin included.
        let worst = volume_changes.iter().map(|c| c.1.abs()).fold(0.0, f64::max);
        if !correct {
            correction.worst_before = worst;
        }
        correction.worst_after = worst;
        Ok(VolumePose {
            skin,
            nodes,
            correction,
            volume_changes,
            untangle: untangled,
            inverted_by_link,
            skin_unfolded,
        })
    }

    /// The skin of [`VolumeRig::pose`] with the correction on, as it is written (its folds
    /// relaxed), before the interior is untangled (the skin is all a contact check needs:
    /// [`super::resolve_finger_contacts_on`]). Contacts are resolved on this very skin: the
    /// relaxation moves a crease's skin by up to a few millimetres, and a thumb kept clear of
    /// the folded crease met the relaxed one 2.6 mm deep.
    pub fn corrected_skin(
        &self,
        hand: &IndividualHand,
        pose: &Pose,
        opts: &VolumeOptions,
    ) -> Result<Vec<Point>> {
        Ok(self.relaxed(hand, pose, true, opts)?.skin.vertices)
    }

    /// Skin and tet nodes of [`VolumeRig::pose`] before the interior is untangled: skinned,
    /// corrected if `correct`, the skin's folds relaxed and the boundary nodes placed on it.
    ///
    /// Relaxing a fold moves the skin of a crease, by up to a few millimetres in a fist, and
    /// with it the boundary of the segments on either side, which can lose (or gain) many times
    /// the field's tolerance of what it had given them. So each segment's target is corrected
    /// by what the relaxation took or added and the field solved again, from the amplitudes
    /// found, at most [`RELAX_ROUNDS`] times; the round whose worst segment is closest to its
    /// rest volume is kept.
    fn relaxed(
        &self,
        hand: &IndividualHand,
        pose: &Pose,
        correct: bool,
        opts: &VolumeOptions,
    ) -> Result<Relaxed> {
        let n = Link::ALL.len();
        let mut target = self.rest_volumes.clone();
        let mut start = vec![0.0; n];
        let mut best: Option<(f64, Relaxed)> = None;
        let mut iterations = 0;
        let mut dqs_alone = None;
        for round in 0..=RELAX_ROUNDS {
            let (mut skin, mut nodes, correction) =
                self.skin_and_nodes(hand, pose, correct, opts, &target, &start)?;
            start.clone_from(&correction.amplitude);
            iterations += correction.iterations;
            // DQS alone is the same every round; the first round, from zero amplitudes towards
            // the rest volumes, measured it.
            dqs_alone.get_or_insert(correction.worst_before);
            let skin_unfolded = self.unfold_posed_skin(hand, pose, &mut skin);
            place_boundary_nodes(&self.binding, &skin, &mut nodes)?;
            let volumes = segment_volumes(&nodes, &self.tets, &self.labels, n);
            let changes = finger_volume_changes(&self.rest_volumes, &volumes);
            let worst = changes.iter().map(|c| c.1.abs()).fold(0.0, f64::max);
            if best.as_ref().is_none_or(|(w, _)| worst < *w) {
                let relaxed = Relaxed {
                    skin,
                    nodes,
                    correction,
                    skin_unfolded,
                };
                best = Some((worst, relaxed));
            }
            if !correct || worst <= opts.tolerance || round == RELAX_ROUNDS {
                break;
            }
            for (l, _) in changes {
                let l = l.index();
                target[l] += self.rest_volumes[l] - volumes[l];
            }
        }
        let mut relaxed = best.expect("at least one round").1;
        relaxed.correction.iterations = iterations;
        relaxed.correction.worst_before = dqs_alone.unwrap_or(0.0);
        Ok(relaxed)
    }

    /// `skin`, `hand`'s skin skinned in `pose`, relaxed where a face turned over from its
    /// bone's rotation of its rest face (blended weights can fold the skin through itself at a
    /// crease that two bones pull apart, such as the radial wrist under the thumb's metacarpal
    /// in a pinch): the faces found so and those left.
    fn unfold_posed_skin(
        &self,
        hand: &IndividualHand,
        pose: &Pose,
        skin: &mut TriMesh,
    ) -> (usize, usize) {
        let rotations: Vec<_> = link_transforms(&hand.skeleton, pose)
            .iter()
            .map(|t| t.rotation)
            .collect();
        let rest = &hand.skin;
        let rest_guard: Vec<Vec3> = (0..rest.n_faces()).map(|f| rest.face_cross(f)).collect();
        let guard = bone_carried_normals(rest, &dominant_links(&hand.weights), &rotations);
        let topology = self.skin_topology.get_or_init(|| rest.topology());
        unfold_skin(rest, &rest_guard, skin, &guard, topology, UNFOLD_PASSES, 1)
    }

    /// Skin and tet nodes skinned by DQS and, if `correct`, moved by the bulge field that gives
    /// the finger segments the volumes `target` (Newton from the amplitudes `start`); the
    /// nodes' boundary is not yet on the skin.
    fn skin_and_nodes(
        &self,
        hand: &IndividualHand,
        pose: &Pose,
        correct: bool,
        opts: &VolumeOptions,
        target: &[f64],
        start: &[f64],
    ) -> Result<(TriMesh, Vec<Point>, VolumeCorrection)> {
        let n = Link::ALL.len();
        let tr = link_transforms(&hand.skeleton, pose);
        let mut skin = hand.posed_skin(pose, Skinning::DualQuaternion);
        let raw = SkinBinding::new(&self.rest_nodes, &self.node_weights, n)?.dual_quaternion(&tr);
        let (nodes, correction) = if correct {
            let basis = BulgeBasis::new(&raw, &self.node_weights, &hand.skeleton, &tr);
            let c = preserve_segment_volumes(
                &raw,
                &basis,
                &self.tets,
                &self.labels,
                target,
                start,
                opts,
            );
            skin.vertices = BulgeBasis::new(&skin.vertices, &hand.weights, &hand.skeleton, &tr)
                .apply(&skin.vertices, &c.amplitude);
            (basis.apply(&raw, &c.amplitude), c)
        } else {
            let c = VolumeCorrection {
                amplitude: vec![0.0; n],
                iterations: 0,
                worst_before: 0.0,
                worst_after: 0.0,
            };
            (raw, c)
        };
        Ok((skin, nodes, correction))
    }
}
/// The [`VolumeRig`] of the `reconstruct` folder `model_dir`: its tetrahedral mesh
/// (`tet.vtk`, homologous to the template's) with the template's node weights. Errors naming
/// `tet.vtk` when it is missing or not homologous to the template's tet mesh (made by another
/// version or other stuffing parameters: re-run reconstruct).
pub fn volume_rig(hand: &IndividualHand, model_dir: &Path) -> Result<VolumeRig> {
    let path = model_dir.join("tet.vtk");
    let tet = crate::io::vtk::read_vtk(&path, Units::Millimetres)?;
    let template = crate::template::model_template(model_dir, hand.side)?;
    // The template's tet mesh from the cache and its node weights as reconstruct stored them:
    // the elastic factorisation is made again only when the weights are not in the cache.
    let template_tet = crate::tet::template_tet_mesh(&template, None)?;
    if tet.n_nodes() != template_tet.n_nodes() || tet.tets != template_tet.tets {
        return Err(Error::input(
            &path,
            format!(
                "{} nodes / {} tetrahedra, not homologous to the {} template's tet mesh ({} / {}); \
                 re-run reconstruct",
                tet.n_nodes(),
                tet.n_tets(),
                hand.side,
                template_tet.n_nodes(),
                template_tet.n_tets()
            ),
        ));
    }
    let binding = crate::tet::bind_boundary(&template_tet, &template.mesh)?;
    let weights = match super::cached_tet_node_weights(&template, template_tet.n_nodes()) {
        Some(w) => w,
        None => {
            let prepared = crate::tet::TemplateTet::from_mesh(&template, template_tet.clone())?;
            let w = super::tet_node_weights(&template, &prepared)?;
            super::store_tet_node_weights(&template, &w);
            w
        }
    };
    VolumeRig::from_parts(template_tet.tets, binding, weights, tet.nodes)
}
