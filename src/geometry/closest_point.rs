//! Exact closest-point, distance, signed-distance and ray queries from points to a triangle mesh,
//! accelerated by a static bounding-volume hierarchy of axis-aligned boxes over the faces.
//!
//! * The tree ([`AabbTree::new`]) is built top-down with a median split of the face centroids
//!   along the longest axis of their bounds (Ericson, *Real-Time Collision Detection*, 2005,
//!   section 6.2.1), so its depth is `ceil(log2(faces / LEAF_SIZE))` whatever the mesh.
//! * A point query ([`AabbTree::closest_point`]) descends nearer child first and prunes every box
//!   that is further than the best triangle found so far (Ericson 6.5.1); the point-triangle test
//!   is Ericson's Voronoi-region method (section 5.1.5), exact up to rounding.
//! * The sign of [`AabbTree::signed_distance`] is that of the angle-weighted pseudo-normal of the
//!   closest feature (face, edge or vertex) dotted with `p - closest` (Bærentzen & Aanæs 2005,
//!   "Signed distance computation using the angle weighted pseudonormal", IEEE TVCG 11(3)),
//!   correct for every point when the mesh is closed, 2-manifold and outward oriented.
//!
//! Queries are read-only, so batches run on rayon; each result depends on its point only, which
//! makes a batch deterministic whatever the thread count. Ties between faces at exactly the same
//! distance go to the lower face index.

use super::{Point, TriMesh, Vec3};
use rayon::prelude::*;
use std::borrow::Cow;
use std::collections::HashMap;

/// Faces per leaf: small leaves prune best for point queries against fine meshes.
const LEAF_SIZE: usize = 4;

/// One node: its box and either a face range (leaf) or its second child (the first child of an
/// inner node is the next node, as the tree is stored in depth-first order).
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: first index into `AabbTree::order`; inner: index of the second child.
    index: u32,
    /// Leaf: number of faces (> 0); inner: 0.
    count: u32,
}

/// Which part of a triangle a closest point lies on, as classified by Ericson's test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// Interior of the face.
    Face,
    /// Edge `k`, from corner `k` to corner `(k + 1) % 3`.
    Edge(u8),
    /// Corner `k`.
    Vertex(u8),
}

/// The result of a closest-point query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// Index of the face in the mesh.
    pub face: usize,
    /// The closest point on the mesh, mm.
    pub point: Point,
    /// Euclidean distance from the query point, mm.
    pub distance: f64,
    /// Barycentric coordinates of `point` with respect to the face's corners (sum 1, each >= 0).
    pub barycentric: [f64; 3],
    /// The feature of the face that holds `point`.
    pub feature: Feature,
}

/// A ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Index of the face hit.
    pub face: usize,
    /// Ray parameter: the hit is at `origin + t * dir`.
    pub t: f64,
    /// The hit point, mm.
    pub point: Point,
}

/// Closest point on triangle `abc` to `p` (Ericson 2005, section 5.1.5, `ClosestPtPointTriangle`):
/// classifies `p` into the Voronoi regions of the three corners, three edges and the face, and
/// projects onto that feature. Returns the point, its barycentric coordinates and the feature.
/// A degenerate triangle (zero area) yields a point on one of its edges or corners: an edge of
/// zero length has no Voronoi region of its own (its region test holds trivially and its
/// projection would be 0/0), so it is skipped and the neighbouring edge or corner answers.
pub fn closest_point_triangle(
    p: &Point,
    a: &Point,
    b: &Point,
    c: &Point,
) -> (Point, [f64; 3], Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, [1.0, 0.0, 0.0], Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, [0.0, 1.0, 0.0], Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    // d1 - d3 = |ab|², d2 - d6 = |ac|² and (d4 - d3) + (d5 - d6) = |bc|² below.
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 && d1 - d3 > 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0], Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, [0.0, 0.0, 1.0], Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 && d2 - d6 > 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w], Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 && (d4 - d3) + (d5 - d6) > 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w], Feature::Edge(1));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    if !(v.is_finite() && w.is_finite()) {
        // Unreachable for finite input (a degenerate triangle falls in an edge or corner
        // region above); kept so that NaN never escapes.
        return (*a, [1.0, 0.0, 0.0], Feature::Vertex(0));
    }
    (a + ab * v + ac * w, [1.0 - v - w, v, w], Feature::Face)
}

/// Squared distance from `p` to the box `[lo, hi]` (0 inside).
#[inline]
fn box_dist2(p: &Point, lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
    let mut d2 = 0.0;
    for k in 0..3 {
        let d = (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0);
        d2 += d * d;
    }
    d2
}

/// A static AABB tree over the faces of a mesh, borrowed ([`AabbTree::new`]) or owned
/// ([`AabbTree::owning`]) (see the module doc).
#[derive(Clone, Debug)]
pub struct AabbTree<'m> {
    mesh: Cow<'m, TriMesh>,
    nodes: Vec<Node>,
    /// Face indices in leaf order.
    order: Vec<u32>,
}

impl AabbTree<'static> {
    /// [`AabbTree::new`] over a mesh the tree keeps, for a structure that holds its own index.
    pub fn owning(mesh: TriMesh) -> Self {
        Self::build(Cow::Owned(mesh))
    }
}

impl<'m> AabbTree<'m> {
    /// Build the tree over every face of `mesh` (median split, Ericson 6.2.1). O(F log F).
    /// An empty mesh gives a tree whose queries return `None`.
    ///
    /// # Panics
    /// Never for a mesh made by [`TriMesh::new`]; meshes beyond 2^32 faces are not supported.
    pub fn new(mesh: &'m TriMesh) -> Self {
        Self::build(Cow::Borrowed(mesh))
    }

    fn build(mesh: Cow<'m, TriMesh>) -> Self {
        let n = mesh.n_faces();
        assert!(n < u32::MAX as usize, "more than 2^32 faces");
        let centroids: Vec<[f64; 3]> = (0..n)
            .map(|f| {
                let [a, b, c] = mesh.corners(f);
                let s = (a.coords + b.coords + c.coords) / 3.0;
                [s.x, s.y, s.z]
            })
            .collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF_SIZE + 1);
        if n > 0 {
            build_node(&mesh, &centroids, &mut order, 0, n, &mut nodes);
        }
        AabbTree { mesh, nodes, order }
    }

    /// The mesh the tree was built over.
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// The closest point of the mesh to `p` (Ericson 5.1.5 per face, pruned by the tree);
    /// `None` for an empty mesh or a non-finite `p`.
    pub fn closest_point(&self, p: &Point) -> Option<Closest> {
        self.closest_point_within(p, f64::INFINITY)
    }

    /// [`Self::closest_point`] when it is within `max_dist` of `p`, else `None`; boxes further
    /// than `max_dist` are never opened, so a query far from the mesh costs a few box tests.
    pub fn closest_point_within(&self, p: &Point, max_dist: f64) -> Option<Closest> {
        // One deref of the borrowed-or-owned mesh, not one per face.
        let mesh: &TriMesh = &self.mesh;
        if self.nodes.is_empty()
            || !p.coords.iter().all(|c| c.is_finite())
            || max_dist.is_nan()
            || max_dist < 0.0
        {
            return None;
        }
        let mut best: Option<(f64, usize, Point, [f64; 3], Feature)> = None;
        let mut best_d2 = max_dist * max_dist;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if box_dist2(p, &node.lo, &node.hi) > best_d2 {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for &f in &self.order[s..s + node.count as usize] {
                    let f = f as usize;
                    let [a, b, c] = mesh.corners(f);
                    let (q, bary, feat) = closest_point_triangle(p, &a, &b, &c);
                    let d2 = (q - p).norm_squared();
                    let better = match best {
                        None => d2 <= best_d2,
                        Some((bd2, bf, ..)) => d2 < bd2 || (d2 == bd2 && f < bf),
                    };
                    if better {
                        best = Some((d2, f, q, bary, feat));
                        best_d2 = d2;
                    }
                }
            } else {
                let (l, r) = (i + 1, node.index);
                let dl = {
                    let n = &self.nodes[l as usize];
                    box_dist2(p, &n.lo, &n.hi)
                };
                let dr = {
                    let n = &self.nodes[r as usize];
                    box_dist2(p, &n.lo, &n.hi)
                };
                // Visit the nearer child first (pushed last).
                if dl <= dr {
                    stack.push(r);
                    stack.push(l);
                } else {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        best.map(|(d2, face, point, barycentric, feature)| Closest {
            face,
            point,
            distance: d2.sqrt(),
            barycentric,
            feature,
        })
    }

    /// Unsigned distance from `p` to the mesh, mm; `None` as for [`Self::closest_point`].
    pub fn distance(&self, p: &Point) -> Option<f64> {
        self.closest_point(p).map(|c| c.distance)
    }

    /// [`Self::closest_point`] of every point, in parallel; deterministic (one result per point,
    /// in order).
    pub fn closest_points(&self, points: &[Point]) -> Vec<Option<Closest>> {
        points.par_iter().map(|p| self.closest_point(p)).collect()
    }

    /// [`Self::distance`] of every point, in parallel.
    pub fn distances(&self, points: &[Point]) -> Vec<Option<f64>> {
        points.par_iter().map(|p| self.distance(p)).collect()
    }

    /// Every face within `radius` of `p`, as `(face, distance)` sorted by face index, appended to
    /// `out` (cleared first). A range query: boxes further than `radius` are pruned.
    pub fn faces_within(&self, p: &Point, radius: f64, out: &mut Vec<(usize, f64)>) {
        // One deref of the borrowed-or-owned mesh, not one per face.
        let mesh: &TriMesh = &self.mesh;
        out.clear();
        if self.nodes.is_empty()
            || !p.coords.iter().all(|c| c.is_finite())
            || radius.is_nan()
            || radius < 0.0
        {
            return;
        }
        let r2 = radius * radius;
        let mut stack: Vec<u32> = vec![0];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if box_dist2(p, &node.lo, &node.hi) > r2 {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for &f in &self.order[s..s + node.count as usize] {
                    let f = f as usize;
                    let [a, b, c] = mesh.corners(f);
                    let (q, ..) = closest_point_triangle(p, &a, &b, &c);
                    let d2 = (q - p).norm_squared();
                    if d2 <= r2 {
                        out.push((f, d2.sqrt()));
                    }
                }
            } else {
                stack.push(node.index);
                stack.push(i + 1);
            }
        }
        out.sort_unstable_by_key(|x| x.0);
    }

    /// The closest point (as [`Self::closest_point`]) together with every face within
    /// `distance + margin` of `p`, as `(face, distance)` sorted by face index, in one traversal
    /// whose pruning bound shrinks with the best distance found so far. `out` is cleared first.
    pub fn closest_with_neighbours(
        &self,
        p: &Point,
        margin: f64,
        out: &mut Vec<(usize, f64)>,
    ) -> Option<Closest> {
        out.clear();
        // One deref of the borrowed-or-owned mesh, not one per face.
        let mesh: &TriMesh = &self.mesh;
        if self.nodes.is_empty()
            || !p.coords.iter().all(|c| c.is_finite())
            || margin.is_nan()
            || margin < 0.0
        {
            return None;
        }
        let mut best: Option<(f64, usize, Point, [f64; 3], Feature)> = None;
        let mut bound2 = f64::INFINITY;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if box_dist2(p, &node.lo, &node.hi) > bound2 {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for &f in &self.order[s..s + node.count as usize] {
                    let f = f as usize;
                    let [a, b, c] = mesh.corners(f);
                    let (q, bary, feat) = closest_point_triangle(p, &a, &b, &c);
                    let d2 = (q - p).norm_squared();
                    if d2 > bound2 {
                        continue;
                    }
                    out.push((f, d2));
                    let better = match best {
                        None => true,
                        Some((bd2, bf, ..)) => d2 < bd2 || (d2 == bd2 && f < bf),
                    };
                    if better {
                        best = Some((d2, f, q, bary, feat));
                        // Never below d2 itself, so exact ties are all visited (lowest index
                        // wins, as in `closest_point`) despite the rounding of sqrt.
                        let r = d2.sqrt() + margin;
                        bound2 = (r * r).max(d2);
                    }
                }
            } else {
                let (l, r) = (i + 1, node.index);
                let dl = box_dist2(p, &self.nodes[l as usize].lo, &self.nodes[l as usize].hi);
                let dr = box_dist2(p, &self.nodes[r as usize].lo, &self.nodes[r as usize].hi);
                if dl <= dr {
                    stack.push(r);
                    stack.push(l);
                } else {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        let (d2, face, point, barycentric, feature) = best?;
        let distance = d2.sqrt();
        // Faces taken in before the bound tightened may lie beyond it.
        out.retain(|&(_, d2)| d2 <= bound2);
        for x in out.iter_mut() {
            x.1 = x.1.sqrt();
        }
        out.sort_unstable_by_key(|x| x.0);
        Some(Closest {
            face,
            point,
            distance,
            barycentric,
            feature,
        })
    }

    /// First hit of the ray `origin + t * dir`, `t` in `(t_min, t_max)`, with the mesh
    /// (Möller & Trumbore 1997 per face, slab test per box: Kay & Kajiya 1986); faces are hit
    /// from either side. `dir` need not be unit; `t` is in units of `dir`.
    pub fn ray_cast(&self, origin: &Point, dir: &Vec3, t_min: f64, t_max: f64) -> Option<RayHit> {
        // One deref of the borrowed-or-owned mesh, not one per face.
        let mesh: &TriMesh = &self.mesh;
        if self.nodes.is_empty() || dir.norm_squared() == 0.0 {
            return None;
        }
        let inv = Vec3::new(1.0 / dir.x, 1.0 / dir.y, 1.0 / dir.z);
        let mut best: Option<(f64, usize)> = None;
        let mut t_best = t_max;
        let mut stack: Vec<u32> = vec![0];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if !slab_hit(origin, &inv, &node.lo, &node.hi, t_min, t_best) {
                continue;
            }
            if node.count > 0 {
                let s = node.index as usize;
                for &f in &self.order[s..s + node.count as usize] {
                    let f = f as usize;
                    let [a, b, c] = mesh.corners(f);
                    if let Some(t) = ray_triangle(origin, dir, &a, &b, &c) {
                        let better = t > t_min
                            && (t < t_best || (t == t_best && best.is_some_and(|(_, bf)| f < bf)));
                        if better {
                            t_best = t;
                            best = Some((t, f));
                        }
                    }
                }
            } else {
                stack.push(node.index);
                stack.push(i + 1);
            }
        }
        best.map(|(t, face)| RayHit {
            face,
            t,
            point: origin + dir * t,
        })
    }
}

/// Ray-triangle intersection parameter (Möller & Trumbore 1997), either side, `None` if parallel
/// or missed.
fn ray_triangle(o: &Point, d: &Vec3, a: &Point, b: &Point, c: &Point) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(&q) * inv)
}

/// Whether the ray meets the box within `[t0, t1]` (slab method; infinite `inv` components from
/// axis-parallel rays are handled by IEEE arithmetic, NaN from `0 * inf` by `max`/`min`).
fn slab_hit(o: &Point, inv: &Vec3, lo: &[f64; 3], hi: &[f64; 3], t0: f64, t1: f64) -> bool {
    let (mut tn, mut tf) = (t0, t1);
    for k in 0..3 {
        let a = (lo[k] - o[k]) * inv[k];
        let b = (hi[k] - o[k]) * inv[k];
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        // A NaN (origin on a slab plane of a flat box with a parallel ray) does not prune.
        if a.is_finite() || a == f64::NEG_INFINITY {
            tn = tn.max(a);
        }
        if b.is_finite() || b == f64::INFINITY {
            tf = tf.min(b);
        }
        if tn > tf {
            return false;
        }
    }
    true
}

/// Build the subtree over `order[start..end]` in depth-first layout and return its slot. The
/// median split halves the range, so the recursion depth is at most log2(F).
fn build_node(
    mesh: &TriMesh,
    centroids: &[[f64; 3]],
    order: &mut [u32],
    start: usize,
    end: usize,
    nodes: &mut Vec<Node>,
) -> u32 {
    let slot = nodes.len();
    let (lo, hi) = face_bounds(mesh, &order[start..end]);
    nodes.push(Node {
        lo,
        hi,
        index: start as u32,
        count: (end - start) as u32,
    });
    if end - start > LEAF_SIZE {
        let (clo, chi) = centroid_bounds(centroids, &order[start..end]);
        let axis = (0..3)
            .max_by(|&i, &j| (chi[i] - clo[i]).total_cmp(&(chi[j] - clo[j])))
            .unwrap_or(0);
        let mid = start + (end - start) / 2;
        // Ties broken by face index, so the layout depends on the mesh only.
        order[start..end].select_nth_unstable_by(mid - start, |&x, &y| {
            centroids[x as usize][axis]
                .total_cmp(&centroids[y as usize][axis])
                .then(x.cmp(&y))
        });
        build_node(mesh, centroids, order, start, mid, nodes);
        let right = build_node(mesh, centroids, order, mid, end, nodes);
        nodes[slot].index = right;
        nodes[slot].count = 0;
    }
    slot as u32
}

fn face_bounds(mesh: &TriMesh, faces: &[u32]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &f in faces {
        for p in mesh.corners(f as usize) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    (lo, hi)
}

fn centroid_bounds(c: &[[f64; 3]], faces: &[u32]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &f in faces {
        for k in 0..3 {
            lo[k] = lo[k].min(c[f as usize][k]);
            hi[k] = hi[k].max(c[f as usize][k]);
        }
    }
    (lo, hi)
}

/// Angle-weighted pseudo-normals of a mesh's faces, edges and vertices (Bærentzen & Aanæs 2005,
/// section 3): the face normal, the sum of the two adjacent face normals for an edge, and the
/// incident-angle-weighted sum of face normals for a vertex ([`TriMesh::vertex_normals`]).
#[derive(Clone, Debug)]
pub struct PseudoNormals {
    face: Vec<Vec3>,
    /// Per face, edge `k` (corner `k` to `k + 1`).
    edge: Vec<[Vec3; 3]>,
    vertex: Vec<Vec3>,
}

impl PseudoNormals {
    /// Compute the pseudo-normals of `mesh`. O(F) with one hash map of edges.
    pub fn new(mesh: &TriMesh) -> Self {
        let face = mesh.face_normals();
        let mut sums: HashMap<(usize, usize), Vec3> =
            HashMap::with_capacity(mesh.n_faces() * 3 / 2);
        for (f, idx) in mesh.faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (idx[k], idx[(k + 1) % 3]);
                *sums.entry((a.min(b), a.max(b))).or_insert_with(Vec3::zeros) += face[f];
            }
        }
        let edge = mesh
            .faces
            .iter()
            .map(|idx| {
                std::array::from_fn(|k| {
                    let (a, b) = (idx[k], idx[(k + 1) % 3]);
                    sums[&(a.min(b), a.max(b))]
                })
            })
            .collect();
        PseudoNormals {
            face,
            edge,
            vertex: mesh.vertex_normals(),
        }
    }

    /// The pseudo-normal of `feature` of face `f` (not normalised; only its direction counts).
    pub fn of(&self, mesh: &TriMesh, f: usize, feature: Feature) -> Vec3 {
        match feature {
            Feature::Face => self.face[f],
            Feature::Edge(k) => self.edge[f][k as usize],
            Feature::Vertex(k) => self.vertex[mesh.faces[f][k as usize]],
        }
    }
}

impl AabbTree<'_> {
    /// Signed distance from `p` to a closed, outward-oriented mesh: positive outside, negative
    /// inside, by the angle-weighted pseudo-normal of the closest feature (Bærentzen & Aanæs
    /// 2005, theorem 1). `normals` must be [`PseudoNormals::new`] of the same mesh. For an open
    /// mesh the sign is only meaningful near the surface. `None` as for [`Self::closest_point`].
    pub fn signed_distance(&self, normals: &PseudoNormals, p: &Point) -> Option<f64> {
        let c = self.closest_point(p)?;
        let n = normals.of(&self.mesh, c.face, c.feature);
        let s = if (p - c.point).dot(&n) < 0.0 {
            -1.0
        } else {
            1.0
        };
        Some(s * c.distance)
    }

    /// [`Self::signed_distance`] of every point, in parallel.
    pub fn signed_distances(&self, normals: &PseudoNormals, points: &[Point]) -> Vec<Option<f64>> {
        points
            .par_iter()
            .map(|p| self.signed_distance(normals, p))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::geometry::mesh::tests::cuboid;
    use crate::rng::Rng;

    /// Reference closest point on a triangle by a different route than Ericson's: the plane
    /// projection when it falls inside (barycentric by Cramer's rule), else the best of the three
    /// clamped segment projections.
    fn reference_triangle(p: &Point, t: [Point; 3]) -> Point {
        let [a, b, c] = t;
        let (e1, e2) = (b - a, c - a);
        let n = e1.cross(&e2);
        if n.norm_squared() > 0.0 {
            let q = p - n * ((p - a).dot(&n) / n.norm_squared());
            let w = q - a;
            let (d11, d12, d22) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
            let (d1, d2) = (w.dot(&e1), w.dot(&e2));
            let den = d11 * d22 - d12 * d12;
            let v = (d22 * d1 - d12 * d2) / den;
            let u = (d11 * d2 - d12 * d1) / den;
            if v >= 0.0 && u >= 0.0 && u + v <= 1.0 {
                return q;
            }
        }
        let seg = |s: Point, e: Point| {
            let d = e - s;
            let t = if d.norm_squared() > 0.0 {
                ((p - s).dot(&d) / d.norm_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            s + d * t
        };
        [seg(a, b), seg(b, c), seg(c, a)]
            .into_iter()
            .min_by(|x, y| (x - p).norm().total_cmp(&(y - p).norm()))
            .unwrap()
    }

    /// Brute-force distance to a mesh with the reference triangle test.
    fn brute_distance(mesh: &TriMesh, p: &Point) -> f64 {
        (0..mesh.n_faces())
            .map(|f| (reference_triangle(p, mesh.corners(f)) - p).norm())
            .fold(f64::INFINITY, f64::min)
    }

    /// Generalised winding number (Jacobson et al. 2013) by the solid angle of each face
    /// (Van Oosterom & Strackee 1983): about 1 inside a closed outward mesh, 0 outside.
    fn winding_number(mesh: &TriMesh, p: &Point) -> f64 {
        let mut w = 0.0;
        for f in 0..mesh.n_faces() {
            let [a, b, c] = mesh.corners(f).map(|q| q - p);
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            let num = a.dot(&b.cross(&c));
            let den = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
            w += 2.0 * num.atan2(den);
        }
        w / (4.0 * std::f64::consts::PI)
    }

    fn random_points(mesh: &TriMesh, n: usize, seed: u64) -> Vec<Point> {
        let (lo, hi) = mesh.bounds().unwrap();
        let pad = 0.1 * mesh.diagonal();
        let mut rng = Rng::new(seed);
        let normals = mesh.vertex_normals();
        (0..n)
            .map(|i| {
                if i % 2 == 0 {
                    Point::new(
                        rng.range(lo.x - pad, hi.x + pad),
                        rng.range(lo.y - pad, hi.y + pad),
                        rng.range(lo.z - pad, hi.z + pad),
                    )
                } else {
                    // Near the surface, where the closest face changes quickly.
                    let v = rng.below(mesh.n_vertices());
                    mesh.vertices[v] + normals[v] * rng.range(-1.0, 1.0) + rng.gauss3(0.3)
                }
            })
            .collect()
    }

    /// The tree's answer is consistent (point on the face, barycentric reproduce it, distance
    /// matches) and as close as brute force.
    fn check_against_brute(mesh: &TriMesh, points: &[Point]) {
        let tree = AabbTree::new(mesh);
        for (i, p) in points.iter().enumerate() {
            let c = tree.closest_point(p).unwrap();
            let brute = brute_distance(mesh, p);
            assert!(
                (c.distance - brute).abs() <= 1e-9 * (1.0 + brute),
                "point {i}: tree {} brute {brute}",
                c.distance
            );
            assert!(((c.point - p).norm() - c.distance).abs() < 1e-9);
            let [a, b, q] = mesh.corners(c.face);
            let from_bary = a.coords * c.barycentric[0]
                + b.coords * c.barycentric[1]
                + q.coords * c.barycentric[2];
            assert!((from_bary - c.point.coords).norm() < 1e-9, "point {i}");
            assert!(c.barycentric.iter().all(|&x| x >= -1e-12));
            assert!((c.barycentric.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let on_face = reference_triangle(&c.point, mesh.corners(c.face));
            assert!(
                (on_face - c.point).norm() < 1e-9,
                "point {i} not on face {}",
                c.face
            );
        }
    }

    #[test]
    fn triangle_regions_match_reference() {
        let mut rng = Rng::new(7);
        for _ in 0..5000 {
            let t = [rng.gauss3(10.0), rng.gauss3(10.0), rng.gauss3(10.0)].map(Point::from);
            let p = Point::from(rng.gauss3(20.0));
            let (q, bary, feature) = closest_point_triangle(&p, &t[0], &t[1], &t[2]);
            let r = reference_triangle(&p, t);
            assert!(((q - p).norm() - (r - p).norm()).abs() < 1e-9);
            assert!((q - r).norm() < 1e-6);
            let zeros = bary.iter().filter(|&&x| x == 0.0).count();
            let expected = match feature {
                Feature::Face => 0,
                Feature::Edge(_) => 1,
                Feature::Vertex(_) => 2,
            };
            assert!(zeros >= expected, "{feature:?} {bary:?}");
            if let Feature::Edge(k) = feature {
                assert_eq!(
                    bary[(k as usize + 2) % 3],
                    0.0,
                    "edge {k} must exclude the opposite corner"
                );
            }
        }
    }

    #[test]
    fn degenerate_triangles_give_finite_points() {
        let a = Point::new(0.0, 0.0, 0.0);
        let b = Point::new(1.0, 1.0, 1.0);
        let c = Point::from(b.coords * 2.0);
        // Every zero-length edge in every position (the slivers of a marching-tetrahedra
        // isosurface have them), and collinear corners, seen from points all around.
        let triangles = [
            [a, a, a],
            [a, b, b],
            [b, a, b],
            [a, a, b],
            [b, b, a],
            [a, b, a],
            [a, b, c],
            [c, a, b],
        ];
        for p in [
            Point::new(3.0, -2.0, 0.5),
            Point::new(-1.0, 0.2, 0.1),
            Point::new(0.5, 0.5, 0.6),
            Point::new(2.5, 2.0, 2.2),
        ] {
            for t in triangles {
                let (q, bary, _) = closest_point_triangle(&p, &t[0], &t[1], &t[2]);
                assert!(
                    q.coords.iter().all(|x| x.is_finite()) && bary.iter().all(|x| x.is_finite()),
                    "{t:?} from {p}"
                );
                let r = reference_triangle(&p, t);
                assert!(
                    ((q - p).norm() - (r - p).norm()).abs() < 1e-9,
                    "{t:?} from {p}"
                );
            }
        }
    }

    #[test]
    fn cube_matches_brute_force_and_closed_form() {
        let (a, b, c) = (20.0, 30.0, 40.0);
        let m = cuboid(a, b, c);
        let pts = random_points(&m, 2000, 11);
        check_against_brute(&m, &pts);
        let tree = AabbTree::new(&m);
        let normals = PseudoNormals::new(&m);
        for p in &pts {
            // Closed form of the signed distance to a box.
            let lo = Vec3::new(-p.x, -p.y, -p.z);
            let hi = Vec3::new(p.x - a, p.y - b, p.z - c);
            let q = lo.sup(&hi);
            let outside = q.sup(&Vec3::zeros()).norm();
            let inside = q.max().min(0.0);
            let expected = outside + inside;
            let sd = tree.signed_distance(&normals, p).unwrap();
            assert!((sd - expected).abs() < 1e-9, "{p}: {sd} vs {expected}");
        }
    }

    #[test]
    fn bounded_query_is_the_closest_point_or_nothing() {
        let m = cuboid(20.0, 30.0, 40.0);
        let tree = AabbTree::new(&m);
        let owned = AabbTree::owning(m.clone());
        let mut rng = Rng::new(21);
        let (mut hits, mut misses) = (0, 0);
        for p in random_points(&m, 2000, 13) {
            let c = tree.closest_point(&p).unwrap();
            assert_eq!(owned.closest_point(&p), Some(c));
            let r = rng.range(0.0, 30.0);
            match tree.closest_point_within(&p, r) {
                Some(b) => {
                    assert!(c.distance <= r);
                    assert_eq!(b, c);
                    hits += 1;
                }
                None => {
                    assert!(c.distance > r, "{p}: {} within {r}", c.distance);
                    misses += 1;
                }
            }
        }
        assert!(hits > 100 && misses > 100, "{hits} hits, {misses} misses");
    }

    #[test]
    fn template_matches_brute_force() {
        let hand = crate::template::load_template(Side::Right).unwrap();
        let pts = random_points(&hand.mesh, 300, 12);
        check_against_brute(&hand.mesh, &pts);
    }

    #[test]
    fn template_sign_agrees_with_winding_number() {
        let mesh = crate::template::load_template(Side::Right)
            .unwrap()
            .base
            .mesh;
        let tree = AabbTree::new(&mesh);
        let normals = PseudoNormals::new(&mesh);
        let pts = random_points(&mesh, 600, 13);
        let (mut inside, mut outside) = (0, 0);
        for (i, p) in pts.iter().enumerate() {
            let sd = tree.signed_distance(&normals, p).unwrap();
            if sd.abs() < 1e-6 {
                continue;
            }
            let w = winding_number(&mesh, p);
            assert!((w - w.round()).abs() < 1e-6, "winding {w}");
            assert_eq!(sd < 0.0, w > 0.5, "point {i} {p}: sd {sd} winding {w}");
            if sd < 0.0 {
                inside += 1;
            } else {
                outside += 1;
            }
        }
        assert!(
            inside > 50 && outside > 50,
            "{inside} inside, {outside} outside"
        );
    }

    #[test]
    fn batch_is_deterministic_and_matches_single_queries() {
        let hand = crate::template::load_template(Side::Right).unwrap();
        let tree = AabbTree::new(&hand.mesh);
        let pts = random_points(&hand.mesh, 2000, 14);
        let batch = tree.closest_points(&pts);
        let again = tree.closest_points(&pts);
        assert_eq!(batch, again);
        for (p, c) in pts.iter().zip(&batch) {
            assert_eq!(*c, tree.closest_point(p));
        }
        let d = tree.distances(&pts);
        assert!(d
            .iter()
            .zip(&batch)
            .all(|(d, c)| *d == c.map(|c| c.distance)));
    }

    #[test]
    fn faces_within_matches_brute_force() {
        let hand = crate::template::load_template(Side::Right).unwrap();
        let mesh = &hand.base.mesh;
        let tree = AabbTree::new(mesh);
        let mut out = Vec::new();
        for (i, p) in random_points(mesh, 200, 15).iter().enumerate() {
            let r = 3.0 + (i % 7) as f64;
            tree.faces_within(p, r, &mut out);
            let brute: Vec<usize> = (0..mesh.n_faces())
                .filter(|&f| (reference_triangle(p, mesh.corners(f)) - p).norm() <= r - 1e-9)
                .collect();
            let got: Vec<usize> = out.iter().map(|x| x.0).collect();
            // Faces at exactly the radius may go either way under rounding.
            assert!(brute.iter().all(|f| got.contains(f)), "point {i}");
            assert!(out.iter().all(|&(_, d)| d <= r), "point {i}");
            assert!(got.windows(2).all(|w| w[0] < w[1]));
        }
    }

    #[test]
    fn closest_with_neighbours_matches_separate_queries() {
        let hand = crate::template::load_template(Side::Right).unwrap();
        let mesh = &hand.base.mesh;
        let tree = AabbTree::new(mesh);
        let (mut out, mut near) = (Vec::new(), Vec::new());
        for (i, p) in random_points(mesh, 300, 17).iter().enumerate() {
            let margin = (i % 5) as f64;
            let c = tree.closest_with_neighbours(p, margin, &mut out);
            assert_eq!(c, tree.closest_point(p), "point {i}");
            let c = c.unwrap();
            tree.faces_within(p, c.distance + margin, &mut near);
            // The same faces up to rounding at the radius.
            assert!(near.iter().all(|x| out.contains(x)), "point {i}");
            assert!(out.iter().all(|&(_, d)| d <= c.distance + margin + 1e-12));
            assert!(out.iter().any(|&(f, _)| f == c.face));
            assert!(out.windows(2).all(|w| w[0].0 < w[1].0));
        }
    }

    #[test]
    fn ray_cast_matches_brute_force() {
        let hand = crate::template::load_template(Side::Right).unwrap();
        let mesh = &hand.base.mesh;
        let tree = AabbTree::new(mesh);
        let mut rng = Rng::new(16);
        let centre = mesh.vertex_centroid();
        let mut hits = 0;
        for _ in 0..300 {
            let o = centre + rng.gauss3(30.0);
            let d = rng.unit_vector();
            let got = tree.ray_cast(&o, &d, 0.0, f64::INFINITY);
            let brute = (0..mesh.n_faces())
                .filter_map(|f| {
                    let [a, b, c] = mesh.corners(f);
                    ray_triangle(&o, &d, &a, &b, &c)
                        .filter(|&t| t > 0.0)
                        .map(|t| (t, f))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            assert_eq!(got.map(|h| (h.t, h.face)), brute);
            hits += got.is_some() as usize;
        }
        assert!(hits > 50);
        // Closed form on a box: from the centre along +x the exit is at the half-width.
        let m = cuboid(20.0, 30.0, 40.0);
        let t = AabbTree::new(&m);
        let h = t
            .ray_cast(
                &Point::new(10.0, 15.0, 20.0),
                &Vec3::x(),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 10.0).abs() < 1e-12 && (h.point.x - 20.0).abs() < 1e-12);
    }

    #[test]
    fn empty_mesh_and_bad_points_give_none() {
        let empty = TriMesh::new(vec![], vec![]).unwrap();
        let tree = AabbTree::new(&empty);
        assert!(tree.closest_point(&Point::origin()).is_none());
        assert!(tree
            .ray_cast(&Point::origin(), &Vec3::x(), 0.0, 1.0)
            .is_none());
        let m = cuboid(1.0, 1.0, 1.0);
        let tree = AabbTree::new(&m);
        assert!(tree
            .closest_point(&Point::new(f64::NAN, 0.0, 0.0))
            .is_none());
        assert!(tree
            .distance(&Point::new(0.0, f64::INFINITY, 0.0))
            .is_none());
    }
}
