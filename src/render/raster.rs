//! Triangle rasterisation with a z-buffer, Lambert shading under a headlight, and the
//! depth-tested overlays (wireframe, points, 3D segments).

use super::{Image, View};
use crate::geometry::{Point, TriMesh, Vec3};

/// How surface normals are turned into brightness.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// One normal per face: facets visible (good for checking tessellation).
    Flat,
    /// Lighting computed at the vertices (angle-weighted vertex normals) and the resulting
    /// colours interpolated (Gouraud 1971).
    Gouraud,
    /// Vertex normals interpolated and lighting computed per pixel (Phong 1975): smooth
    /// highlights on a coarse mesh, no Mach bands along edges.
    Phong,
}

/// Options of [`render_mesh_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Shading model (default [`Shading::Phong`]).
    pub shading: Shading,
    /// Ambient share of the brightness in [0, 1] (default 0.25); the rest is Lambert diffuse.
    pub ambient: f64,
    /// Colour of the empty background (default white).
    pub background: [u8; 3],
    /// Colour of the surface when no per-vertex colours are given (default a light skin tone).
    pub base_colour: [u8; 3],
    /// Draw the mesh edges over the surface in this colour (depth-tested).
    pub wireframe: Option<[u8; 3]>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            shading: Shading::Phong,
            ambient: 0.25,
            background: [255, 255, 255],
            base_colour: [236, 200, 170],
            wireframe: None,
        }
    }
}

/// Render `mesh` seen through `view` into a `width × height` image with default options
/// (see [`render_mesh_with`]).
///
/// # Panics
/// If `colors` is given with a length other than the number of vertices.
pub fn render_mesh(
    mesh: &TriMesh,
    colors: Option<&[[u8; 3]]>,
    view: &View,
    width: u32,
    height: u32,
) -> Image {
    render_mesh_with(mesh, colors, view, width, height, &RenderOptions::default())
}

/// Orthographic z-buffer rendering (Catmull 1974) with Lambert shading under a headlight.
///
/// Each triangle is scan-converted over its pixel bounding box with edge functions (Pineda
/// 1988), sampling pixel centres and applying the top-left fill rule so that pixels on an edge
/// shared by two triangles are drawn exactly once. Depth, colour and normal are interpolated
/// barycentrically, which is exact under an orthographic projection. The light comes from the
/// eye (direction `-view.forward()`); the brightness is `ambient + (1 − ambient) · max(0, n·l)`
/// times the per-vertex colour (or `base_colour`). Lighting is one-sided: a face seen from its
/// back gets only the ambient term, so a mesh with inward faces shows up dark.
///
/// # Panics
/// If `colors` is given with a length other than the number of vertices.
pub fn render_mesh_with(
    mesh: &TriMesh,
    colors: Option<&[[u8; 3]]>,
    view: &View,
    width: u32,
    height: u32,
    opts: &RenderOptions,
) -> Image {
    if let Some(c) = colors {
        assert_eq!(
            c.len(),
            mesh.n_vertices(),
            "render_mesh: one colour per vertex is needed"
        );
    }
    let mut img = Image::new(width, height, opts.background);
    let light = -view.forward();
    let ambient = opts.ambient.clamp(0.0, 1.0);
    let lambert = |n: &Vec3| ambient + (1.0 - ambient) * n.dot(&light).max(0.0);
    let colour = |v: usize| -> Vec3 {
        let c = colors.map_or(opts.base_colour, |c| c[v]);
        Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
    };

    let screen: Vec<(f64, f64, f64)> = mesh
        .vertices
        .iter()
        .map(|p| view.project(p, width, height))
        .collect();
    let vertex_normals = match opts.shading {
        Shading::Flat => Vec::new(),
        _ => mesh.vertex_normals(),
    };
    let face_normals = mesh.face_normals();

    for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
        let idx = [a, b, c];
        let col = idx.map(colour);
        let fnormal = face_normals[f];
        // Per-vertex quantity interpolated across the face: the lit colour (Gouraud), the
        // normal (Phong), or nothing (Flat).
        let (attr, normals): ([Vec3; 3], [Vec3; 3]) = match opts.shading {
            Shading::Flat => (col, [fnormal; 3]),
            Shading::Gouraud => (
                [0, 1, 2].map(|k| col[k] * lambert(&vertex_normals[idx[k]])),
                [fnormal; 3],
            ),
            Shading::Phong => (col, idx.map(|v| vertex_normals[v])),
        };
        let facing_away = fnormal.dot(&light) < 0.0;
        rasterise_triangle(&mut img, [screen[a], screen[b], screen[c]], |bary| {
            let c = attr[0] * bary[0] + attr[1] * bary[1] + attr[2] * bary[2];
            let shade = match opts.shading {
                Shading::Gouraud => 1.0,
                Shading::Flat => lambert(&fnormal),
                Shading::Phong => {
                    if facing_away {
                        ambient
                    } else {
                        let n = normals[0] * bary[0] + normals[1] * bary[1] + normals[2] * bary[2];
                        lambert(&n.try_normalize(0.0).unwrap_or(fnormal))
                    }
                }
            };
            to_rgb(c * shade)
        });
    }

    if let Some(wire) = opts.wireframe {
        let bias = depth_tolerance(view) * 0.25;
        for [a, b] in mesh.topology().edges {
            draw_line_px(&mut img, screen[a], screen[b], 1.0, wire, Some(bias));
        }
    }
    img
}

fn to_rgb(c: Vec3) -> [u8; 3] {
    [c.x, c.y, c.z].map(|x| x.round().clamp(0.0, 255.0) as u8)
}

/// Edge function of `p` against the directed edge `a → b` (twice the signed area of
/// `a, b, p`; positive when `p` is on the right in y-down pixel coordinates).
#[inline]
fn edge(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> f64 {
    (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
}

/// Top-left fill rule for a triangle with positive [`edge`] orientation: a sample exactly on
/// an edge belongs to the triangle only if the edge is a top edge (horizontal, running in +x)
/// or a left edge (running in −y).
#[inline]
fn owns_edge(a: (f64, f64), b: (f64, f64)) -> bool {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    (dy == 0.0 && dx > 0.0) || dy < 0.0
}

/// Scan-convert one triangle given in pixel coordinates with depth, z-testing every covered
/// pixel centre and writing `shade(barycentric)` where it is nearest.
fn rasterise_triangle<F>(img: &mut Image, tri: [(f64, f64, f64); 3], mut shade: F)
where
    F: FnMut([f64; 3]) -> [u8; 3],
{
    let mut v = tri;
    let mut p = v.map(|t| (t.0, t.1));
    let mut area = edge(p[0], p[1], p[2]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    // Bring the triangle to positive orientation so the fill rule has one form; remember the
    // swap to hand the barycentric weights back in the caller's vertex order.
    let swapped = area < 0.0;
    if swapped {
        v.swap(1, 2);
        p.swap(1, 2);
        area = -area;
    }
    let (w, h) = (img.width as f64, img.height as f64);
    let xmin = p.iter().map(|q| q.0).fold(f64::INFINITY, f64::min);
    let xmax = p.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max);
    let ymin = p.iter().map(|q| q.1).fold(f64::INFINITY, f64::min);
    let ymax = p.iter().map(|q| q.1).fold(f64::NEG_INFINITY, f64::max);
    if xmax < 0.0 || ymax < 0.0 || xmin > w || ymin > h {
        return;
    }
    // Pixels whose centre (i + 0.5) can fall inside [min, max].
    let x0 = (xmin - 0.5).ceil().max(0.0) as i64;
    let x1 = ((xmax - 0.5).floor().min(w - 1.0)) as i64;
    let y0 = (ymin - 0.5).ceil().max(0.0) as i64;
    let y1 = ((ymax - 0.5).floor().min(h - 1.0)) as i64;
    let owns = [
        owns_edge(p[1], p[2]),
        owns_edge(p[2], p[0]),
        owns_edge(p[0], p[1]),
    ];
    let width = img.width as usize;
    for y in y0..=y1 {
        let py = y as f64 + 0.5;
        for x in x0..=x1 {
            let q = (x as f64 + 0.5, py);
            let e = [
                edge(p[1], p[2], q),
                edge(p[2], p[0], q),
                edge(p[0], p[1], q),
            ];
            if (0..3).any(|k| e[k] < 0.0 || (e[k] == 0.0 && !owns[k])) {
                continue;
            }
            let b = e.map(|x| x / area);
            let z = b[0] * v[0].2 + b[1] * v[1].2 + b[2] * v[2].2;
            let i = y as usize * width + x as usize;
            if z < img.depth[i] {
                img.depth[i] = z;
                let bary = if swapped { [b[0], b[2], b[1]] } else { b };
                let c = shade(bary);
                img.rgb[3 * i..3 * i + 3].copy_from_slice(&c);
            }
        }
    }
}

/// Depth slack (mm) under which an overlay counts as lying on the surface: 2 % of the larger
/// half extent of the view, i.e. about 2 mm for a hand filling the picture.
fn depth_tolerance(view: &View) -> f64 {
    let (hw, hh) = view.half_extents();
    0.02 * hw.max(hh)
}

/// Anti-aliased line of `width_px` between two projected points, depth-tested per pixel
/// against the image's z-buffer with slack `bias` (mm) when `bias` is `Some`.
fn draw_line_px(
    img: &mut Image,
    a: (f64, f64, f64),
    b: (f64, f64, f64),
    width_px: f64,
    colour: [u8; 3],
    bias: Option<f64>,
) {
    let r = 0.5 * width_px.max(0.0);
    let reach = r + 1.0;
    if ![a.0, a.1, b.0, b.1].iter().all(|c| c.is_finite()) {
        return;
    }
    let x0 = (a.0.min(b.0) - reach).floor().max(0.0);
    let x1 = (a.0.max(b.0) + reach).ceil().min(img.width as f64 - 1.0);
    let y0 = (a.1.min(b.1) - reach).floor().max(0.0);
    let y1 = (a.1.max(b.1) + reach).ceil().min(img.height as f64 - 1.0);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    for y in y0 as i64..=y1 as i64 {
        for x in x0 as i64..=x1 as i64 {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let t = if len2 > 0.0 {
                (((px - a.0) * dx + (py - a.1) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (cx, cy) = (a.0 + t * dx, a.1 + t * dy);
            let dist = ((px - cx).powi(2) + (py - cy).powi(2)).sqrt();
            // Coverage of a 1-px-wide pixel by the band |dist| <= r (box-filter approximation).
            let cover = (r + 0.5 - dist).clamp(0.0, 1.0);
            if cover <= 0.0 {
                continue;
            }
            if let Some(bias) = bias {
                let z = a.2 + t * (b.2 - a.2);
                let i = y as usize * img.width as usize + x as usize;
                if z > img.depth[i] + bias {
                    continue;
                }
            }
            img.blend_pixel(x, y, colour, cover);
        }
    }
}

/// Draw `points` as filled discs of `radius_px` with a thin dark outline, so they read on
/// both light skin and dark colour maps.
///
/// With `on_top = false` a point is drawn only if it is not hidden by the rendered surface:
/// its depth may exceed the z-buffer at its centre pixel by at most 2 % of the view's larger
/// half extent (a landmark lying on the skin stays visible, one on the far side does not).
/// Points outside the image are skipped.
pub fn draw_points(
    img: &mut Image,
    view: &View,
    points: &[Point],
    radius_px: f64,
    colour: [u8; 3],
    on_top: bool,
) {
    let tol = depth_tolerance(view);
    let outline = colour.map(|c| (c as f64 * 0.35) as u8);
    for p in points {
        let (x, y, z) = view.project(p, img.width, img.height);
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        if !on_top {
            let (ix, iy) = (x.floor(), y.floor());
            if ix < 0.0 || iy < 0.0 || ix >= img.width as f64 || iy >= img.height as f64 {
                continue;
            }
            let i = iy as usize * img.width as usize + ix as usize;
            if z > img.depth[i] + tol {
                continue;
            }
        }
        let r = radius_px.max(0.5);
        draw_line_px(img, (x, y, z), (x, y, z), 2.0 * r + 2.0, outline, None);
        draw_line_px(img, (x, y, z), (x, y, z), 2.0 * r, colour, None);
    }
}

/// Draw 3D segments (e.g. skeleton bones) as anti-aliased lines of `width_px`.
///
/// With `on_top = false` each pixel of a segment is depth-tested against the rendered surface
/// with the same slack as [`draw_points`]; bones inside the skin want `on_top = true`.
pub fn draw_segments(
    img: &mut Image,
    view: &View,
    segments: &[[Point; 2]],
    width_px: f64,
    colour: [u8; 3],
    on_top: bool,
) {
    let bias = (!on_top).then(|| depth_tolerance(view));
    for [a, b] in segments {
        let pa = view.project(a, img.width, img.height);
        let pb = view.project(b, img.width, img.height);
        draw_line_px(img, pa, pb, width_px, colour, bias);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;

    fn covered(img: &Image) -> usize {
        img.depth.iter().filter(|d| d.is_finite()).count()
    }

    #[test]
    fn unit_cube_along_z_covers_its_square_exactly() {
        let cube = cuboid(1.0, 1.0, 1.0);
        // 2 mm visible over 100 px: 50 px/mm, the unit square spans pixels 25..75 exactly.
        let view =
            View::along(-Vec3::z(), Vec3::y()).with_frame(Point::new(0.5, 0.5, 0.5), 1.0, 1.0);
        let img = render_mesh(&cube, None, &view, 100, 100);
        assert_eq!(covered(&img), 50 * 50);
        assert!(img.pixel(24, 50) == Some([255, 255, 255]));
        assert!(img.pixel(25, 50) != Some([255, 255, 255]));
        // Seen head-on under the headlight, the front face is fully lit: the base colour.
        assert_eq!(
            img.pixel(50, 50),
            Some(RenderOptions::default().base_colour)
        );
        // The front face (z = 1) is the nearest: depth of z = 1 relative to the centre.
        assert!((img.depth[50 * 100 + 50] - (-0.5)).abs() < 1e-12);
    }

    #[test]
    fn oblique_cube_covers_analytic_projected_area() {
        // The orthographic shadow of a unit cube along unit d has area |dx| + |dy| + |dz|.
        let cube = cuboid(1.0, 1.0, 1.0);
        for d in [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.3, -0.8, 0.5),
            Vec3::new(-2.0, 0.5, 0.1),
        ] {
            let d = d.normalize();
            let view = View::along(d, Vec3::z()).with_frame(Point::new(0.5, 0.5, 0.5), 1.0, 1.0);
            let (w, s) = (400u32, 200.0);
            let img = render_mesh(&cube, None, &view, w, w);
            let area_px = (d.x.abs() + d.y.abs() + d.z.abs()) * s * s;
            // Sampling error is bounded by about one pixel along the perimeter (< 6·s here).
            let err = (covered(&img) as f64 - area_px).abs();
            assert!(err < 6.0 * s, "{d:?}: {} vs {area_px}", covered(&img));
        }
    }

    #[test]
    fn nearer_triangle_wins_in_any_draw_order() {
        let tri = |z: f64| {
            vec![
                Point::new(-1.0, -1.0, z),
                Point::new(1.0, -1.0, z),
                Point::new(0.0, 1.0, z),
            ]
        };
        let red = [255, 0, 0];
        let blue = [0, 0, 255];
        for near_first in [true, false] {
            let (za, zb) = if near_first { (1.0, -1.0) } else { (-1.0, 1.0) };
            let mut v = tri(za);
            v.extend(tri(zb));
            let mesh = TriMesh::new(v, vec![[0, 1, 2], [3, 4, 5]]).unwrap();
            let colours = [red, red, red, blue, blue, blue];
            let view = View::along(-Vec3::z(), Vec3::y()).fit_mesh(&mesh, 0.1);
            let opts = RenderOptions {
                ambient: 1.0,
                ..Default::default()
            };
            let img = render_mesh_with(&mesh, Some(&colours), &view, 64, 64, &opts);
            // Looking along −z the eye is at +z: the z = +1 triangle is nearer.
            let expect = if near_first { red } else { blue };
            assert_eq!(img.pixel(32, 32), Some(expect));
        }
    }

    #[test]
    fn shared_edges_are_drawn_once_and_inward_faces_are_dark() {
        // A square split on its diagonal, coloured additively would show double draws: check
        // instead that every pixel of the square is covered and none outside.
        let v = vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(1.0, 1.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]]).unwrap();
        let view =
            View::along(-Vec3::z(), Vec3::y()).with_frame(Point::new(0.5, 0.5, 0.0), 1.0, 1.0);
        let img = render_mesh(&m, None, &view, 64, 64);
        assert_eq!(covered(&img), 32 * 32);
        // Seen from behind (faces point to +z, eye at −z): ambient only.
        let back =
            View::along(Vec3::z(), Vec3::y()).with_frame(Point::new(0.5, 0.5, 0.0), 1.0, 1.0);
        for shading in [Shading::Flat, Shading::Gouraud, Shading::Phong] {
            let opts = RenderOptions {
                shading,
                ..Default::default()
            };
            let img = render_mesh_with(&m, None, &back, 64, 64, &opts);
            let base = opts.base_colour;
            let expect = base.map(|c| (c as f64 * opts.ambient).round() as u8);
            assert_eq!(img.pixel(32, 32), Some(expect), "{shading:?}");
        }
    }

    #[test]
    fn overlays_respect_depth() {
        let cube = cuboid(1.0, 1.0, 1.0);
        let view =
            View::along(-Vec3::z(), Vec3::y()).with_frame(Point::new(0.5, 0.5, 0.5), 1.0, 1.0);
        let mut img = render_mesh(&cube, None, &view, 100, 100);
        let green = [0, 200, 0];
        // A point on the front face shows; one on the back face (hidden) does not.
        draw_points(
            &mut img,
            &view,
            &[Point::new(0.3, 0.3, 1.0)],
            3.0,
            green,
            false,
        );
        draw_points(
            &mut img,
            &view,
            &[Point::new(0.7, 0.7, 0.0)],
            3.0,
            green,
            false,
        );
        let (x, y, _) = view.project(&Point::new(0.3, 0.3, 1.0), 100, 100);
        assert_eq!(img.pixel(x as u32, y as u32), Some(green));
        let (x, y, _) = view.project(&Point::new(0.7, 0.7, 0.0), 100, 100);
        assert_ne!(img.pixel(x as u32, y as u32), Some(green));
        draw_points(
            &mut img,
            &view,
            &[Point::new(0.7, 0.7, 0.0)],
            3.0,
            green,
            true,
        );
        assert_eq!(img.pixel(x as u32, y as u32), Some(green));
        // A segment through the cube's inside is hidden unless drawn on top.
        let seg = [[Point::new(0.2, 0.5, 0.5), Point::new(0.8, 0.5, 0.5)]];
        let mut a = render_mesh(&cube, None, &view, 100, 100);
        let before = a.clone();
        draw_segments(&mut a, &view, &seg, 3.0, green, false);
        assert_eq!(a, before);
        draw_segments(&mut a, &view, &seg, 3.0, green, true);
        assert_eq!(a.pixel(50, 50), Some(green));
    }

    #[test]
    fn wireframe_draws_visible_edges_only() {
        let cube = cuboid(1.0, 1.0, 1.0);
        // Eye towards (+0.2, +0.3, +1): vertex 0 = (0,0,0) and its edges are hidden.
        let view = View::along(Vec3::new(-0.2, -0.3, -1.0), Vec3::y()).fit_mesh(&cube, 0.1);
        let opts = RenderOptions {
            wireframe: Some([0, 0, 0]),
            ..Default::default()
        };
        let img = render_mesh_with(&cube, None, &view, 200, 200, &opts);
        let plain = render_mesh(&cube, None, &view, 200, 200);
        let at = |p: Point| {
            let (x, y, _) = view.project(&p, 200, 200);
            (x as u32, y as u32)
        };
        // Visible edge (0,0,1)-(1,0,1): drawn dark.
        let (x, y) = at(Point::new(0.5, 0.0, 1.0));
        let darkest = (x - 1..=x + 1)
            .flat_map(|i| (y - 1..=y + 1).map(move |j| (i, j)))
            .map(|(i, j)| {
                img.pixel(i, j)
                    .unwrap()
                    .iter()
                    .map(|&c| c as u32)
                    .sum::<u32>()
            })
            .min()
            .unwrap();
        assert!(darkest < 200, "{darkest}");
        // Hidden edge (0,0,0)-(1,0,0): its midpoint shows the surface as without wireframe.
        let (x, y) = at(Point::new(0.5, 0.0, 0.0));
        assert_eq!(img.pixel(x, y), plain.pixel(x, y));
        assert_ne!(plain.pixel(x, y), Some([255, 255, 255]));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(128))]
        /// Arbitrary triangles (including huge, tiny and off-screen ones) and view directions
        /// never panic, and the z-buffer only ever holds depths of drawn pixels.
        #[test]
        fn arbitrary_scenes_render_without_panic(
            coords in proptest::collection::vec(-1e7f64..1e7, 9..=27),
            dir in proptest::array::uniform3(-1.0f64..1.0),
            small in proptest::bool::ANY,
        ) {
            let scale = if small { 1e-9 } else { 1.0 };
            let vertices: Vec<Point> = coords
                .chunks_exact(3)
                .map(|c| Point::new(c[0], c[1], c[2]) * scale)
                .collect();
            let faces: Vec<[usize; 3]> = (0..vertices.len() / 3).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
            let mesh = TriMesh { vertices, faces };
            let view = View::along(Vec3::from(dir), Vec3::y()).fit_points(&mesh.vertices[..3], 0.0);
            let opts = RenderOptions { wireframe: Some([0, 0, 0]), ..Default::default() };
            let mut img = render_mesh_with(&mesh, None, &view, 37, 23, &opts);
            draw_points(&mut img, &view, &mesh.vertices, 2.0, [255, 0, 0], false);
            draw_segments(&mut img, &view, &[[mesh.vertices[0], mesh.vertices[1]]], 3.0, [0, 0, 255], false);
            proptest::prop_assert_eq!(img.rgb.len(), 37 * 23 * 3);
        }
    }
}
