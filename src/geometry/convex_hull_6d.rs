//! Convex hulls in six dimensions: our own Quickhull (Barber, Dobkin & Huhdanpaa 1996, "The
//! Quickhull algorithm for convex hulls", ACM TOMS 22(4)) with simplicial facets (the grasp
//! wrench space is one). No permissively licensed Rust crate computes d > 3 hulls (qhull's
//! bindings carry the qhull licence and a C build).
//!
//! Input points are joggled by a deterministic [`JOGGLE`] relative perturbation (qhull's `QJ`)
//! so that they are in general position and every facet is a simplex; a retry with a larger
//! joggle covers the rare hull that round-off breaks. [`Hull::nearest_offset`] finds the facet
//! nearest an interior origin without building the whole hull (the expanding polytope idea):
//! it refines only the facets near the origin and gives the whole hull's offset on the same
//! joggled points.

use nalgebra::Vector6;
use std::sync::atomic::{AtomicBool, Ordering};

/// The dimension.
pub const D: usize = 6;

/// Relative size of the joggle (qhull `QJ`): large against round-off, small against the
/// precision epsilon is reported with.
pub const JOGGLE: f64 = 1e-7;

#[derive(Clone, Debug)]
struct Facet {
    verts: [usize; D],
    /// Across the ridge without `verts[k]`.
    neighbours: [usize; D],
    normal: Vector6<f64>,
    offset: f64,
    outside: Vec<usize>,
    alive: bool,
}

impl Facet {
    /// A live facet with no outside points yet.
    fn new(
        verts: [usize; D],
        neighbours: [usize; D],
        (normal, offset): (Vector6<f64>, f64),
    ) -> Facet {
        Facet {
            verts,
            neighbours,
            normal,
            offset,
            outside: Vec::new(),
            alive: true,
        }
    }
}

/// A full-dimensional convex hull in 6-D with simplicial facets.
#[derive(Clone, Debug)]
pub struct Hull {
    points: Vec<Vector6<f64>>,
    facets: Vec<Facet>,
    interior: Vector6<f64>,
}

/// Unit normal of the hyperplane through six points, or `None` when they are affinely
/// dependent: the null vector of the 5 x 6 matrix of edge vectors by Gaussian elimination
/// with complete pivoting (Golub & Van Loan, "Matrix Computations", 3.4.8), the stable way to
/// a null space, in place of the six 5 x 5 cofactor determinants of the generalised cross
/// product (same vector up to scale, a sixth of the work). The dependence test is the
/// cofactor vector's length against the edges' scale: that length is the product of the
/// pivots times the null vector's length with a unit free component.
pub(crate) fn hyperplane(p: &[Vector6<f64>; D]) -> Option<(Vector6<f64>, f64)> {
    let mut e = [[0.0; D]; D - 1];
    let mut scale: f64 = 0.0;
    for i in 1..D {
        for k in 0..D {
            e[i - 1][k] = p[i][k] - p[0][k];
            scale = scale.max(e[i - 1][k].abs());
        }
    }
    // cols[c]: the original column now at position c.
    let mut cols: [usize; D] = std::array::from_fn(|c| c);
    let mut det: f64 = 1.0;
    for r in 0..D - 1 {
        let (mut bi, mut bj, mut bv) = (r, r, -1.0);
        for (i, row) in e.iter().enumerate().skip(r) {
            for (j, x) in row.iter().enumerate().skip(r) {
                if x.abs() > bv {
                    (bi, bj, bv) = (i, j, x.abs());
                }
            }
        }
        // NaN or zero: the edges do not span five dimensions.
        if bv.is_nan() || bv <= 0.0 {
            return None;
        }
        e.swap(r, bi);
        if bj != r {
            for row in e.iter_mut() {
                row.swap(r, bj);
            }
            cols.swap(r, bj);
        }
        let piv = e[r][r];
        det *= piv;
        let pivot_row = e[r];
        for row in e.iter_mut().skip(r + 1) {
            let f = row[r] / piv;
            if f != 0.0 {
                for (x, p) in row.iter_mut().zip(pivot_row).skip(r) {
                    *x -= f * p;
                }
            }
        }
    }
    // Free variable: the last column.
    let mut x = [0.0; D];
    x[D - 1] = 1.0;
    for r in (0..D - 1).rev() {
        let mut acc = 0.0;
        for j in r + 1..D {
            acc += e[r][j] * x[j];
        }
        x[r] = -acc / e[r][r];
    }
    let mut n = Vector6::zeros();
    for c in 0..D {
        n[cols[c]] = x[c];
    }
    let len = n.norm();
    if !len.is_finite() || (det * len).abs() <= 1e-24 * scale.powi(5).max(1e-300) {
        return None;
    }
    let n = n / len;
    Some((n, n.dot(&p[0])))
}

/// Determinant of a 6 x 6 matrix (rows), by Gaussian elimination with partial pivoting.
fn det6(mut m: [[f64; D]; D]) -> f64 {
    let mut det = 1.0;
    for r in 0..D {
        let p = (r..D)
            .max_by(|&a, &b| m[a][r].abs().total_cmp(&m[b][r].abs()))
            .expect("rows left");
        if m[p][r] == 0.0 {
            return 0.0;
        }
        if p != r {
            m.swap(p, r);
            det = -det;
        }
        let piv = m[r][r];
        det *= piv;
        let pivot_row = m[r];
        for row in m.iter_mut().skip(r + 1) {
            let f = row[r] / piv;
            for (x, p) in row.iter_mut().zip(pivot_row).skip(r + 1) {
                *x -= f * p;
            }
        }
    }
    det
}

/// The vertex set of the ridge of a facet with vertices `verts` that omits `verts[skip]`,
/// as one number: the five indices sorted and packed in 25 bits each (inputs have fewer than
/// 2^25 points, checked in [`Hull::build`]), so that ridges pair by sorting integers.
fn ridge_key(verts: &[usize; D], skip: usize) -> u128 {
    let mut k = [0usize; D - 1];
    let mut n = 0;
    for (v, &x) in verts.iter().enumerate() {
        if v != skip {
            // Insertion sort of five.
            let mut i = n;
            while i > 0 && k[i - 1] > x {
                k[i] = k[i - 1];
                i -= 1;
            }
            k[i] = x;
            n += 1;
        }
    }
    k.iter().fold(0u128, |acc, &x| (acc << 25) | x as u128)
}

/// Scratch buffers of one hull construction (reused across Quickhull iterations).
#[derive(Default)]
struct Scratch {
    /// Facet -> (round, visible) marks of the visibility search.
    mark: Vec<(usize, bool)>,
    visible: Vec<usize>,
    new_ids: Vec<usize>,
    /// Ridges of the new facets through the apex: ([`ridge_key`], facet, slot).
    ridges: Vec<(u128, usize, usize)>,
    orphans: Vec<usize>,
    /// Dead facet slots to reuse.
    free: Vec<usize>,
}

impl Hull {
    /// Quickhull of `input`; `None` when the points do not span 6-D. Tries joggles of
    /// [`JOGGLE`] and 100 and 10,000 times larger (qhull retries `QJ` the same way) until the
    /// construction succeeds and the hull passes its convexity check.
    pub fn new(input: &[Vector6<f64>]) -> Option<Hull> {
        with_joggles(input, |p, j| Hull::build(p, j, None))
    }

    /// [`Hull::new`], given up (`None`) as soon as `stop` is found set: a caller that builds
    /// the hull beside other work which may make it unwanted. Checked once per point added.
    pub fn new_unless(input: &[Vector6<f64>], stop: &AtomicBool) -> Option<Hull> {
        with_joggles(input, |p, j| Hull::build(p, j, Some(stop)))
    }

    /// The distance from the origin to the nearest facet of the hull of `input` when the
    /// origin is inside (the Ferrari-Canny epsilon, [`Hull::min_offset`] of [`Hull::new`]),
    /// without building the whole hull; when the origin is outside, a negative number (the
    /// offset of one facet the origin lies beyond, not necessarily the most negative); `None`
    /// when the points do not span 6-D. Same joggle and retries as [`Hull::new`].
    ///
    /// The idea of the expanding polytope algorithm (van den Bergen 2001, "Proximity queries
    /// and penetration depth computation on 3D game objects", GDC; the distance from an inside
    /// point to the boundary of a convex hull from support queries alone), on Quickhull's
    /// beneath-beyond step: keep a polytope `P` spanned by some of the points, take its facet
    /// `F` nearest the origin and the point furthest beyond `F`. If no point is beyond `F`
    /// (within the construction's tolerance), `F`'s hyperplane supports the whole hull, so the
    /// hull's boundary is no further from the origin than `F`; and `P` lies inside the hull, so
    /// the boundary is no nearer than `P`'s, which is `F`. Otherwise that point is added to
    /// `P` and the search goes on. Only facets near the origin are ever refined: a grasp wrench
    /// space of 248 wrenches has about 29,000 facets, this builds a few hundred.
    pub fn nearest_offset(input: &[Vector6<f64>]) -> Option<f64> {
        with_joggles(input, Hull::expand_nearest)
    }

    pub(crate) fn expand_nearest(input: &[Vector6<f64>], joggle: f64) -> Option<f64> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        /// A facet's offset ordered by `total_cmp`, for the heap.
        #[derive(PartialEq)]
        struct Key(f64);
        impl Eq for Key {}
        impl PartialOrd for Key {
            fn partial_cmp(&self, o: &Key) -> Option<std::cmp::Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Key {
            fn cmp(&self, o: &Key) -> std::cmp::Ordering {
                self.0.total_cmp(&o.0)
            }
        }
        let (mut h, mut rest, eps) = Hull::start(input, joggle)?;
        // Stale entries (dead facets, or slots reused by a facet with another offset) are
        // skipped when popped.
        let mut heap: BinaryHeap<Reverse<(Key, usize)>> = h
            .facets
            .iter()
            .enumerate()
            .map(|(i, f)| Reverse((Key(f.offset), i)))
            .collect();
        let mut s = Scratch::default();
        let mut round = 0usize;
        while let Some(Reverse((Key(offset), f))) = heap.pop() {
            if !h.facets[f].alive || h.facets[f].offset != offset {
                continue;
            }
            round += 1;
            if round > 200_000 {
                return None;
            }
            let beyond = rest
                .iter()
                .enumerate()
                .map(|(k, &p)| (k, h.dist(f, p)))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match beyond {
                Some((k, d)) if d > eps => {
                    let apex = rest.swap_remove(k);
                    h.add_point(f, apex, round, eps, &mut s)?;
                    heap.extend(
                        s.new_ids
                            .iter()
                            .map(|&id| Reverse((Key(h.facets[id].offset), id))),
                    );
                }
                _ => return h.locally_convex(1e3 * eps).then_some(offset),
            }
        }
        None
    }

    /// The joggled points (qhull `QJ`, [`Hull::new`]) and the initial simplex's seven facets,
    /// with the points not in the simplex and the distance tolerance of the construction.
    fn start(input: &[Vector6<f64>], joggle: f64) -> Option<(Hull, Vec<usize>, f64)> {
        if input.len() < D + 1
            || input.len() >= 1 << 25
            || input.iter().any(|p| !p.iter().all(|x| x.is_finite()))
        {
            return None;
        }
        let scale = input
            .iter()
            .map(|p| p.amax())
            .fold(0.0, f64::max)
            .max(1e-300);
        // Deterministic joggle (qhull QJ) from a fixed-seed generator: independent per
        // coordinate (an affine hash would preserve the very dependencies it must break).
        let mut rng = crate::rng::Rng::new(0x6A09_E667);
        let points: Vec<Vector6<f64>> = input
            .iter()
            .map(|p| Vector6::from_fn(|k, _| p[k] + rng.range(-1.0, 1.0) * joggle * scale))
            .collect();
        let eps = 1e-3 * joggle * scale;
        let simplex = initial_simplex(&points, eps)?;
        let interior = simplex.iter().map(|&i| points[i]).sum::<Vector6<f64>>() / (D + 1) as f64;
        let mut h = Hull {
            points,
            facets: Vec::new(),
            interior,
        };
        // Facet i omits simplex vertex i; facets i and j share the ridge omitting both.
        for i in 0..=D {
            let vs: Vec<usize> = (0..=D).filter(|&k| k != i).collect();
            let verts: [usize; D] = std::array::from_fn(|k| simplex[vs[k]]);
            let neighbours: [usize; D] = std::array::from_fn(|k| vs[k]);
            let plane = h.oriented_plane(&verts)?;
            h.facets.push(Facet::new(verts, neighbours, plane));
        }
        let rest: Vec<usize> = (0..h.points.len())
            .filter(|i| !simplex.contains(i))
            .collect();
        Some((h, rest, eps))
    }

    pub(crate) fn build(
        input: &[Vector6<f64>],
        joggle: f64,
        stop: Option<&AtomicBool>,
    ) -> Option<Hull> {
        let (mut h, all, eps) = Hull::start(input, joggle)?;
        h.assign(&all, &(0..=D).collect::<Vec<_>>(), eps);
        let mut guard = 0usize;
        // Facets that may have outside points (stale entries are skipped when popped).
        let mut pending: Vec<usize> = (0..=D).collect();
        let mut s = Scratch::default();
        loop {
            guard += 1;
            if guard > 200_000 || stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                return None;
            }
            let Some(f0) = std::iter::from_fn(|| pending.pop())
                .find(|&f| h.facets[f].alive && !h.facets[f].outside.is_empty())
            else {
                break;
            };
            let fa = &h.facets[f0];
            let apex = *fa
                .outside
                .iter()
                .max_by(|&&a, &&b| h.dist(f0, a).total_cmp(&h.dist(f0, b)))
                .expect("non-empty");
            h.add_point(f0, apex, guard, eps, &mut s)?;
            pending.extend(s.new_ids.iter().copied());
        }
        h.locally_convex(1e3 * eps).then_some(h)
    }

    /// One Quickhull step: the facets `apex` sees (searched through the adjacency from `f0`,
    /// which sees it) are replaced by the cone from `apex` to their horizon; their outside
    /// points go to the new facets (`s.new_ids`). `None` on a broken adjacency (round-off).
    fn add_point(
        &mut self,
        f0: usize,
        apex: usize,
        round: usize,
        eps: f64,
        s: &mut Scratch,
    ) -> Option<()> {
        let h = self;
        s.mark.resize(h.facets.len(), (0, false));
        s.visible.clear();
        s.visible.push(f0);
        s.mark[f0] = (round, true);
        let mut qi = 0;
        while qi < s.visible.len() {
            let f = s.visible[qi];
            qi += 1;
            for k in 0..D {
                let g = h.facets[f].neighbours[k];
                if s.mark[g].0 == round {
                    continue;
                }
                let vis = h.dist(g, apex) > eps;
                s.mark[g] = (round, vis);
                if vis {
                    s.visible.push(g);
                }
            }
        }
        // New facets over the horizon ridges (a visible facet's ridge whose neighbour is not
        // visible), each linked to the facet beyond.
        s.new_ids.clear();
        s.ridges.clear();
        for vi in 0..s.visible.len() {
            let f = s.visible[vi];
            for k in 0..D {
                let g = h.facets[f].neighbours[k];
                if s.mark[g].1 {
                    continue;
                }
                let mut verts = h.facets[f].verts;
                verts[k] = apex;
                let plane = h.oriented_plane(&verts)?;
                let mut neighbours = [usize::MAX; D];
                neighbours[k] = g;
                let facet = Facet::new(verts, neighbours, plane);
                // A dead slot is reused only when it is not one of this step's visible facets
                // (those die below, after their links are read).
                let id = match s.free.pop() {
                    Some(id) => {
                        let old = std::mem::replace(&mut h.facets[id], facet);
                        // Keep the old outside list's capacity.
                        let mut out = old.outside;
                        out.clear();
                        h.facets[id].outside = out;
                        id
                    }
                    None => {
                        h.facets.push(facet);
                        h.facets.len() - 1
                    }
                };
                let gk = h.facets[g]
                    .neighbours
                    .iter()
                    .position(|&x| x == f)
                    .expect("adjacency is symmetric");
                h.facets[g].neighbours[gk] = id;
                s.new_ids.push(id);
                // Its ridges through the apex, to pair with the other new facets.
                for m in 0..D {
                    if m == k {
                        continue;
                    }
                    s.ridges.push((ridge_key(&verts, m), id, m));
                }
            }
        }
        // Every ridge through the apex is shared by exactly two new facets.
        s.ridges.sort_unstable();
        if !s.ridges.len().is_multiple_of(2) {
            return None;
        }
        for pair in s.ridges.chunks_exact(2) {
            let ((ka, a, ia), (kb, b, ib)) = (pair[0], pair[1]);
            if ka != kb {
                return None;
            }
            h.facets[a].neighbours[ia] = b;
            h.facets[b].neighbours[ib] = a;
        }
        s.orphans.clear();
        for &f in &s.visible {
            h.facets[f].alive = false;
            s.orphans.append(&mut h.facets[f].outside);
            s.free.push(f);
        }
        if s.mark.len() < h.facets.len() {
            s.mark.resize(h.facets.len(), (0, false));
        }
        // Reused slots must not carry this round's visible mark.
        for &id in &s.new_ids {
            s.mark[id] = (0, false);
        }
        s.orphans.retain(|&p| p != apex);
        let orphans = std::mem::take(&mut s.orphans);
        h.assign(&orphans, &s.new_ids, eps);
        s.orphans = orphans;
        Some(())
    }

    /// Whether every ridge is convex: for each facet, the vertex of each neighbour opposite
    /// their shared ridge lies below the facet (within `tol`). A closed simplicial surface
    /// that is locally convex at every ridge bounds a convex polytope (Tietze's theorem on
    /// locally convex sets), and Quickhull only discards points below a facet, so this checks
    /// what round-off could break, in O(facets) instead of O(facets x points).
    fn locally_convex(&self, tol: f64) -> bool {
        self.facets.iter().filter(|f| f.alive).all(|f| {
            f.neighbours.iter().all(|&g| {
                let gf = &self.facets[g];
                gf.alive
                    && gf
                        .verts
                        .iter()
                        .filter(|v| !f.verts.contains(v))
                        .all(|&v| f.normal.dot(&self.points[v]) - f.offset <= tol)
            })
        })
    }

    fn dist(&self, f: usize, p: usize) -> f64 {
        self.facets[f].normal.dot(&self.points[p]) - self.facets[f].offset
    }

    fn oriented_plane(&self, verts: &[usize; D]) -> Option<(Vector6<f64>, f64)> {
        let p: [Vector6<f64>; D] = std::array::from_fn(|k| self.points[verts[k]]);
        let (n, b) = hyperplane(&p)?;
        if n.dot(&self.interior) - b > 0.0 {
            Some((-n, -b))
        } else {
            Some((n, b))
        }
    }

    fn assign(&mut self, pts: &[usize], facets: &[usize], eps: f64) {
        for &p in pts {
            if let Some(&f) = facets.iter().find(|&&f| self.dist(f, p) > eps) {
                self.facets[f].outside.push(p);
            }
        }
    }

    /// Number of facets.
    pub fn n_facets(&self) -> usize {
        self.facets.iter().filter(|f| f.alive).count()
    }

    /// Smallest signed distance from the origin to a facet plane, positive when the origin is
    /// inside (the Ferrari-Canny epsilon).
    pub fn min_offset(&self) -> f64 {
        self.facets
            .iter()
            .filter(|f| f.alive)
            .map(|f| f.offset)
            .fold(f64::MAX, f64::min)
    }

    /// 6-D volume: the sum of the simplices from an interior point to every facet.
    pub fn volume(&self) -> f64 {
        let c = self.interior;
        let mut v = 0.0;
        for f in self.facets.iter().filter(|f| f.alive) {
            let m: [[f64; D]; D] =
                std::array::from_fn(|k| std::array::from_fn(|r| self.points[f.verts[k]][r] - c[r]));
            v += det6(m).abs();
        }
        v / 720.0
    }
}

/// `construct` on `input` joggled by [`JOGGLE`], then 100 and 10,000 times more until it
/// succeeds (qhull retries `QJ` the same way); `None` when `input` does not span 6-D, which is
/// tested on the raw points (the joggle must not invent a sixth dimension).
fn with_joggles<T>(
    input: &[Vector6<f64>],
    construct: impl Fn(&[Vector6<f64>], f64) -> Option<T>,
) -> Option<T> {
    let scale = input.iter().map(|p| p.amax()).fold(0.0, f64::max);
    if input.len() <= D
        || scale.is_nan()
        || scale <= 0.0
        || initial_simplex(input, 1e-9 * scale).is_none()
    {
        return None;
    }
    [1.0, 1e2, 1e4]
        .into_iter()
        .find_map(|m| construct(input, JOGGLE * m))
}

/// Six affinely independent points spanning the largest simplex found greedily (the two
/// furthest apart along some axis, then repeatedly the point furthest from the affine hull so
/// far), or `None` when the input does not span 6-D.
fn initial_simplex(points: &[Vector6<f64>], eps: f64) -> Option<Vec<usize>> {
    let mut best = (0, 0, -1.0);
    for k in 0..D {
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in points.iter().enumerate() {
            if p[k] < points[lo][k] {
                lo = i;
            }
            if p[k] > points[hi][k] {
                hi = i;
            }
        }
        let ext = points[hi][k] - points[lo][k];
        if ext > best.2 {
            best = (lo, hi, ext);
        }
    }
    if best.2 <= eps {
        return None;
    }
    let mut chosen = vec![best.0, best.1];
    let mut basis: Vec<Vector6<f64>> = Vec::new();
    let o = points[best.0];
    let first = points[best.1] - o;
    basis.push(first.normalize());
    while chosen.len() < D + 1 {
        let mut far = (usize::MAX, 0.0);
        for (i, p) in points.iter().enumerate() {
            let mut r = p - o;
            for b in &basis {
                r -= b * b.dot(&r);
            }
            let d = r.norm();
            if d > far.1 {
                far = (i, d);
            }
        }
        if far.0 == usize::MAX || far.1 <= eps * 1e3 {
            return None;
        }
        let mut r = points[far.0] - o;
        for b in &basis {
            r -= b * b.dot(&r);
        }
        basis.push(r.normalize());
        chosen.push(far.0);
    }
    Some(chosen)
}
