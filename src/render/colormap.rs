//! The viridis colour map and a colour bar with its end values in mm.
//!
//! Viridis (S. van der Walt & N. Smith, 2015, CC0; the matplotlib default) is perceptually
//! uniform and readable with colour-vision deficiencies and in greyscale, which suits deviation
//! maps (e.g. distance between reconstructed and scanned skin).

use super::{draw_label_sized, label_size, Image};
use crate::error::Result;

/// Viridis sampled at every 8th entry of its 256-entry 8-bit table (entries 0, 8, …, 248)
/// plus the last (255); linear interpolation between these nodes reproduces the intermediate
/// entries within 2/255.
const VIRIDIS: [[u8; 3]; 33] = [
    [68, 1, 84],
    [70, 12, 95],
    [71, 24, 106],
    [72, 34, 115],
    [71, 44, 123],
    [69, 54, 129],
    [66, 64, 133],
    [62, 73, 137],
    [58, 82, 139],
    [54, 90, 140],
    [50, 98, 141],
    [47, 106, 141],
    [44, 114, 142],
    [40, 122, 142],
    [38, 129, 142],
    [35, 137, 141],
    [32, 144, 140],
    [30, 152, 138],
    [30, 159, 136],
    [33, 167, 132],
    [40, 174, 127],
    [50, 181, 122],
    [62, 188, 115],
    [77, 194, 107],
    [94, 201, 97],
    [112, 206, 86],
    [131, 211, 75],
    [151, 216, 62],
    [173, 220, 48],
    [194, 223, 34],
    [215, 226, 25],
    [236, 228, 26],
    [253, 231, 37],
];

/// Table entry (0..=255) of node `k` of [`VIRIDIS`].
fn node(k: usize) -> f64 {
    if k == 32 {
        255.0
    } else {
        8.0 * k as f64
    }
}

/// Viridis colour of `t` in [0, 1] (clamped; NaN gives mid grey so missing values stand out).
pub fn viridis(t: f64) -> [u8; 3] {
    if t.is_nan() {
        return [128, 128, 128];
    }
    let e = t.clamp(0.0, 1.0) * 255.0;
    let k = ((e / 8.0).floor() as usize).min(31);
    let s = ((e - node(k)) / (node(k + 1) - node(k))).clamp(0.0, 1.0);
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    [0, 1, 2].map(|i| (a[i] as f64 + s * (b[i] as f64 - a[i] as f64)).round() as u8)
}

/// Map `values` linearly from `[min, max]` onto viridis (values outside are clamped; if
/// `max <= min` every finite value gets the low end).
pub fn map_values(values: &[f64], min: f64, max: f64) -> Vec<[u8; 3]> {
    let span = max - min;
    values
        .iter()
        .map(|&v| {
            if v.is_nan() {
                viridis(f64::NAN)
            } else if span > 0.0 {
                viridis((v - min) / span)
            } else {
                viridis(0.0)
            }
        })
        .collect()
}

/// A vertical colour bar image `width × height` on white: the viridis gradient (max at the
/// top) with tick marks and labels "`min` mm", midpoint and "`max` mm" to its right
/// ([`colour_bar_ticks`] with those three ticks; none for an empty range).
pub fn colour_bar(min_mm: f64, max_mm: f64, width: u32, height: u32) -> Result<Image> {
    let ticks: Vec<(f64, String)> = [min_mm, 0.5 * (min_mm + max_mm), max_mm]
        .into_iter()
        .map(|v| (v, format!("{v:.1} mm")))
        .collect();
    colour_bar_ticks(min_mm, max_mm, &ticks, "", width, height)
}

/// A vertical colour bar `width × height` on white with `title` above it: the viridis gradient
/// from `min` (bottom) to `max` (top), a tick and its label (e.g. `"1.5"`, `"≥ 3.0"`) to the
/// right at each of `ticks` (value, label); ticks outside `[min, max]` are skipped.
pub fn colour_bar_ticks(
    min: f64,
    max: f64,
    ticks: &[(f64, String)],
    title: &str,
    width: u32,
    height: u32,
) -> Result<Image> {
    let mut img = Image::new(width, height, [255, 255, 255]);
    let size = (height as f64 / 24.0).clamp(10.0, 16.0);
    let pad = (size * 0.75).ceil() as i64;
    let head = if title.is_empty() {
        0
    } else {
        (size * 1.8) as i64
    };
    let bar_w = ((width as f64 * 0.18) as i64).clamp(6, 32);
    let (top, bottom) = (head + pad, height as i64 - pad - 1);
    if bottom <= top || width < 8 {
        return Ok(img);
    }
    let x0 = pad.min(width as i64 / 4);
    if !title.is_empty() {
        draw_label_sized(&mut img, x0 as i32, 2, title, [0, 0, 0], size)?;
    }
    for y in top..=bottom {
        let t = (bottom - y) as f64 / (bottom - top) as f64;
        let c = viridis(t);
        for x in x0..x0 + bar_w {
            img.set_pixel(x, y, c);
        }
    }
    let black = [0, 0, 0];
    let span = max - min;
    for (v, text) in ticks {
        if span.is_nan() || span <= 0.0 || *v < min - 1e-12 || *v > max + 1e-12 {
            continue;
        }
        let y = bottom - (((v - min) / span) * (bottom - top) as f64).round() as i64;
        for x in x0 + bar_w..x0 + bar_w + 5 {
            img.set_pixel(x, y, black);
        }
        let (_, th) = label_size(text, size)?;
        draw_label_sized(
            &mut img,
            (x0 + bar_w + 8) as i32,
            (y - th as i64 / 2) as i32,
            text,
            black,
            size,
        )?;
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_endpoints_midpoint_and_clamping() {
        // matplotlib: viridis(0) = #440154, viridis(1) = #fde725, entry 128 = (32, 144, 140).
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(128.0 / 255.0), [32, 144, 140]);
        // Entries between the nodes (matplotlib's 8-bit table) within 2/255.
        for (entry, rgb) in [
            (4, [69, 6, 90]),
            (100, [42, 118, 142]),
            (252, [246, 230, 31]),
        ] {
            let got = viridis(entry as f64 / 255.0);
            assert!(
                (0..3).all(|i| (got[i] as i32 - rgb[i]).abs() <= 2),
                "{entry}: {got:?}"
            );
        }
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), [128, 128, 128]);
        // Lightness increases monotonically along viridis (its design goal): check the green
        // channel, which dominates luminance and rises throughout.
        let g: Vec<u8> = (0..=100).map(|i| viridis(i as f64 / 100.0)[1]).collect();
        assert!(g.windows(2).all(|w| w[0] <= w[1]));
        let m = map_values(&[1.0, 3.0, 2.0, f64::NAN], 1.0, 3.0);
        assert_eq!(m[0], viridis(0.0));
        assert_eq!(m[1], viridis(1.0));
        assert_eq!(m[2], viridis(0.5));
        assert_eq!(m[3], [128, 128, 128]);
    }

    #[test]
    fn ticked_bar_puts_ticks_at_their_values() {
        let ticks: Vec<(f64, String)> = [0.0, 1.0, 2.0, 9.0]
            .iter()
            .map(|v| (*v, format!("{v:.1}")))
            .collect();
        let bar = colour_bar_ticks(0.0, 2.0, &ticks, "mm", 120, 240).unwrap();
        // The strip's column: the first non-white pixel left to right at mid height.
        let col = (0..bar.width)
            .find(|&x| bar.pixel(x, 150) != Some([255, 255, 255]))
            .unwrap()
            + 2;
        let ys: Vec<u32> = (0..bar.height)
            // Colour, not the grey of text or white.
            .filter(|&y| {
                bar.pixel(col, y)
                    .is_some_and(|c| c[0] != c[1] || c[1] != c[2])
            })
            .collect();
        let (top, bottom) = (ys[0], *ys.last().unwrap());
        assert_eq!(bar.pixel(col, bottom), Some(viridis(0.0)));
        assert_eq!(bar.pixel(col, top), Some(viridis(1.0)));
        // The tick of 1.0 sits halfway, just right of the strip.
        let mid = (top + bottom) / 2;
        let tick_x = (col..bar.width)
            .find(|&x| bar.pixel(x, mid) == Some([0, 0, 0]))
            .unwrap();
        assert!(tick_x < col + 40);
        assert!(colour_bar_ticks(0.0, 0.0, &ticks, "", 120, 240).is_ok());
    }

    #[test]
    fn colour_bar_runs_low_to_high_upwards() {
        let bar = colour_bar(0.0, 4.5, 160, 300).unwrap();
        assert_eq!((bar.width, bar.height), (160, 300));
        // Find the strip by its top and bottom colours.
        let col = (0..bar.width)
            .find(|&x| bar.pixel(x, 150) != Some([255, 255, 255]))
            .unwrap()
            + 2;
        let ys: Vec<u32> = (0..bar.height)
            .filter(|&y| bar.pixel(col, y) != Some([255, 255, 255]))
            .collect();
        let (top, bottom) = (ys[0], *ys.last().unwrap());
        assert_eq!(bar.pixel(col, top), Some(viridis(1.0)));
        assert_eq!(bar.pixel(col, bottom), Some(viridis(0.0)));
        // Labels were drawn to the right of the strip.
        let inked = (0..bar.height)
            .flat_map(|y| (col + 30..bar.width).map(move |x| (x, y)))
            .filter(|&(x, y)| bar.pixel(x, y) != Some([255, 255, 255]))
            .count();
        assert!(inked > 100);
    }
}
