//! The skin's surface error per anatomical region: a partition of the template's vertices into
//! fingers, fingertips, dorsal and palmar palm, thenar, hypothenar and wrist, carried to any
//! reconstruction by vertex index (`skin.obj` is homologous to the template: same vertices in
//! the same order), and the mean, 95th percentile and max of the skin-to-reference distance in
//! each region.
//!
//! The rule, on the high-resolution template of the hand in its rest posture (its skin weights
//! and skeleton; [`template_regions`]):
//!
//! 1. Each vertex's dominant link (the largest skin weight, [`crate::template::dominant_links`]):
//!    a distal link (`X_DIST`, `T_DIST`) makes it **fingertips**; a proximal or middle link
//!    (`X_PROX`, `X_MID`, `T_PROX`) **fingers**; `T_META` **thenar** (the soft tissue over the
//!    thumb metacarpal, which on the palmar side is the thenar eminence); `ARM` **wrist**.
//! 2. A `PALM` vertex is **wrist** when it lies less than [`WRIST_BAND_MM`] distal of the wrist
//!    centre along the palm's axis (wrist centre to middle MCP centre).
//! 3. The other `PALM` vertices are palmar when their normal points against the palm's dorsal
//!    axis (the wrist frame's y), else **dorsal palm**. A palmar one is **hypothenar** when it
//!    lies ulnar of the line midway between the ring and little MCP centres (along the radial
//!    axis, little MCP to index MCP) and within the proximal [`HYPOTHENAR_LENGTH`] of the
//!    palm's length at the little finger (wrist to little MCP along the palm axis), else
//!    **palmar palm**.
//! 4. Clean-up: every region must be one connected patch (fingers and fingertips one per
//!    digit, since the digits only meet through the palm). The vertex normal test in step 3
//!    leaves small islands where the palm's border curls; every patch but the largest of its
//!    region (and digit) is emptied and its vertices take, in index order and repeatedly, the
//!    most common region among their already labelled neighbours, so each island joins a region
//!    that surrounds it.
//!
//! The directions are anatomical (dorsal, distal, radial), so the rule gives mirror-equal
//! regions on the left and right templates.

use super::surface_error::SurfaceError;
use crate::anatomy::{Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{TriMesh, Vec3};
use crate::skeleton::Skeleton;
use crate::template::{dominant_links, LinkWeights};
use serde::Serialize;
use std::path::Path;

/// Skin less than this distal of the wrist centre along the palm axis is the wrist, mm.
pub const WRIST_BAND_MM: f64 = 15.0;

/// The hypothenar covers this proximal share of the palm's length at the little finger (the
/// eminence ends near the distal palmar crease, about a quarter of the way short of the MCP).
pub(crate) const HYPOTHENAR_LENGTH: f64 = 0.75;

/// An anatomical region of the hand's skin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Region {
    /// Proximal and middle phalanges of the four fingers and the thumb's proximal phalanx.
    Fingers,
    /// Distal phalanges of the five digits.
    Fingertips,
    /// The back of the palm.
    DorsalPalm,
    /// The palmar palm without the thenar and hypothenar eminences.
    PalmarPalm,
    /// The soft tissue of the thumb metacarpal (the thenar eminence on the palmar side).
    Thenar,
    /// The palmar ulnar palm proximal of the distal palmar crease.
    Hypothenar,
    /// The skin within [`WRIST_BAND_MM`] distal of the wrist centre and everything proximal.
    Wrist,
}

impl Region {
    /// Every region, distal first.
    pub const ALL: [Region; 7] = [
        Region::Fingertips,
        Region::Fingers,
        Region::DorsalPalm,
        Region::PalmarPalm,
        Region::Thenar,
        Region::Hypothenar,
        Region::Wrist,
    ];

    /// Its name in `metrics.json` and the reports.
    pub fn name(self) -> &'static str {
        match self {
            Region::Fingers => "fingers",
            Region::Fingertips => "fingertips",
            Region::DorsalPalm => "dorsal palm",
            Region::PalmarPalm => "palmar palm",
            Region::Thenar => "thenar",
            Region::Hypothenar => "hypothenar",
            Region::Wrist => "wrist",
        }
    }
}

/// A region and, for fingers and fingertips, the digit (0 thumb .. 4 little): the unit that
/// must be one connected patch.
type Patch = (Region, usize);

/// The digit of a link index into [`Link::ALL`] (thumb 0 .. little 4; `None` for arm and palm).
fn digit(link: usize) -> Option<usize> {
    (link >= Link::TMeta.index()).then(|| (link - Link::TMeta.index()) / 3)
}

/// The regions of every vertex of `mesh` (the template in its rest posture, with its skin
/// `weights` and `skeleton`), by the rule in the module's documentation.
pub(crate) fn template_regions(
    mesh: &TriMesh,
    weights: &LinkWeights,
    skeleton: &Skeleton,
) -> Vec<Region> {
    template_patches(mesh, weights, skeleton)
        .into_iter()
        .map(|p| p.0)
        .collect()
}

/// [`template_regions`] with the digit of the finger and fingertip vertices (0 elsewhere).
fn template_patches(mesh: &TriMesh, weights: &LinkWeights, skeleton: &Skeleton) -> Vec<Patch> {
    let dominant = dominant_links(weights);
    let normals = mesh.vertex_normals();
    let (wrist, [dorsal, radial, distal]) = skeleton.hand_directions();
    let along = |v: Vec3, axis: Vec3| v.dot(&axis);
    let ring = skeleton.centre(Joint::RMcp) - wrist;
    let little = skeleton.centre(Joint::LMcp) - wrist;
    let hypothenar_radial = 0.5 * (along(ring, radial) + along(little, radial));
    let hypothenar_distal = HYPOTHENAR_LENGTH * along(little, distal);

    let patches: Vec<Option<Patch>> = (0..mesh.n_vertices())
        .map(|i| {
            let link = dominant[i];
            let r = mesh.vertices[i] - wrist;
            let d = digit(link).unwrap_or(0);
            let region = if link == Link::Arm.index() {
                Region::Wrist
            } else if link == Link::TMeta.index() {
                Region::Thenar
            } else if link != Link::Palm.index() {
                if (link - Link::TMeta.index()) % 3 == 2 {
                    Region::Fingertips
                } else {
                    Region::Fingers
                }
            } else if along(r, distal) < WRIST_BAND_MM {
                Region::Wrist
            } else if normals[i].dot(&dorsal) >= 0.0 {
                Region::DorsalPalm
            } else if along(r, radial) < hypothenar_radial && along(r, distal) < hypothenar_distal {
                Region::Hypothenar
            } else {
                Region::PalmarPalm
            };
            let d = if matches!(region, Region::Fingers | Region::Fingertips) {
                d
            } else {
                0
            };
            Some((region, d))
        })
        .collect();
    let rings = mesh.topology().vertex_rings;
    keep_largest_patches(patches, &rings)
}

/// Connected components of the vertices with the same patch (over `rings`): per vertex its
/// component id, and each component's size.
fn components(patches: &[Option<Patch>], rings: &[Vec<usize>]) -> (Vec<usize>, Vec<usize>) {
    let mut comp = vec![usize::MAX; patches.len()];
    let mut sizes = Vec::new();
    for start in 0..patches.len() {
        if comp[start] != usize::MAX || patches[start].is_none() {
            continue;
        }
        let id = sizes.len();
        let mut stack = vec![start];
        comp[start] = id;
        let mut n = 0;
        while let Some(v) = stack.pop() {
            n += 1;
            for &w in &rings[v] {
                if comp[w] == usize::MAX && patches[w] == patches[start] {
                    comp[w] = id;
                    stack.push(w);
                }
            }
        }
        sizes.push(n);
    }
    (comp, sizes)
}

/// Step 4 of the rule: keep the largest connected component of every patch, empty the others,
/// and give their vertices (in index order, until none is left) the most common patch among
/// their labelled neighbours (ties to the first in [`Region::ALL`] order, then the digit).
fn keep_largest_patches(mut patches: Vec<Option<Patch>>, rings: &[Vec<usize>]) -> Vec<Patch> {
    let (comp, sizes) = components(&patches, rings);
    let mut largest: std::collections::BTreeMap<Patch, usize> = Default::default();
    for (v, p) in patches.iter().enumerate() {
        if let Some(p) = p {
            let best = largest.entry(*p).or_insert(comp[v]);
            if sizes[comp[v]] > sizes[*best] {
                *best = comp[v];
            }
        }
    }
    for v in 0..patches.len() {
        if let Some(p) = patches[v] {
            if largest[&p] != comp[v] {
                patches[v] = None;
            }
        }
    }
    let rank = |p: &Patch| (Region::ALL.iter().position(|r| *r == p.0), p.1);
    loop {
        let mut changed = false;
        let mut left = false;
        for v in 0..patches.len() {
            if patches[v].is_some() {
                continue;
            }
            let mut votes: Vec<(Patch, usize)> = Vec::new();
            for &w in &rings[v] {
                if let Some(p) = patches[w] {
                    match votes.iter_mut().find(|x| x.0 == p) {
                        Some(x) => x.1 += 1,
                        None => votes.push((p, 1)),
                    }
                }
            }
            let best = votes
                .into_iter()
                .max_by(|a, b| a.1.cmp(&b.1).then(rank(&b.0).cmp(&rank(&a.0))));
            match best {
                Some((p, _)) => {
                    patches[v] = Some(p);
                    changed = true;
                }
                None => left = true,
            }
        }
        if !left || !changed {
            break;
        }
    }
    // A vertex with no labelled vertex in its connected piece of the mesh (none on a closed
    // template) is counted with the wrist rather than dropped.
    patches
        .into_iter()
        .map(|p| p.unwrap_or((Region::Wrist, 0)))
        .collect()
}

/// The regions of the generic template of `side`, for its vertices (and those of any skin
/// homologous to it).
pub fn hand_regions(side: Side) -> Result<Vec<Region>> {
    let t = crate::template::load_template(side)?;
    Ok(template_regions(&t.mesh, &t.weights, &t.skeleton))
}

/// The regions of the template a model folder was made from
/// ([`crate::template::model_template`]), for the vertices of its skin.
pub fn model_regions(model_dir: &std::path::Path, side: Side) -> Result<Vec<Region>> {
    let t = crate::template::model_template(model_dir, side)?;
    Ok(template_regions(&t.mesh, &t.weights, &t.skeleton))
}

/// The surface error of one region.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RegionError {
    /// Region name ([`Region::name`]), or `hand distal of the wrist` for every region but the
    /// wrist.
    pub region: String,
    /// Skin vertices in it.
    pub vertices: usize,
    /// Mean distance to the reference, mm.
    pub mean_mm: f64,
    /// 95th percentile, mm.
    pub p95_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
}

impl RegionError {
    fn of(region: &str, d: &[f64]) -> RegionError {
        let s = SurfaceError::of(d);
        RegionError {
            region: region.to_string(),
            vertices: s.n,
            mean_mm: s.mean_mm,
            p95_mm: s.p95_mm,
            max_mm: s.max_mm,
        }
    }
}

/// The skin-to-reference distance per region (`metrics.json`'s `surface_regions`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceRegions {
    /// One entry per region, in [`Region::ALL`] order.
    pub regions: Vec<RegionError>,
    /// Every region but the wrist together: the hand distal of the wrist.
    pub hand_distal_of_wrist: RegionError,
    /// The other direction over the same part of the hand: reference points whose nearest skin
    /// vertex is not in the wrist region, to the skin. A reference that reaches further up the
    /// forearm than the skin would otherwise count its whole forearm as skin error.
    pub reverse_hand_distal_of_wrist: Option<RegionError>,
}

impl SurfaceRegions {
    /// The entry of `region`.
    pub fn get(&self, region: Region) -> Option<&RegionError> {
        self.regions.iter().find(|r| r.region == region.name())
    }
}

/// Statistics of the per-vertex `distances` (skin vertex -> reference surface) in each region
/// of `regions` (one per vertex), and, given `reverse` (reference point -> skin distance, and
/// the nearest skin vertex of each), the reverse distances of the hand distal of the wrist.
/// Errors name `skin` when the counts differ: the skin is then not homologous to the template.
pub fn surface_regions(
    distances: &[f64],
    reverse: Option<(&[f64], &[usize])>,
    regions: &[Region],
    skin: &Path,
) -> Result<SurfaceRegions> {
    if distances.len() != regions.len() {
        return Err(Error::input(
            skin,
            format!(
                "{} vertices where the template has {}: not homologous to the template, so the \
                 regions cannot be carried to it",
                distances.len(),
                regions.len()
            ),
        ));
    }
    let pick = |keep: &dyn Fn(Region) -> bool| -> Vec<f64> {
        distances
            .iter()
            .zip(regions)
            .filter(|(_, r)| keep(**r))
            .map(|(d, _)| *d)
            .collect()
    };
    Ok(SurfaceRegions {
        regions: Region::ALL
            .iter()
            .map(|&r| RegionError::of(r.name(), &pick(&|x| x == r)))
            .collect(),
        hand_distal_of_wrist: RegionError::of(
            "hand distal of the wrist",
            &pick(&|x| x != Region::Wrist),
        ),
        reverse_hand_distal_of_wrist: reverse.map(|(d, nearest)| {
            let kept: Vec<f64> = d
                .iter()
                .zip(nearest)
                .filter(|(_, &v)| regions.get(v).is_some_and(|r| *r != Region::Wrist))
                .map(|(d, _)| *d)
                .collect();
            RegionError::of("reference to skin, hand distal of the wrist", &kept)
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::template::load_template;

    fn count(regions: &[Region], r: Region) -> usize {
        regions.iter().filter(|x| **x == r).count()
    }

    /// Every vertex has exactly one region (the labels are one per vertex), every region is
    /// used, and both hands give the same count in each region (the rule is anatomical and the
    /// left template is the mirrored right).
    #[test]
    fn regions_cover_the_template_and_mirror() {
        let (r, l) = (
            hand_regions(Side::Right).unwrap(),
            hand_regions(Side::Left).unwrap(),
        );
        let n = load_template(Side::Right).unwrap().mesh.n_vertices();
        assert_eq!(r.len(), n);
        assert_eq!(l.len(), n);
        let total: usize = Region::ALL.iter().map(|&x| count(&r, x)).sum();
        assert_eq!(total, n, "each vertex in exactly one region");
        for x in Region::ALL {
            assert!(count(&r, x) > 100, "{}: {}", x.name(), count(&r, x));
            assert_eq!(count(&r, x), count(&l, x), "{}", x.name());
        }
    }

    /// Each region is one connected patch of the surface; fingers and fingertips one per digit
    /// (neighbouring fingers' patches touch at the finger webs, so the four fingers' proximal
    /// phalanges are one piece of surface together).
    #[test]
    fn each_region_is_one_patch() {
        let t = load_template(Side::Right).unwrap();
        let patches = template_patches(&t.mesh, &t.weights, &t.skeleton);
        let rings = t.mesh.topology().vertex_rings;
        let keys: std::collections::BTreeSet<Patch> = patches.iter().copied().collect();
        for x in Region::ALL {
            let digits = matches!(x, Region::Fingers | Region::Fingertips);
            let n = keys.iter().filter(|k| k.0 == x).count();
            assert_eq!(n, if digits { 5 } else { 1 }, "{}", x.name());
        }
        for k in keys {
            let one: Vec<Option<Patch>> = patches.iter().map(|p| (*p == k).then_some(k)).collect();
            let (_, sizes) = components(&one, &rings);
            assert_eq!(
                sizes.len(),
                1,
                "{} digit {}: sizes {sizes:?}",
                k.0.name(),
                k.1
            );
        }
    }

    /// The regions sit where anatomy puts them on the template: fingertips beyond the DIP/IP,
    /// the wrist proximal of the palm, palmar regions on the palmar side, the hypothenar ulnar
    /// of the thenar.
    #[test]
    fn regions_sit_where_anatomy_says() {
        let t = load_template(Side::Right).unwrap();
        let regions = hand_regions(Side::Right).unwrap();
        let sk = &t.skeleton;
        let w = sk.centre(Joint::Wrist);
        let dorsal = sk.joint(Joint::Wrist).y();
        let radial = sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp);
        let distal = sk.centre(Joint::MMcp) - w;
        let mean = |x: Region| {
            let pts: Vec<Vec3> = (0..regions.len())
                .filter(|&i| regions[i] == x)
                .map(|i| t.mesh.vertices[i] - w)
                .collect();
            pts.iter().sum::<Vec3>() / pts.len() as f64
        };
        let m = |x: Region| {
            (
                mean(x).dot(&distal),
                mean(x).dot(&dorsal),
                mean(x).dot(&radial),
            )
        };
        assert!(m(Region::Wrist).0 < m(Region::PalmarPalm).0);
        assert!(m(Region::PalmarPalm).0 < m(Region::Fingers).0);
        assert!(m(Region::Fingers).0 < m(Region::Fingertips).0);
        assert!(m(Region::DorsalPalm).1 > m(Region::PalmarPalm).1);
        assert!(m(Region::DorsalPalm).1 > m(Region::Hypothenar).1);
        assert!(m(Region::Thenar).2 > m(Region::Hypothenar).2);
        assert!(m(Region::PalmarPalm).2 > m(Region::Hypothenar).2);
    }

    /// The statistics per region are those of the vertices carrying it, and the hand distal of
    /// the wrist is every vertex but the wrist's.
    #[test]
    fn statistics_follow_the_labels() {
        let regions = [
            Region::Wrist,
            Region::Fingers,
            Region::Fingers,
            Region::Thenar,
            Region::Wrist,
        ];
        let d = [10.0, 1.0, 3.0, 5.0, 20.0];
        // Reference points: two near skin vertex 0 (wrist), one near 1, one near 3, one with
        // an out-of-range vertex (no region: left out).
        let rev = [30.0, 40.0, 2.0, 4.0, 9.0];
        let nearest = [0, 4, 1, 3, usize::MAX];
        let s =
            surface_regions(&d, Some((&rev, &nearest)), &regions, Path::new("skin.obj")).unwrap();
        let f = s.get(Region::Fingers).unwrap();
        assert_eq!((f.vertices, f.mean_mm, f.max_mm), (2, 2.0, 3.0));
        assert_eq!(s.get(Region::Wrist).unwrap().mean_mm, 15.0);
        assert_eq!(s.get(Region::Hypothenar).unwrap().vertices, 0);
        let h = &s.hand_distal_of_wrist;
        assert_eq!((h.vertices, h.mean_mm, h.max_mm), (3, 3.0, 5.0));
        let r = s.reverse_hand_distal_of_wrist.as_ref().unwrap();
        assert_eq!((r.vertices, r.mean_mm, r.max_mm), (2, 3.0, 4.0));
        let e = surface_regions(&d[..4], None, &regions, Path::new("out/skin.obj")).unwrap_err();
        assert!(e.to_string().contains("out/skin.obj"), "{e}");
    }
}
