//! Charts of a tracked trial against time, read from its `motion.json`: the joint angles
//! (`angles.png`) and the contact area per digit with the markers' residual RMS
//! (`contact_area.png`). Frames without a value (unsolved, or the part's pose unknown) are
//! gaps in the lines, never zeros.

use super::charts::{plot_err, GRID, INK};
use crate::anatomy::{Finger, Joint, Link};
use crate::error::Result;
use crate::render::{plot_font_family, Image};
use crate::track::MotionFile;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Size of `angles.png`, pixels.
pub const ANGLES_SIZE: (u32, u32) = (1200, 720);
/// Size of `contact_area.png`, pixels.
pub const CONTACT_AREA_SIZE: (u32, u32) = (1200, 640);

/// Proximal, middle and distal joint of a digit.
const JOINT_COLOURS: [RGBColor; 3] = [
    RGBColor(31, 90, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];

/// Thumb to little, then the palm.
const GROUP_COLOURS: [RGBColor; 6] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(110, 110, 110),
];

/// The contact groups of the area chart: the five digits (their three links each) and the
/// palm (with the forearm, which rarely touches anything).
pub const GROUPS: [&str; 6] = ["thumb", "index", "middle", "ring", "little", "palm"];

/// The group ([`GROUPS`] index) of a link.
pub fn group_of(link: Link) -> usize {
    match link {
        Link::Arm | Link::Palm => 5,
        l => Finger::ALL
            .iter()
            .position(|f| f.links().contains(&l))
            .unwrap_or(5),
    }
}

/// Draw into a `size` bitmap with `draw` and encode it as PNG.
fn png_chart(
    size: (u32, u32),
    draw: impl for<'a> FnOnce(&DrawingArea<BitMapBackend<'a>, Shift>) -> Result<()>,
) -> Result<Vec<u8>> {
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw(&area)?;
        area.present().map_err(|e| plot_err("a chart")(&e))?;
    }
    let mut img = Image::new(size.0, size.1, [255, 255, 255]);
    img.rgb = buf;
    img.to_png()
}

/// The runs of consecutive `Some` values of `ys` as (time s, value) polylines.
pub fn runs(ys: &[Option<f64>], rate: f64) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut open = false;
    for (f, y) in ys.iter().enumerate() {
        match y {
            Some(v) if v.is_finite() => {
                if !open {
                    out.push(Vec::new());
                    open = true;
                }
                if let Some(r) = out.last_mut() {
                    r.push((f as f64 / rate, *v));
                }
            }
            _ => open = false,
        }
    }
    out
}

/// A value range holding `values` with 5 % padding (at least `min_span` wide).
fn range_of<'a>(values: impl Iterator<Item = &'a f64>, min_span: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in values {
        if v.is_finite() {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return (0.0, min_span);
    }
    if hi - lo < min_span {
        let m = 0.5 * (lo + hi);
        (lo, hi) = (m - 0.5 * min_span, m + 0.5 * min_span);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// One panel of lines against time: each series `(label, colour, values per frame)`.
#[allow(clippy::too_many_arguments)]
fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    font: &str,
    caption: &str,
    y_desc: &str,
    duration_s: f64,
    rate: f64,
    series: &[(String, RGBColor, Vec<Option<f64>>)],
    y_range: Option<(f64, f64)>,
) -> Result<()> {
    let err = plot_err(caption);
    let (lo, hi) =
        y_range.unwrap_or_else(|| range_of(series.iter().flat_map(|s| s.2.iter().flatten()), 10.0));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (font, 15).into_font().color(&INK))
        .margin(8)
        .x_label_area_size(32)
        .y_label_area_size(52)
        .build_cartesian_2d(0.0..duration_s.max(1e-6), lo..hi)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .bold_line_style(GRID)
        .x_desc("time (s)")
        .y_desc(y_desc)
        .label_style((font, 11).into_font().color(&INK))
        .axis_desc_style((font, 12).into_font().color(&INK))
        .x_labels(6)
        .y_labels(5)
        .draw()
        .map_err(|e| err(&e))?;
    for (label, colour, ys) in series {
        let c = *colour;
        let mut first = true;
        for run in runs(ys, rate) {
            let s = chart
                .draw_series(LineSeries::new(run, c.stroke_width(2)))
                .map_err(|e| err(&e))?;
            if first && !label.is_empty() {
                s.label(label.clone()).legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2))
                });
                first = false;
            }
        }
    }
    if series
        .iter()
        .any(|s| !s.0.is_empty() && s.2.iter().any(Option::is_some))
    {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(GRID)
            .label_font((font, 11).into_font().color(&INK))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    Ok(())
}

/// Per frame, the first angle (flexion; a hinge's only angle) of `joint` in degrees.
pub fn flexion_deg(file: &MotionFile, joint: Joint) -> Vec<Option<f64>> {
    match file.joints.get(joint.name()) {
        Some(t) => t
            .angles_deg
            .iter()
            .map(|a| a.as_ref().and_then(|a| a.first().copied()))
            .collect(),
        None => vec![None; file.frames],
    }
}

fn duration_s(file: &MotionFile) -> f64 {
    file.frames.saturating_sub(1) as f64 / file.rate.max(1e-9)
}

/// `angles.png`: six panels, one per digit (the flexion of its three joints) and the wrist
/// (its flexion and abduction), in degrees from the static trial's posture against time.
pub fn angles_chart(file: &MotionFile) -> Result<Vec<u8>> {
    let font = plot_font_family()?;
    let dur = duration_s(file);
    png_chart(ANGLES_SIZE, |root| {
        root.fill(&WHITE).map_err(|e| plot_err("angles")(&e))?;
        let panels = root.split_evenly((2, 3));
        for (k, f) in Finger::ALL.iter().enumerate() {
            let series: Vec<(String, RGBColor, Vec<Option<f64>>)> = f
                .joints()
                .iter()
                .enumerate()
                .map(|(r, j)| {
                    (
                        j.name().to_string(),
                        JOINT_COLOURS[r],
                        flexion_deg(file, *j),
                    )
                })
                .collect();
            let caption = format!("{} flexion", f.trial_name());
            line_panel(
                &panels[k], font, &caption, "degrees", dur, file.rate, &series, None,
            )?;
        }
        let wrist = file.joints.get(Joint::Wrist.name());
        let component = |i: usize| -> Vec<Option<f64>> {
            match wrist {
                Some(t) => t
                    .angles_deg
                    .iter()
                    .map(|a| a.as_ref().and_then(|a| a.get(i).copied()))
                    .collect(),
                None => vec![None; file.frames],
            }
        };
        let series = vec![
            ("flexion".to_string(), JOINT_COLOURS[0], component(0)),
            ("abduction".to_string(), JOINT_COLOURS[1], component(1)),
        ];
        line_panel(
            &panels[5], font, "wrist", "degrees", dur, file.rate, &series, None,
        )
    })
}

/// Per frame: `None` where the contacts are unknown (the frame unsolved, or the part's pose
/// unknown, or no part at all), else the contact area of each of [`GROUPS`], mm².
pub fn group_areas(file: &MotionFile) -> Vec<Option<[f64; 6]>> {
    let unsolved: std::collections::BTreeSet<usize> =
        file.unsolved_frames.iter().copied().collect();
    let mut out: Vec<Option<[f64; 6]>> = (0..file.frames)
        .map(|f| {
            let part_known = file
                .part
                .as_ref()
                .is_some_and(|p| p.pose.get(f).is_some_and(Option::is_some));
            (part_known && !unsolved.contains(&f)).then_some([0.0; 6])
        })
        .collect();
    for c in &file.contacts {
        let (Some(Some(a)), Some(l)) = (out.get_mut(c.frame), Link::from_name(&c.link)) else {
            continue;
        };
        a[group_of(l)] += c.area_mm2;
    }
    out
}

/// Per frame: the RMS of the markers' residuals, mm (`None` where no marker has one).
pub fn residual_rms_mm(file: &MotionFile) -> Vec<Option<f64>> {
    (0..file.frames)
        .map(|f| {
            let (mut ss, mut n) = (0.0, 0usize);
            for r in file.marker_residual_mm.values() {
                if let Some(Some(v)) = r.get(f) {
                    ss += v * v;
                    n += 1;
                }
            }
            (n > 0).then(|| (ss / n as f64).sqrt())
        })
        .collect()
}

/// `contact_area.png`: above, the contact area of each digit and of the palm against time
/// (lines, mm²; gaps where the contacts are unknown); below, the RMS of the markers'
/// residuals per frame (how well the model fits the markers).
pub fn contact_area_chart(file: &MotionFile) -> Result<Vec<u8>> {
    let font = plot_font_family()?;
    let dur = duration_s(file);
    let areas = group_areas(file);
    let rms = residual_rms_mm(file);
    png_chart(CONTACT_AREA_SIZE, |root| {
        root.fill(&WHITE)
            .map_err(|e| plot_err("contact area")(&e))?;
        let (top, bottom) = root.split_vertically((CONTACT_AREA_SIZE.1 as f64 * 0.64) as u32);
        let series: Vec<(String, RGBColor, Vec<Option<f64>>)> = GROUPS
            .iter()
            .enumerate()
            .map(|(g, name)| {
                (
                    name.to_string(),
                    GROUP_COLOURS[g],
                    areas.iter().map(|a| a.map(|a| a[g])).collect(),
                )
            })
            .collect();
        let top_area = series
            .iter()
            .flat_map(|s| s.2.iter().flatten())
            .copied()
            .fold(0.0, f64::max);
        let caption = if areas.iter().all(Option::is_none) {
            "contact area (unknown: no part tracked)"
        } else {
            "contact area per digit"
        };
        line_panel(
            &top,
            font,
            caption,
            "mm²",
            dur,
            file.rate,
            &series,
            Some((0.0, (top_area * 1.08).max(10.0))),
        )?;
        let (_, hi) = range_of(rms.iter().flatten(), 0.5);
        line_panel(
            &bottom,
            font,
            "marker residual RMS per frame",
            "mm",
            dur,
            file.rate,
            &[(String::new(), RGBColor(60, 60, 60), rms.clone())],
            Some((0.0, hi)),
        )
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::track::{ContactRecord, JointTrack, PartPose, PartTrack};
    use std::collections::BTreeMap;

    /// A trial of 50 frames at 25 Hz: frames 10-12 unsolved, the part's pose unknown in frame
    /// 30, the thumb's and the index's distal links and the palm in contact in frames 20-39.
    pub(crate) fn sample() -> MotionFile {
        let n = 50;
        let unsolved: Vec<usize> = vec![10, 11, 12];
        let mut joints = BTreeMap::new();
        for j in Joint::ALL {
            let angles = (0..n)
                .map(|f| {
                    (!unsolved.contains(&f))
                        .then(|| vec![f as f64 + j.index() as f64; j.dof().min(2)])
                })
                .collect();
            joints.insert(
                j.name().to_string(),
                JointTrack {
                    centre: vec![None; n],
                    angles_deg: angles,
                    held_frames: if j == Joint::LDip { vec![5, 6] } else { vec![] },
                    coupled_frames: Vec::new(),
                },
            );
        }
        let mut contacts = Vec::new();
        for f in 20..40 {
            for (link, area, depth) in [
                ("T_DIST", 100.0, 0.5),
                ("I_DIST", 40.0 + f as f64, 0.1 * (f - 19) as f64),
                ("PALM", 300.0, 0.0),
            ] {
                contacts.push(ContactRecord {
                    frame: f,
                    link: link.into(),
                    area_mm2: area,
                    depth_mm: depth,
                });
            }
        }
        let pose = PartPose {
            translation_mm: [0.0; 3],
            rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        let mut residual = BTreeMap::new();
        residual.insert(
            "I_NAIL".to_string(),
            (0..n).map(|f| (f % 2 == 0).then_some(3.0)).collect(),
        );
        residual.insert(
            "PALM_1".to_string(),
            (0..n).map(|f| (f != 49).then_some(4.0)).collect(),
        );
        let mut rejected = BTreeMap::new();
        rejected.insert("M_NAIL".to_string(), vec![3, 4, 5]);
        MotionFile {
            units: "mm".into(),
            rate: 25.0,
            frames: n,
            frame: "lab".into(),
            joints,
            tips: BTreeMap::new(),
            marker_residual_mm: residual,
            contacts,
            unsolved_frames: unsolved,
            rejected_frames: rejected,
            part: Some(PartTrack {
                source: "markers".into(),
                pose: (0..n).map(|f| (f != 30).then(|| pose.clone())).collect(),
                filled_frames: Vec::new(),
                marker_rms_mm: Vec::new(),
            }),
            warnings: vec!["a <warning> & more".into()],
        }
    }

    #[test]
    fn runs_break_at_gaps_and_time_is_frame_over_rate() {
        let r = runs(
            &[Some(1.0), Some(2.0), None, Some(3.0), Some(f64::NAN)],
            4.0,
        );
        assert_eq!(r, vec![vec![(0.0, 1.0), (0.25, 2.0)], vec![(0.75, 3.0)]]);
        assert!(runs(&[None, None], 1.0).is_empty());
    }

    #[test]
    fn groups_sum_links_and_leave_unknown_frames_out() {
        assert_eq!(group_of(Link::TMeta), 0);
        assert_eq!(group_of(Link::IDist), 1);
        assert_eq!(group_of(Link::LProx), 4);
        assert_eq!(group_of(Link::Palm), 5);
        let m = sample();
        let a = group_areas(&m);
        assert_eq!(a.len(), 50);
        // Unsolved, or the part unknown: no value (a gap), not zero.
        for f in [10, 11, 12, 30] {
            assert_eq!(a[f], None, "frame {f}");
        }
        assert_eq!(a[5], Some([0.0; 6]));
        assert_eq!(a[25], Some([100.0, 65.0, 0.0, 0.0, 0.0, 300.0]));
        // RMS over the markers seen: sqrt((9 + 16) / 2) in even frames, 4 in odd ones.
        let r = residual_rms_mm(&m);
        assert!((r[0].unwrap() - 12.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(r[1], Some(4.0));
        assert_eq!(r[49], None);
        assert_eq!(flexion_deg(&m, Joint::IPip)[3], Some(3.0 + 5.0));
        assert_eq!(flexion_deg(&m, Joint::IPip)[11], None);
    }

    #[test]
    fn charts_decode_at_their_sizes() {
        let m = sample();
        for (png, size) in [
            (angles_chart(&m).unwrap(), ANGLES_SIZE),
            (contact_area_chart(&m).unwrap(), CONTACT_AREA_SIZE),
        ] {
            let img = image::load_from_memory(&png).unwrap().to_rgb8();
            assert_eq!((img.width(), img.height()), size);
            // Something was drawn in colour (the lines), not only axes and text.
            let coloured = img
                .pixels()
                .filter(|p| p.0.iter().max().unwrap() - p.0.iter().min().unwrap() > 60)
                .count();
            assert!(coloured > 500, "{coloured}");
        }
        // Without a part, the contact chart still draws (its areas unknown throughout).
        let mut bare = sample();
        bare.part = None;
        bare.contacts.clear();
        assert!(group_areas(&bare).iter().all(Option::is_none));
        assert!(contact_area_chart(&bare).is_ok());
    }
}
