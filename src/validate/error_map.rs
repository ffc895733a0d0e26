//! The error map of a fitted skin (the seed paper's Figure 10(e)): the distance of every skin
//! vertex to the CT-like reference surface and, the other way, of the reference's vertices to
//! the skin (a skin that misses a part of the hand, e.g. a finger web, only shows up in that
//! direction), their statistics (section 5.2: mean, max, min, SD; plus the 95th percentile),
//! pictures of the skin coloured by its distance (dorsal, palmar, radial and ulnar views with a
//! colour bar in mm) and a GLB with the same vertex colours.

use super::surface_error::{distances_to_surface, SurfaceError};
use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::io::gltf::{glb_bytes, Scene, SceneMesh};
use crate::io::Units;
use crate::render::{
    colour_bar_ticks, draw_label_sized, label_size, map_values, render_mesh_with, Image,
    RenderOptions, View,
};
use crate::skeleton::record::JointRecord;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The reverse direction measures at most this many reference vertices (an even stride over
/// the vertex list). The CT-like reference has about 850,000 vertices spread evenly over the
/// surface (an isosurface on a 0.5 mm grid), so a stride keeps the sample uniform over the
/// surface while bounding the time; the count measured is reported.
pub(crate) const MAX_REVERSE_POINTS: usize = 250_000;

/// Distances in both directions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ErrorMap {
    /// Per skin vertex: distance to the reference surface, mm.
    #[serde(skip)]
    pub skin_to_reference: Vec<f64>,
    /// Statistics of `skin_to_reference`.
    pub skin_to_reference_stats: SurfaceError,
    /// Per measured reference vertex (every `reference_stride`-th): distance to the skin, mm.
    #[serde(skip)]
    pub reference_to_skin: Vec<f64>,
    /// Statistics of the distances of reference vertices to the skin surface.
    pub reference_to_skin_stats: SurfaceError,
    /// Per measured reference vertex: the skin vertex nearest to its closest point on the skin
    /// (the corner of the closest face with the largest barycentric weight), so that reference
    /// points can be given the skin's regions.
    #[serde(skip)]
    pub reference_nearest_skin_vertex: Vec<usize>,
    /// Reference vertices in the mesh (the statistics above cover `reference_to_skin_stats.n`
    /// of them, every `stride`-th).
    pub reference_vertices: usize,
    /// Stride of the reference vertices measured.
    pub reference_stride: usize,
}

/// Measure `skin` against `reference` both ways (see [`MAX_REVERSE_POINTS`]).
pub fn error_map(skin: &TriMesh, reference: &TriMesh) -> ErrorMap {
    error_map_with(skin, reference, MAX_REVERSE_POINTS)
}

/// [`error_map`] measuring at most `max_reverse` reference vertices (at least 1).
pub(crate) fn error_map_with(skin: &TriMesh, reference: &TriMesh, max_reverse: usize) -> ErrorMap {
    let (forward, (reverse, stride)) = rayon::join(
        || distances_to_surface(&skin.vertices, &AabbTree::new(reference)),
        || {
            let stride = reference.n_vertices().div_ceil(max_reverse.max(1)).max(1);
            let pts: Vec<Point> = reference.vertices.iter().step_by(stride).copied().collect();
            let closest = AabbTree::new(skin).closest_points(&pts);
            let distances: Vec<f64> = closest
                .iter()
                .map(|c| c.as_ref().map_or(f64::INFINITY, |c| c.distance))
                .collect();
            let nearest: Vec<usize> = closest
                .iter()
                .map(|c| {
                    c.as_ref().map_or(usize::MAX, |c| {
                        let k = (0..3)
                            .max_by(|&a, &b| c.barycentric[a].total_cmp(&c.barycentric[b]))
                            .unwrap_or(0);
                        skin.faces[c.face][k]
                    })
                })
                .collect();
            ((distances, nearest), stride)
        },
    );
    let (reverse, nearest) = reverse;
    ErrorMap {
        skin_to_reference_stats: SurfaceError::of(&forward),
        skin_to_reference: forward,
        reference_to_skin_stats: SurfaceError::of(&reverse),
        reference_to_skin: reverse,
        reference_nearest_skin_vertex: nearest,
        reference_vertices: reference.n_vertices(),
        reference_stride: stride,
    }
}

/// The anatomical directions of a hand from its joints table (`link_model.json`): dorsal (the
/// wrist frame's y), distal (wrist to middle MCP) and radial (little MCP to index MCP), each
/// made orthogonal to the previous ones. Errors name `path` and the joint.
pub fn hand_directions(
    joints: &BTreeMap<String, JointRecord>,
    path: &Path,
) -> Result<(Vec3, Vec3, Vec3)> {
    let get = |j: Joint| -> Result<&JointRecord> {
        joints
            .get(j.name())
            .ok_or_else(|| Error::input(path, format!("joint {j} is missing from 'joints'")))
    };
    let c = |j: Joint| -> Result<Vec3> {
        let r = get(j)?;
        Ok(Vec3::new(r.centre[0], r.centre[1], r.centre[2]))
    };
    let w = get(Joint::Wrist)?;
    let dorsal = Vec3::new(w.frame[1][0], w.frame[1][1], w.frame[1][2]);
    let bad = |what: &str| Error::input(path, format!("the joints give no {what} direction"));
    let dorsal = dorsal.try_normalize(1e-9).ok_or_else(|| bad("dorsal"))?;
    let distal = c(Joint::MMcp)? - c(Joint::Wrist)?;
    let distal = (distal - dorsal * distal.dot(&dorsal))
        .try_normalize(1e-9)
        .ok_or_else(|| bad("distal"))?;
    let radial = c(Joint::IMcp)? - c(Joint::LMcp)?;
    let radial = (radial - dorsal * radial.dot(&dorsal) - distal * radial.dot(&distal))
        .try_normalize(1e-9)
        .ok_or_else(|| bad("radial"))?;
    Ok((dorsal, distal, radial))
}

/// The four standard views of a hand (name, camera), distal up: looking at the back of the
/// hand, at the palm, at the thumb side and at the little-finger side.
pub(crate) fn hand_views(dorsal: Vec3, distal: Vec3, radial: Vec3) -> [(&'static str, View); 4] {
    [
        ("dorsal", View::along(-dorsal, distal)),
        ("palmar", View::along(dorsal, distal)),
        ("radial", View::along(-radial, distal)),
        ("ulnar", View::along(radial, distal)),
    ]
}

/// A round top for the colour scale: the 99th percentile of `values` rounded up to 0.5 mm
/// (at least 0.5 mm), so that a few extreme vertices do not wash out the rest of the map.
pub fn colour_scale_top(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let p99 = v
        .get((0.99 * v.len().saturating_sub(1) as f64) as usize)
        .copied()
        .unwrap_or(0.0);
    ((p99 / 0.5).ceil() * 0.5).max(0.5)
}

/// Ticks every 0.5 or 1 mm (whichever gives at most 8) from 0 to `top`; the last one reads
/// "≥ top" when values beyond it were clamped.
fn ticks(top: f64, clamped: bool) -> Vec<(f64, String)> {
    let step = if top / 0.5 <= 8.0 {
        0.5
    } else {
        (top / 8.0).ceil()
    };
    let n = (top / step).round() as usize;
    (0..=n)
        .map(|k| {
            let v = (k as f64 * step).min(top);
            let s = if k == n && clamped {
                format!("≥ {v:.1}")
            } else {
                format!("{v:.1}")
            };
            (v, s)
        })
        .collect()
}

/// Pictures of `skin` coloured by `values` (mm, one per vertex) on viridis from 0 to `top`:
/// the first `n_views` (1 to 4) views of [`hand_views`] side by side at one common scale (so
/// sizes compare), each named under it, a colour bar in mm at the right and `title` above.
/// `view_px` is the width of one view (height 1.45×).
pub fn render_error_views(
    skin: &TriMesh,
    values: &[f64],
    directions: (Vec3, Vec3, Vec3),
    top: f64,
    title: &str,
    view_px: u32,
    n_views: usize,
) -> Result<Image> {
    if values.len() != skin.n_vertices() {
        return Err(Error::invalid(format!(
            "error map: {} values for {} skin vertices",
            values.len(),
            skin.n_vertices()
        )));
    }
    let colours = map_values(values, 0.0, top);
    let n_views = n_views.clamp(1, 4);
    let views: Vec<(&str, View)> = hand_views(directions.0, directions.1, directions.2)
        .into_iter()
        .take(n_views)
        .map(|(n, v)| (n, v.fit_mesh(skin, 0.04)))
        .collect();
    // One scale for all four: the largest extents.
    let (hw, hh) = views.iter().fold((0.0f64, 0.0f64), |(a, b), (_, v)| {
        let (w, h) = v.half_extents();
        (a.max(w), b.max(h))
    });
    let (vw, vh) = (view_px, (view_px as f64 * 1.45) as u32);
    let hw = hw.max(hh * vw as f64 / vh as f64);
    let hh = hh.max(hw * vh as f64 / vw as f64);
    let opts = RenderOptions {
        ambient: 0.35,
        ..RenderOptions::default()
    };
    let size = (view_px as f64 / 20.0).clamp(11.0, 18.0);
    let head = if title.is_empty() {
        0
    } else {
        (size * 2.2) as u32
    };
    let foot = (size * 2.0) as u32;
    let bar_w = (view_px as f64 * 0.55) as u32;
    let nv = views.len() as u32;
    let mut img = Image::new(nv * vw + bar_w, head + vh + foot, [255, 255, 255]);
    for (k, (name, v)) in views.iter().enumerate() {
        let v = v.with_frame(v.center(), hw, hh);
        let tile = render_mesh_with(skin, Some(&colours), &v, vw, vh, &opts);
        let x = k as u32 * vw;
        img.blit(&tile, x as i64, head as i64);
        let (tw, _) = label_size(name, size)?;
        draw_label_sized(
            &mut img,
            (x + vw / 2) as i32 - tw as i32 / 2,
            (head + vh) as i32 + (size * 0.4) as i32,
            name,
            [40, 40, 40],
            size,
        )?;
    }
    let clamped = values.iter().any(|&x| x > top);
    let bar = colour_bar_ticks(
        0.0,
        top,
        &ticks(top, clamped),
        if view_px < 150 { "mm" } else { "distance (mm)" },
        bar_w,
        (vh as f64 * 0.8) as u32,
    )?;
    img.blit(&bar, (nv * vw) as i64, (head + vh / 10) as i64);
    if !title.is_empty() {
        draw_label_sized(&mut img, 12, (size * 0.5) as i32, title, [20, 20, 20], size)?;
    }
    Ok(img)
}

/// sRGB bytes to the linear RGBA that glTF's `COLOR_0` holds (glTF 2.0, 3.7.2.1: vertex colours
/// are linear), with the sRGB transfer function (IEC 61966-2-1).
pub(crate) fn srgb_to_linear(c: [u8; 3]) -> [f32; 4] {
    let f = |x: u8| {
        let s = x as f64 / 255.0;
        let l = if s <= 0.04045 {
            s / 12.92
        } else {
            ((s + 0.055) / 1.055).powf(2.4)
        };
        l as f32
    };
    [f(c[0]), f(c[1]), f(c[2]), 1.0]
}

/// The custom vertex attribute of `error-map.glb` that holds each vertex's distance to the
/// reference, mm (the view page reads it out where the reader clicks).
pub const ERROR_ATTRIBUTE: &str = "_ERROR_MM";

/// `skin` with its error colours (viridis, 0 to `top` mm) as GLB bytes: one mesh named
/// `error map`, lengths in metres, colours in `COLOR_0`, the distances themselves in
/// [`ERROR_ATTRIBUTE`], through the same [`crate::io::gltf`] writer as every other GLB of the
/// toolkit.
pub fn error_map_glb(skin: &TriMesh, values: &[f64], top: f64) -> Result<Vec<u8>> {
    let colours = map_values(values, 0.0, top);
    let scene = Scene {
        meshes: vec![SceneMesh {
            name: "error map".into(),
            mesh: skin.clone(),
            normals: Some(skin.vertex_normals()),
            colors: Some(colours.into_iter().map(srgb_to_linear).collect()),
            skin: None,
            attributes: vec![crate::io::gltf::VertexAttribute {
                name: ERROR_ATTRIBUTE.into(),
                values: values.iter().map(|&v| v as f32).collect(),
            }],
            morph_targets: Vec::new(),
        }],
        animations: Vec::new(),
    };
    glb_bytes(&scene, Units::Metres)
}

/// [`error_map_glb`] written to `path` atomically.
pub fn write_error_map_glb(path: &Path, skin: &TriMesh, values: &[f64], top: f64) -> Result<()> {
    crate::io::atomic::write_bytes_atomic(path, &error_map_glb(skin, values, top)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::icosphere;

    /// The metric itself: a closed surface against itself is 0 everywhere in both directions;
    /// against a copy offset by 1 mm along its vertex normals it is 1 mm up to the curvature
    /// of the sphere (an offset vertex's distance to the inner facets is exactly 1 mm at the
    /// vertices and at most the chord sagitta less in between).
    #[test]
    fn distances_to_self_and_to_a_normal_offset() {
        let s = icosphere(20.0, 4);
        let m = error_map(&s, &s);
        assert!(m.skin_to_reference_stats.max_mm < 1e-9);
        assert!(m.reference_to_skin_stats.max_mm < 1e-9);
        assert_eq!(m.skin_to_reference.len(), s.n_vertices());
        let normals = s.vertex_normals();
        let off = TriMesh::new(
            s.vertices
                .iter()
                .zip(&normals)
                .map(|(p, n)| p + n * 1.0)
                .collect(),
            s.faces.clone(),
        )
        .unwrap();
        let m = error_map(&off, &s);
        let f = &m.skin_to_reference_stats;
        // Every offset vertex is 1 mm from the sphere's vertex under it; the facets between
        // vertices lie inside the circumscribed sphere by at most the sagitta r(1 - cos(e/2r))
        // with e the longest edge.
        let e = s
            .faces
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (s.vertices[a] - s.vertices[b]).norm())
            .fold(0.0, f64::max);
        let sag = 20.0 * (1.0 - (e / 40.0).cos());
        assert!(
            f.min_mm > 1.0 - 1e-9 && f.max_mm < 1.0 + sag + 1e-9,
            "{f:?}"
        );
        let r = &m.reference_to_skin_stats;
        assert!(r.mean_mm > 0.95 && r.max_mm < 1.0 + 1e-9, "{r:?}");
        // The stride caps the reverse sample and is reported.
        let m = error_map_with(&off, &s, 100);
        assert!(m.reference_to_skin_stats.n <= 100 && m.reference_stride > 1);
        assert_eq!(m.reference_vertices, s.n_vertices());
    }

    #[test]
    fn colour_scale_and_ticks() {
        let v: Vec<f64> = (0..1000).map(|i| i as f64 / 1000.0 * 2.2).collect();
        assert_eq!(colour_scale_top(&v), 2.5);
        assert_eq!(colour_scale_top(&[]), 0.5);
        let t = ticks(2.5, true);
        assert_eq!(t.len(), 6);
        assert_eq!(t.last().unwrap().1, "≥ 2.5");
        assert!(ticks(12.0, false).len() <= 9);
        // The sRGB transfer: black and white kept, 128 to 0.2159 (IEC 61966-2-1).
        assert_eq!(srgb_to_linear([0, 255, 0])[..3], [0.0, 1.0, 0.0]);
        assert!((srgb_to_linear([128, 0, 0])[0] - 0.2158605).abs() < 1e-4);
    }
}
