//! Per-vertex distance from a fitted skin (`skin.obj`) to the CT-like reference surface
//! (`reference.ply`): the seed paper's section 5.2 error (mean, max, min, SD), plus the 95th
//! percentile.

use crate::error::Result;
use crate::geometry::closest_point::AabbTree;
use crate::geometry::Point;
use crate::io::{obj, ply, Units};
use serde::Serialize;
use std::path::Path;

/// Summary of the distances.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceError {
    /// Vertices measured.
    pub n: usize,
    /// Mean distance, mm.
    pub mean_mm: f64,
    /// Standard deviation, mm.
    pub sd_mm: f64,
    /// Smallest, mm.
    pub min_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
    /// 95th percentile, mm.
    pub p95_mm: f64,
}

impl SurfaceError {
    /// Mean, SD (population), min, max and 95th percentile (nearest rank below) of `d`.
    pub fn of(d: &[f64]) -> SurfaceError {
        let mut d = d.to_vec();
        d.sort_by(f64::total_cmp);
        let n = d.len().max(1);
        let mean = d.iter().sum::<f64>() / n as f64;
        let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        SurfaceError {
            n: d.len(),
            mean_mm: mean,
            sd_mm: sd,
            min_mm: d.first().copied().unwrap_or(0.0),
            max_mm: d.last().copied().unwrap_or(0.0),
            p95_mm: d
                .get((0.95 * (d.len().saturating_sub(1)) as f64) as usize)
                .copied()
                .unwrap_or(0.0),
        }
    }
}

/// Unsigned distance of every point of `points` to the surface of `tree`, in order (infinite
/// for a tree without faces or a non-finite point, so it shows in the statistics).
pub fn distances_to_surface(points: &[Point], tree: &AabbTree) -> Vec<f64> {
    tree.distances(points)
        .into_iter()
        .map(|d| d.unwrap_or(f64::INFINITY))
        .collect()
}

/// Distances of the vertices of `skin` (OBJ, mm) to the surface `reference` (PLY, mm).
pub fn surface_error(skin: &Path, reference: &Path) -> Result<SurfaceError> {
    let s = obj::read_obj(skin, Units::Millimetres)?;
    let r = ply::read_ply(reference, Units::Millimetres)?.mesh;
    let tree = AabbTree::new(&r);
    Ok(SurfaceError::of(&distances_to_surface(&s.vertices, &tree)))
}
