//! Polygonisation of the implicit skin: the signed distance sampled on a regular grid, turned
//! into a partial-volume occupancy, and its 0.5 isosurface by the CT scan's marching tetrahedra
//! ([`crate::synth::voxel_scan::isosurface`]), which makes it closed, 2-manifold and outward.

use super::implicit::HandField;
use crate::error::Result;
use crate::geometry::{Point, TriMesh};
use crate::synth::voxel_scan::{isosurface, Grid, FULL, PADDING};
use rayon::prelude::*;

/// Width of the linear ramp of the occupancy across the surface, in voxels: the distance maps to
/// `0.5 - d / (RAMP · voxel)`, so both ends of every grid edge (up to √3 voxels long) that crosses
/// the surface stay on the ramp and linear interpolation puts the vertex where the distance is 0.
const RAMP: f64 = 4.0;

/// Coarse grid step of the narrow band, in voxels.
const COARSE: usize = 4;

/// The `field`'s zero level set inside the box spanned by `points` plus `margin` mm, on a grid
/// of `voxel_mm`. Errors when the surface reaches the grid's boundary.
pub fn polygonise(
    field: &HandField,
    points: &[Point],
    margin: f64,
    voxel_mm: f64,
) -> Result<TriMesh> {
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let first: [i64; 3] =
        std::array::from_fn(|k| ((lo[k] - margin) / voxel_mm).floor() as i64 - PADDING);
    let last: [i64; 3] =
        std::array::from_fn(|k| ((hi[k] + margin) / voxel_mm).ceil() as i64 + PADDING);
    let dims: [usize; 3] = std::array::from_fn(|k| (last[k] - first[k] + 1) as usize);
    let mut grid = Grid {
        voxel_mm,
        first,
        dims,
        values: vec![0; dims[0] * dims[1] * dims[2]],
    };
    let ramp = RAMP * voxel_mm;
    // Narrow band: the field on a grid COARSE times coarser first; a fine node whose nearest
    // coarse node is further from the surface than that node can be from it (half a coarse
    // cell's diagonal) plus the ramp and a safety margin takes its occupancy from the sign alone
    // (the field is a distance bound, so it changes by at most about its step).
    let cdims: [usize; 3] = std::array::from_fn(|k| (dims[k] - 1) / COARSE + 1);
    let g = &grid;
    let coarse: Vec<f64> = (0..cdims[0])
        .into_par_iter()
        .flat_map_iter(|ci| {
            let mut out = Vec::with_capacity(cdims[1] * cdims[2]);
            for cj in 0..cdims[1] {
                for ck in 0..cdims[2] {
                    out.push(field.distance(&g.position(ci * COARSE, cj * COARSE, ck * COARSE)));
                }
            }
            out
        })
        .collect();
    let band = 0.5 * (COARSE as f64) * voxel_mm * 3f64.sqrt() + 0.5 * ramp + 2.0;
    let values: Vec<u16> = (0..dims[0])
        .into_par_iter()
        .flat_map_iter(|i| {
            let mut out = Vec::with_capacity(dims[1] * dims[2]);
            let ci = ((i + COARSE / 2) / COARSE).min(cdims[0] - 1);
            for j in 0..dims[1] {
                let cj = ((j + COARSE / 2) / COARSE).min(cdims[1] - 1);
                for k in 0..dims[2] {
                    let ck = ((k + COARSE / 2) / COARSE).min(cdims[2] - 1);
                    let dc = coarse[(ci * cdims[1] + cj) * cdims[2] + ck];
                    let d = if dc.abs() > band {
                        dc
                    } else {
                        field.distance(&g.position(i, j, k))
                    };
                    let occ = (0.5 - d / ramp).clamp(0.0, 1.0);
                    out.push((occ * FULL as f64).round() as u16);
                }
            }
            out
        })
        .collect();
    grid.values = values;
    isosurface(&grid, 0.5)
}
