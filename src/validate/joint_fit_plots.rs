//! The seed paper's Figures 8 and 9 drawn with plotters, as PNG (vendored DejaVu Sans) and SVG.
//!
//! Figure 8, one picture per digit (and one for the wrist), one row per joint: the trajectory of
//! the child marker farthest from the centre (as the paper shows) in the parent's reference
//! pose, in two projections on the joint's frame, with the fitted circle (1-DOF: in the plane of
//! the motion; 3-DOF: the sphere's outline), and the histogram of the marker's distance to the
//! centre minus its mean (the fitted radius). Figure 9: mean and SD of every child marker's
//! distance to its joint's centre.

use super::charts::{histogram, plot_err, save_both, Figure, FIT, GRID, INK, TRAJ};
use super::joint_fit::{JointFit, MarkerTrack};
use crate::anatomy::{Finger, Joint};
use crate::error::Result;
use crate::render::plot_font_family;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Samples drawn per projection (every n-th frame; the statistics use all).
const MAX_DRAWN: usize = 700;

/// Every `n`-th point so that at most [`MAX_DRAWN`] remain.
fn thin(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let step = points.len().div_ceil(MAX_DRAWN).max(1);
    points.iter().step_by(step).copied().collect()
}

fn mean_sd(x: &[f64]) -> (f64, f64) {
    let n = x.len().max(1) as f64;
    let m = x.iter().sum::<f64>() / n;
    (
        m,
        (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt(),
    )
}

fn circle(cx: f64, cy: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=180)
        .map(|k| {
            let t = k as f64 / 180.0 * std::f64::consts::TAU;
            (cx + r * t.cos(), cy + r * t.sin())
        })
        .collect()
}

/// One projection of a marker's trajectory with its fitted circle. `axes` picks the frame
/// coordinates shown (horizontal, vertical); `fit` is the curve drawn.
#[allow(clippy::too_many_arguments)]
fn projection<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    caption: &str,
    track: &MarkerTrack,
    axes: (usize, usize),
    centre_h: f64,
    half: f64,
    fit: &[(f64, f64)],
    labels: (&str, &str),
) -> Result<()> {
    let err = plot_err(caption);
    let pts: Vec<(f64, f64)> = track
        .points
        .iter()
        .map(|p| (p[axes.0], p[axes.1]))
        .collect();
    // Equal scales on both axes, so that circles look round: the plotting area's pixel size
    // is the titled area less the margins and label areas given below.
    let area = area
        .titled(caption, (font, 14).into_font().color(&INK))
        .map_err(|e| err(&e))?;
    let (w, h) = area.dim_in_pixel();
    let (pw, ph) = (
        (w as f64 - 12.0 - 44.0).max(1.0),
        (h as f64 - 12.0 - 34.0).max(1.0),
    );
    let (hx, hy) = if pw > ph {
        (half * pw / ph, half)
    } else {
        (half, half * ph / pw)
    };
    let mut chart = ChartBuilder::on(&area)
        .margin(6)
        .x_label_area_size(34)
        .y_label_area_size(44)
        .build_cartesian_2d(centre_h - hx..centre_h + hx, -hy..hy)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .x_desc(labels.0)
        .y_desc(labels.1)
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .x_labels(5)
        .y_labels(5)
        .draw()
        .map_err(|e| err(&e))?;
    chart
        .draw_series(
            thin(&pts)
                .into_iter()
                .map(|p| Circle::new(p, 2, TRAJ.mix(0.55).filled())),
        )
        .map_err(|e| err(&e))?;
    chart
        .draw_series(std::iter::once(PathElement::new(
            fit.to_vec(),
            FIT.stroke_width(2),
        )))
        .map_err(|e| err(&e))?;
    chart
        .draw_series(std::iter::once(Cross::new(
            (0.0, 0.0),
            5,
            BLACK.stroke_width(2),
        )))
        .map_err(|e| err(&e))?;
    Ok(())
}

/// The three panels of one joint's row.
fn joint_row<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    fit: &JointFit,
) -> Result<()> {
    let panels = area.split_evenly((1, 3));
    let Some(track) = fit.farthest() else {
        return Ok(());
    };
    let radii = track.radii();
    let (mean, sd) = mean_sd(&radii);
    let extent = track
        .points
        .iter()
        .map(|p| p[1].abs().max(p[2].abs()))
        .fold(mean, f64::max)
        * 1.08;
    let j = fit.joint;
    if j.dof() == 1 {
        // The circle lies in the plane normal to the axis (x); its radius is the marker's mean
        // distance to the axis, its plane the marker's mean position along the axis.
        let in_plane: Vec<f64> = track
            .points
            .iter()
            .map(|p| (p[1] * p[1] + p[2] * p[2]).sqrt())
            .collect();
        let (r, _) = mean_sd(&in_plane);
        let (x_mean, _) = mean_sd(&track.points.iter().map(|p| p[0]).collect::<Vec<_>>());
        projection(
            &panels[0],
            font,
            &format!("{j}: {} in the plane of motion", track.name),
            track,
            (2, 1),
            0.0,
            extent,
            &circle(0.0, 0.0, r),
            ("along the link z (mm)", "dorsal y (mm)"),
        )?;
        projection(
            &panels[1],
            font,
            &format!("{j}: edge-on, axis horizontal"),
            track,
            (0, 1),
            x_mean,
            extent,
            &[(x_mean, -r), (x_mean, r)],
            ("along the axis x (mm)", "dorsal y (mm)"),
        )?;
    } else {
        projection(
            &panels[0],
            font,
            &format!("{j}: {} seen from the side", track.name),
            track,
            (2, 1),
            0.0,
            extent,
            &circle(0.0, 0.0, mean),
            ("along the link z (mm)", "dorsal y (mm)"),
        )?;
        projection(
            &panels[1],
            font,
            &format!("{j}: seen along the link"),
            track,
            (0, 1),
            0.0,
            extent,
            &circle(0.0, 0.0, mean),
            ("x (mm)", "dorsal y (mm)"),
        )?;
    }
    let dev: Vec<f64> = radii.iter().map(|r| r - mean).collect();
    histogram(
        &panels[2],
        font,
        &format!("radius {mean:.1} mm, SD {sd:.2} mm, {} frames", radii.len()),
        &[(&dev, FIT, "")],
        "distance to centre − mean radius (mm)",
        true,
    )
}

fn digit_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    fits: &[&JointFit],
) -> Result<()> {
    area.fill(&WHITE).map_err(|e| plot_err("figure 8")(&e))?;
    let rows = area.split_evenly((fits.len().max(1), 1));
    for (row, fit) in rows.iter().zip(fits) {
        joint_row(row, font, fit)?;
    }
    Ok(())
}

/// Figure 8 for every digit and the wrist into `dir` (`fit-wrist`, `fit-thumb`, ...).
pub fn joint_fit_figures(fits: &[JointFit], dir: &Path) -> Result<Vec<Figure>> {
    let font = plot_font_family()?;
    let mut groups: Vec<(String, Vec<&JointFit>)> = vec![(
        "wrist".into(),
        fits.iter().filter(|f| f.joint == Joint::Wrist).collect(),
    )];
    for f in Finger::ALL {
        groups.push((
            f.trial_name().to_string(),
            fits.iter()
                .filter(|x| x.joint.finger() == Some(f))
                .collect(),
        ));
    }
    let per_row = 330;
    let mut figures = Vec::new();
    for (name, group) in groups {
        if group.is_empty() {
            continue;
        }
        let size = (1260, per_row * group.len() as u32);
        let title = format!(
            "{name}: {}",
            group
                .iter()
                .map(|f| f.joint.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
        figures.push(save_both(
            dir,
            &format!("fit-{name}"),
            title,
            size,
            |a| digit_chart(a, font, &group),
            |a| digit_chart(a, font, &group),
        )?);
    }
    Ok(figures)
}

fn radius_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    fits: &[JointFit],
) -> Result<()> {
    let err = plot_err("figure 9");
    area.fill(&WHITE).map_err(|e| err(&e))?;
    let markers: Vec<(usize, &JointFit, &MarkerTrack)> = fits
        .iter()
        .enumerate()
        .flat_map(|(k, f)| f.markers.iter().map(move |m| (k, f, m)))
        .collect();
    let n = markers.len().max(1) as f64;
    let parts = area.split_evenly((2, 1));
    let rmax = markers.iter().map(|m| m.2.radius_mean).fold(10.0, f64::max) * 1.1;
    let sdmax = markers.iter().map(|m| m.2.radius_sd).fold(0.05, f64::max) * 1.15;
    let colour = |k: usize| if k.is_multiple_of(2) { FIT } else { TRAJ };
    let mut top = ChartBuilder::on(&parts[0])
        .caption(
            "mean distance of each child marker to its joint centre (± SD)",
            (font, 15).into_font().color(&INK),
        )
        .margin(8)
        .x_label_area_size(10)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.5..n - 0.5, 0.0..rmax)
        .map_err(|e| err(&e))?;
    top.configure_mesh()
        .disable_x_mesh()
        .disable_x_axis()
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .y_desc("radius (mm)")
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .draw()
        .map_err(|e| err(&e))?;
    // ± SD bars with short caps.
    top.draw_series(markers.iter().enumerate().flat_map(|(i, (k, _, m))| {
        let (x, lo, hi) = (
            i as f64,
            m.radius_mean - m.radius_sd,
            m.radius_mean + m.radius_sd,
        );
        let style = colour(*k).stroke_width(2);
        [
            PathElement::new(vec![(x, lo), (x, hi)], style),
            PathElement::new(vec![(x - 0.2, lo), (x + 0.2, lo)], style),
            PathElement::new(vec![(x - 0.2, hi), (x + 0.2, hi)], style),
        ]
    }))
    .map_err(|e| err(&e))?;
    top.draw_series(
        markers
            .iter()
            .enumerate()
            .map(|(i, (k, _, m))| Circle::new((i as f64, m.radius_mean), 3, colour(*k).filled())),
    )
    .map_err(|e| err(&e))?;
    let mut bottom = ChartBuilder::on(&parts[1])
        .caption(
            "SD of that distance (the spread of the marker about its circle or sphere)",
            (font, 15).into_font().color(&INK),
        )
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.5..n - 0.5, 0.0..sdmax)
        .map_err(|e| err(&e))?;
    bottom
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .y_desc("SD (mm)")
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .draw()
        .map_err(|e| err(&e))?;
    bottom
        .draw_series(markers.iter().enumerate().map(|(i, (k, _, m))| {
            Rectangle::new(
                [(i as f64 - 0.35, 0.0), (i as f64 + 0.35, m.radius_sd)],
                colour(*k).mix(0.8).filled(),
            )
        }))
        .map_err(|e| err(&e))?;
    // Joint names under their groups of markers.
    let style = (font, 12)
        .into_font()
        .color(&INK)
        .pos(plotters::style::text_anchor::Pos::new(
            plotters::style::text_anchor::HPos::Center,
            plotters::style::text_anchor::VPos::Top,
        ));
    for (k, f) in fits.iter().enumerate() {
        let idx: Vec<usize> = markers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.0 == k)
            .map(|(i, _)| i)
            .collect();
        let Some(&first) = idx.first() else { continue };
        let mid = (first + idx[idx.len() - 1]) as f64 / 2.0;
        let (x, y) = bottom.backend_coord(&(mid, 0.0));
        // `area` is the whole picture, whose origin is the backend's.
        area.draw(&Text::new(
            f.joint.name().to_string(),
            (x, y + 8),
            style.clone(),
        ))
        .map_err(|e| err(&e))?;
    }
    Ok(())
}

/// Figure 9 into `dir` (`marker-radii.png`, `.svg`).
pub fn radius_figure(fits: &[JointFit], dir: &Path) -> Result<Figure> {
    let font = plot_font_family()?;
    save_both(
        dir,
        "marker-radii",
        "Distance of every child marker to its joint centre (the seed paper's Figure 9)".into(),
        (1260, 620),
        |a| radius_chart(a, font, fits),
        |a| radius_chart(a, font, fits),
    )
}
