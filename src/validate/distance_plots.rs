//! The distribution of the skin's distances to the reference, both ways, as a chart (PNG and
//! SVG) beside the error map.

use super::charts::{histogram, plot_err, save_both, Figure, FIT, TRAJ};
use super::error_map::ErrorMap;
use crate::error::Result;
use crate::render::plot_font_family;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

fn chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    map: &ErrorMap,
) -> Result<()> {
    let reverse = &map.reference_to_skin;
    area.fill(&WHITE)
        .map_err(|e| plot_err("distance histogram")(&e))?;
    let (a, b) = (&map.skin_to_reference_stats, &map.reference_to_skin_stats);
    histogram(
        area,
        font,
        &format!(
            "skin → reference: mean {:.2}, SD {:.2}, max {:.2} mm    reference → skin: mean {:.2}, SD {:.2}, max {:.2} mm",
            a.mean_mm, a.sd_mm, a.max_mm, b.mean_mm, b.sd_mm, b.max_mm
        ),
        &[
            (&map.skin_to_reference, FIT, "skin.obj vertices → reference.ply"),
            (reverse, TRAJ, "reference.ply vertices → skin.obj"),
        ],
        "distance (mm)",
        false,
    )
}

/// `distances.png` / `.svg` in `dir`.
pub fn distance_histograms(map: &ErrorMap, dir: &Path) -> Result<Figure> {
    let font = plot_font_family()?;
    save_both(
        dir,
        "distances",
        "Distribution of the distances between skin and reference".into(),
        (1000, 380),
        |a| chart(a, font, map),
        |a| chart(a, font, map),
    )
}
