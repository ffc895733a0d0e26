//! A shape prior for the skin where no marker and no caliper reaches: the palmar palm, the
//! thenar and hypothenar eminences, the fingertip pulp.
//!
//! The landmark fit (seed paper section 3.5) moves the template only where a landmark or a
//! caliper pair pulls; elsewhere the surface follows the template's shape through the fit's
//! smoothness. What is left is the template's own shape where the subject's differs. The prior
//! learns that remainder from a population whose true surfaces are known (CT-like references):
//!
//! 1. per training subject, the fitted skin's **normal offset** to the reference at every
//!    template vertex ([`normal_offsets`]: along the vertex normal, to the nearest facing surface,
//!    both directions), filled where no ray finds the reference and smoothed over the vertex
//!    rings;
//! 2. a principal component analysis of these fields (the mean field and `K` modes, the
//!    covariance taken over the subjects: Turk & Pentland's small-sample trick);
//! 3. a ridge regression from what the capture measures of the subject's size and tissue (the
//!    caliper dimensions, and the dorsal tissue depth at each joint between its landmark marker
//!    and the link model's joint: [`subject_features`], logarithms, standardised) to the mode
//!    scores, as anthropometric hand models predict shape from dimensions (Kouchi & Mochimaru's
//!    homologous-model PCA);
//! 4. `K` and the ridge chosen by leave-one-out cross-validation over the training subjects
//!    ([`train_shape_prior`]).
//!
//! At fit time ([`ShapePrior::predict`]) the field predicted from the subject's features is
//! added along the fitted skin's normals, before the caliper rounds measure it, so that the
//! calipers still read their given values and the landmarks, where the field learned almost no
//! offset, stay on their markers.
//!
//! A prior is data: the one shipped with the generic template is trained on simulated
//! subjects of both bodies that no validation subject shares (the README says which and how
//! to train another, e.g. from a lab's own CT scans).

use super::unfold::{half_ring_step, relax_folds};
use crate::anatomy::Dimension;
use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, Topology, TriMesh, Vec3};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Rays look this far along and against a vertex normal for the reference surface, mm.
pub(crate) const OFFSET_REACH_MM: f64 = 12.0;

/// A hit counts when its face's normal is within this angle's cosine of the vertex normal
/// (the surface the vertex stands for, not a neighbouring digit's back).
const FACING_COS: f64 = 0.5;

/// Smoothing passes over the vertex rings applied to each training field (a reference is a
/// voxel scan, rough at its resolution).
pub const SMOOTHING_PASSES: usize = 4;

/// How far from the training population's mean, in its standard deviations, a subject's
/// feature is still read as it is ([`ShapePrior::predict`]); the README gives the figures
/// this was chosen on.
pub const FEATURE_LIMIT_SD: f64 = 5.0;

/// Offsets stored to this resolution, mm.
const STORED_RESOLUTION_MM: f64 = 0.01;

/// Per vertex of `skin`: the signed distance along its unit normal to the nearest surface of
/// `reference` that faces the same way, within [`OFFSET_REACH_MM`] (positive: the reference
/// lies outside the skin). `None` where no ray meets such a surface.
pub fn normal_offsets(skin: &TriMesh, reference: &TriMesh) -> Vec<Option<f64>> {
    let tree = AabbTree::new(reference);
    let face_normals = reference.face_normals();
    let normals = skin.vertex_normals();
    let facing = |hit: Option<crate::geometry::closest_point::RayHit>, n: &Vec3| {
        hit.filter(|h| face_normals[h.face].dot(n) >= FACING_COS)
            .map(|h| h.t)
    };
    skin.vertices
        .par_iter()
        .zip(normals.par_iter())
        .map(|(v, n)| {
            if n.norm_squared() == 0.0 {
                return None;
            }
            let out = facing(tree.ray_cast(v, n, 0.0, OFFSET_REACH_MM), n);
            let inn = facing(tree.ray_cast(v, &-n, 0.0, OFFSET_REACH_MM), n).map(|t| -t);
            match (out, inn) {
                (Some(a), Some(b)) => Some(if a <= -b { a } else { b }),
                (a, b) => a.or(b),
            }
        })
        .collect()
}

/// `field` with its missing values filled from their neighbours (repeatedly, over `rings`) and
/// then averaged with them `passes` times (uniform Laplacian smoothing). Vertices no path
/// reaches from a known value get 0.
pub fn fill_and_smooth(field: &[Option<f64>], rings: &[Vec<usize>], passes: usize) -> Vec<f64> {
    let mut known: Vec<Option<f64>> = field.to_vec();
    loop {
        let mut changed = false;
        let next: Vec<Option<f64>> = (0..known.len())
            .map(|i| {
                known[i].or_else(|| {
                    let vals: Vec<f64> = rings[i].iter().filter_map(|&j| known[j]).collect();
                    (!vals.is_empty()).then(|| vals.iter().sum::<f64>() / vals.len() as f64)
                })
            })
            .collect();
        for (a, b) in known.iter().zip(&next) {
            changed |= a.is_none() && b.is_some();
        }
        known = next;
        if !changed {
            break;
        }
    }
    let mut x: Vec<f64> = known.into_iter().map(|v| v.unwrap_or(0.0)).collect();
    for _ in 0..passes {
        x = (0..x.len()).map(|i| half_ring_step(&x, rings, i)).collect();
    }
    x
}

/// One training subject: its features and its fitted skin's normal offsets to its
/// reference (from a fit made without a prior).
#[derive(Clone, Debug)]
pub struct PriorSample {
    /// Name shown in the cross-validation table.
    pub name: String,
    /// The subject's features ([`subject_features`]).
    pub features: BTreeMap<String, f64>,
    /// Per template vertex, filled and smoothed ([`fill_and_smooth`]), mm.
    pub offsets: Vec<f64>,
    /// Per template vertex: whether a ray found the reference there (only those are scored).
    pub measured: Vec<bool>,
}

/// The trained prior: a normal-offset field per template vertex predicted from the subject's
/// features (see the module documentation).
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapePrior {
    /// What the file is.
    pub format: String,
    /// Vertices of the template the prior belongs to.
    pub vertices: usize,
    /// Training subjects, by name.
    pub trained_on: Vec<String>,
    /// The features the regression reads ([`subject_features`]).
    pub features: Vec<String>,
    /// Per feature: mean and standard deviation over the training subjects.
    pub feature_mean: Vec<f64>,
    pub feature_sd: Vec<f64>,
    /// Ridge parameter chosen by cross-validation.
    pub ridge: f64,
    /// Mean field, in units of [`STORED_RESOLUTION_MM`].
    pub mean: Vec<i32>,
    /// Modes (unit norm), each per vertex, scaled by 1e4 and rounded.
    pub modes: Vec<Vec<i32>>,
    /// Per mode: the regression's coefficients on the standardised features, mm of score per
    /// feature SD.
    pub coefficients: Vec<Vec<f64>>,
    /// Leave-one-out figures of the training (RMS of the offset field over measured vertices,
    /// without and with the prior, per subject), mm.
    pub cross_validation: Vec<CrossValidation>,
}

/// A training subject's leave-one-out figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrossValidation {
    pub subject: String,
    /// RMS of its offsets (what the fit without a prior leaves), mm.
    pub without_mm: f64,
    /// RMS of its offsets minus the field a prior trained without it predicts, mm.
    pub with_mm: f64,
}

const FORMAT: &str = "ergohand shape prior 1";
const MODE_SCALE: f64 = 1e4;

/// A joint as the link model gives it, for the tissue-depth features: its centre and, for a
/// hinge, its axis.
#[derive(Clone, Debug)]
pub struct JointLine {
    pub centre: Point,
    pub axis: Option<Vec3>,
}

/// The features a prior may read of a subject, by name: `ln(value)` of each caliper dimension
/// (its `subject.toml` key), and `depth:JOINT`, the logarithm of the dorsal tissue depth at each
/// joint's landmark (its marker's distance from the joint's centre, or from a hinge's axis, less
/// the marker's offset; at least 1 mm). `joints` are the link model the skin stage receives: the
/// one it writes has its hinges moved onto the fitted skin, so depths read there depend on the
/// fit.
pub fn subject_features(
    dimensions: &BTreeMap<Dimension, f64>,
    markers: &BTreeMap<String, Point>,
    joints: &BTreeMap<String, JointLine>,
    marker_offset_mm: f64,
) -> BTreeMap<String, f64> {
    let mut f: BTreeMap<String, f64> = dimensions
        .iter()
        .filter(|(_, v)| **v > 0.0)
        .map(|(d, v)| (d.name(), v.ln()))
        .collect();
    for (name, j) in joints {
        let Some(m) = markers.get(name) else { continue };
        let r = m - j.centre;
        let d = match j.axis.and_then(|a| a.try_normalize(0.0)) {
            Some(a) => (r - a * r.dot(&a)).norm(),
            None => r.norm(),
        };
        if d.is_finite() {
            f.insert(
                format!("depth:{name}"),
                (d - marker_offset_mm).max(1.0).ln(),
            );
        }
    }
    f
}

/// The standardised features: each centred and scaled by the training population's; a missing
/// one reads as the population's mean.
fn standardise(
    features: &BTreeMap<String, f64>,
    names: &[String],
    mean: &[f64],
    sd: &[f64],
) -> DVector<f64> {
    DVector::from_iterator(
        names.len(),
        names
            .iter()
            .enumerate()
            .map(|(k, n)| match features.get(n) {
                Some(v) => (v - mean[k]) / sd[k],
                None => 0.0,
            }),
    )
}

/// The mean field and the leading principal modes of a set of fields, with each field's scores.
/// The first `k` modes of a PCA do not depend on how many are kept, and each mode's regression
/// is separate, so one PCA serves every `(k, ridge)` of the cross-validation's grid.
struct Pca {
    mean: DVector<f64>,
    /// V × K_max, unit columns.
    modes: DMatrix<f64>,
    /// n × K_max.
    scores: DMatrix<f64>,
}

impl Pca {
    /// The mean of `fields` and their `k` leading modes (at most `n - 1`).
    fn new(fields: &[&DVector<f64>], k: usize) -> Pca {
        let n = fields.len();
        let v = fields[0].len();
        let mut mean = DVector::zeros(v);
        for x in fields {
            mean += *x;
        }
        mean /= n as f64;
        let centred = DMatrix::from_fn(v, n, |i, j| fields[j][i] - mean[i]);
        let k = k.min(n.saturating_sub(1));
        let mut modes = DMatrix::zeros(v, k);
        if k > 0 {
            // The subjects' Gram matrix has the covariance's non-zero eigenvalues (n << v).
            let gram = centred.transpose() * &centred;
            let eig = SymmetricEigen::new(gram);
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
            for (c, &e) in order.iter().take(k).enumerate() {
                let u = &centred * eig.eigenvectors.column(e);
                let norm = u.norm();
                if norm > 0.0 {
                    modes.set_column(c, &(u / norm));
                }
            }
        }
        let scores = centred.transpose() * &modes;
        Pca {
            mean,
            modes,
            scores,
        }
    }

    /// The ridge regression of the first `k` modes' scores on the standardised features `zm`
    /// (n × F, rows as the fields), K × F.
    fn coefficients(&self, zm: &DMatrix<f64>, k: usize, ridge: f64) -> DMatrix<f64> {
        let k = k.min(self.modes.ncols());
        let f = zm.ncols();
        if k == 0 {
            return DMatrix::zeros(0, f);
        }
        let a = zm.transpose() * zm + DMatrix::identity(f, f) * ridge;
        let b = zm.transpose() * self.scores.columns(0, k);
        a.cholesky()
            .map(|c| c.solve(&b).transpose())
            .unwrap_or_else(|| DMatrix::zeros(k, f))
    }

    /// The field predicted for standardised features `z` by the first `coefficients.nrows()`
    /// modes.
    fn predict(&self, coefficients: &DMatrix<f64>, z: &DVector<f64>) -> DVector<f64> {
        let k = coefficients.nrows();
        &self.mean + self.modes.columns(0, k) * (coefficients * z)
    }
}

/// The features of `z`'s subjects as rows (n × F).
fn feature_rows(z: &[&DVector<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(z.len(), z.first().map_or(0, |r| r.len()), |i, j| z[i][j])
}

/// RMS of `a - b` over the `measured` entries.
fn rms(a: &DVector<f64>, b: Option<&DVector<f64>>, measured: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for i in 0..a.len() {
        if measured[i] {
            let d = a[i] - b.map_or(0.0, |b| b[i]);
            s += d * d;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// Modes tried by the cross-validation.
pub(crate) const MODE_CHOICES: [usize; 9] = [0, 1, 2, 3, 4, 6, 8, 12, 16];
/// Ridge parameters tried by the cross-validation (on standardised features).
pub(crate) const RIDGE_CHOICES: [f64; 7] = [0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0];

/// Train a prior on `samples` (at least 3, all of the same template): the number of modes from
/// [`MODE_CHOICES`] and the ridge from [`RIDGE_CHOICES`] that give the least mean leave-one-out
/// RMS, and the leave-one-out figures of that choice.
pub fn train_shape_prior(samples: &[PriorSample]) -> Result<ShapePrior> {
    if samples.len() < 3 {
        return Err(Error::invalid(format!(
            "a shape prior needs at least 3 training subjects, got {}",
            samples.len()
        )));
    }
    let v = samples[0].offsets.len();
    if let Some(s) = samples.iter().find(|s| s.offsets.len() != v) {
        return Err(Error::invalid(format!(
            "training subject {} has {} skin vertices, the first has {v}: not the same template",
            s.name,
            s.offsets.len()
        )));
    }
    // Features most subjects have (a lab may skip a dimension).
    let mut count: BTreeMap<&String, usize> = BTreeMap::new();
    for s in samples {
        for k in s.features.keys() {
            *count.entry(k).or_default() += 1;
        }
    }
    let names: Vec<String> = count
        .into_iter()
        .filter(|(_, c)| c * 2 >= samples.len())
        .map(|(k, _)| k.clone())
        .collect();
    let (mut fmean, mut fsd) = (Vec::new(), Vec::new());
    for n in &names {
        let xs: Vec<f64> = samples
            .iter()
            .filter_map(|s| s.features.get(n).copied())
            .collect();
        let m = xs.iter().sum::<f64>() / xs.len() as f64;
        let sd = (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / xs.len() as f64).sqrt();
        fmean.push(m);
        fsd.push(sd.max(1e-6));
    }
    let fields: Vec<DVector<f64>> = samples
        .iter()
        .map(|s| DVector::from_column_slice(&s.offsets))
        .collect();
    let z: Vec<DVector<f64>> = samples
        .iter()
        .map(|s| standardise(&s.features, &names, &fmean, &fsd))
        .collect();
    // Per left-out subject: one PCA of the others with the most modes tried, then every
    // (modes, ridge) of the grid.
    let grid: Vec<(usize, f64)> = MODE_CHOICES
        .iter()
        .flat_map(|&k| {
            RIDGE_CHOICES
                .iter()
                .filter(move |&&r| k > 0 || r == RIDGE_CHOICES[0])
                .map(move |&r| (k, r))
        })
        .collect();
    let k_max = MODE_CHOICES.iter().copied().max().unwrap_or(0);
    let per_subject: Vec<Vec<CrossValidation>> = (0..samples.len())
        .into_par_iter()
        .map(|out| {
            let idx: Vec<usize> = (0..samples.len()).filter(|&i| i != out).collect();
            let f: Vec<&DVector<f64>> = idx.iter().map(|&i| &fields[i]).collect();
            let zm = feature_rows(&idx.iter().map(|&i| &z[i]).collect::<Vec<_>>());
            let pca = Pca::new(&f, k_max);
            let without_mm = rms(&fields[out], None, &samples[out].measured);
            grid.iter()
                .map(|&(k, ridge)| {
                    let p = pca.predict(&pca.coefficients(&zm, k, ridge), &z[out]);
                    CrossValidation {
                        subject: samples[out].name.clone(),
                        without_mm,
                        with_mm: rms(&fields[out], Some(&p), &samples[out].measured),
                    }
                })
                .collect()
        })
        .collect();
    let mut best: Option<(f64, usize, f64, Vec<CrossValidation>)> = None;
    for (g, &(k, ridge)) in grid.iter().enumerate() {
        let cv: Vec<CrossValidation> = per_subject.iter().map(|c| c[g].clone()).collect();
        let score = cv.iter().map(|c| c.with_mm).sum::<f64>() / cv.len() as f64;
        log::debug!("shape prior: {k} modes, ridge {ridge}: leave-one-out RMS {score:.3} mm");
        if best.as_ref().is_none_or(|b| score < b.0) {
            best = Some((score, k, ridge, cv));
        }
    }
    let (_, k, ridge, cv) = best.expect("the grid is not empty");
    let all: Vec<&DVector<f64>> = fields.iter().collect();
    let pca = Pca::new(&all, k);
    let coefficients = pca.coefficients(&feature_rows(&z.iter().collect::<Vec<_>>()), k, ridge);
    let quantise = |x: f64, s: f64| (x * s).round() as i32;
    Ok(ShapePrior {
        format: FORMAT.to_string(),
        vertices: v,
        trained_on: samples.iter().map(|s| s.name.clone()).collect(),
        features: names,
        feature_mean: fmean,
        feature_sd: fsd,
        ridge,
        mean: pca
            .mean
            .iter()
            .map(|x| quantise(*x, 1.0 / STORED_RESOLUTION_MM))
            .collect(),
        modes: (0..pca.modes.ncols())
            .map(|c| {
                pca.modes
                    .column(c)
                    .iter()
                    .map(|x| quantise(*x, MODE_SCALE))
                    .collect()
            })
            .collect(),
        coefficients: (0..coefficients.nrows())
            .map(|r| coefficients.row(r).iter().copied().collect())
            .collect(),
        cross_validation: cv,
    })
}

impl std::fmt::Debug for ShapePrior {
    /// The summary ([`ShapePrior::summary`]), which names the content: the fields are long.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.summary())
    }
}

impl ShapePrior {
    /// One line that says what the prior is and names its content (an FNV-1a hash of its
    /// numbers), for reports and input fingerprints.
    pub fn summary(&self) -> String {
        let mut h = crate::io::fingerprint::Fnv1a::default();
        let numbers = self
            .mean
            .iter()
            .chain(self.modes.iter().flatten())
            .map(|x| *x as f64)
            .chain(self.coefficients.iter().flatten().copied())
            .chain(self.feature_mean.iter().chain(&self.feature_sd).copied());
        for x in numbers {
            h.update(&x.to_le_bytes());
        }
        format!(
            "shape prior of {} subjects, {} modes, ridge {} (fnv1a {:016x})",
            self.trained_on.len(),
            self.modes.len(),
            self.ridge,
            h.finish()
        )
    }

    /// Read a prior from JSON; `label` names the source in errors.
    pub fn from_json(bytes: &[u8], label: &std::path::Path) -> Result<ShapePrior> {
        let p: ShapePrior = serde_json::from_slice(bytes)
            .map_err(|e| Error::input(label, format!("not a shape prior: {e}")))?;
        if p.format != FORMAT {
            return Err(Error::input(
                label,
                format!("format '{}' is not '{FORMAT}'", p.format),
            ));
        }
        let f = p.features.len();
        if p.feature_mean.len() != f
            || p.feature_sd.len() != f
            || p.mean.len() != p.vertices
            || p.modes.len() != p.coefficients.len()
            || p.modes.iter().any(|m| m.len() != p.vertices)
            || p.coefficients.iter().any(|c| c.len() != f)
        {
            return Err(Error::input(
                label,
                "the sizes of mean, modes, coefficients and features disagree",
            ));
        }
        if let Some(n) = p.features.iter().find(|n| {
            let depth = n.strip_prefix("depth:");
            Dimension::from_name(n).is_none()
                && depth.is_none_or(|j| crate::anatomy::Joint::from_name(j).is_none())
        }) {
            return Err(Error::input(
                label,
                format!("feature '{n}' is not one ergohand knows"),
            ));
        }
        Ok(p)
    }

    /// The prior shipped with the generic template (see the module documentation).
    pub fn builtin() -> Arc<ShapePrior> {
        static PRIOR: std::sync::OnceLock<Arc<ShapePrior>> = std::sync::OnceLock::new();
        PRIOR
            .get_or_init(|| {
                Arc::new(
                    ShapePrior::from_json(
                        BUILTIN_JSON.as_bytes(),
                        std::path::Path::new("assets/generic-hand/shape-prior.json"),
                    )
                    .expect("the shipped shape prior is valid (a test reads it)"),
                )
            })
            .clone()
    }

    /// The subject's features standardised by the training population's mean and SD.
    fn standardised(&self, features: &BTreeMap<String, f64>) -> DVector<f64> {
        standardise(
            features,
            &self.features,
            &self.feature_mean,
            &self.feature_sd,
        )
    }

    /// Every feature the prior reads, by name, with the subject's value standardised by the
    /// training population (training SDs from its mean; a missing feature reads 0), in the
    /// prior's feature order.
    pub fn standard_scores(&self, features: &BTreeMap<String, f64>) -> Vec<(String, f64)> {
        let z = self.standardised(features);
        self.features
            .iter()
            .cloned()
            .zip(z.iter().copied())
            .collect()
    }

    /// The features of a subject that lie more than `limit_sd` training SDs from the training
    /// mean, each with its standardised value, in the prior's feature order.
    pub fn outside(&self, features: &BTreeMap<String, f64>, limit_sd: f64) -> Vec<(String, f64)> {
        self.standard_scores(features)
            .into_iter()
            .filter(|(_, v)| v.abs() > limit_sd)
            .collect()
    }

    /// The normal offset per template vertex predicted for a subject with these features
    /// ([`subject_features`]), mm. A feature beyond [`FEATURE_LIMIT_SD`] is read at that limit:
    /// a linear model extrapolated far outside its training population predicts offsets no
    /// training hand showed, and such a feature is more often a wrong caliper or a slipped
    /// marker than a hand that unusual.
    pub fn predict(&self, features: &BTreeMap<String, f64>) -> Vec<f64> {
        let z = self
            .standardised(features)
            .map(|v| v.clamp(-FEATURE_LIMIT_SD, FEATURE_LIMIT_SD));
        let scores: Vec<f64> = self
            .coefficients
            .iter()
            .map(|c| c.iter().zip(z.iter()).map(|(a, b)| a * b).sum())
            .collect();
        (0..self.vertices)
            .map(|i| {
                self.mean[i] as f64 * STORED_RESOLUTION_MM
                    + self
                        .modes
                        .iter()
                        .zip(&scores)
                        .map(|(m, s)| m[i] as f64 / MODE_SCALE * s)
                        .sum::<f64>()
            })
            .collect()
    }
}

/// A face counts as folded by a displacement when its normal turns by more than this angle's
/// cosine (60°) or its area falls below [`FOLD_AREA_RATIO`] of the face's before.
const FOLD_COS: f64 = 0.5;

/// See [`FOLD_COS`].
const FOLD_AREA_RATIO: f64 = 0.25;

/// The displacement that moves every vertex of `mesh` (whose [`Topology`] is `topology`) by
/// `offsets[i]` along its unit normal, relaxed where it would fold the surface, and the number
/// of faces still folded after `max_passes` relaxations over a fixed neighbourhood (the folded
/// faces' vertices and one ring: the field is smoothed only where it folds, and what it leaves
/// turned over the skin's own unfolding relaxes, [`super::unfold::unfold_skin`]). `guard`
/// holds, per face, a direction its normal must keep facing (the template's face carried by
/// its bone); a face already turned away before is left to the fit's own fold check.
///
/// A normal offset folds a surface wherever it exceeds the local radius of curvature (an
/// inward offset on a ridge, an outward one in a crease): the offset surface of a ridge 3 mm
/// lower is not the ridge's normal offset. Where a face would turn by more than 60° or shrink
/// to a quarter, the displacement of its vertices and their rings is averaged with the
/// neighbours' (half a uniform-Laplacian step, on the 3D vectors, so that converging normals
/// cancel), and the test repeated; elsewhere the offsets stay exactly as predicted.
pub fn fold_free_displacement(
    mesh: &TriMesh,
    topology: &Topology,
    offsets: &[f64],
    guard: &[Vec3],
    max_passes: usize,
) -> (Vec<Vec3>, usize) {
    let normals = mesh.vertex_normals();
    let mut d: Vec<Vec3> = normals.iter().zip(offsets).map(|(n, s)| n * *s).collect();
    let folded = |f: usize, d: &[Vec3]| -> bool {
        let p = mesh.faces[f].map(|v| mesh.vertices[v] + d[v]);
        let (a, b) = (mesh.face_cross(f), (p[1] - p[0]).cross(&(p[2] - p[0])));
        let g = guard[f];
        a.dot(&b) < FOLD_COS * a.norm() * b.norm()
            || b.norm() < FOLD_AREA_RATIO * a.norm()
            || (g.dot(&a) > 0.0 && g.dot(&b) <= 0.0)
    };
    let left = relax_folds(mesh, topology, &mut d, folded, max_passes, 1);
    (d, left)
}

static BUILTIN_JSON: &str = include_str!("../../assets/generic-hand/shape-prior.json");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skin::unfold::UNFOLD_PASSES;

    fn sphere(r: f64) -> TriMesh {
        crate::geometry::mesh::tests::icosphere(r, 3)
    }

    /// Concentric spheres: the offset along every normal is the difference of the radii, up to
    /// the facets' sagitta (the vertices sit on the true sphere, the facets inside it).
    #[test]
    fn normal_offsets_of_concentric_spheres_are_the_radii_apart() {
        // The references turned a little, so that no ray runs exactly through one of their
        // vertices (both spheres share the icosahedron's directions).
        let turn = nalgebra::Isometry3::rotation(Vec3::new(0.05, 0.11, 0.07));
        let (skin, outer, inner) = (
            sphere(20.0),
            sphere(23.0).transformed(&turn),
            sphere(18.0).transformed(&turn),
        );
        // A face of a level-3 icosphere of radius r spans about 0.16 r: sagitta < 0.004 r.
        for (reference, expect) in [(&outer, 3.0), (&inner, -2.0)] {
            let d = normal_offsets(&skin, reference);
            for (i, x) in d.iter().enumerate() {
                let x = x.unwrap_or_else(|| panic!("vertex {i}: no hit on radius {expect}"));
                assert!((x - expect).abs() < 0.15, "{x} vs {expect}");
            }
        }
        // Out of reach: no offset.
        let far = sphere(20.0 + OFFSET_REACH_MM + 1.0);
        assert!(normal_offsets(&skin, &far).iter().all(Option::is_none));
    }

    /// A surface facing the other way (the back of a neighbouring digit) is not taken.
    #[test]
    fn normal_offsets_ignore_surfaces_facing_away() {
        let skin = sphere(10.0);
        let mut flipped = sphere(13.0);
        for f in &mut flipped.faces {
            f.swap(1, 2);
        }
        assert!(normal_offsets(&skin, &flipped).iter().all(Option::is_none));
    }

    fn face_normals(m: &TriMesh, d: &[Vec3]) -> Vec<Vec3> {
        m.faces
            .iter()
            .map(|f| {
                let p = f.map(|v| m.vertices[v] + d[v]);
                (p[1] - p[0]).cross(&(p[2] - p[0]))
            })
            .collect()
    }

    /// Offsets that fold nothing come back exactly as normal offsets.
    #[test]
    fn fold_free_displacement_keeps_offsets_that_fold_nothing() {
        let m = sphere(10.0);
        let offsets: Vec<f64> = m.vertices.iter().map(|v| 0.1 * v.z).collect();
        let guard = face_normals(&m, &vec![Vec3::zeros(); m.n_vertices()]);
        let (d, folded) =
            fold_free_displacement(&m, &m.topology(), &offsets, &guard, UNFOLD_PASSES);
        assert_eq!(folded, 0);
        for ((x, n), s) in d.iter().zip(m.vertex_normals()).zip(&offsets) {
            assert!((x - n * *s).norm() < 1e-12);
        }
    }

    /// An inward offset deeper than the radius on a cap of a sphere turns the cap inside out
    /// along the normals; relaxed, no face faces inward and the far side keeps its offsets.
    #[test]
    fn fold_free_displacement_unfolds_an_offset_beyond_the_radius() {
        let r = 5.0;
        let m = sphere(r);
        let offsets: Vec<f64> = m
            .vertices
            .iter()
            .map(|v| if v.z > 0.5 * r { -1.2 * r } else { 0.0 })
            .collect();
        let before = face_normals(&m, &vec![Vec3::zeros(); m.n_vertices()]);
        let naive: Vec<Vec3> = m
            .vertex_normals()
            .iter()
            .zip(&offsets)
            .map(|(n, s)| n * *s)
            .collect();
        let turned = |d: &[Vec3]| {
            face_normals(&m, d)
                .iter()
                .zip(&before)
                .filter(|(b, a)| a.dot(b) < 0.0)
                .count()
        };
        assert!(turned(&naive) > 10, "the naive offsets fold the cap");
        let (d, folded) =
            fold_free_displacement(&m, &m.topology(), &offsets, &before, UNFOLD_PASSES);
        eprintln!(
            "naive {} turned, relaxed {} turned, {folded} folded",
            turned(&naive),
            turned(&d)
        );
        assert_eq!(folded, 0);
        assert_eq!(turned(&d), 0);
        // The cap still moves in: relaxing spreads the dent, it does not undo it.
        let top = (0..m.n_vertices())
            .max_by(|&a, &b| m.vertices[a].z.total_cmp(&m.vertices[b].z))
            .unwrap();
        assert!(d[top].z < -0.25 * r, "the top moved {:.2} mm", d[top].z);
        for (v, x) in m.vertices.iter().zip(&d) {
            if v.z < -0.5 * r {
                assert_eq!(*x, Vec3::zeros());
            }
        }
    }

    #[test]
    fn fill_and_smooth_fills_gaps_and_keeps_a_constant() {
        let m = sphere(10.0);
        let rings = m.topology().vertex_rings;
        let field: Vec<Option<f64>> = (0..m.n_vertices())
            .map(|i| (i % 3 != 0).then_some(1.5))
            .collect();
        let out = fill_and_smooth(&field, &rings, 4);
        assert!(out.iter().all(|x| (x - 1.5).abs() < 1e-12));
        // Nothing known: zero.
        let none = fill_and_smooth(&vec![None; m.n_vertices()], &rings, 2);
        assert!(none.iter().all(|x| *x == 0.0));
    }

    fn feats(d: &BTreeMap<Dimension, f64>) -> BTreeMap<String, f64> {
        subject_features(d, &BTreeMap::new(), &BTreeMap::new(), 4.0)
    }

    fn dims(scale: f64, thick: f64) -> BTreeMap<Dimension, f64> {
        Dimension::all()
            .into_iter()
            .enumerate()
            .map(|(k, d)| {
                let base = 15.0 + k as f64;
                let v = if d == Dimension::HandThicknessMc3 {
                    30.0 * thick
                } else {
                    base
                };
                (d, v * scale)
            })
            .collect()
    }

    /// The cross-validation's shortcut: one PCA with the most modes, truncated to `k` and
    /// regressed with a ridge, predicts what a PCA of `k` modes from scratch does (the leading
    /// modes of a PCA do not depend on how many are kept).
    #[test]
    fn one_pca_serves_every_mode_count() {
        // Deterministic fields and features with structure in several directions.
        let n = 12;
        let v = 40;
        let fields: Vec<DVector<f64>> = (0..n)
            .map(|j| {
                DVector::from_fn(v, |i, _| {
                    let (x, y) = (i as f64, j as f64);
                    (0.3 * x + y).sin() + 0.5 * (0.7 * x * y).cos() + 0.1 * y
                })
            })
            .collect();
        let z: Vec<DVector<f64>> = (0..n)
            .map(|j| DVector::from_fn(3, |k, _| ((j * (k + 2)) as f64 * 0.37).sin()))
            .collect();
        let f: Vec<&DVector<f64>> = fields.iter().collect();
        let zr: Vec<&DVector<f64>> = z.iter().collect();
        let pca = Pca::new(&f, 8);
        let zm = feature_rows(&zr);
        let probe = DVector::from_vec(vec![0.4, -1.1, 0.7]);
        for k in [0, 1, 3, 8] {
            for ridge in [0.1, 10.0] {
                let whole = Pca::new(&f, k);
                let want = whole.predict(&whole.coefficients(&zm, k, ridge), &probe);
                let got = pca.predict(&pca.coefficients(&zm, k, ridge), &probe);
                assert!((want - got).amax() < 1e-9, "k {k}, ridge {ridge}");
            }
        }
    }

    /// Fields made by a known linear model of two dimensions' logarithms plus a fixed mean:
    /// the trained prior predicts a subject it never saw to within the quantisation, and its
    /// leave-one-out figures show the gain.
    #[test]
    fn training_recovers_a_linear_model_of_the_dimensions() {
        let v = 300;
        let mean: Vec<f64> = (0..v).map(|i| (i as f64 * 0.1).sin()).collect();
        let mode_a: Vec<f64> = (0..v).map(|i| (i as f64 * 0.05).cos()).collect();
        let mode_b: Vec<f64> = (0..v).map(|i| if i < v / 2 { 1.0 } else { -0.5 }).collect();
        let field = |d: &BTreeMap<Dimension, f64>| -> Vec<f64> {
            let a = 20.0 * (d[&Dimension::WristBreadth] / 15.0).ln();
            let b = 15.0 * (d[&Dimension::HandThicknessMc3] / 30.0).ln();
            (0..v)
                .map(|i| mean[i] + a * mode_a[i] + b * mode_b[i])
                .collect()
        };
        let mut rng = crate::rng::Rng::new(5);
        let samples: Vec<PriorSample> = (0..30)
            .map(|k| {
                let d = dims(rng.range(0.85, 1.15), rng.range(0.8, 1.2));
                PriorSample {
                    name: format!("s{k}"),
                    offsets: field(&d),
                    features: feats(&d),
                    measured: vec![true; v],
                }
            })
            .collect();
        let prior = train_shape_prior(&samples).unwrap();
        assert_eq!(prior.vertices, v);
        assert!(prior.modes.len() >= 2, "{} modes", prior.modes.len());
        let fresh = dims(1.07, 0.9);
        let (want, got) = (field(&fresh), prior.predict(&feats(&fresh)));
        let err = want
            .iter()
            .zip(&got)
            .fold(0.0_f64, |w, (a, b)| w.max((a - b).abs()));
        // Ridge shrinkage on 30 subjects and the stored resolution (0.01 mm, modes 1e-4).
        assert!(err < 0.1, "worst vertex off by {err} mm");
        for c in &prior.cross_validation {
            assert!(c.with_mm < 0.2 * c.without_mm, "{c:?}");
        }
        // JSON round trip.
        let json = serde_json::to_vec(&prior).unwrap();
        let back = ShapePrior::from_json(&json, std::path::Path::new("p.json")).unwrap();
        // serde_json reads a float to within an ulp (no float_roundtrip): the stored integers
        // come back exactly and the predictions to rounding.
        assert_eq!((&back.mean, &back.modes), (&prior.mean, &prior.modes));
        let again = back.predict(&feats(&fresh));
        assert!(again.iter().zip(&got).all(|(a, b)| (a - b).abs() < 1e-9));
        // A feature far outside the training population is read at the limit: a hand of a
        // wrist breadth beyond it gets the same field as one exactly at it, and is named.
        let k = prior
            .features
            .iter()
            .position(|n| n == &Dimension::WristBreadth.name())
            .unwrap();
        let at_limit = |sd: f64| {
            let mut f = feats(&fresh);
            f.insert(
                prior.features[k].clone(),
                prior.feature_mean[k] + sd * prior.feature_sd[k],
            );
            f
        };
        let (limit, far) = (at_limit(FEATURE_LIMIT_SD), at_limit(3.0 * FEATURE_LIMIT_SD));
        let (a, b) = (prior.predict(&limit), prior.predict(&far));
        assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9));
        assert!(prior.outside(&feats(&fresh), FEATURE_LIMIT_SD).is_empty());
        let named = prior.outside(&far, FEATURE_LIMIT_SD);
        assert_eq!(named.len(), 1, "{named:?}");
        assert_eq!(named[0].0, prior.features[k]);
        assert!((named[0].1 - 3.0 * FEATURE_LIMIT_SD).abs() < 1e-9);
        // Inside the limit the field still follows the feature.
        let inside = prior.predict(&at_limit(0.5 * FEATURE_LIMIT_SD));
        assert!(inside.iter().zip(&a).any(|(x, y)| (x - y).abs() > 1e-6));
    }

    #[test]
    fn training_refuses_too_few_or_mixed_subjects() {
        let s = |n: usize| PriorSample {
            name: format!("v{n}"),
            features: feats(&dims(1.0, 1.0)),
            offsets: vec![0.0; n],
            measured: vec![true; n],
        };
        assert!(train_shape_prior(&[s(5), s(5)]).is_err());
        let e = train_shape_prior(&[s(5), s(5), s(6)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("v6") && e.contains("template"), "{e}");
    }

    #[test]
    fn a_prior_whose_sizes_disagree_is_refused_naming_the_file() {
        let mut p = (*ShapePrior::builtin()).clone();
        p.mean.pop();
        let json = serde_json::to_vec(&p).unwrap();
        let e = ShapePrior::from_json(&json, std::path::Path::new("lab/prior.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("lab/prior.json") && e.contains("sizes"), "{e}");
        let e = ShapePrior::from_json(b"{}", std::path::Path::new("x.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.json"), "{e}");
    }

    /// The shipped prior belongs to the shipped templates (both hands share the vertex order).
    #[test]
    fn the_shipped_prior_fits_the_shipped_templates() {
        let p = ShapePrior::builtin();
        for side in [crate::anatomy::Side::Right, crate::anatomy::Side::Left] {
            let t = crate::template::load_template(side).unwrap();
            assert_eq!(p.vertices, t.mesh.n_vertices());
        }
        assert!(p.trained_on.len() >= 20);
        assert!(p.features.iter().any(|f| f.starts_with("depth:")));
    }

    /// The tissue depth: a marker 4 mm off the skin, 11 mm from a 3-DOF centre and 9 mm from a
    /// hinge's axis (3 mm along it, which section 3.6 may move).
    #[test]
    fn tissue_depth_is_the_marker_to_joint_distance_less_the_offset() {
        let markers: BTreeMap<String, Point> = [
            ("I_MCP".to_string(), Point::new(0.0, 11.0, 0.0)),
            ("I_PIP".to_string(), Point::new(3.0, 9.0, 0.0)),
        ]
        .into();
        let joints: BTreeMap<String, JointLine> = [
            (
                "I_MCP".to_string(),
                JointLine {
                    centre: Point::origin(),
                    axis: None,
                },
            ),
            (
                "I_PIP".to_string(),
                JointLine {
                    centre: Point::origin(),
                    axis: Some(Vec3::new(2.0, 0.0, 0.0)),
                },
            ),
        ]
        .into();
        let f = subject_features(&BTreeMap::new(), &markers, &joints, 4.0);
        assert!((f["depth:I_MCP"] - 7.0_f64.ln()).abs() < 1e-12);
        assert!((f["depth:I_PIP"] - 5.0_f64.ln()).abs() < 1e-12);
        assert_eq!(f.len(), 2);
    }
}
