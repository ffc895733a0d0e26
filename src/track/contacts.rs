//! Contacts of the replayed hand with the part, frame by frame: the paper's stated purpose,
//! "calculate and visualize contact areas between the product models and the hand models" for
//! the subject's own hand moving on the product.
//!
//! In each frame where both the hand and the part are tracked, the individual skin is posed by
//! linear blend skinning with the tracked link transforms ([`Kinematics::evaluate`]; the skin
//! and the link model share the static trial's frame, so a link's transform from the
//! reference posture is exactly the skinning transform) and taken into the part's own frame by
//! the inverse of the part's tracked pose, so the part's query structure is built once. Each
//! skin vertex is then probed against the part as the grasp stage probes it
//! ([`PartShape::probe`]): within `tolerance_mm` of the surface, or inside the part at any
//! depth, it is in contact, and its share of the rest skin area counts for its dominant link.
//! Penetration matters here as it does not in the grasp stage: tracked digits are placed by
//! markers, not stopped at the surface, so a vertex deeper than the broad phase's band is
//! measured exactly for its depth instead of being dropped.
//!
//! Accumulated over the trial, the contact map counts per skin vertex and per part vertex the
//! frames in contact. A part vertex is in contact in a frame when a touching skin vertex's
//! projection on the part lies within the skin's mean edge length of it: the skin is the
//! coarser mesh, and a projection alone would mark one part vertex per skin vertex, a speckle.

use super::kinematics::Kinematics;
use super::Tracked;
use crate::geometry::{Point, TriMesh};
use crate::grasp::broad::Zone;
use crate::grasp::contact::{vertex_areas, PartShape, Probe};
use crate::grasp::hand::{PosableHand, SkinnedHand};
// The same `[R − I | t]` linear blend skinning forms, so a posed vertex is the very one.
use crate::pose::skinning::displacement_matrix;
use nalgebra::Isometry3;
use rayon::prelude::*;

/// Contact replay settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayOptions {
    /// A skin vertex within this distance of the part (or inside it) is in contact, mm; the
    /// grasp stage's default.
    pub tolerance_mm: f64,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            tolerance_mm: crate::grasp::contact::ContactOptions::default().tolerance_mm,
        }
    }
}

/// One frame's contacts.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameContacts {
    /// Skin area in contact per link ([`Link::index`]), mm² (rest areas).
    pub link_area_mm2: [f64; 17],
    /// Deepest penetration per link, mm (0 when only within the tolerance).
    pub link_depth_mm: [f64; 17],
    /// Skin vertices in contact, ascending.
    pub skin_vertices: Vec<u32>,
}

impl FrameContacts {
    /// Total contact area, mm².
    pub fn total_area_mm2(&self) -> f64 {
        self.link_area_mm2.iter().sum()
    }
}

/// Contacts over a trial.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactReplay {
    /// Per frame; `None` where the hand or the part was not tracked.
    pub frames: Vec<Option<FrameContacts>>,
    /// Per skin vertex: frames in contact.
    pub skin_count: Vec<u32>,
    /// Per part vertex: frames in contact.
    pub part_count: Vec<u32>,
}

impl ContactReplay {
    /// Frames where the hand was solved but the part's pose was unknown, so contacts are `None`.
    pub fn missing(&self, tracked: &Tracked) -> Vec<usize> {
        (0..self.frames.len())
            .filter(|&f| self.frames[f].is_none() && tracked.frames[f].state.is_some())
            .collect()
    }
}

/// Part vertices in a dense uniform grid (cells in one array, compressed rows), for the
/// contact map's radius search: a few array reads per touching vertex and frame.
struct VertexGrid {
    origin: Point,
    cell: f64,
    dims: [i64; 3],
    start: Vec<u32>,
    items: Vec<u32>,
}

impl VertexGrid {
    fn new(points: &[Point], cell: f64) -> VertexGrid {
        let (mut lo, mut hi) = (Point::origin(), Point::origin());
        if let Some(first) = points.first() {
            (lo, hi) = (*first, *first);
            for p in points {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
        }
        let dims = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / cell).floor() as i64 + 1);
        let mut g = VertexGrid {
            origin: lo,
            cell,
            dims,
            start: Vec::new(),
            items: Vec::new(),
        };
        let n_cells = (dims[0] * dims[1] * dims[2]) as usize;
        let idx: Vec<usize> = points
            .iter()
            .map(|p| g.index(g.key(p)).expect("inside its own bounds"))
            .collect();
        let mut start = vec![0u32; n_cells + 1];
        for &c in &idx {
            start[c + 1] += 1;
        }
        for c in 0..n_cells {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; points.len()];
        for (v, &c) in idx.iter().enumerate() {
            items[fill[c] as usize] = v as u32;
            fill[c] += 1;
        }
        g.start = start;
        g.items = items;
        g
    }

    fn key(&self, p: &Point) -> [i64; 3] {
        [0, 1, 2].map(|a| ((p[a] - self.origin[a]) / self.cell).floor() as i64)
    }

    fn index(&self, k: [i64; 3]) -> Option<usize> {
        (0..3)
            .all(|a| (0..self.dims[a]).contains(&k[a]))
            .then(|| ((k[0] * self.dims[1] + k[1]) * self.dims[2] + k[2]) as usize)
    }

    /// Vertices within `r <= cell` of `p`, appended to `out`.
    fn within(&self, points: &[Point], p: &Point, r: f64, out: &mut Vec<u32>) {
        let k = self.key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(c) = self.index([k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    let vs = &self.items[self.start[c] as usize..self.start[c + 1] as usize];
                    out.extend(
                        vs.iter()
                            .copied()
                            .filter(|&v| (points[v as usize] - p).norm_squared() <= r * r),
                    );
                }
            }
        }
    }
}

/// Per link, a bound on where linear blend skinning can put the vertices it dominates: the
/// rest sphere about them and the links their weights blend.
struct LinkBound {
    centre: Point,
    radius: f64,
    blends: Vec<usize>,
}

impl LinkBound {
    fn of(hand: &SkinnedHand) -> Vec<LinkBound> {
        let rest = &hand.rest_mesh().vertices;
        hand.link_vertices()
            .iter()
            .enumerate()
            .map(|(l, vs)| {
                if vs.is_empty() {
                    return LinkBound {
                        centre: Point::origin(),
                        radius: 0.0,
                        blends: Vec::new(),
                    };
                }
                let c = vs
                    .iter()
                    .fold(nalgebra::Vector3::zeros(), |a, &i| a + rest[i].coords)
                    / vs.len() as f64;
                let centre = Point::from(c);
                let radius = vs
                    .iter()
                    .map(|&i| (rest[i] - centre).norm())
                    .fold(0.0, f64::max);
                let mut blends: Vec<usize> = vs
                    .iter()
                    .flat_map(|&i| hand.hand.weights[i].iter().map(|&(k, _)| k))
                    .filter(|&k| k != l)
                    .collect();
                blends.sort_unstable();
                blends.dedup();
                LinkBound {
                    centre,
                    radius,
                    blends,
                }
            })
            .collect()
    }

    /// Whether some vertex of the link may lie within `reach` of the box `lo..hi` under the
    /// link transforms `t` (`l` the link). A blended vertex `Σ w_k T_k v` lies within
    /// `max_k |T_k v - T_l v|` of `T_l v`, and for `v` in the rest sphere that is at most
    /// `|T_k c - T_l c| + ‖R_k - R_l‖ r`.
    fn may_reach(
        &self,
        l: usize,
        t: &[Isometry3<f64>],
        lo: &Point,
        hi: &Point,
        reach: f64,
    ) -> bool {
        let tl = t[l] * self.centre;
        let spread = self
            .blends
            .iter()
            .map(|&k| {
                let dr = t[k].rotation.to_rotation_matrix().matrix()
                    - t[l].rotation.to_rotation_matrix().matrix();
                (t[k] * self.centre - tl).norm() + dr.norm() * self.radius
            })
            .fold(0.0, f64::max);
        let gap = (0..3)
            .map(|a| (lo[a] - tl[a]).max(tl[a] - hi[a]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt();
        gap <= self.radius + spread + reach
    }
}

/// A link's deepest penetration after its branch and bound, and the exact queries it made (the
/// index in the frame's touching list, what the query found).
type LinkDeepest = (f64, Vec<(usize, Option<Known>)>);

/// What a skin vertex last learnt exactly about the part: where it was, its signed distance
/// there (negative inside) and its projection on the part.
#[derive(Clone, Copy, Debug)]
struct Known {
    at: Point,
    signed: f64,
    projection: Point,
}

/// A vertex in one frame, as far as the bounds allow without a query.
#[derive(Clone, Copy, Debug)]
enum Status {
    /// Farther than the tolerance outside.
    Apart,
    /// In contact; the signed distance lies within `signed ± slack` (`slack` 0: exact).
    Touching {
        signed: f64,
        slack: f64,
        projection: Point,
    },
}

/// The exact signed distance and projection of `p` (unsigned on an open part).
fn exact(part: &PartShape, p: &Point) -> Option<Known> {
    match part.probe(p, f64::INFINITY) {
        Probe::Hit(d, q, _) => Some(Known {
            at: *p,
            signed: d,
            projection: q,
        }),
        _ => None,
    }
}

/// What the broad phase alone can say about the part: whether its outside zone decides
/// "apart" for the tolerance, and the box outside which every point is in that zone.
#[derive(Clone, Copy, Debug)]
struct Broad {
    decides: bool,
    lo: Point,
    hi: Point,
}

impl Broad {
    /// A grid cell is near or inside only if it meets the part's box grown by the band, so a
    /// point farther than one cell beyond that box lies in an outside cell.
    fn of(part: &PartShape, tol: f64) -> Broad {
        let grow = part.grid.band + part.grid.cell_mm() + 1e-6;
        Broad {
            decides: part.grid.band >= tol,
            lo: part.lo - nalgebra::Vector3::repeat(grow),
            hi: part.hi + nalgebra::Vector3::repeat(grow),
        }
    }

    /// How far `p` can move and stay in the outside zone (0 inside the box).
    fn clearance(&self, p: &Point) -> f64 {
        (0..3)
            .map(|a| (self.lo[a] - p[a]).max(p[a] - self.hi[a]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// Classify the vertex at `p` given what it knew, querying the part only when the bounds
/// cannot decide (the signed distance is 1-Lipschitz: it changes by at most the distance
/// moved). Also returns how far the vertex can move from `p` and still be classified apart
/// without a query (`-inf` when touching).
fn classify(
    part: &PartShape,
    broad: &Broad,
    p: &Point,
    known: &mut Option<Known>,
    tol: f64,
) -> (Status, f64) {
    // Apart by the last query or by the broad phase's outside zone, whichever is asked first:
    // the query's bound first spares the grid lookup.
    let moved = known.map(|k| (p - k.at).norm());
    if let (Some(k), Some(moved)) = (*known, moved) {
        if k.signed - moved > tol {
            return (Status::Apart, k.signed - moved - tol);
        }
    }
    if broad.decides && part.grid.zone(p) == Zone::Outside {
        // Apart for as long as it stays in the outside zone (its last query, if any, no
        // longer says so).
        return (Status::Apart, broad.clearance(p));
    }
    if let (Some(k), Some(moved)) = (*known, moved) {
        if k.signed + moved <= tol {
            let st = Status::Touching {
                signed: k.signed,
                slack: moved,
                projection: k.projection + (p - k.at),
            };
            return (st, f64::NEG_INFINITY);
        }
    }
    *known = exact(part, p);
    match known {
        Some(k) if k.signed <= tol => (
            Status::Touching {
                signed: k.signed,
                slack: 0.0,
                projection: k.projection,
            },
            f64::NEG_INFINITY,
        ),
        Some(k) => (Status::Apart, k.signed - tol),
        None => (Status::Apart, f64::NEG_INFINITY),
    }
}

/// A touching vertex of one frame, with what the link's aggregation needs.
#[derive(Clone, Copy, Debug)]
struct Touch {
    /// Index in its link's vertex list.
    j: u32,
    /// Skin vertex.
    vertex: u32,
    /// Place in its block.
    slot: u32,
    signed: f64,
    slack: f64,
    projection: Point,
    at: Point,
}

/// Vertices per block: small enough that a block near a contact holds few apart vertices,
/// large enough that the per-block bound costs little beside the vertices it spares.
const BLOCK: usize = 32;

/// A spatial block of one link's vertices with a dense state: their rest positions and
/// weights, what each last learnt, and how far the block may move from where it was last
/// classified and still be all apart without posing a vertex.
struct Block {
    link: usize,
    /// Rest sphere about the vertices.
    centre: Point,
    radius: f64,
    /// The links the vertices' weights blend.
    blend: Vec<usize>,
    /// Per vertex: index in the link's vertex list, skin vertex, rest position.
    j: Vec<u32>,
    vertex: Vec<u32>,
    rest: Vec<[f64; 3]>,
    /// Weights of vertex `v`: `weights[w_start[v]..w_start[v + 1]]`, in the skin's order.
    w_start: Vec<u32>,
    weights: Vec<(u32, f64)>,
    known: Vec<Option<Known>>,
    /// Where the blend links took the centre, and their rotations inverted, when the block
    /// was last classified; empty before.
    ref_centre: Vec<Point>,
    ref_rotation: Vec<nalgebra::UnitQuaternion<f64>>,
    /// The least distance a vertex could move then and still be apart unqueried.
    margin: f64,
    /// This frame's touching vertices.
    touching: Vec<Touch>,
}

impl Block {
    /// The blocks of `hand`: each link's vertices in Morton order of their rest positions, cut
    /// into runs of [`BLOCK`].
    fn of(hand: &SkinnedHand) -> Vec<Block> {
        let rest = &hand.rest_mesh().vertices;
        let mut out = Vec::new();
        for (l, vs) in hand.link_vertices().iter().enumerate() {
            let Some(lo) = vs.iter().map(|&i| rest[i]).reduce(|a, b| a.inf(&b)) else {
                continue;
            };
            let mut order: Vec<(u64, usize)> = vs
                .iter()
                .enumerate()
                .map(|(j, &i)| {
                    let q = (rest[i] - lo).map(|x| (x / 0.25).clamp(0.0, 1048575.0) as u64);
                    (morton(q.x, q.y, q.z), j)
                })
                .collect();
            order.sort_unstable();
            for run in order.chunks(BLOCK) {
                let js: Vec<usize> = run.iter().map(|&(_, j)| j).collect();
                let c = js
                    .iter()
                    .fold(nalgebra::Vector3::zeros(), |a, &j| a + rest[vs[j]].coords)
                    / js.len() as f64;
                let centre = Point::from(c);
                let radius = js
                    .iter()
                    .map(|&j| (rest[vs[j]] - centre).norm())
                    .fold(0.0, f64::max);
                let mut w_start = vec![0u32];
                let mut weights = Vec::new();
                for &j in &js {
                    weights.extend(hand.hand.weights[vs[j]].iter().map(|&(k, w)| (k as u32, w)));
                    w_start.push(weights.len() as u32);
                }
                let mut blend: Vec<usize> = weights.iter().map(|&(k, _)| k as usize).collect();
                blend.push(l);
                blend.sort_unstable();
                blend.dedup();
                out.push(Block {
                    link: l,
                    centre,
                    radius,
                    blend,
                    j: js.iter().map(|&j| j as u32).collect(),
                    vertex: js.iter().map(|&j| vs[j] as u32).collect(),
                    rest: js
                        .iter()
                        .map(|&j| {
                            let p = rest[vs[j]];
                            [p.x, p.y, p.z]
                        })
                        .collect(),
                    w_start,
                    weights,
                    known: vec![None; js.len()],
                    ref_centre: Vec::new(),
                    ref_rotation: Vec::new(),
                    margin: f64::NEG_INFINITY,
                    touching: Vec::new(),
                });
            }
        }
        out
    }

    /// Whether every vertex is still surely apart under the link transforms `t`: a blended
    /// vertex moved by at most `max_k |T_k v - T'_k v|` since the reference transforms `T'`,
    /// and for `v` in the rest sphere that is at most `|T_k c - T'_k c| + ‖R_k - R'_k‖ r`,
    /// the spectral norm being `2 sin(θ/2)` of the rotation between them.
    fn still_apart(&self, t: &[Isometry3<f64>]) -> bool {
        if self.ref_centre.is_empty() || self.margin <= 0.0 {
            return false;
        }
        let mut moved = 0.0f64;
        for ((&k, c0), q0) in self
            .blend
            .iter()
            .zip(&self.ref_centre)
            .zip(&self.ref_rotation)
        {
            let turn = (q0 * t[k].rotation).imag().norm();
            moved = moved.max((t[k] * self.centre - c0).norm() + 2.0 * turn * self.radius);
        }
        // Headroom for rounding and for weights summing to 1 only to 1e-6.
        moved * (1.0 + 1e-5) + 1e-9 < self.margin
    }

    /// Pose and classify every vertex (`mats`: [`displacement`] of `t`), remembering the
    /// touching ones and the block's margin.
    fn classify(
        &mut self,
        part: &PartShape,
        broad: &Broad,
        t: &[Isometry3<f64>],
        mats: &[[f64; 12]],
        tol: f64,
    ) {
        self.touching.clear();
        let mut margin = f64::INFINITY;
        for v in 0..self.rest.len() {
            // The same arithmetic as the skin binding's, so the positions are the same.
            let [x, y, z] = self.rest[v];
            let (mut dx, mut dy, mut dz) = (0.0, 0.0, 0.0);
            let ws = &self.weights[self.w_start[v] as usize..self.w_start[v + 1] as usize];
            for &(l, a) in ws {
                let m = &mats[l as usize];
                dx += a * (m[0] * x + m[1] * y + m[2] * z + m[3]);
                dy += a * (m[4] * x + m[5] * y + m[6] * z + m[7]);
                dz += a * (m[8] * x + m[9] * y + m[10] * z + m[11]);
            }
            let p = Point::new(x + dx, y + dy, z + dz);
            let (st, m) = classify(part, broad, &p, &mut self.known[v], tol);
            margin = margin.min(m);
            if let Status::Touching {
                signed,
                slack,
                projection,
            } = st
            {
                self.touching.push(Touch {
                    j: self.j[v],
                    vertex: self.vertex[v],
                    slot: v as u32,
                    signed,
                    slack,
                    projection,
                    at: p,
                });
            }
        }
        self.margin = margin;
        self.ref_centre.clear();
        self.ref_rotation.clear();
        for &k in &self.blend {
            self.ref_centre.push(t[k] * self.centre);
            self.ref_rotation.push(t[k].rotation.inverse());
        }
    }
}

/// Interleave the low 20 bits of `x`, `y`, `z`.
fn morton(x: u64, y: u64, z: u64) -> u64 {
    let spread = |v: u64| (0..20).fold(0, |r, b| r | (((v >> b) & 1) << (3 * b)));
    spread(x) | (spread(y) << 1) | (spread(z) << 2)
}

/// Contacts of `hand` (the individual hand of the model `kin` was read from) with `part` (in
/// its own frame) over the `tracked` trial, whose `part` holds the part's pose per frame (part
/// frame -> lab): [`replay_frames`] with the tracked link transforms ([`Kinematics::evaluate`])
/// of every frame where both the hand and the part are known.
pub fn replay_contacts(
    hand: &SkinnedHand,
    kin: &Kinematics,
    tracked: &Tracked,
    part: &PartShape,
    opts: &ReplayOptions,
) -> ContactReplay {
    let frames: Vec<Option<PosedFrame>> = (0..tracked.frames.len())
        .map(|f| {
            let pose = tracked.part.as_ref().and_then(|(poses, _)| poses[f])?;
            let state = tracked.frames[f].state.as_ref()?;
            Some(PosedFrame {
                links: kin.evaluate(state).links,
                part: pose,
            })
        })
        .collect();
    replay_frames(hand, &frames, part, opts)
}

/// One frame to replay: every link's transform from the hand's rest posture to the lab
/// ([`Link::index`] order), and the part's pose (part frame -> lab).
///
/// [`Link::index`]: crate::anatomy::Link::index
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosedFrame {
    pub links: [Isometry3<f64>; 17],
    pub part: Isometry3<f64>,
}

/// Contacts of `hand` (posed by linear blend skinning with each frame's link transforms) with
/// `part` (in its own frame) over `frames` (`None`: the hand or the part unknown there, no
/// contacts).
///
/// Frames run in order and each vertex remembers its last exact query: a vertex is queried
/// again only when the distance it has moved since could have carried it across the
/// tolerance, and the deepest penetration of a link is found by branch and bound over its
/// vertices' depth intervals, querying only those that could still be deepest. A link whose
/// blended vertices cannot reach the part's box is not posed, nor is a block of a link's
/// vertices (neighbours at rest) that has not moved, by a bound on its skinning transforms,
/// as far as its vertices could move and stay apart. The contact areas and depths are exactly
/// those of querying every vertex in every frame; a contact map's projection is the last exact
/// one moved with the vertex. Blocks run in parallel.
pub fn replay_frames(
    hand: &SkinnedHand,
    frames_in: &[Option<PosedFrame>],
    part: &PartShape,
    opts: &ReplayOptions,
) -> ContactReplay {
    let n = frames_in.len();
    let skin = hand.rest_mesh();
    let areas = vertex_areas(skin);
    let radius = mean_edge_length(skin).max(1e-3);
    let grid = VertexGrid::new(&part.mesh.vertices, radius);
    let tol = opts.tolerance_mm;
    let broad = Broad::of(part, tol);
    let bounds = LinkBound::of(hand);
    let mut blocks = Block::of(hand);
    let mut part_stamp = vec![usize::MAX; part.mesh.n_vertices()];
    let mut skin_count = vec![0u32; skin.n_vertices()];
    let mut part_count = vec![0u32; part.mesh.n_vertices()];
    let mut frames = Vec::with_capacity(n);
    let mut touching: Vec<(Touch, usize)> = Vec::new();
    for (f, frame) in frames_in.iter().enumerate() {
        let Some(frame) = frame else {
            frames.push(None);
            continue;
        };
        let to_part = frame.part.inverse();
        let transforms: Vec<Isometry3<f64>> = frame.links.iter().map(|l| to_part * l).collect();
        let mats: Vec<[f64; 12]> = transforms.iter().map(displacement_matrix).collect();
        // Only the links that may come within the tolerance of the part's box are posed and
        // probed; the others' vertices are apart, and keep what they knew.
        let near: Vec<bool> = bounds
            .iter()
            .enumerate()
            .map(|(l, b)| {
                !hand.link_vertices()[l].is_empty()
                    && b.may_reach(l, &transforms, &part.lo, &part.hi, tol)
            })
            .collect();
        blocks.par_iter_mut().with_min_len(8).for_each(|b| {
            if !near[b.link] || b.still_apart(&transforms) {
                b.touching.clear();
            } else {
                b.classify(part, &broad, &transforms, &mats, tol);
            }
        });

        let mut area = [0.0; 17];
        let mut depth = [0.0f64; 17];
        let mut skin_touch = Vec::new();
        let mut under = Vec::new();
        // In each link's vertex order, as the areas are summed in it.
        touching.clear();
        for (bi, b) in blocks.iter().enumerate() {
            touching.extend(b.touching.iter().map(|&t| (t, bi)));
        }
        touching.sort_unstable_by_key(|(t, bi)| (blocks[*bi].link, t.j));
        // Per link, the vertices whose depth is not known exactly: (upper bound, touch).
        let mut open: Vec<Vec<(f64, usize)>> = vec![Vec::new(); 17];
        for (e, &(tc, bi)) in touching.iter().enumerate() {
            let l = blocks[bi].link;
            let i = tc.vertex as usize;
            area[l] += areas[i];
            depth[l] = depth[l].max(-(tc.signed + tc.slack));
            if tc.slack > 0.0 && -(tc.signed - tc.slack) > depth[l] {
                open[l].push((-(tc.signed - tc.slack), e));
            }
            skin_touch.push(tc.vertex);
        }
        // The part's vertices under the projections, in parallel chunks (each is stamped once
        // per frame below, so their order does not matter).
        under.extend(
            touching
                .par_chunks(256)
                .flat_map_iter(|chunk| {
                    let mut out = Vec::new();
                    for (tc, _) in chunk {
                        grid.within(&part.mesh.vertices, &tc.projection, radius, &mut out);
                    }
                    out
                })
                .collect::<Vec<u32>>(),
        );
        // Each link's branch and bound on its own (links are independent), the queries made
        // kept for the vertices' blocks afterwards.
        let found: Vec<LinkDeepest> = open
            .par_iter_mut()
            .enumerate()
            .map(|(l, cands)| {
                let mut d = depth[l];
                let mut queried = Vec::new();
                cands.sort_by(|a, b| b.0.total_cmp(&a.0));
                for &(upper, e) in cands.iter() {
                    if upper <= d {
                        break;
                    }
                    let k = exact(part, &touching[e].0.at);
                    if let Some(k) = k {
                        d = d.max(-k.signed);
                    }
                    queried.push((e, k));
                }
                (d, queried)
            })
            .collect();
        for (l, (d, queried)) in found.into_iter().enumerate() {
            depth[l] = d;
            for (e, k) in queried {
                let (tc, bi) = touching[e];
                blocks[bi].known[tc.slot as usize] = k;
            }
        }
        skin_touch.sort_unstable();
        for &v in &skin_touch {
            skin_count[v as usize] += 1;
        }
        // Each part vertex once per frame, however many projections fall near it.
        for &v in &under {
            if part_stamp[v as usize] != f {
                part_stamp[v as usize] = f;
                part_count[v as usize] += 1;
            }
        }
        frames.push(Some(FrameContacts {
            link_area_mm2: area,
            link_depth_mm: depth.map(|d| d.max(0.0)),
            skin_vertices: skin_touch,
        }));
    }
    ContactReplay {
        frames,
        skin_count,
        part_count,
    }
}

/// Mean edge length of `mesh`, mm (each edge once per face that has it).
fn mean_edge_length(mesh: &TriMesh) -> f64 {
    let mut s = 0.0;
    for f in &mesh.faces {
        for k in 0..3 {
            s += (mesh.vertices[f[k]] - mesh.vertices[f[(k + 1) % 3]]).norm();
        }
    }
    s / (3 * mesh.faces.len()).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{Link, Side};
    use crate::track::fixture::{grasp_states, lab_start};
    use crate::track::{Attachment, FrameSolution, HandState};
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// Top face of the slab part, in its own frame: z = 0 (the slab is 1000 x 1000 x 400 mm
    /// below it, so near its top's centre the signed distance is z).
    fn slab() -> PartShape {
        let m = crate::geometry::mesh::tests::cuboid(1000.0, 1000.0, 400.0)
            .transformed(&Isometry3::translation(-500.0, -500.0, -400.0));
        PartShape::with_band(m, 1.0).unwrap().0
    }

    fn solution(state: Option<HandState>) -> FrameSolution {
        FrameSolution {
            state,
            residual_mm: Vec::new(),
            rejected: Vec::new(),
            held: Vec::new(),
            coupled: Vec::new(),
            iterations: 0,
        }
    }

    /// The template hand closing while a slab's top cuts through its palm (the slab moves with
    /// the palm, turned so the cut is oblique), away for a stretch and back: every frame's
    /// areas and depths are those of the closed form, the signed distance to the top face
    /// being the height above it, computed on the skin posed afresh.
    #[test]
    fn replayed_contacts_equal_the_closed_form_on_a_slab() {
        let hand = SkinnedHand::template(Side::Right).unwrap();
        let kin = Kinematics::full(hand.skeleton().clone());
        let n = 240;
        let states = grasp_states(n, 100.0, lab_start());
        let rest = &hand.rest_mesh().vertices;
        let palm: Vec<usize> = hand.link_vertices()[Link::Palm.index()].clone();
        let centre = palm
            .iter()
            .fold(Vector3::zeros(), |a, &i| a + rest[i].coords)
            / palm.len() as f64;
        // Part frame -> rest frame: the top face through the palm's centroid, tilted.
        let cut = Isometry3::from_parts(
            Translation3::from(centre),
            UnitQuaternion::from_euler_angles(0.3, -0.5, 0.2),
        );
        let poses: Vec<Option<Isometry3<f64>>> = (0..n)
            .map(|f| {
                let away = if (100..130).contains(&f) { 600.0 } else { 0.0 };
                (f != 50).then(|| states[f].palm * cut * Isometry3::translation(0.0, 0.0, -away))
            })
            .collect();
        let tracked = Tracked {
            attachment: Attachment {
                markers: Vec::new(),
            },
            frames: (0..n)
                .map(|f| solution((f != 70).then(|| states[f].clone())))
                .collect(),
            part: Some((poses.clone(), vec![None; n])),
            part_filled: Vec::new(),
            rate: 100.0,
            warnings: Vec::new(),
        };
        let part = slab();
        let opts = ReplayOptions::default();
        let replay = replay_contacts(&hand, &kin, &tracked, &part, &opts);
        let areas = vertex_areas(hand.rest_mesh());
        let links = hand.vertex_link();
        let mut posed = Vec::new();
        let mut touched_frames = 0;
        for f in 0..n {
            let got = &replay.frames[f];
            let (Some(pose), false) = (poses[f], f == 70) else {
                assert!(got.is_none(), "frame {f}: hand or part unknown");
                continue;
            };
            let got = got.as_ref().expect("both known");
            let t = kin.evaluate(&states[f]);
            let tr: Vec<Isometry3<f64>> = t.links.iter().map(|l| pose.inverse() * l).collect();
            hand.pose_all(&tr, &mut posed);
            let mut area = [0.0; 17];
            let mut depth = [0.0f64; 17];
            let mut verts = Vec::new();
            for (i, p) in posed.iter().enumerate() {
                if p.z <= opts.tolerance_mm {
                    area[links[i]] += areas[i];
                    depth[links[i]] = depth[links[i]].max(-p.z);
                    verts.push(i as u32);
                }
            }
            assert!(
                got.skin_vertices == verts,
                "frame {f}: the vertices in contact differ"
            );
            for l in 0..17 {
                assert!(
                    (got.link_area_mm2[l] - area[l]).abs() < 1e-9,
                    "frame {f} link {l}"
                );
                assert!(
                    (got.link_depth_mm[l] - depth[l]).abs() < 1e-9,
                    "frame {f} link {l}: {} against {}",
                    got.link_depth_mm[l],
                    depth[l]
                );
            }
            if (100..130).contains(&f) {
                assert!(verts.is_empty(), "frame {f}: the slab is away");
            } else {
                assert!(got.total_area_mm2() > 1000.0, "frame {f}: the palm is cut");
                touched_frames += 1;
            }
        }
        // The map counts each skin vertex's frames in contact.
        let count_of = |v: usize| {
            replay
                .frames
                .iter()
                .flatten()
                .filter(|fc| fc.skin_vertices.binary_search(&(v as u32)).is_ok())
                .count() as u32
        };
        for v in (0..rest.len()).step_by(97) {
            assert_eq!(replay.skin_count[v], count_of(v), "vertex {v}");
        }
        // The slab's only vertices are its corners, hundreds of millimetres from any contact.
        assert!(touched_frames > 150);
        assert_eq!(replay.part_count, vec![0; 8]);
        let records = replay.records();
        assert!(records
            .iter()
            .all(|r| r.area_mm2 > 0.0 && r.frame != 70 && r.frame != 50));
    }
}
