//! A chart of the joint errors against the truth: centre error per joint (3-DOF and 1-DOF
//! joints in two colours) and hinge-axis error per 1-DOF joint, beside the table of section 3.

use super::charts::{plot_err, save_both, Figure, FIT, GRID, INK, TRAJ};
use super::link_accuracy::LinkAccuracy;
use crate::anatomy::Joint;
use crate::error::Result;
use crate::render::plot_font_family;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Bars of `values` (label, value, colour) with the labels under them.
fn bars<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    root: &DrawingArea<DB, Shift>,
    font: &str,
    caption: &str,
    y_desc: &str,
    values: &[(String, f64, RGBColor)],
) -> Result<()> {
    let err = plot_err(caption);
    let n = values.len().max(1) as f64;
    let top = values.iter().map(|v| v.1).fold(0.5, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (font, 15).into_font().color(&INK))
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.5..n - 0.5, 0.0..top)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .y_desc(y_desc)
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .draw()
        .map_err(|e| err(&e))?;
    chart
        .draw_series(values.iter().enumerate().map(|(i, (_, v, c))| {
            Rectangle::new(
                [(i as f64 - 0.36, 0.0), (i as f64 + 0.36, *v)],
                c.mix(0.85).filled(),
            )
        }))
        .map_err(|e| err(&e))?;
    let style = (font, 11)
        .into_font()
        .color(&INK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (i, (label, v, _)) in values.iter().enumerate() {
        let (x, y) = chart.backend_coord(&(i as f64, 0.0));
        // `root` is the whole picture, whose origin is the backend's.
        root.draw(&Text::new(label.clone(), (x, y + 6), style.clone()))
            .map_err(|e| err(&e))?;
        let (x, y) = chart.backend_coord(&(i as f64, *v));
        root.draw(&Text::new(format!("{v:.2}"), (x, y - 15), style.clone()))
            .map_err(|e| err(&e))?;
    }
    Ok(())
}

fn chart<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    font: &str,
    acc: &LinkAccuracy,
) -> Result<()> {
    root.fill(&WHITE)
        .map_err(|e| plot_err("joint errors")(&e))?;
    let (left, right) = root.split_horizontally((root.dim_in_pixel().0 as f64 * 0.62) as u32);
    let dof = |j: &str| Joint::from_name(j).map_or(0, |j| j.dof());
    let centres: Vec<(String, f64, RGBColor)> = acc
        .joints
        .iter()
        .map(|e| {
            let c = if dof(&e.joint) == 3 { FIT } else { TRAJ };
            (e.joint.clone(), e.centre_mm, c)
        })
        .collect();
    bars(
        &left,
        root,
        font,
        "centre error (blue: 3-DOF, red: 1-DOF joints)",
        "mm",
        &centres,
    )?;
    let axes: Vec<(String, f64, RGBColor)> = acc
        .joints
        .iter()
        .filter_map(|e| Some((e.joint.clone(), e.axis_deg?, TRAJ)))
        .collect();
    bars(&right, root, font, "hinge axis error", "degrees", &axes)
}

/// `joint-errors.png` / `.svg` in `dir`.
pub fn joint_error_figure(acc: &LinkAccuracy, dir: &Path) -> Result<Figure> {
    let font = plot_font_family()?;
    save_both(
        dir,
        "joint-errors",
        "Joint centre and axis errors against the truth".into(),
        (1260, 380),
        |a| chart(a, font, acc),
        |a| chart(a, font, acc),
    )
}
