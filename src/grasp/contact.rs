//! Contacts between the posed skin and the part, from point queries on the part's face tree.
//!
//! The part is indexed by the toolkit's face tree ([`AabbTree`]) and, when it is a closed
//! oriented 2-manifold, angle-weighted pseudo-normals (Bærentzen & Aanæs 2005), which make the
//! projection of a point tell inside from outside; both are built once per part. A voxel broad
//! phase ([`super::broad::NearGrid`]) answers most skin vertices without a query: only those
//! that may lie within [`GRID_BAND_MM`] of the surface are projected on the part (bounded by
//! the search radius), the rest are known to be outside (or deep inside). A vertex is in contact
//! when it lies within `tolerance_mm` of the surface or inside the part. Its share of the skin
//! area (one third of each incident face, on the rest mesh) is its contact area. Per link the
//! contact vertices are summarised into a few contact patches (farthest-point seeds, nearest-seed
//! assignment) with the area-weighted mean point on the part, the mean inward normal and the
//! deepest penetration: the point contacts the grasp quality uses.

use super::broad::{NearGrid, Zone};
use crate::anatomy::{Finger, Link};
use crate::error::{Error, Result};
use crate::geometry::closest_point::{AabbTree, Closest, PseudoNormals};
use crate::geometry::{Point, TriMesh, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Part geometry ready for queries, in world coordinates, mm.
pub struct PartShape {
    /// Surface, mm.
    pub mesh: TriMesh,
    /// Closest-point and ray index over a copy of `mesh`.
    pub tree: AabbTree<'static>,
    /// Pseudo-normals of `mesh` for the inside test (only when `closed`).
    normals: Option<PseudoNormals>,
    /// Unit outward face normals of `mesh`.
    pub face_normals: Vec<Vec3>,
    /// Whether inside tests are available (closed, oriented 2-manifold).
    pub closed: bool,
    /// Centre of mass (uniform density; the area centroid when open), mm.
    pub centre_of_mass: Point,
    /// Largest distance from the centre of mass to a vertex, mm (GraspIt's torque scale).
    pub max_radius: f64,
    /// Axis-aligned bounds.
    pub lo: Point,
    /// Axis-aligned bounds.
    pub hi: Point,
    /// Broad phase.
    pub grid: NearGrid,
    /// A finer broad phase whose band is the default contact tolerance ([`TOUCH_BAND_MM`]): the
    /// closing's checks skip the skin it puts outside, which neither touches nor presses.
    pub touch_grid: NearGrid,
}

/// Band of the broad phase, mm: queries with a search radius up to this skip the exact
/// projection of every point the grid puts outside the band.
pub const GRID_BAND_MM: f64 = 3.0;

/// Band of [`PartShape::touch_grid`], mm: [`ContactOptions`]' default tolerance.
pub const TOUCH_BAND_MM: f64 = 1.0;

/// A point against the part, from [`PartShape::probe`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Probe {
    /// Outside and farther than the search radius.
    Far,
    /// Inside the closed part, deeper than the search radius.
    Deep,
    /// Within the search radius: signed distance (negative inside), projection, and the outward
    /// unit normal there (the closest feature's pseudo-normal on a closed part, the face normal
    /// on an open one).
    Hit(f64, Point, Vec3),
}

/// Centre of mass of the solid bounded by a closed mesh (signed tetrahedra from the origin).
pub(crate) fn solid_centroid(mesh: &TriMesh) -> Option<Point> {
    let mut v = 0.0;
    let mut c = Vec3::zeros();
    for f in 0..mesh.n_faces() {
        let [a, b, d] = mesh.corners(f);
        let vol = a.coords.dot(&b.coords.cross(&d.coords)) / 6.0;
        v += vol;
        c += (a.coords + b.coords + d.coords) * (vol / 4.0);
    }
    (v.abs() > 1e-9).then(|| Point::from(c / v))
}

impl PartShape {
    /// Build the query structure of `mesh` (mm, world frame). Returns warnings: an open or
    /// non-manifold part falls back to surface distance without inside tests.
    pub fn new(mesh: TriMesh) -> Result<(PartShape, Vec<String>)> {
        Self::with_band(mesh, GRID_BAND_MM)
    }

    /// [`PartShape::new`] with a broad phase of band `band_mm`: queries with a search radius
    /// up to it are answered by the grid for every point farther than about twice the band
    /// from the surface. A narrower band than the default's pays when the search radius is
    /// small and most points lie a few millimetres off the surface (a hand tracked on the
    /// part, where every frame is queried); its grid has eight times the cells per halving.
    pub fn with_band(mesh: TriMesh, band_mm: f64) -> Result<(PartShape, Vec<String>)> {
        let mut warnings = Vec::new();
        if mesh.n_faces() == 0 {
            return Err(Error::invalid("part: the mesh has no triangles"));
        }
        let closed = match mesh.check_closed_manifold() {
            Ok(()) if mesh.signed_volume() > 0.0 => true,
            Ok(()) => {
                warnings.push(
                    "part: the mesh is inside out (negative volume); inside tests are off, contacts use surface distance".into(),
                );
                false
            }
            Err(e) => {
                warnings.push(format!(
                    "part: not a closed 2-manifold ({e}); inside tests are off, contacts use surface distance"
                ));
                false
            }
        };
        // The two broad phases (their flood fills are most of a large part's set-up) beside
        // the face tree and the rest.
        let ((grid, touch_grid), (tree, normals, com)) = rayon::join(
            || {
                rayon::join(
                    || NearGrid::new(&mesh, band_mm, closed),
                    || NearGrid::new(&mesh, TOUCH_BAND_MM, closed),
                )
            },
            || {
                let com = if closed {
                    solid_centroid(&mesh).unwrap_or_else(|| mesh.vertex_centroid())
                } else {
                    mesh.vertex_centroid()
                };
                (
                    AabbTree::owning(mesh.clone()),
                    closed.then(|| PseudoNormals::new(&mesh)),
                    com,
                )
            },
        );
        let max_radius = mesh
            .vertices
            .iter()
            .map(|v| (v - com).norm())
            .fold(0.0, f64::max);
        let (lo, hi) = mesh.bounds().expect("non-empty");
        let size = hi - lo;
        let diag = size.norm();
        if !(10.0..=2000.0).contains(&diag) {
            warnings.push(format!(
                "part: its size is {:.4} x {:.4} x {:.4} mm (diagonal {diag:.4} mm) but a hand-held part is 10 to 2000 mm across: check part.units",
                size.x, size.y, size.z
            ));
        }
        Ok((
            PartShape {
                face_normals: mesh.face_normals(),
                mesh,
                tree,
                normals,
                closed,
                centre_of_mass: com,
                max_radius,
                lo,
                hi,
                grid,
                touch_grid,
            },
            warnings,
        ))
    }

    /// Signed distance of `p` to the surface (negative inside when closed) and the projection,
    /// or `None` when the surface is further than `max_dist` (inside deeper than `max_dist`
    /// is also `None`).
    pub fn query(&self, p: &Point, max_dist: f64) -> Option<(f64, Point, Vec3)> {
        match self.probe(p, max_dist) {
            Probe::Hit(d, q, n) => Some((d, q, n)),
            _ => None,
        }
    }

    /// Where `p` is relative to the part within `max_dist` (see [`Probe`]); the broad phase
    /// answers when `max_dist` is within its band.
    #[inline]
    pub fn probe(&self, p: &Point, max_dist: f64) -> Probe {
        let zone = self.grid.zone(p);
        if max_dist <= self.grid.band {
            match zone {
                Zone::Outside => return Probe::Far,
                Zone::Inside => return Probe::Deep,
                Zone::Near => {}
            }
        }
        match (&self.normals, zone) {
            // A near point on a closed part needs the closest feature even beyond the search
            // radius, for its side: one unbounded traversal answers both, where a bounded query
            // that finds nothing would be followed by a second, unbounded one.
            (Some(normals), Zone::Near) => {
                let Some((c, within)) = self.tree.closest_point_and_within(p, max_dist) else {
                    return Probe::Far;
                };
                let (d, q, n) = self.closed_hit(normals, p, &c);
                if within && self.in_reach(p, max_dist) {
                    Probe::Hit(d, q, n)
                } else if d < 0.0 {
                    Probe::Deep
                } else {
                    Probe::Far
                }
            }
            _ => match self.exact(p, max_dist) {
                Some((d, q, n)) => Probe::Hit(d, q, n),
                None if !self.closed => Probe::Far,
                None => match zone {
                    Zone::Inside => Probe::Deep,
                    _ => Probe::Far,
                },
            },
        }
    }

    /// Unsigned distance to the surface with no bound (for messages about deep points).
    pub fn distance(&self, p: &Point) -> f64 {
        self.tree.distance(p).unwrap_or(f64::INFINITY)
    }

    /// First hit of the ray `origin + t * dir` (either side of a face), as `t`.
    pub fn ray_cast(&self, origin: &Point, dir: &Vec3) -> Option<f64> {
        self.tree
            .ray_cast(origin, dir, 0.0, f64::INFINITY)
            .map(|h| h.t)
    }

    /// Whether the part's bounds grown by `max_dist` hold `p` (else nothing is within reach).
    fn in_reach(&self, p: &Point, max_dist: f64) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] - max_dist && p[a] <= self.hi[a] + max_dist)
    }

    fn exact(&self, p: &Point, max_dist: f64) -> Option<(f64, Point, Vec3)> {
        if !self.in_reach(p, max_dist) {
            return None;
        }
        let c = self.tree.closest_point_within(p, max_dist)?;
        match &self.normals {
            Some(normals) => Some(self.closed_hit(normals, p, &c)),
            None => Some((c.distance, c.point, self.face_normals[c.face])),
        }
    }

    /// Signed distance, projection and outward unit normal of `p` from its closest point `c` on
    /// the closed part.
    fn closed_hit(&self, normals: &PseudoNormals, p: &Point, c: &Closest) -> (f64, Point, Vec3) {
        // The closest feature's pseudo-normal: the sign, and a normal that does not depend on
        // which of the faces meeting at an edge or corner the query happened to name.
        let n = normals.of(&self.mesh, c.face, c.feature);
        let inside = (p - c.point).dot(&n) < 0.0;
        let n = n.try_normalize(1e-12).unwrap_or(self.face_normals[c.face]);
        let d = c.distance;
        (if inside { -d } else { d }, c.point, n)
    }
}

/// Contact detection settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactOptions {
    /// A skin vertex within this distance of the part counts as touching, mm.
    pub tolerance_mm: f64,
    /// Search radius, mm: vertices deeper inside are not measured (the autograsp never lets
    /// the skin go that deep); up to [`GRID_BAND_MM`] the broad phase skips far vertices.
    pub search_mm: f64,
    /// At most this many contact patches per link.
    pub patches_per_link: usize,
}

impl Default for ContactOptions {
    fn default() -> Self {
        ContactOptions {
            tolerance_mm: TOUCH_BAND_MM,
            search_mm: GRID_BAND_MM,
            patches_per_link: 4,
        }
    }
}

/// One point contact: a patch of touching skin on one link.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Contact {
    /// Link name ([`Link::name`]).
    pub link: String,
    /// Link index ([`Link::index`]).
    #[serde(skip)]
    pub link_index: usize,
    /// Area-weighted mean of the touching vertices' projections on the part, mm.
    pub point: [f64; 3],
    /// Unit normal pointing into the part (the direction the skin pushes).
    pub normal: [f64; 3],
    /// Deepest penetration of the patch's vertices, mm (0 when only within tolerance).
    pub depth_mm: f64,
    /// Skin area of the patch, mm².
    pub area_mm2: f64,
}

/// Contacts of a posed hand.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactSet {
    /// Per skin vertex: signed distance to the part when within the search radius.
    pub vertex_distance: Vec<Option<f64>>,
    /// Point contacts (patches), by link then patch.
    pub contacts: Vec<Contact>,
    /// Contact area per link index, mm².
    pub link_area_mm2: Vec<f64>,
    /// Deepest penetration per link index, mm.
    pub link_depth_mm: Vec<f64>,
}

impl ContactSet {
    /// Contact area per link name (links with contact only).
    pub fn area_by_link(&self) -> BTreeMap<String, f64> {
        Link::ALL
            .iter()
            .filter(|l| self.link_area_mm2[l.index()] > 0.0)
            .map(|l| (l.name().to_string(), self.link_area_mm2[l.index()]))
            .collect()
    }

    /// Contact area per finger (thumb first) plus the palm (everything else), mm².
    pub fn area_by_finger(&self) -> BTreeMap<String, f64> {
        let mut out = BTreeMap::new();
        let mut rest = self.total_area_mm2();
        for f in Finger::ALL {
            let a: f64 = f
                .links()
                .iter()
                .map(|l| self.link_area_mm2[l.index()])
                .sum();
            rest -= a;
            out.insert(f.trial_name().to_string(), a);
        }
        out.insert("palm".into(), rest.max(0.0));
        out
    }

    /// Total contact area, mm².
    pub fn total_area_mm2(&self) -> f64 {
        self.link_area_mm2.iter().sum()
    }

    /// Deepest penetration over all links, mm.
    pub fn max_depth_mm(&self) -> f64 {
        self.link_depth_mm.iter().cloned().fold(0.0, f64::max)
    }

    /// Whether `link` touches.
    pub fn touches(&self, link: usize) -> bool {
        self.link_area_mm2[link] > 0.0
    }

    /// How the contacts envelop the part ([`Envelope`]).
    pub fn envelope(&self) -> Envelope {
        let fingers_wrapped: Vec<String> = Finger::ALL[1..]
            .iter()
            .filter(|f| f.links().iter().all(|l| self.touches(l.index())))
            .map(|f| f.trial_name().to_string())
            .collect();
        let palm = self.touches(Link::Palm.index());
        Envelope {
            palm,
            wraps: palm && fingers_wrapped.len() >= WRAP_FINGERS,
            fingers_wrapped,
        }
    }
}

/// Fingers that must wrap the part with all three phalanges, with the palm touching, for a
/// grasp to count as a wrap ([`Envelope::wraps`]).
pub const WRAP_FINGERS: usize = 3;

/// How a grasp envelops the part: a power grasp holds it against the palm with the phalanges
/// of the closing fingers wrapped round it (Cutkosky 1989, "power grasps"; Kamakura et al.
/// 1980, the standard power grip: the palm and the palmar surfaces of all phalanges); a grasp
/// that holds by the fingertips with the palm off the part holds differently, and loads the
/// hand differently, from the grasp a person makes.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct Envelope {
    /// The palm touches the part.
    pub palm: bool,
    /// The fingers (index to little) whose proximal, middle and distal phalanges all touch.
    pub fingers_wrapped: Vec<String>,
    /// The palm and at least [`WRAP_FINGERS`] fingers wrapped.
    pub wraps: bool,
}

impl Envelope {
    /// In words, for tables and summaries: `wraps (palm on; wrapped: index middle ring)` or
    /// `no wrap (palm off; wrapped: no finger)`.
    pub fn describe(&self) -> String {
        format!(
            "{} (palm {}; wrapped: {})",
            if self.wraps { "wraps" } else { "no wrap" },
            if self.palm { "on" } else { "off" },
            if self.fingers_wrapped.is_empty() {
                "no finger".to_string()
            } else {
                self.fingers_wrapped.join(" ")
            }
        )
    }
}

/// Per-vertex skin area: a third of each incident face's area.
pub fn vertex_areas(mesh: &TriMesh) -> Vec<f64> {
    let mut a = vec![0.0; mesh.n_vertices()];
    for (f, area) in mesh.faces.iter().zip(mesh.face_areas()) {
        for &v in f {
            a[v] += area / 3.0;
        }
    }
    a
}

/// Signed distances of `points` to the part within `search_mm` (parallel, deterministic).
pub fn vertex_distances(
    part: &PartShape,
    points: &[Point],
    search_mm: f64,
) -> Vec<Option<(f64, Point, Vec3)>> {
    points
        .par_iter()
        .with_min_len(512)
        .map(|p| part.query(p, search_mm))
        .collect()
}

/// Contacts between the posed skin `points` (per-vertex `links` and rest `areas`) and `part`.
pub fn contacts(
    part: &PartShape,
    points: &[Point],
    links: &[usize],
    areas: &[f64],
    opts: &ContactOptions,
) -> ContactSet {
    let q = vertex_distances(part, points, opts.search_mm);
    contacts_from(&q, points, links, areas, opts)
}

/// [`contacts`] from already computed per-vertex queries.
pub(crate) fn contacts_from(
    q: &[Option<(f64, Point, Vec3)>],
    _points: &[Point],
    links: &[usize],
    areas: &[f64],
    opts: &ContactOptions,
) -> ContactSet {
    let nl = Link::ALL.len();
    let mut link_area = vec![0.0; nl];
    let mut link_depth = vec![0.0f64; nl];
    let mut touching: Vec<Vec<usize>> = vec![Vec::new(); nl];
    for (i, r) in q.iter().enumerate() {
        if let Some((d, _, _)) = r {
            if *d <= opts.tolerance_mm {
                let l = links[i];
                link_area[l] += areas[i];
                link_depth[l] = link_depth[l].max(-d);
                touching[l].push(i);
            }
        }
    }
    let mut out = Vec::new();
    for (l, vs) in touching.iter().enumerate().take(nl) {
        if vs.is_empty() {
            continue;
        }
        let proj = |i: usize| q[i].as_ref().expect("touching").1;
        // Farthest-point seeds (deterministic: start at the first touching vertex).
        let mut seeds = vec![vs[0]];
        while seeds.len() < opts.patches_per_link {
            let (far, dist) = vs
                .iter()
                .map(|&i| {
                    let d = seeds
                        .iter()
                        .map(|&s| (proj(i) - proj(s)).norm())
                        .fold(f64::MAX, f64::min);
                    (i, d)
                })
                .fold((vs[0], -1.0), |a, b| if b.1 > a.1 { b } else { a });
            // Patches smaller than 3 mm add no distinct contact.
            if dist < 3.0 {
                break;
            }
            seeds.push(far);
        }
        let mut acc = vec![(Vec3::zeros(), Vec3::zeros(), 0.0, 0.0f64); seeds.len()];
        for &i in vs {
            let p = proj(i);
            let k = (0..seeds.len())
                .min_by(|&a, &b| {
                    (p - proj(seeds[a]))
                        .norm()
                        .total_cmp(&(p - proj(seeds[b])).norm())
                })
                .expect("one seed");
            let (d, _, n) = q[i].expect("touching");
            let w = areas[i].max(1e-12);
            acc[k].0 += p.coords * w;
            acc[k].1 += -n * w;
            acc[k].2 += w;
            acc[k].3 = acc[k].3.max(-d);
        }
        for (sp, sn, w, depth) in acc {
            if w <= 0.0 {
                continue;
            }
            let p = sp / w;
            let n = sn.try_normalize(1e-12).unwrap_or(Vec3::z());
            out.push(Contact {
                link: Link::ALL[l].name().to_string(),
                link_index: l,
                point: [p.x, p.y, p.z],
                normal: [n.x, n.y, n.z],
                depth_mm: depth.max(0.0),
                area_mm2: w,
            });
        }
    }
    ContactSet {
        vertex_distance: q.iter().map(|r| r.map(|x| x.0)).collect(),
        contacts: out,
        link_area_mm2: link_area,
        link_depth_mm: link_depth,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_part() -> PartShape {
        // A 200 x 200 x 50 slab whose top face is z = 0.
        let m = crate::geometry::mesh::tests::cuboid(200.0, 200.0, 50.0)
            .transformed(&nalgebra::Isometry3::translation(-100.0, -100.0, -50.0));
        PartShape::new(m).unwrap().0
    }

    #[test]
    fn signed_distance_of_slab() {
        let p = plane_part();
        assert!(p.closed);
        let (d, q, n) = p.query(&Point::new(1.0, 2.0, 3.0), 10.0).unwrap();
        assert!((d - 3.0).abs() < 1e-9 && (q - Point::new(1.0, 2.0, 0.0)).norm() < 1e-9);
        assert!((n - Vec3::z()).norm() < 1e-9);
        let (d, _, _) = p.query(&Point::new(1.0, 2.0, -4.0), 10.0).unwrap();
        assert!((d + 4.0).abs() < 1e-9);
        assert!(p.query(&Point::new(1.0, 2.0, 30.0), 10.0).is_none());
    }

    #[test]
    fn fingertip_pressed_on_plane_has_spherical_cap_area() {
        // A 8 mm fingertip pressed 1.5 mm into a plane: skin within t = 1 mm of the plane or
        // inside it is the spherical cap of height h = 1.5 + 1, area 2 pi R h.
        let r = 8.0;
        let tip = crate::geometry::mesh::tests::icosphere(r, 5)
            .transformed(&nalgebra::Isometry3::translation(0.0, 0.0, r - 1.5));
        let part = plane_part();
        let links = vec![Link::ALL[5].index(); tip.n_vertices()];
        let areas = vertex_areas(&tip);
        let c = contacts(
            &part,
            &tip.vertices,
            &links,
            &areas,
            &ContactOptions::default(),
        );
        let expect = 2.0 * std::f64::consts::PI * r * 2.5;
        let got = c.total_area_mm2();
        assert!((got - expect).abs() < 0.1 * expect, "{got} vs {expect}");
        assert!((c.max_depth_mm() - 1.5).abs() < 0.1, "{}", c.max_depth_mm());
        // The patches push down, into the plane.
        for k in &c.contacts {
            assert!(k.normal[2] < -0.99, "{:?}", k.normal);
        }
    }

    #[test]
    fn flat_pad_on_plane_has_pad_area() {
        // A 15 x 20 mm flat pad, 5 mm thick, 0.2 mm above the plane: its bottom face (300 mm²)
        // is within the 1 mm tolerance, and so is a 0.8 mm band of its sides (perimeter 70 mm,
        // 56 mm²): 356 mm² analytically.
        let sdf = |p: &Point| {
            let q = [p.x.abs() - 7.5, p.y.abs() - 10.0, (p.z - 2.7).abs() - 2.5];
            let out = Vec3::new(q[0].max(0.0), q[1].max(0.0), q[2].max(0.0)).norm();
            out + q[0].max(q[1]).max(q[2]).min(0.0)
        };
        let pad = super::super::parts::mesh_sdf(
            sdf,
            Point::new(-8.0, -11.0, 0.0),
            Point::new(8.0, 11.0, 6.0),
            0.25,
        )
        .unwrap();
        let links = vec![Link::ALL[8].index(); pad.n_vertices()];
        let c = contacts(
            &plane_part(),
            &pad.vertices,
            &links,
            &vertex_areas(&pad),
            &ContactOptions::default(),
        );
        let got = c.area_by_link()[Link::ALL[8].name()];
        assert!((got - 356.0).abs() < 0.1 * 356.0, "{got}");
        assert!(c.max_depth_mm() < 1e-9);
    }

    #[test]
    fn open_part_warns_and_has_no_inside() {
        let mut m = crate::geometry::mesh::tests::cuboid(10.0, 10.0, 10.0);
        m.faces.pop();
        let (p, w) = PartShape::new(m).unwrap();
        assert!(!p.closed);
        assert!(w.iter().any(|s| s.contains("closed")), "{w:?}");
        let (d, _, _) = p.query(&Point::new(5.0, 5.0, 9.0), 5.0).unwrap();
        assert!(d > 0.0);
    }

    #[test]
    fn wrong_units_warn_with_size() {
        let (_, w) = PartShape::new(crate::geometry::mesh::tests::cuboid(0.06, 0.06, 0.2)).unwrap();
        assert!(
            w.iter()
                .any(|s| s.contains("part.units") && s.contains("0.2")),
            "{w:?}"
        );
    }

    /// A wrap is the palm and three fingers with every phalanx; a finger missing one phalanx
    /// is not wrapped, and without the palm nothing wraps.
    #[test]
    fn a_wrap_is_the_palm_and_three_fingers_with_every_phalanx() {
        let with = |links: &[Link]| {
            let mut area = vec![0.0; Link::ALL.len()];
            for l in links {
                area[l.index()] = 10.0;
            }
            ContactSet {
                vertex_distance: Vec::new(),
                contacts: Vec::new(),
                link_area_mm2: area,
                link_depth_mm: vec![0.0; Link::ALL.len()],
            }
            .envelope()
        };
        let fingers = |fs: &[Finger]| -> Vec<Link> { fs.iter().flat_map(|f| f.links()).collect() };
        let mut three = fingers(&[Finger::Index, Finger::Middle, Finger::Ring]);
        let e = with(&three);
        assert!(!e.palm && !e.wraps && e.fingers_wrapped.len() == 3, "{e:?}");
        three.push(Link::Palm);
        let e = with(&three);
        assert!(e.wraps, "{e:?}");
        assert_eq!(e.describe(), "wraps (palm on; wrapped: index middle ring)");
        assert_eq!(e.fingers_wrapped, ["index", "middle", "ring"]);
        // The thumb's phalanges do not count as a wrapped finger.
        let mut thumb = fingers(&[Finger::Thumb, Finger::Index, Finger::Middle]);
        thumb.push(Link::Palm);
        thumb.retain(|&l| l != Link::MMid);
        let e = with(&thumb);
        assert!(!e.wraps && e.fingers_wrapped == ["index"], "{e:?}");
    }
}
