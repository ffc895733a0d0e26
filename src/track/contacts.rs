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
use crate::anatomy::Link;
use crate::geometry::{Point, TriMesh};
use crate::grasp::contact::{vertex_areas, PartShape, Probe};
use crate::grasp::hand::{PosableHand, SkinnedHand};
use nalgebra::Isometry3;
use rayon::prelude::*;
use std::collections::HashMap;

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
    /// Part vertices under the contact, ascending.
    pub part_vertices: Vec<u32>,
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
    /// Frames with contacts measured (hand and part both tracked).
    pub fn measured(&self) -> usize {
        self.frames.iter().filter(|f| f.is_some()).count()
    }

    /// Frames where the hand was solved but the part's pose was unknown, so contacts are `None`.
    pub fn missing(&self, tracked: &Tracked) -> Vec<usize> {
        (0..self.frames.len())
            .filter(|&f| self.frames[f].is_none() && tracked.frames[f].state.is_some())
            .collect()
    }
}

/// Part vertices in a uniform grid, for the contact map's radius search.
struct VertexGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl VertexGrid {
    fn new(points: &[Point], cell: f64) -> VertexGrid {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            cells.entry(Self::key(p, cell)).or_default().push(i as u32);
        }
        VertexGrid { cell, cells }
    }

    fn key(p: &Point, cell: f64) -> [i64; 3] {
        [
            (p.x / cell).floor() as i64,
            (p.y / cell).floor() as i64,
            (p.z / cell).floor() as i64,
        ]
    }

    /// Vertices within `r <= cell` of `p`, appended to `out`.
    fn within(&self, points: &[Point], p: &Point, r: f64, out: &mut Vec<u32>) {
        let k = Self::key(p, self.cell);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(vs) = self.cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
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
}

/// The contacts of one posed skin (`points`, in the part's frame) with `part`.
fn frame_contacts(
    part: &PartShape,
    grid: &VertexGrid,
    radius: f64,
    points: &[Point],
    links: &[usize],
    areas: &[f64],
    opts: &ReplayOptions,
) -> FrameContacts {
    let mut area = [0.0; 17];
    let mut depth = [0.0f64; 17];
    let mut skin = Vec::new();
    let mut under = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let hit = match part.probe(p, opts.tolerance_mm) {
            Probe::Far => None,
            Probe::Hit(d, q, _) => (d <= opts.tolerance_mm).then_some((d, q)),
            Probe::Deep => part.tree.closest_point(p).map(|c| (-c.distance, c.point)),
        };
        let Some((d, q)) = hit else { continue };
        let l = links[i];
        area[l] += areas[i];
        depth[l] = depth[l].max(-d);
        skin.push(i as u32);
        grid.within(&part.mesh.vertices, &q, radius, &mut under);
    }
    under.sort_unstable();
    under.dedup();
    FrameContacts {
        link_area_mm2: area,
        link_depth_mm: depth,
        skin_vertices: skin,
        part_vertices: under,
    }
}

/// Contacts of `hand` (the individual hand of the model `kin` was read from) with `part` (in
/// its own frame) over the `tracked` trial, whose `part` holds the part's pose per frame (part
/// frame -> lab). Frames run in parallel; the result does not depend on the thread count.
pub fn replay_contacts(
    hand: &SkinnedHand,
    kin: &Kinematics,
    tracked: &Tracked,
    part: &PartShape,
    opts: &ReplayOptions,
) -> ContactReplay {
    let n = tracked.frames.len();
    let skin = hand.rest_mesh();
    let areas = vertex_areas(skin);
    let links = hand.vertex_link();
    let radius = mean_edge_length(skin).max(1e-3);
    let grid = VertexGrid::new(&part.mesh.vertices, radius);
    let part_pose = |f: usize| -> Option<Isometry3<f64>> {
        tracked.part.as_ref().and_then(|(poses, _)| poses[f])
    };
    let frames: Vec<Option<FrameContacts>> = (0..n)
        .into_par_iter()
        .map_init(Vec::new, |posed, f| {
            let state = tracked.frames[f].state.as_ref()?;
            let to_part = part_pose(f)?.inverse();
            let t = kin.evaluate(state);
            let transforms: Vec<Isometry3<f64>> =
                t.links.iter().map(|l| to_part * l).collect();
            hand.pose_all(&transforms, posed);
            Some(frame_contacts(
                part, &grid, radius, posed, links, &areas, opts,
            ))
        })
        .collect();
    let mut skin_count = vec![0u32; skin.n_vertices()];
    let mut part_count = vec![0u32; part.mesh.n_vertices()];
    for fc in frames.iter().flatten() {
        for &v in &fc.skin_vertices {
            skin_count[v as usize] += 1;
        }
        for &v in &fc.part_vertices {
            part_count[v as usize] += 1;
        }
    }
    debug_assert_eq!(Link::ALL.len(), 17);
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
