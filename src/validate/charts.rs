//! Shared plumbing of the report's charts: one drawing function rendered twice, into a PNG
//! (plotters' bitmap backend with the vendored DejaVu Sans) and an SVG, and the histogram
//! used by several charts.

use crate::error::{Error, Result};
use crate::io::atomic::write_bytes_atomic;
use crate::render::Image;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// A chart written as PNG and SVG.
#[derive(Clone, Debug)]
pub struct Figure {
    /// The PNG file.
    pub png: PathBuf,
    /// The SVG file.
    pub svg: PathBuf,
    /// The PNG bytes (for embedding).
    pub png_bytes: Vec<u8>,
    /// A one-line title.
    pub title: String,
}

/// The trajectory's red and the fit's blue of the paper's Figure 8.
pub const TRAJ: RGBColor = RGBColor(214, 39, 40);
/// The fitted curve's blue.
pub const FIT: RGBColor = RGBColor(31, 90, 180);
/// Grid lines.
pub const GRID: RGBColor = RGBColor(225, 225, 225);
/// Text.
pub const INK: RGBColor = RGBColor(40, 40, 40);

pub fn plot_err(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> Error + '_ {
    move |e| Error::invalid(format!("could not draw {what}: {e:?}"))
}

/// Draw the same chart into a PNG and an SVG named `stem` in `dir`.
pub fn save_both(
    dir: &Path,
    stem: &str,
    title: String,
    size: (u32, u32),
    png: impl for<'a> FnOnce(&DrawingArea<BitMapBackend<'a>, Shift>) -> Result<()>,
    svg: impl for<'a> FnOnce(&DrawingArea<SVGBackend<'a>, Shift>) -> Result<()>,
) -> Result<Figure> {
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        png(&area)?;
        area.present().map_err(|e| plot_err(stem)(&e))?;
    }
    let mut img = Image::new(size.0, size.1, [255, 255, 255]);
    img.rgb = buf;
    let png_path = dir.join(format!("{stem}.png"));
    let png_bytes = img.to_png()?;
    write_bytes_atomic(&png_path, &png_bytes)?;
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, size).into_drawing_area();
        svg(&area)?;
        area.present().map_err(|e| plot_err(stem)(&e))?;
    }
    let svg_path = dir.join(format!("{stem}.svg"));
    write_bytes_atomic(&svg_path, text.as_bytes())?;
    Ok(Figure {
        png: png_path,
        svg: svg_path,
        png_bytes,
        title,
    })
}

/// Histogram of one or more sets of `values` (mm), each `(values, colour, legend)`, in 40 bins
/// over a range holding 99.5 % of them (`symmetric`: ±range, else 0..range), as shares of
/// each set in percent.
pub fn histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    caption: &str,
    sets: &[(&[f64], RGBColor, &str)],
    x_desc: &str,
    symmetric: bool,
) -> Result<()> {
    let err = plot_err(caption);
    let mut abs: Vec<f64> = sets
        .iter()
        .flat_map(|s| s.0.iter().map(|v| v.abs()))
        .collect();
    abs.sort_by(f64::total_cmp);
    let p995 = abs
        .get((0.995 * abs.len().saturating_sub(1) as f64) as usize)
        .copied()
        .unwrap_or(0.0);
    let range = (p995 * 1.1).max(0.02);
    let lo = if symmetric { -range } else { 0.0 };
    let bins = 40usize;
    let w = (range - lo) / bins as f64;
    let shares: Vec<Vec<f64>> = sets
        .iter()
        .map(|(values, _, _)| {
            let mut counts = vec![0usize; bins];
            for v in values.iter() {
                let k = ((v - lo) / w).floor();
                if k >= 0.0 && (k as usize) < bins {
                    counts[k as usize] += 1;
                }
            }
            let total = values.len().max(1) as f64;
            counts.iter().map(|&c| 100.0 * c as f64 / total).collect()
        })
        .collect();
    let top = shares
        .iter()
        .flatten()
        .copied()
        .fold(0.0, f64::max)
        .max(1.0)
        * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (font, 14).into_font().color(&INK))
        .margin(6)
        .x_label_area_size(34)
        .y_label_area_size(44)
        .build_cartesian_2d(lo..range, 0.0..top)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .x_desc(x_desc)
        .y_desc("share (%)")
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .x_labels(6)
        .y_labels(4)
        .draw()
        .map_err(|e| err(&e))?;
    let n = sets.len().max(1) as f64;
    for (k, ((_, colour, legend), share)) in sets.iter().zip(&shares).enumerate() {
        let c = *colour;
        let series = chart
            .draw_series(share.iter().enumerate().map(|(b, &s)| {
                // Side by side within the bin when there are several sets.
                let x0 = lo + b as f64 * w + k as f64 * w / n;
                Rectangle::new([(x0, 0.0), (x0 + w / n, s)], c.mix(0.8).filled())
            }))
            .map_err(|e| err(&e))?;
        if !legend.is_empty() {
            series
                .label(*legend)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], c.filled()));
        }
    }
    if sets.iter().any(|s| !s.2.is_empty()) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(GRID)
            .label_font((font, 12).into_font().color(&INK))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    Ok(())
}
