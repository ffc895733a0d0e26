//! A small software renderer for the report pictures: orthographic views of triangle meshes with
//! a z-buffer and Lambert shading, overlays (points, 3D segments, labels), colour maps with a
//! colour bar, and grids of views. No GPU, no window; the output is an RGB8 [`Image`] saved as
//! PNG.
//!
//! Conventions: world coordinates in mm; pixel `(0, 0)` is the top-left corner and pixel
//! centres sit at half-integer coordinates; depth grows away from the viewer.

pub mod colormap;
mod raster;
mod text;

pub use colormap::{colour_bar, colour_bar_ticks, map_values, viridis};
pub use raster::{
    draw_points, draw_segments, render_mesh, render_mesh_with, RenderOptions, Shading,
};
pub use text::{draw_label, draw_label_sized, label_size, plot_font_family, LABEL_SIZE};

use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use std::path::Path;

/// Orthographic camera: looks along `forward`, with `up` pointing to the top of the image,
/// showing the `2·half_width × 2·half_height` mm rectangle centred on `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    center: Point,
    half_width: f64,
    half_height: f64,
}

impl View {
    /// A camera looking along `dir` with `up` towards the top of the image (`up` is
    /// orthogonalised against `dir`). It shows the ±1 mm square around the origin until fitted
    /// with [`View::fit_points`], [`View::fit_box`] or [`View::fit_mesh`].
    ///
    /// Degenerate input is repaired rather than refused, since views are presets chosen in code:
    /// a zero `dir` looks along −z; an `up` parallel to `dir` is replaced by the world axis most
    /// orthogonal to `dir`.
    pub fn along(dir: Vec3, up: Vec3) -> View {
        let forward = dir.try_normalize(1e-12).unwrap_or(-Vec3::z());
        let mut up_o = up - forward * up.dot(&forward);
        if up_o.norm() < 1e-9 * up.norm().max(1e-300) || up_o.norm() < 1e-12 {
            let axis = [Vec3::x(), Vec3::y(), Vec3::z()]
                .into_iter()
                .min_by(|a, b| a.dot(&forward).abs().total_cmp(&b.dot(&forward).abs()))
                .unwrap_or(Vec3::y());
            up_o = axis - forward * axis.dot(&forward);
        }
        let up_n = up_o.normalize();
        // Right-handed screen frame: right = forward × up, so looking along −z with +y up puts
        // +x to the right.
        let right = forward.cross(&up_n);
        View {
            forward,
            right,
            up: up_n,
            center: Point::origin(),
            half_width: 1.0,
            half_height: 1.0,
        }
    }

    /// Unit viewing direction (from the eye into the scene).
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// Unit vector pointing to the right of the image.
    pub fn right(&self) -> Vec3 {
        self.right
    }

    /// Unit vector pointing to the top of the image.
    pub fn up(&self) -> Vec3 {
        self.up
    }

    /// Centre of the visible rectangle (world, mm).
    pub fn center(&self) -> Point {
        self.center
    }

    /// Half extents of the visible rectangle, mm (right, up).
    pub fn half_extents(&self) -> (f64, f64) {
        (self.half_width, self.half_height)
    }

    /// The same direction, showing exactly the given rectangle (half extents in mm, clamped
    /// to be positive).
    pub fn with_frame(mut self, center: Point, half_width: f64, half_height: f64) -> View {
        self.center = center;
        self.half_width = positive_or(half_width, 1.0);
        self.half_height = positive_or(half_height, 1.0);
        self
    }

    /// Fit the view to the projections of `points`, leaving `margin` (a fraction of the larger
    /// half extent, e.g. 0.05) free on every side. No points: unchanged.
    pub fn fit_points(self, points: &[Point], margin: f64) -> View {
        if points.is_empty() {
            return self;
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            let q = [
                p.coords.dot(&self.right),
                p.coords.dot(&self.up),
                p.coords.dot(&self.forward),
            ];
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        let mid = |k: usize| 0.5 * (lo[k] + hi[k]);
        let center = Point::from(self.right * mid(0) + self.up * mid(1) + self.forward * mid(2));
        let (hw, hh) = (0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]));
        let pad = margin.max(0.0) * hw.max(hh);
        let fallback = if hw.max(hh) > 0.0 { hw.max(hh) } else { 1.0 };
        self.with_frame(
            center,
            positive_or(hw + pad, fallback),
            positive_or(hh + pad, fallback),
        )
    }

    /// Fit the view to the eight corners of the box `[lo, hi]` (see [`View::fit_points`]).
    pub fn fit_box(self, lo: Point, hi: Point, margin: f64) -> View {
        let corners: Vec<Point> = (0..8)
            .map(|i| {
                Point::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        self.fit_points(&corners, margin)
    }

    /// Fit the view to the mesh's vertices (tighter than its bounding box).
    pub fn fit_mesh(self, mesh: &TriMesh, margin: f64) -> View {
        self.fit_points(&mesh.vertices, margin)
    }

    /// Pixels per mm when this view is drawn into a `width × height` image: the visible
    /// rectangle is scaled uniformly to fit and centred.
    pub fn scale(&self, width: u32, height: u32) -> f64 {
        (width as f64 / (2.0 * self.half_width)).min(height as f64 / (2.0 * self.half_height))
    }

    /// Pixel coordinates `(x, y)` (continuous; pixel centres at `i + 0.5`) and depth (mm along
    /// `forward` from the view centre) of world point `p` in a `width × height` image.
    pub fn project(&self, p: &Point, width: u32, height: u32) -> (f64, f64, f64) {
        let s = self.scale(width, height);
        let d = p - self.center;
        (
            0.5 * width as f64 + s * d.dot(&self.right),
            0.5 * height as f64 - s * d.dot(&self.up),
            d.dot(&self.forward),
        )
    }
}

fn positive_or(x: f64, fallback: f64) -> f64 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        fallback
    }
}

/// An RGB8 image with the depth buffer of what was rendered into it.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major RGB bytes, `3 · width · height` of them, top row first.
    pub rgb: Vec<u8>,
    /// Row-major depth (mm along the view direction) of the nearest surface at each pixel;
    /// `f64::INFINITY` where nothing was rendered. Used to depth-test overlays.
    pub depth: Vec<f64>,
}

impl Image {
    /// A `width × height` image filled with `background` and an empty depth buffer.
    pub fn new(width: u32, height: u32, background: [u8; 3]) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            rgb: background.repeat(n),
            depth: vec![f64::INFINITY; n],
        }
    }

    /// Colour of pixel `(x, y)`, `None` outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 3 * (y as usize * self.width as usize + x as usize);
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    /// Set pixel `(x, y)`; ignored outside the image.
    pub fn set_pixel(&mut self, x: i64, y: i64, c: [u8; 3]) {
        self.blend_pixel(x, y, c, 1.0);
    }

    /// Blend `c` over pixel `(x, y)` with opacity `alpha` in [0, 1]; ignored outside.
    pub fn blend_pixel(&mut self, x: i64, y: i64, c: [u8; 3], alpha: f64) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let a = alpha.clamp(0.0, 1.0);
        let i = 3 * (y as usize * self.width as usize + x as usize);
        for (dst, &src) in self.rgb[i..i + 3].iter_mut().zip(&c) {
            let old = *dst as f64;
            *dst = (old + (src as f64 - old) * a).round() as u8;
        }
    }

    /// Encode as PNG (8-bit RGB).
    pub fn to_png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&self.rgb, self.width, self.height, image::ColorType::Rgb8)
            .map_err(|e| Error::invalid(format!("PNG encoding failed: {e}")))?;
        Ok(out)
    }

    /// Write as a PNG file, atomically (temporary file + rename).
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let bytes = self.to_png().map_err(|e| e.in_file(path))?;
        crate::io::atomic::write_bytes_atomic(path, &bytes)
    }

    /// Copy `src` into this image with its top-left corner at `(x, y)` (clipped). Depth is
    /// copied too, so overlays can still be depth-tested in the composed picture.
    pub fn blit(&mut self, src: &Image, x: i64, y: i64) {
        for sy in 0..src.height as i64 {
            let ty = y + sy;
            if ty < 0 || ty >= self.height as i64 {
                continue;
            }
            for sx in 0..src.width as i64 {
                let tx = x + sx;
                if tx < 0 || tx >= self.width as i64 {
                    continue;
                }
                let si = sy as usize * src.width as usize + sx as usize;
                let ti = ty as usize * self.width as usize + tx as usize;
                self.rgb[3 * ti..3 * ti + 3].copy_from_slice(&src.rgb[3 * si..3 * si + 3]);
                self.depth[ti] = src.depth[si];
            }
        }
    }
}

use image::ImageEncoder as _;

/// Tile `images` row by row, `cols` per row (at least 1), each centred in a cell as large as
/// the largest image, on a white background. No images: a 0 × 0 image.
pub fn compose_grid(images: &[Image], cols: usize) -> Image {
    let cols = cols.max(1).min(images.len().max(1));
    let rows = images.len().div_ceil(cols);
    let cw = images.iter().map(|i| i.width).max().unwrap_or(0);
    let ch = images.iter().map(|i| i.height).max().unwrap_or(0);
    let mut out = Image::new(cw * cols as u32, ch * rows as u32, [255, 255, 255]);
    for (k, img) in images.iter().enumerate() {
        let (r, c) = (k / cols, k % cols);
        let x = c as i64 * cw as i64 + (cw - img.width) as i64 / 2;
        let y = r as i64 * ch as i64 + (ch - img.height) as i64 / 2;
        out.blit(img, x, y);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_frame_is_right_handed_and_fits() {
        let v = View::along(-Vec3::z(), Vec3::y());
        assert!((v.right() - Vec3::x()).norm() < 1e-15);
        assert!((v.up() - Vec3::y()).norm() < 1e-15);
        // Degenerate up: still an orthonormal frame.
        let w = View::along(Vec3::new(0.0, 2.0, 0.0), Vec3::y());
        assert!(w.up().dot(&w.forward()).abs() < 1e-12);
        assert!((w.right().cross(&w.up()) + w.forward()).norm() < 1e-12);
        // Fitting: the box's projected extremes land `margin` inside the image borders.
        let f = v.fit_box(
            Point::new(10.0, 20.0, 0.0),
            Point::new(30.0, 30.0, 5.0),
            0.1,
        );
        let (x0, y0, _) = f.project(&Point::new(10.0, 30.0, 0.0), 240, 120);
        let (x1, y1, _) = f.project(&Point::new(30.0, 20.0, 0.0), 240, 120);
        // half extents 10 x 5 mm + 1 mm padding: scale = min(240/22, 120/12) = 10 px/mm.
        assert!((f.scale(240, 120) - 10.0).abs() < 1e-12);
        assert!((x0 - 20.0).abs() < 1e-9 && (x1 - 220.0).abs() < 1e-9);
        assert!((y0 - 10.0).abs() < 1e-9 && (y1 - 110.0).abs() < 1e-9);
    }

    #[test]
    fn png_round_trip_keeps_size_and_pixels() {
        let mut img = Image::new(7, 5, [10, 20, 30]);
        img.set_pixel(3, 2, [255, 0, 128]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.png");
        img.save_png(&path).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!((back.width(), back.height()), (7, 5));
        assert_eq!(back.as_raw(), &img.rgb);
        // Only the final file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn grid_places_cells() {
        let a = Image::new(4, 2, [255, 0, 0]);
        let b = Image::new(2, 2, [0, 0, 255]);
        let g = compose_grid(&[a.clone(), b.clone(), a], 2);
        assert_eq!((g.width, g.height), (8, 4));
        assert_eq!(g.pixel(0, 0), Some([255, 0, 0]));
        assert_eq!(g.pixel(4, 0), Some([255, 255, 255]));
        assert_eq!(g.pixel(5, 0), Some([0, 0, 255]));
        assert_eq!(g.pixel(0, 3), Some([255, 0, 0]));
        assert_eq!(g.pixel(7, 3), Some([255, 255, 255]));
        assert_eq!(compose_grid(&[], 3).width, 0);
    }
}
