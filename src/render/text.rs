//! Text labels drawn with plotters' `ab_glyph` text rasteriser straight into an [`Image`]
//! buffer, using the vendored DejaVu Sans (Bitstream Vera licence, `assets/fonts/`).

use super::Image;
use crate::error::{Error, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::OnceLock;

/// DejaVu Sans 2.37, embedded so that pictures look the same on every machine.
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Family name the font is registered under in plotters' font table.
const FAMILY: &str = "ergohand-sans";

/// DejaVu Sans ascent as a share of ascent + descent (hhea 1901 / (1901 + 483)). ab_glyph
/// scales a font so that ascent + descent equals the requested pixel size, and plotters puts
/// the baseline half a size below the given point; shifting by `size · (ASCENT − 1/2)` puts the
/// top of the line box at the requested point.
const ASCENT: f64 = 1901.0 / 2384.0;

/// Default label size, px (height of the line box: ascent + descent).
pub const LABEL_SIZE: f64 = 16.0;

/// Register the vendored font once per process; the result is cached.
fn font_ready() -> Result<()> {
    static READY: OnceLock<bool> = OnceLock::new();
    let ok = *READY.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::invalid(
            "the vendored font assets/fonts/DejaVuSans.ttf could not be loaded",
        ))
    }
}

/// The font family name for plotters charts, with the vendored DejaVu Sans registered under
/// it. It is `sans-serif`, so that an SVG chart (whose text names its family) falls back to
/// the viewer's own sans-serif font, while PNG charts use the vendored one.
pub fn plot_font_family() -> Result<&'static str> {
    static READY: OnceLock<bool> = OnceLock::new();
    let ok = *READY.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, DEJAVU_SANS).is_ok()
            && plotters::style::register_font("sans-serif", FontStyle::Bold, DEJAVU_SANS).is_ok()
    });
    if ok {
        Ok("sans-serif")
    } else {
        Err(Error::invalid(
            "the vendored font assets/fonts/DejaVuSans.ttf could not be loaded",
        ))
    }
}

/// Draw `text` with the top-left corner of its line box at pixel `(x, y)` in `colour`, at the default size
/// ([`LABEL_SIZE`] px). Parts outside the image are clipped.
pub fn draw_label(img: &mut Image, x: i32, y: i32, text: &str, colour: [u8; 3]) -> Result<()> {
    draw_label_sized(img, x, y, text, colour, LABEL_SIZE)
}

/// [`draw_label`] at `size_px` (the font's em size in pixels).
///
/// The image buffer is wrapped in a plotters `BitMapBackend` (RGB8, the same layout), so the
/// glyphs are anti-aliased by blending onto whatever is already drawn.
pub fn draw_label_sized(
    img: &mut Image,
    x: i32,
    y: i32,
    text: &str,
    colour: [u8; 3],
    size_px: f64,
) -> Result<()> {
    font_ready()?;
    if img.width == 0 || img.height == 0 || text.is_empty() {
        return Ok(());
    }
    let (w, h) = (img.width, img.height);
    let mut backend = BitMapBackend::with_buffer(&mut img.rgb, (w, h));
    let rgb = RGBColor(colour[0], colour[1], colour[2]);
    let style = TextStyle::from((FAMILY, size_px).into_font()).color(&rgb);
    backend
        .draw_text(
            text,
            &style,
            (x, y + (size_px * (ASCENT - 0.5)).round() as i32),
        )
        .map_err(|e| Error::invalid(format!("could not draw label {text:?}: {e}")))?;
    backend
        .present()
        .map_err(|e| Error::invalid(format!("could not draw label {text:?}: {e}")))
}

/// Width (advance) and height (line box, i.e. `size_px` rounded up) in pixels of `text` at
/// `size_px`, for laying out labels.
pub fn label_size(text: &str, size_px: f64) -> Result<(u32, u32)> {
    font_ready()?;
    let (w, _) = (FAMILY, size_px)
        .into_font()
        .box_size(text)
        .map_err(|e| Error::invalid(format!("could not measure label {text:?}: {e:?}")))?;
    Ok((w, size_px.max(0.0).ceil() as u32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_marks_pixels_inside_its_box_only() {
        let mut img = Image::new(120, 40, [255, 255, 255]);
        draw_label(&mut img, 10, 8, "I_MCP 12 mm", [0, 0, 0]).unwrap();
        let (tw, th) = label_size("I_MCP 12 mm", LABEL_SIZE).unwrap();
        assert!(tw > 40 && th > 8, "{tw} x {th}");
        let mut inked = 0;
        for y in 0..img.height {
            for x in 0..img.width {
                if img.pixel(x, y) != Some([255, 255, 255]) {
                    inked += 1;
                    // Allow the anti-aliasing fringe of one or two pixels.
                    assert!(x + 2 >= 10 && x <= 10 + tw + 2, "ink at x = {x}");
                    assert!(y + 1 >= 8 && y <= 8 + th + 1, "ink at y = {y}");
                }
            }
        }
        assert!(inked > 50);
        // Clipped text does not panic.
        draw_label(&mut img, 110, 35, "clipped", [255, 0, 0]).unwrap();
        draw_label(&mut img, -50, -50, "gone", [255, 0, 0]).unwrap();
    }
}
