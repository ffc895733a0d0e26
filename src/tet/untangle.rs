//! Local untangling of inverted tetrahedra by moving free nodes.
//!
//! A mesh whose boundary is held on a skin that bends hard (a fist's palmar creases, a fitted
//! skin that folds where the template could not follow the subject) can leave elements inverted
//! after the elastic step or after skinning, since neither keeps a volume positive. Following
//! the optimisation-based untangling of Freitag & Plassmann (2000, "Local optimization-based
//! simultaneous mesh untangling and improvement") and Knupp (2001, "Hexahedral and tetrahedral
//! mesh untangling"), one free node at a time is moved to the position that brings every
//! element of its star above a target volume:
//!
//! `min_x Σ_{t ∈ star} max(0, τ_t − V_t(x))² + μ |x − x₀|²`,
//!
//! where `V_t` is linear in the one node's position (`∇_a V = −((c − b) × (d − b)) / 6` for
//! the corner `a` of `[a, b, c, d]`, and alike for the others by even permutation), so each
//! node's problem is a convex piecewise quadratic solved exactly by a few Newton steps on its
//! active set. The small proximal term `μ` keeps a node from drifting once its star is valid.
//! Sweeps start at the free nodes of the inverted elements and widen to their neighbours when
//! an element stays inverted (its own nodes are boxed in by the held boundary). One node at a
//! time stalls where no position of a node is valid with its neighbours where they are (two
//! nodes collapsed onto each other at a crease): what is left is then solved for all the nodes
//! within one, two and three rings of it at once, by Gauss-Newton on the same cost, the
//! boundary nodes among them given the boundary's current reach (a crease pressed flat holds a
//! sliver whose way out is a boundary node one ring further). A penalty on the negative volumes
//! alone still has local minima where a sliver is pinned by its valid neighbours; what it
//! leaves is handed to the regularised Winslow functional ([`super::winslow`]) over the free
//! nodes within three rings, which weighs every element's shape as well as its sign.
//!
//! Nothing moves in a mesh without inverted elements, so a valid mesh is returned unchanged.

use super::winslow::untangle_winslow;
use crate::geometry::tet_mesh::element_signed_volume;
use crate::geometry::{Point, Vec3};
use nalgebra::Matrix3;
use serde::Serialize;

/// Rings of neighbours around what the penalty leaves inverted that the Winslow step moves.
const WINSLOW_RINGS: usize = 3;

/// Runs of [`untangle`] at most: a fresh run starts from what the one before left inverted,
/// and the runs stop as soon as one clears nothing more. A deep fold of a posed skin can clear
/// a few elements per run for more than four runs before none is left; the cap only bounds the
/// time of a fold that keeps clearing one element at a time.
const RUNS: usize = 10;

/// Options of [`untangle`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UntangleOptions {
    /// The target volume of an element, as a fraction of its reference volume.
    pub target_fraction: f64,
    /// Most sweeps over the active nodes at each step of the boundary's reach.
    pub max_sweeps: usize,
    /// How far a boundary node may give way at most, mm (0 holds the boundary).
    pub max_boundary_move_mm: f64,
}

impl Default for UntangleOptions {
    fn default() -> Self {
        UntangleOptions {
            // A tenth of the reference volume: well clear of zero, yet a compressed element of a
            // bent joint (often at 30-60 % of its rest volume) is not disturbed.
            target_fraction: 0.1,
            max_sweeps: 20,
            // A fist's palmar creases fold the skinned surface through itself by about 4 mm,
            // the thumb web of a tripod by more; the last 2 mm are only reached where 4 mm
            // left an element inverted, and a boundary that gives way further would no longer
            // be the skin.
            max_boundary_move_mm: 6.0,
        }
    }
}

/// What [`untangle`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct UntangleStats {
    /// Inverted (or flat) elements before.
    pub inverted_before: usize,
    /// And after.
    pub inverted_after: usize,
    /// Nodes moved.
    pub nodes_moved: usize,
    /// Largest move of a node, mm.
    pub max_move_mm: f64,
    /// Largest move of a boundary node, mm (0 when the boundary was held throughout).
    pub max_boundary_move_mm: f64,
    /// Sweeps run.
    pub sweeps: usize,
}

/// Gradient of the signed volume of `tet` with respect to its corner `k` (see the module
/// documentation).
fn volume_gradient(nodes: &[Point], tet: &[usize; 4], k: usize) -> Vec3 {
    // Even permutations that bring corner k first.
    const PERM: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]];
    let p = PERM[k];
    let b = nodes[tet[p[1]]];
    let c = nodes[tet[p[2]]];
    let d = nodes[tet[p[3]]];
    -(c - b).cross(&(d - b)) / 6.0
}

/// The signed volumes of node `v`'s star as functions of `v`'s position `x`: per element
/// `(g, c)` with `V(x) = g·x + c`, exactly (the volume is linear in one corner).
fn star_volumes(
    nodes: &[Point],
    tets: &[[usize; 4]],
    star: &[usize],
    v: usize,
) -> Vec<(Vec3, f64)> {
    star.iter()
        .map(|&t| {
            let tet = &tets[t];
            let k = tet.iter().position(|&x| x == v).unwrap_or(0);
            let g = volume_gradient(nodes, tet, k);
            (
                g,
                element_signed_volume(nodes, tet) - g.dot(&nodes[v].coords),
            )
        })
        .collect()
}

/// The elements of `tets` whose signed volume at `nodes` is not positive.
fn inverted_elements(nodes: &[Point], tets: &[[usize; 4]]) -> Vec<usize> {
    (0..tets.len())
        .filter(|&t| element_signed_volume(nodes, &tets[t]) <= 0.0)
        .collect()
}

/// Signed volumes scored as [`better`] compares them: (inverted count, smallest volume).
fn volume_score(vols: impl Iterator<Item = f64> + Clone) -> (usize, f64) {
    let bad = vols.clone().filter(|v| *v <= 0.0).count();
    (bad, vols.fold(f64::INFINITY, f64::min))
}

/// The star of [`star_volumes`] with its node at `x`: its [`volume_score`].
fn star_score(lin: &[(Vec3, f64)], x: &Vec3) -> (usize, f64) {
    volume_score(lin.iter().map(|(g, c)| g.dot(x) + c))
}

/// Node -> the elements around it, for the `n` nodes of the mesh of `tets`.
fn node_stars(n: usize, tets: &[[usize; 4]]) -> Vec<Vec<usize>> {
    let mut star: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (t, tet) in tets.iter().enumerate() {
        for &v in tet {
            star[v].push(t);
        }
    }
    star
}

/// Whether score `a` is better than `b`: fewer inverted, or as many and a larger smallest volume.
fn better(a: (usize, f64), b: (usize, f64)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 > b.1)
}

/// `x` pulled back into the ball of radius `reach` around `origin`.
fn within_reach(x: Vec3, origin: Vec3, reach: f64) -> Vec3 {
    let d = (x - origin).norm();
    if d > reach {
        origin + (x - origin) * (reach / d)
    } else {
        x
    }
}

/// Move the `nodes` of the mesh of `tets` so that no element has a non-positive volume. The
/// interior nodes (all but `boundary`) move freely; the boundary is held at first, and only where elements
/// stay inverted with the interior moved (an element pinned between boundary faces that fold
/// through each other) may its nodes give way, by at most 0.25, 0.5, 1, 2 mm and then
/// `opts.max_boundary_move_mm` from where they started, each step tried only when the one
/// before left an element inverted. `reference` gives each element's reference volume (its
/// rest or template volume; the absolute value is used), from which the target volume
/// `opts.target_fraction · |reference|` is set. Elements that are not inverted, and nodes that
/// are not needed, stay where they are.
///
/// What the runs leave inverted is tried once more from where they left it, as a fresh start
/// (the boundary held again at first, each boundary node given what is left of its
/// `opts.max_boundary_move_mm`), and that result kept when it leaves fewer: the runs widen
/// around what they first found and stop once one clears nothing; a fresh start works on the
/// last few alone, and sometimes clears a sliver between nodes the runs had moved onto each
/// other with the interior alone. What is still inverted then goes to
/// [`untangle_winslow`] over the interior nodes within three rings of it, the boundary held
/// where the runs left it, and that result is kept when it leaves fewer.
pub fn untangle(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    boundary: &[usize],
    reference: &[f64],
    opts: &UntangleOptions,
) -> UntangleStats {
    let n = nodes.len();
    let mut on_boundary = vec![false; n];
    for &v in boundary {
        on_boundary[v] = true;
    }
    let original = nodes.to_vec();
    let budget: Vec<f64> = on_boundary
        .iter()
        .map(|&b| {
            if b {
                opts.max_boundary_move_mm
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let mut stats = untangle_runs(nodes, tets, &on_boundary, reference, opts, &budget);
    if stats.inverted_after > 0 {
        let left: Vec<f64> = budget
            .iter()
            .zip(nodes.iter().zip(&original))
            .map(|(b, (a, o))| (b - (a - o).norm()).max(0.0))
            .collect();
        let mut again = nodes.to_vec();
        let second = untangle_runs(&mut again, tets, &on_boundary, reference, opts, &left);
        stats.sweeps += second.sweeps;
        if second.inverted_after < stats.inverted_after {
            nodes.copy_from_slice(&again);
            stats.inverted_after = second.inverted_after;
        }
    }
    if stats.inverted_after > 0 {
        let star = node_stars(n, tets);
        let bad = inverted_elements(nodes, tets);
        let in_region = within_rings(tets, &star, &bad, WINSLOW_RINGS);
        let free: Vec<usize> = (0..n)
            .filter(|&v| in_region[v] && !on_boundary[v])
            .collect();
        let mut again = nodes.to_vec();
        untangle_winslow(&mut again, tets, &free, reference);
        let left = inverted_elements(&again, tets).len();
        if left < stats.inverted_after {
            nodes.copy_from_slice(&again);
            stats.inverted_after = left;
        }
    }
    for ((a, b), &boundary_node) in nodes.iter().zip(&original).zip(&on_boundary) {
        let d = (a - b).norm();
        if d > 0.0 {
            stats.nodes_moved += 1;
            stats.max_move_mm = stats.max_move_mm.max(d);
            if boundary_node {
                stats.max_boundary_move_mm = stats.max_boundary_move_mm.max(d);
            }
        }
    }
    stats
}

/// The runs of [`untangle`], each node of the boundary (`on_boundary`) given way by at most
/// its `budget`, mm; the counts of what is inverted and the sweeps in the stats.
fn untangle_runs(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    on_boundary: &[bool],
    reference: &[f64],
    opts: &UntangleOptions,
    budget: &[f64],
) -> UntangleStats {
    let n = nodes.len();
    let inverted = |nodes: &[Point]| inverted_elements(nodes, tets);
    let mut bad = inverted(nodes);
    let mut stats = UntangleStats {
        inverted_before: bad.len(),
        inverted_after: bad.len(),
        ..Default::default()
    };
    if bad.is_empty() {
        return stats;
    }
    let star = node_stars(n, tets);
    let target: Vec<f64> = reference
        .iter()
        .map(|v| opts.target_fraction * v.abs())
        .collect();
    let start = nodes.to_vec();
    let mut ladder = vec![0.0];
    let mut r = 0.25;
    while r < opts.max_boundary_move_mm {
        ladder.push(r);
        r *= 2.0;
    }
    if opts.max_boundary_move_mm > 0.0 {
        ladder.push(opts.max_boundary_move_mm);
    }
    // A run focuses on the nodes around what is inverted when it starts, and widens as it goes;
    // where it widened far and stalled, a fresh run from the elements still inverted (its
    // nodes still bound to within the reach of where they first were) clears what is left.
    // How far each node may go from where it started: interior nodes anywhere; a boundary
    // node keeps the reach an earlier run gave it.
    let mut reach: Vec<f64> = on_boundary
        .iter()
        .map(|&b| if b { 0.0 } else { f64::INFINITY })
        .collect();
    for _run in 0..RUNS {
        let inverted_at_start = bad.len();
        let mut active = vec![false; n];
        for &boundary_reach in &ladder {
            if bad.is_empty() {
                break;
            }
            // The nodes of what is inverted and of the elements around it may move (the boundary's
            // by this step's reach).
            let around = |bad: &[usize], active: &mut Vec<bool>, reach: &mut Vec<f64>| {
                for &t in bad {
                    for &v in &tets[t] {
                        for &u in star[v].iter().flat_map(|&s| tets[s].iter()) {
                            if on_boundary[u] {
                                reach[u] = reach[u].max(boundary_reach.min(budget[u]));
                            }
                            if reach[u] > 0.0 {
                                active[u] = true;
                            }
                        }
                    }
                }
            };
            around(&bad, &mut active, &mut reach);
            let mut unchanged = 0;
            for _ in 0..opts.max_sweeps {
                stats.sweeps += 1;
                let mut order: Vec<usize> = (0..n).filter(|&v| active[v]).collect();
                // Forward then backward (symmetric Gauss-Seidel).
                let backward: Vec<usize> = order.iter().rev().copied().collect();
                order.extend(backward);
                for &v in &order {
                    relax_node(
                        nodes,
                        tets,
                        &star[v],
                        &target,
                        v,
                        (start[v].coords, reach[v]),
                    );
                }
                let now = inverted(nodes);
                // The same elements inverted after three sweeps: this reach is not enough.
                unchanged = if now == bad { unchanged + 1 } else { 0 };
                bad = now;
                if bad.is_empty() || unchanged == 3 {
                    break;
                }
                around(&bad, &mut active, &mut reach);
            }
            // One node at a time stalls where no position of a node is valid with its neighbours
            // where they are (two nodes collapsed onto each other in a crease): the nodes around
            // what is left move together, over a widening neighbourhood, before the boundary is
            // given more reach.
            for rings in 1..=JOINT_RINGS {
                if bad.is_empty() {
                    break;
                }
                let before = bad.len();
                let region = Region {
                    rings,
                    boundary_reach,
                    budget,
                };
                for group in touching_groups(tets, &star, &bad) {
                    untangle_jointly(
                        nodes, tets, &star, &group, &target, &mut reach, &start, region,
                    );
                }
                bad = inverted(nodes);
                stats.sweeps += 1;
                if bad.len() > before {
                    break;
                }
            }
        }
        // What the penalty's compromises leave inverted (a sliver flattened between its
        // neighbours) is polished by raising the star's smallest volume itself, one node at a time,
        // accepting only moves that leave fewer inverted elements or a larger smallest volume.
        for _ in 0..opts.max_sweeps {
            if bad.is_empty() {
                break;
            }
            let nodes_of_bad: Vec<usize> = bad
                .iter()
                .flat_map(|&t| tets[t].iter().copied())
                .filter(|&v| reach[v] > 0.0)
                .collect();
            for v in nodes_of_bad {
                raise_smallest_volume(nodes, tets, &star[v], v, (start[v].coords, reach[v]));
            }
            stats.sweeps += 1;
            let now = inverted(nodes);
            let stalled = now == bad;
            bad = now;
            if stalled {
                break;
            }
        }
        if bad.is_empty() || bad.len() >= inverted_at_start {
            break;
        }
    }
    stats.inverted_after = bad.len();
    stats
}

/// Rings of neighbours around what stays inverted that [`untangle_jointly`] widens to at most.
const JOINT_RINGS: usize = 3;

/// Most free nodes [`untangle_jointly`] moves together (its normal equations are dense): a
/// few slivers' neighbourhoods, not a fold of hundreds of elements, which the node-by-node
/// sweeps handle.
const JOINT_MAX_NODES: usize = 250;

/// Node -> whether it is a corner of one of the elements `bad` or within `rings` rings of
/// neighbours of one (`star`: each node's elements).
fn within_rings(
    tets: &[[usize; 4]],
    star: &[Vec<usize>],
    bad: &[usize],
    rings: usize,
) -> Vec<bool> {
    let mut in_region = vec![false; star.len()];
    let mut frontier: Vec<usize> = bad.iter().flat_map(|&t| tets[t]).collect();
    for &v in &frontier {
        in_region[v] = true;
    }
    for _ in 0..rings {
        let mut next = Vec::new();
        for &v in &frontier {
            for &u in star[v].iter().flat_map(|&t| tets[t].iter()) {
                if !in_region[u] {
                    in_region[u] = true;
                    next.push(u);
                }
            }
        }
        frontier = next;
    }
    in_region
}

/// The elements `bad` grouped by shared nodes (each group a connected cluster).
fn touching_groups(tets: &[[usize; 4]], star: &[Vec<usize>], bad: &[usize]) -> Vec<Vec<usize>> {
    let is_bad: std::collections::HashSet<usize> = bad.iter().copied().collect();
    let mut seen = std::collections::HashSet::new();
    let mut groups = Vec::new();
    for &t in bad {
        if !seen.insert(t) {
            continue;
        }
        let mut group = vec![t];
        let mut k = 0;
        while k < group.len() {
            let e = group[k];
            k += 1;
            for u in tets[e].iter().flat_map(|&v| star[v].iter().copied()) {
                if is_bad.contains(&u) && seen.insert(u) {
                    group.push(u);
                }
            }
        }
        groups.push(group);
    }
    groups
}

/// The neighbourhood [`untangle_jointly`] moves: the nodes within `rings` rings of the
/// elements it untangles, a boundary node among them by at least `boundary_reach` (at most
/// its `budget`).
#[derive(Clone, Copy, Debug)]
struct Region<'a> {
    rings: usize,
    boundary_reach: f64,
    budget: &'a [f64],
}

/// The problem of the module documentation for all free nodes of the `region` around the
/// elements `bad` at once (the volume is linear in each corner, so the residuals' Jacobian is
/// the corners' volume gradients), by Gauss-Newton steps with a halving line search on the true
/// cost, each node kept within its reach of `start`. The boundary nodes of the region get the
/// region's reach, not only those next to what is inverted: a crease pressed flat holds a
/// sliver between boundary faces one ring out that must give way with it. The region is left
/// as it was unless it ends with fewer inverted elements, or as many and a larger smallest
/// volume; then its nodes keep the reach they were given.
#[allow(clippy::too_many_arguments)]
fn untangle_jointly(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    star: &[Vec<usize>],
    bad: &[usize],
    target: &[f64],
    reach: &mut [f64],
    start: &[Point],
    Region {
        rings,
        boundary_reach,
        budget,
    }: Region,
) {
    let n = nodes.len();
    let in_region = within_rings(tets, star, bad, rings);
    let (free, free_reach): (Vec<usize>, Vec<f64>) = (0..n)
        .filter(|&v| in_region[v])
        .map(|v| (v, reach[v].max(boundary_reach.min(budget[v]))))
        .filter(|&(_, r)| r > 0.0)
        .unzip();
    if free.is_empty() || free.len() > JOINT_MAX_NODES {
        return;
    }
    let mut column = vec![usize::MAX; n];
    for (k, &v) in free.iter().enumerate() {
        column[v] = k;
    }
    let mut elems: Vec<usize> = free.iter().flat_map(|&v| star[v].iter().copied()).collect();
    elems.sort_unstable();
    elems.dedup();
    let x0: Vec<Point> = free.iter().map(|&v| nodes[v]).collect();
    let score = |nodes: &[Point]| {
        volume_score(
            elems
                .iter()
                .map(|&t| element_signed_volume(nodes, &tets[t])),
        )
    };
    let entry = score(nodes);
    let scale = elems
        .iter()
        .map(|&t| volume_gradient(nodes, &tets[t], 0).norm_squared())
        .sum::<f64>()
        / elems.len() as f64;
    let mu = 1e-3 * scale;
    let cost = |nodes: &[Point]| -> f64 {
        elems
            .iter()
            .map(|&t| {
                (target[t] - element_signed_volume(nodes, &tets[t]))
                    .max(0.0)
                    .powi(2)
            })
            .sum::<f64>()
            + mu * free
                .iter()
                .zip(&x0)
                .map(|(&v, p)| (nodes[v] - p).norm_squared())
                .sum::<f64>()
    };
    let m = 3 * free.len();
    for _ in 0..50 {
        let mut h = nalgebra::DMatrix::<f64>::identity(m, m) * (2.0 * mu);
        let mut g = nalgebra::DVector::<f64>::zeros(m);
        for (k, &v) in free.iter().enumerate() {
            let d = nodes[v] - x0[k];
            for a in 0..3 {
                g[3 * k + a] += 2.0 * mu * d[a];
            }
        }
        let mut active = 0;
        for &t in &elems {
            let r = target[t] - element_signed_volume(nodes, &tets[t]);
            if r <= 0.0 {
                continue;
            }
            active += 1;
            let grads: Vec<(usize, Vec3)> = (0..4)
                .filter(|&c| column[tets[t][c]] != usize::MAX)
                .map(|c| (column[tets[t][c]], volume_gradient(nodes, &tets[t], c)))
                .collect();
            for &(i, gi) in &grads {
                for a in 0..3 {
                    g[3 * i + a] -= 2.0 * r * gi[a];
                }
                for &(j, gj) in &grads {
                    for a in 0..3 {
                        for b in 0..3 {
                            h[(3 * i + a, 3 * j + b)] += 2.0 * gi[a] * gj[b];
                        }
                    }
                }
            }
        }
        if active == 0 {
            break;
        }
        let Some(step) = h.cholesky().map(|c| c.solve(&(-&g))) else {
            break;
        };
        let f = cost(nodes);
        let here: Vec<Point> = free.iter().map(|&v| nodes[v]).collect();
        let mut s = 1.0;
        let mut moved = false;
        while s > 1e-4 {
            for (k, &v) in free.iter().enumerate() {
                let y =
                    here[k].coords + Vec3::new(step[3 * k], step[3 * k + 1], step[3 * k + 2]) * s;
                nodes[v] = Point::from(within_reach(y, start[v].coords, free_reach[k]));
            }
            if cost(nodes) < f {
                moved = true;
                break;
            }
            s *= 0.5;
        }
        if !moved {
            for (k, &v) in free.iter().enumerate() {
                nodes[v] = here[k];
            }
            break;
        }
    }
    if better(score(nodes), entry) {
        for (&v, &r) in free.iter().zip(&free_reach) {
            reach[v] = r;
        }
    } else {
        for (k, &v) in free.iter().enumerate() {
            nodes[v] = x0[k];
        }
    }
}

/// One node's problem of the module documentation, solved by Newton steps on its active set.
/// Where the targets cannot all be met (a node boxed in by a folded boundary), the compromise
/// can leave an element inverted that smaller targets would clear, so the targets are lowered
/// tenfold twice and the position with the fewest inverted elements (then the largest smallest
/// volume) is kept.
fn relax_node(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    star: &[usize],
    target: &[f64],
    v: usize,
    (origin, reach): (Vec3, f64),
) {
    let lin = star_volumes(nodes, tets, star, v);
    let terms: Vec<(Vec3, f64, f64)> = lin
        .iter()
        .zip(star)
        .map(|(&(g, c), &t)| (g, c, target[t]))
        .collect();
    let x0 = nodes[v].coords;
    let score = |x: &Vec3| star_score(&lin, x);
    let meets = |x: &Vec3| terms.iter().all(|(g, c, tau)| g.dot(x) + c >= *tau);
    if meets(&x0) {
        return;
    }
    let scale = terms.iter().map(|t| t.0.norm_squared()).sum::<f64>() / terms.len() as f64;
    let mu = 1e-3 * scale;
    let mut best = (x0, score(&x0));
    // Where the star is stuck from here, the centre of its other nodes (the position a
    // star-shaped neighbourhood is valid at) is the last start tried.
    let centre = {
        let mut sum = Vec3::zeros();
        let mut k = 0.0;
        for &t in star {
            for &u in &tets[t] {
                if u != v {
                    sum += nodes[u].coords;
                    k += 1.0;
                }
            }
        }
        sum / k
    };
    for (from, lower) in [(x0, 1.0), (x0, 0.1), (x0, 0.01), (centre, 0.1)] {
        let x = within_reach(newton_on_star(&terms, from, mu, lower), origin, reach);
        let s = score(&x);
        if better(s, best.1) {
            best = (x, s);
        }
        if s.0 == 0 {
            break;
        }
    }
    nodes[v] = Point::from(best.0);
}

/// Move node `v` up the gradient of the smallest volume of its star (a subgradient ascent of
/// the max-min problem of Freitag & Plassmann), within `reach` of `origin`, accepting a step
/// only when the star then has fewer inverted elements, or as many and a larger smallest volume.
fn raise_smallest_volume(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    star: &[usize],
    v: usize,
    (origin, reach): (Vec3, f64),
) {
    let terms = star_volumes(nodes, tets, star, v);
    let score = |x: &Vec3| star_score(&terms, x);
    let mut x = nodes[v].coords;
    let mut s = score(&x);
    // Steps from a tenth of the star's typical edge down to a thousandth of it.
    let edge = terms.iter().map(|(g, _)| g.norm().sqrt()).sum::<f64>() / terms.len() as f64;
    let mut step = 0.1 * edge;
    for _ in 0..60 {
        if s.0 == 0 || step < 1e-3 * edge {
            break;
        }
        let (g, _) = terms
            .iter()
            .min_by(|a, b| (a.0.dot(&x) + a.1).total_cmp(&(b.0.dot(&x) + b.1)))
            .copied()
            .unwrap_or((Vec3::zeros(), 0.0));
        let Some(dir) = g.try_normalize(1e-300) else {
            break;
        };
        let y = within_reach(x + dir * step, origin, reach);
        let sy = score(&y);
        if better(sy, s) {
            x = y;
            s = sy;
        } else {
            step *= 0.5;
        }
    }
    nodes[v] = Point::from(x);
}

/// Minimise `Σ max(0, lower·τ − g·x − c)² + μ |x − x₀|²` from `x₀`.
fn newton_on_star(terms: &[(Vec3, f64, f64)], x0: Vec3, mu: f64, lower: f64) -> Vec3 {
    let cost = |x: &Vec3| -> f64 {
        terms
            .iter()
            .map(|(g, c, tau)| (lower * tau - g.dot(x) - c).max(0.0).powi(2))
            .sum::<f64>()
            + mu * (x - x0).norm_squared()
    };
    let mut x = x0;
    for _ in 0..20 {
        let mut h = Matrix3::identity() * (2.0 * mu);
        let mut grad = (x - x0) * (2.0 * mu);
        for (g, c, tau) in terms {
            let r = lower * tau - g.dot(&x) - c;
            if r > 0.0 {
                h += g * g.transpose() * 2.0;
                grad -= g * (2.0 * r);
            }
        }
        let Some(step) = h.lu().solve(&(-grad)) else {
            break;
        };
        // The function is convex and piecewise quadratic: a full Newton step can only overshoot
        // across a kink, which a halving line search on the true cost catches.
        let f = cost(&x);
        let mut s = 1.0;
        let mut moved = false;
        while s > 1e-4 {
            let y = x + step * s;
            if cost(&y) < f {
                x = y;
                moved = true;
                break;
            }
            s *= 0.5;
        }
        if !moved || step.norm() * s < 1e-9 {
            break;
        }
    }
    x
}

// The crease fixture's reader, shared with the bench that times the same crease.
#[cfg(test)]
#[path = "../../tests/common/crease_fold.rs"]
mod crease_fold;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::tet_mesh::TetMesh;

    /// The gradient formula against central differences of the signed volume, for every corner.
    #[test]
    fn volume_gradient_matches_differences() {
        let nodes = vec![
            Point::new(0.1, 0.2, -0.3),
            Point::new(1.3, 0.1, 0.2),
            Point::new(0.2, 1.1, 0.4),
            Point::new(0.3, -0.2, 1.5),
        ];
        let tet = [0, 1, 2, 3];
        for k in 0..4 {
            let g = volume_gradient(&nodes, &tet, k);
            for axis in 0..3 {
                let h = 1e-6;
                let mut p = nodes.clone();
                p[k].coords[axis] += h;
                let mut m = nodes.clone();
                m[k].coords[axis] -= h;
                let fd =
                    (element_signed_volume(&p, &tet) - element_signed_volume(&m, &tet)) / (2.0 * h);
                assert!((fd - g[axis]).abs() < 1e-8, "corner {k} axis {axis}");
            }
        }
    }

    /// A palmar crease of a posed fist (procedural subject, section scaling on), cut out of
    /// its mesh three rings around the one element the sweeps could not clear, as they left
    /// it, with everything outside those rings and the skin's nodes held: the sweeps alone
    /// stay stuck on it, the Winslow step clears it with the held nodes unmoved.
    #[test]
    fn a_crease_the_sweeps_leave_is_cleared_by_the_winslow_step() {
        let super::crease_fold::CreaseFold {
            nodes,
            tets,
            held,
            reference,
        } = super::crease_fold::crease_fold();
        let opts = UntangleOptions {
            max_boundary_move_mm: 0.0,
            ..Default::default()
        };
        let mut on_boundary = vec![false; nodes.len()];
        for &v in &held {
            on_boundary[v] = true;
        }
        let mut sweeps = nodes.clone();
        let budget = vec![0.0; nodes.len()];
        let alone = untangle_runs(&mut sweeps, &tets, &on_boundary, &reference, &opts, &budget);
        assert!(alone.inverted_before > 0 && alone.inverted_after > 0);
        let mut full = nodes.clone();
        let stats = untangle(&mut full, &tets, &held, &reference, &opts);
        assert_eq!(stats.inverted_after, 0);
        assert_all_positive(&full, &tets);
        for &v in &held {
            assert_eq!(full[v], nodes[v]);
        }
    }

    /// The six vertices of the unit octahedron, on the axes.
    fn octahedron() -> Vec<Point> {
        vec![
            Point::new(1.0, 0.0, 0.0),
            Point::new(-1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, -1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
            Point::new(0.0, 0.0, -1.0),
        ]
    }

    /// An octahedron around two nodes on its axis (a fan of four elements from each to its cap,
    /// four joining them to the equator), the two nodes swapped, so that the four joining
    /// elements are inverted: the nodes, the elements, their targets (a tenth of their volumes
    /// in order) and the inverted ones.
    fn swapped_pair() -> (Vec<Point>, Vec<[usize; 4]>, Vec<f64>, Vec<usize>) {
        let mut nodes = octahedron();
        nodes.extend([Point::new(0.0, 0.0, 0.3), Point::new(0.0, 0.0, -0.3)]);
        let equator = [[0, 2], [2, 1], [1, 3], [3, 0]];
        let mut tets: Vec<[usize; 4]> = Vec::new();
        for [a, b] in equator {
            tets.push([6, a, b, 4]);
            tets.push([7, a, b, 5]);
            tets.push([6, 7, a, b]);
        }
        for t in tets.iter_mut() {
            if element_signed_volume(&nodes, t) < 0.0 {
                t.swap(2, 3);
            }
        }
        let target: Vec<f64> = tets
            .iter()
            .map(|t| 0.1 * element_signed_volume(&nodes, t))
            .collect();
        assert!(target.iter().all(|v| *v > 0.0));
        nodes.swap(6, 7);
        let bad: Vec<usize> = (0..tets.len())
            .filter(|&t| element_signed_volume(&nodes, &tets[t]) <= 0.0)
            .collect();
        assert_eq!(bad.len(), 4, "the four joining elements");
        (nodes, tets, target, bad)
    }

    /// [`untangle_jointly`] on the nodes within one ring of `bad`, the region's boundary nodes
    /// given `boundary_reach`.
    fn untangle_one_ring(
        nodes: &mut [Point],
        tets: &[[usize; 4]],
        bad: &[usize],
        target: &[f64],
        reach: &mut [f64],
        start: &[Point],
        boundary_reach: f64,
    ) {
        let star = node_stars(nodes.len(), tets);
        let budget = vec![f64::INFINITY; nodes.len()];
        let region = Region {
            rings: 1,
            boundary_reach,
            budget: &budget,
        };
        untangle_jointly(nodes, tets, &star, bad, target, reach, start, region);
    }

    /// Every element of `tets` has a positive volume.
    fn assert_all_positive(nodes: &[Point], tets: &[[usize; 4]]) {
        for (t, tet) in tets.iter().enumerate() {
            assert!(
                element_signed_volume(nodes, tet) > 0.0,
                "element {t} still inverted"
            );
        }
    }

    /// The [`swapped_pair`] in a held octahedron, the pair free: moved together, the two come
    /// back in order, every element positive, the held nodes where they were.
    #[test]
    fn two_swapped_nodes_are_untangled_together() {
        let (mut nodes, tets, target, bad) = swapped_pair();
        let held = nodes[..6].to_vec();
        let mut reach = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::INFINITY, f64::INFINITY];
        let start = nodes.clone();
        untangle_one_ring(&mut nodes, &tets, &bad, &target, &mut reach, &start, 0.0);
        assert_all_positive(&nodes, &tets);
        assert_eq!(nodes[..6], held[..]);
        assert!(nodes[6].z > nodes[7].z, "{} {}", nodes[6], nodes[7]);
    }

    /// The [`swapped_pair`] with every node held on the boundary: with no reach the joint solve
    /// can move nothing and the region stays inverted; given a region's reach of 1 mm, boundary
    /// nodes the inverted elements do not name included, it clears every element, no node
    /// further than that from where it started, and the nodes keep the reach they used.
    #[test]
    fn a_held_pair_gives_way_by_the_region_s_reach() {
        let (mut nodes, tets, target, bad) = swapped_pair();
        let start = nodes.clone();
        let mut reach = [0.0; 8];
        untangle_one_ring(&mut nodes, &tets, &bad, &target, &mut reach, &start, 0.0);
        assert_eq!(nodes, start);
        untangle_one_ring(&mut nodes, &tets, &bad, &target, &mut reach, &start, 1.0);
        assert_all_positive(&nodes, &tets);
        for (v, (p, q)) in nodes.iter().zip(&start).enumerate() {
            assert!(
                (p - q).norm() <= 1.0 + 1e-12,
                "node {v} moved {}",
                (p - q).norm()
            );
            if p != q {
                assert_eq!(reach[v], 1.0, "node {v}");
            }
        }
        assert!(nodes[6].z > nodes[7].z, "{} {}", nodes[6], nodes[7]);
    }

    /// The [`swapped_pair`] with every node on the boundary and a reach too short to part the
    /// pair (each of its nodes must pass the other, 0.6 mm apart): elements stay inverted, and
    /// the fresh start after the runs moves no node further than the reach from where it was
    /// before either (its budget is what the runs left; given the reach again, it would part
    /// the pair).
    #[test]
    fn the_fresh_start_keeps_the_boundary_within_its_reach() {
        let (mut nodes, tets, target, _) = swapped_pair();
        let start = nodes.clone();
        let reference: Vec<f64> = target.iter().map(|t| t * 10.0).collect();
        let opts = UntangleOptions {
            max_boundary_move_mm: 0.2,
            ..UntangleOptions::default()
        };
        let boundary: Vec<usize> = (0..nodes.len()).collect();
        let stats = untangle(&mut nodes, &tets, &boundary, &reference, &opts);
        assert!(stats.inverted_after > 0, "{stats:?}");
        for (v, (p, q)) in nodes.iter().zip(&start).enumerate() {
            assert!(
                (p - q).norm() <= 0.2 + 1e-9,
                "node {v} moved {}",
                (p - q).norm()
            );
        }
        assert!(stats.max_boundary_move_mm <= 0.2 + 1e-9, "{stats:?}");
    }

    /// Eight tetrahedra fanned around one free node inside a held octahedron: the node pushed
    /// outside the octahedron inverts some of them, and untangling brings it back inside with
    /// every element above its target; a valid mesh is left untouched.
    #[test]
    fn a_free_node_pushed_out_of_its_cage_comes_back() {
        // Octahedron vertices 0..6, centre 6.
        let mut nodes = octahedron();
        nodes.push(Point::origin());
        let faces = [
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        let mut tets: Vec<[usize; 4]> = faces.iter().map(|f| [6, f[0], f[1], f[2]]).collect();
        for t in tets.iter_mut() {
            if element_signed_volume(&nodes, t) < 0.0 {
                t.swap(2, 3);
            }
        }
        let reference: Vec<f64> = tets
            .iter()
            .map(|t| element_signed_volume(&nodes, t))
            .collect();
        assert!(reference.iter().all(|v| *v > 0.0));
        let boundary: Vec<usize> = (0..6).collect();
        let opts = UntangleOptions::default();

        let mut valid = TetMesh {
            nodes: nodes.clone(),
            tets: tets.clone(),
        };
        let s = untangle(&mut valid.nodes, &valid.tets, &boundary, &reference, &opts);
        assert_eq!((s.inverted_before, s.nodes_moved), (0, 0));
        assert_eq!(valid.nodes, nodes);

        nodes[6] = Point::new(1.6, 0.4, -0.2);
        let mut mesh = TetMesh { nodes, tets };
        let before = mesh.inverted_count();
        assert!(before > 0);
        let s = untangle(&mut mesh.nodes, &mesh.tets, &boundary, &reference, &opts);
        assert_eq!(s.inverted_before, before);
        assert_eq!(s.inverted_after, 0);
        assert_eq!(mesh.inverted_count(), 0);
        // Every element near its target volume (the proximal term keeps the node a little
        // short of it), the held nodes where they were.
        for (t, r) in reference.iter().enumerate() {
            assert!(
                mesh.tet_volume(t) >= 0.05 * r,
                "{t}: {}",
                mesh.tet_volume(t)
            );
        }
        assert_eq!(mesh.nodes[..6], valid.nodes[..6]);
        // Inside the octahedron: |x| + |y| + |z| < 1.
        let c = mesh.nodes[6];
        assert!(c.x.abs() + c.y.abs() + c.z.abs() < 1.0, "{c}");
    }
}
