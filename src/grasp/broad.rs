//! Broad phase of the skin-part queries: a voxel grid over the part that tells, in a few
//! nanoseconds per point, whether a point may lie within a band of the surface (then the exact
//! parry query runs), is surely outside and farther, or (closed parts) surely inside and deeper.
//!
//! Built by rasterising every triangle's bounding box, grown by the band, into the grid (a
//! cell touched by none contains no point within the band of the surface: conservative), then
//! flood-filling the untouched cells from the grid's border: those reached are outside, those
//! enclosed are inside (only for closed parts; an open part's untouched cells all count as
//! outside). The cost is linear in the triangles and cells (milliseconds for 100k triangles).
//! Points outside the grid are outside the part and farther than the band.

use crate::geometry::{Point, TriMesh};

/// What the grid knows about a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Zone {
    /// Outside the part, farther than the band from its surface.
    Outside,
    /// Possibly within the band of the surface: query exactly.
    Near,
    /// Inside the closed part, deeper than the band.
    Inside,
}

const OUT: u8 = 0;
const NEAR: u8 = 1;
const IN: u8 = 2;

/// See the module documentation.
#[derive(Clone, Debug)]
pub struct NearGrid {
    origin: Point,
    cell: f64,
    dims: [usize; 3],
    cells: Vec<u8>,
    /// Every point within this distance of the surface is [`Zone::Near`], mm.
    pub band: f64,
}

impl NearGrid {
    /// The grid of `mesh` (mm) for a band of `band` mm; `closed` enables the inside zone.
    /// Cells are half the band wide (a point flagged near is then at most about 1.9 bands
    /// from the surface instead of 2.7: fewer exact queries), coarser if the grid would exceed
    /// 8 million cells.
    pub fn new(mesh: &TriMesh, band: f64, closed: bool) -> NearGrid {
        let (lo, hi) = mesh.bounds().unwrap_or((Point::origin(), Point::origin()));
        let band = band.max(1e-3);
        let margin = band + 1e-6;
        let ext = (hi - lo).add_scalar(2.0 * margin);
        let vol = ext.x * ext.y * ext.z;
        let cell = (0.5 * band).max((vol / 8.0e6).cbrt());
        // One spare layer of cells on every side keeps the border outside for the flood fill.
        let origin = lo - nalgebra::Vector3::repeat(margin + cell);
        let dims: [usize; 3] = std::array::from_fn(|a| (ext[a] / cell).ceil() as usize + 3);
        let mut cells = vec![OUT; dims[0] * dims[1] * dims[2]];
        let idx = |i: usize, j: usize, k: usize| (i * dims[1] + j) * dims[2] + k;
        let to_cell = |x: f64, a: usize| -> usize {
            (((x - origin[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1)
        };
        for f in &mesh.faces {
            let [a, b, c] = [
                mesh.vertices[f[0]],
                mesh.vertices[f[1]],
                mesh.vertices[f[2]],
            ];
            let r: [[usize; 2]; 3] = std::array::from_fn(|ax| {
                let lo = a[ax].min(b[ax]).min(c[ax]) - band;
                let hi = a[ax].max(b[ax]).max(c[ax]) + band;
                [to_cell(lo, ax), to_cell(hi, ax)]
            });
            for i in r[0][0]..=r[0][1] {
                for j in r[1][0]..=r[1][1] {
                    for k in r[2][0]..=r[2][1] {
                        cells[idx(i, j, k)] = NEAR;
                    }
                }
            }
        }
        if closed {
            // Untouched cells start inside; those connected to the border become outside.
            for c in cells.iter_mut() {
                if *c == OUT {
                    *c = IN;
                }
            }
            let mut stack = vec![[0usize, 0, 0]];
            cells[0] = OUT;
            while let Some([i, j, k]) = stack.pop() {
                let mut push = |i: usize, j: usize, k: usize| {
                    let n = idx(i, j, k);
                    if cells[n] == IN {
                        cells[n] = OUT;
                        stack.push([i, j, k]);
                    }
                };
                if i > 0 {
                    push(i - 1, j, k);
                }
                if i + 1 < dims[0] {
                    push(i + 1, j, k);
                }
                if j > 0 {
                    push(i, j - 1, k);
                }
                if j + 1 < dims[1] {
                    push(i, j + 1, k);
                }
                if k > 0 {
                    push(i, j, k - 1);
                }
                if k + 1 < dims[2] {
                    push(i, j, k + 1);
                }
            }
        }
        NearGrid {
            origin,
            cell,
            dims,
            cells,
            band,
        }
    }

    /// The zone of `p`.
    #[inline]
    pub fn zone(&self, p: &Point) -> Zone {
        let mut ijk = [0usize; 3];
        for a in 0..3 {
            let x = (p[a] - self.origin[a]) / self.cell;
            // NaN fails both tests and counts as outside.
            if !(x >= 0.0 && x < self.dims[a] as f64) {
                return Zone::Outside;
            }
            ijk[a] = x as usize;
        }
        match self.cells[(ijk[0] * self.dims[1] + ijk[1]) * self.dims[2] + ijk[2]] {
            NEAR => Zone::Near,
            IN => Zone::Inside,
            _ => Zone::Outside,
        }
    }

    /// Cell size, mm.
    pub fn cell_mm(&self) -> f64 {
        self.cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::closest_point::AabbTree;

    #[test]
    fn zones_agree_with_exact_distances() {
        let m = crate::geometry::mesh::tests::icosphere(20.0, 3);
        let g = NearGrid::new(&m, 2.0, true);
        let tree = AabbTree::new(&m);
        let mut rng = crate::rng::Rng::new(4);
        let (mut near, mut inside, mut outside) = (0, 0, 0);
        for _ in 0..20_000 {
            let p = Point::new(
                rng.range(-30.0, 30.0),
                rng.range(-30.0, 30.0),
                rng.range(-30.0, 30.0),
            );
            let d = tree.closest_point(&p).unwrap().distance;
            let r = p.coords.norm();
            match g.zone(&p) {
                Zone::Near => near += 1,
                // Conservative: never a point within the band.
                Zone::Inside => {
                    inside += 1;
                    assert!(d > 2.0 && r < 20.0, "{p} {d}");
                }
                Zone::Outside => {
                    outside += 1;
                    assert!(d > 2.0 && r > 19.0, "{p} {d}");
                }
            }
        }
        assert!(near > 0 && inside > 0 && outside > 0);
        // The near shell is a few cells thick, not the whole box.
        assert!(near < 20_000 / 3, "{near}");
        // An open mesh has no inside.
        let mut open = m.clone();
        open.faces.truncate(open.faces.len() - 10);
        let g = NearGrid::new(&open, 2.0, false);
        assert_eq!(g.zone(&Point::origin()), Zone::Outside);
        assert_eq!(g.zone(&Point::new(1e9, 0.0, 0.0)), Zone::Outside);
        assert_eq!(g.zone(&Point::new(f64::NAN, 0.0, 0.0)), Zone::Outside);
    }
}
