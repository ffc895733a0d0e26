//! The tables of a subject's report, built once and written both as HTML and as Markdown.

use super::subject_validation::SubjectValidation;
use crate::anatomy::Joint;

/// One table cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// The text shown.
    pub text: String,
    /// Highlight the cell (a value beyond the report's attention threshold).
    pub flag: bool,
}

impl Cell {
    /// A plain cell.
    pub fn new(text: impl Into<String>) -> Cell {
        Cell {
            text: text.into(),
            flag: false,
        }
    }
    /// A cell highlighted when `flag`.
    pub fn flagged(text: impl Into<String>, flag: bool) -> Cell {
        Cell {
            text: text.into(),
            flag,
        }
    }
}

/// A table: header, rows, which columns are numbers (right-aligned), a note under it.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Column headings.
    pub head: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<Cell>>,
    /// Per column: numeric (right-aligned).
    pub numeric: Vec<bool>,
    /// Rows set apart as a summary at the bottom (the last `summary_rows` rows).
    pub summary_rows: usize,
    /// A sentence under the table (empty: none).
    pub note: String,
}

impl Table {
    fn new(head: &[&str], numeric: &[bool]) -> Table {
        Table {
            head: head.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
            numeric: numeric.to_vec(),
            summary_rows: 0,
            note: String::new(),
        }
    }
}

/// Centre errors above this are highlighted, mm.
pub(crate) const FLAG_CENTRE_MM: f64 = 2.0;
/// Axis errors above this are highlighted, degrees.
pub(crate) const FLAG_AXIS_DEG: f64 = 3.0;
/// Differences from the given dimensions above this are highlighted, mm.
pub(crate) const FLAG_DIMENSION_MM: f64 = 0.5;
/// Differences from the true dimensions above this are highlighted, mm (the simulated
/// calipers alone are off by up to about 1 mm).
pub(crate) const FLAG_DIMENSION_TRUE_MM: f64 = 1.0;

fn f2(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.2}")
    } else {
        "–".into()
    }
}

/// `x` with its sign (a typographic minus); a value that rounds to zero shows no sign.
pub fn signed(x: f64, digits: usize) -> String {
    let s = format!("{x:+.digits$}");
    if s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s.replace('-', "−")
    }
}

/// Sorted-copy median (the upper one for an even count); NaN when empty.
pub fn median(v: &[f64]) -> f64 {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Why the error map section is missing (one sentence, for the report).
pub const SKIPPED_SURFACE: &str = "Skipped: the subject folder has no reference.ply (a CT-like scan of the hand), so there is no surface to measure the skin against.";
/// Why the joint-centre section is missing (one sentence, for the report).
pub const SKIPPED_TRUTH: &str = "Skipped: the subject folder has no truth.json (only simulated subjects know their true joints), so the estimated centres and axes have nothing to be compared with.";

/// One sentence naming the references this report was measured against and the sections
/// skipped for want of the others; `None` when both optional references were present (a
/// simulated subject's report says nothing about them, as before).
pub fn references_sentence(v: &SubjectValidation) -> Option<String> {
    let r = v.references;
    if r.reference_ply && r.truth_json {
        return None;
    }
    let mut present = vec!["subject.toml's caliper dimensions"];
    let mut absent = Vec::new();
    if r.reference_ply {
        present.insert(0, "reference.ply");
    } else {
        absent.push(
            "reference.ply absent, so section 1 (skin against the reference surface) is skipped",
        );
    }
    if r.truth_json {
        present.insert(0, "truth.json");
    } else {
        absent.push("truth.json absent, so section 3 (joint centres and axes against the truth) is skipped and dimensions and link lengths are shown without true values");
    }
    Some(format!(
        "References: {} present; {}.",
        present.join(" and "),
        absent.join("; ")
    ))
}

/// The medians the suite and the summary cards quote: 3-DOF centres, 1-DOF centres, axes
/// (NaN without `truth.json`).
pub fn link_medians(v: &SubjectValidation) -> (f64, f64, f64) {
    let Some(link) = &v.link else {
        return (f64::NAN, f64::NAN, f64::NAN);
    };
    let dof = |e: &super::JointError| Joint::from_name(&e.joint).map(|j| j.dof());
    let c3: Vec<f64> = link
        .joints
        .iter()
        .filter(|e| dof(e) == Some(3))
        .map(|e| e.centre_mm)
        .collect();
    let c1: Vec<f64> = link
        .joints
        .iter()
        .filter(|e| dof(e) == Some(1))
        .map(|e| e.centre_mm)
        .collect();
    let ax: Vec<f64> = link.joints.iter().filter_map(|e| e.axis_deg).collect();
    (median(&c3), median(&c1), median(&ax))
}

/// Key figures (label, value, explanation) for the top of the report.
pub fn key_figures(v: &SubjectValidation) -> Vec<(String, String, String)> {
    let (c3, c1, ax) = link_medians(v);
    let total: f64 = v.reconstruct_timings_s.values().sum();
    let mut k = Vec::new();
    if let (Some(s), Some(r)) = (&v.surface, &v.surface_reverse) {
        k.push((
            "skin → reference".into(),
            format!("{:.2} mm", s.mean_mm),
            format!(
                "mean distance; 95th percentile {:.2}, max {:.2} mm",
                s.p95_mm, s.max_mm
            ),
        ));
        if let Some(h) = v.surface_regions.as_ref().map(|r| &r.hand_distal_of_wrist) {
            k.push((
                "hand distal of the wrist".into(),
                format!("{:.2} mm", h.mean_mm),
                format!(
                    "skin → reference over every region but the wrist; max {:.2} mm",
                    h.max_mm
                ),
            ));
        }
        k.push((
            "reference → skin".into(),
            format!("{:.2} mm", r.mean_mm),
            format!(
                "mean distance over the whole reference, forearm included; max {:.2} mm",
                r.max_mm
            ),
        ));
        if let Some(h) = v
            .surface_regions
            .as_ref()
            .and_then(|r| r.reverse_hand_distal_of_wrist.as_ref())
        {
            k.push((
                "reference → skin, distal of the wrist".into(),
                format!("{:.2} mm", h.mean_mm),
                format!(
                    "reference points whose nearest skin vertex is not in the wrist region; max \
                     {:.2} mm",
                    h.max_mm
                ),
            ));
        }
    }
    if v.link.is_some() {
        k.push((
            "joint centres".into(),
            format!("{c3:.2} / {c1:.2} mm"),
            "median error, 3-DOF / 1-DOF joints".into(),
        ));
        k.push((
            "hinge axes".into(),
            format!("{ax:.2}°"),
            "median angle to the true axis".into(),
        ));
    }
    k.push((
        "dimensions".into(),
        format!(
            "{} ± {:.3} mm",
            signed(v.dimensions.mean_vs_given_mm, 3),
            v.dimensions.sd_vs_given_mm
        ),
        format!(
            "{} caliper dimensions on the skin − given",
            v.dimensions.dimensions.len()
        ),
    ));
    if total > 0.0 {
        k.push((
            "reconstruction".into(),
            format!("{total:.1} s"),
            "time of reconstruct's stages".into(),
        ));
    }
    k
}

/// Distances both ways, with the seed paper's figures for comparison (`None` without
/// `reference.ply`).
pub fn surface_table(v: &SubjectValidation) -> Option<Table> {
    let (surface, reverse) = (v.surface.as_ref()?, v.surface_reverse.as_ref()?);
    let (stride, vertices) = (v.reference_stride?, v.reference_vertices?);
    let mut t = Table::new(
        &[
            "direction",
            "points",
            "mean",
            "SD",
            "min",
            "95th percentile",
            "max (mm)",
        ],
        &[false, true, true, true, true, true, true],
    );
    for (name, s) in [
        ("skin.obj vertices → reference.ply", surface),
        ("reference.ply vertices → skin.obj", reverse),
    ] {
        t.rows.push(vec![
            Cell::new(name),
            Cell::new(s.n.to_string()),
            Cell::new(f2(s.mean_mm)),
            Cell::new(f2(s.sd_mm)),
            Cell::new(format!("{:.4}", s.min_mm)),
            Cell::new(f2(s.p95_mm)),
            Cell::new(f2(s.max_mm)),
        ]);
    }
    t.rows.push(vec![
        Cell::new("seed paper, skin → CT of a plaster hand"),
        Cell::new("–"),
        Cell::new("1.63"),
        Cell::new("1.42"),
        Cell::new("0.0004"),
        Cell::new("–"),
        Cell::new("15.13"),
    ]);
    t.summary_rows = 1;
    t.note = format!(
        "Reference → skin measures every {}th of the reference's {} vertices (an even sample of the isosurface).",
        stride, vertices
    );
    if stride == 1 {
        t.note = format!("Reference → skin measures all {vertices} vertices of the reference.");
    }
    Some(t)
}

/// The skin-to-reference distance per anatomical region (`surface_regions`), with the hand
/// distal of the wrist as the summary row (`None` without `reference.ply`).
pub fn region_table(v: &SubjectValidation) -> Option<Table> {
    let r = v.surface_regions.as_ref()?;
    let mut t = Table::new(
        &["region", "vertices", "mean", "95th percentile", "max (mm)"],
        &[false, true, true, true, true],
    );
    for e in r
        .regions
        .iter()
        .chain(std::iter::once(&r.hand_distal_of_wrist))
    {
        let empty = e.vertices == 0;
        let num = |x: f64| if empty { "–".to_string() } else { f2(x) };
        t.rows.push(vec![
            Cell::new(e.region.clone()),
            Cell::new(e.vertices.to_string()),
            Cell::new(num(e.mean_mm)),
            Cell::new(num(e.p95_mm)),
            Cell::new(num(e.max_mm)),
        ]);
    }
    t.summary_rows = 1;
    t.note = format!(
        "skin.obj vertices → reference.ply by region of the template hand, carried to the skin by vertex index: fingertips are the distal links, fingers the proximal and middle phalanges, the thenar the thumb metacarpal, the wrist the skin less than {:.0} mm distal of the wrist centre and the forearm; the palm is split into dorsal and palmar by the normal, with the hypothenar its palmar ulnar part (src/validate/surface_regions.rs).",
        super::surface_regions::WRIST_BAND_MM
    );
    Some(t)
}

/// Per joint: estimator, range of motion, centre and axis errors against the truth (`None`
/// without `truth.json`).
pub fn joint_table(v: &SubjectValidation) -> Option<Table> {
    let link = v.link.as_ref()?;
    let mut t = Table::new(
        &[
            "joint",
            "DOF",
            "estimator",
            "trial",
            "range of motion (°)",
            "centre error (mm)",
            "centre SD (mm)",
            "axis error (°)",
        ],
        &[false, true, false, false, true, true, true, true],
    );
    for e in &link.joints {
        let fit = v.joint_fits.iter().find(|f| f.joint == e.joint);
        t.rows.push(vec![
            Cell::new(&e.joint),
            Cell::new(fit.map(|f| f.dof.to_string()).unwrap_or_default()),
            Cell::new(fit.map(|f| f.estimator.clone()).unwrap_or_default()),
            Cell::new(fit.map(|f| f.trial.clone()).unwrap_or_default()),
            Cell::new(
                fit.map(|f| format!("{:.0}", f.range_of_motion_deg))
                    .unwrap_or_default(),
            ),
            Cell::flagged(f2(e.centre_mm), e.centre_mm > FLAG_CENTRE_MM),
            Cell::new(
                fit.and_then(|f| f.centre_sd_mm)
                    .map(f2)
                    .unwrap_or_else(|| "–".into()),
            ),
            Cell::flagged(
                e.axis_deg.map(f2).unwrap_or_else(|| "–".into()),
                e.axis_deg.is_some_and(|a| a > FLAG_AXIS_DEG),
            ),
        ]);
    }
    let (c3, c1, ax) = link_medians(v);
    t.rows.push(vec![
        Cell::new("median"),
        Cell::new(""),
        Cell::new(""),
        Cell::new(""),
        Cell::new(""),
        Cell::new(format!("3-DOF {c3:.2}, 1-DOF {c1:.2}")),
        Cell::new(""),
        Cell::new(f2(ax)),
    ]);
    t.summary_rows = 1;
    t.note = format!(
        "Highlighted: centre errors above {FLAG_CENTRE_MM} mm, axis errors above {FLAG_AXIS_DEG}°. 1-DOF centres are the ones after section 3.6 (slid along the axis onto the skin's cross-section)."
    );
    Some(t)
}

/// The caliper dimensions measured on the skin against the given and the true values (the
/// true columns only when `truth.json` gave them).
pub fn dimension_table(v: &SubjectValidation) -> Table {
    let mut t = Table::new(
        &[
            "dimension",
            "on skin",
            "given",
            "true",
            "skin − given",
            "skin − true (mm)",
        ],
        &[false, true, true, true, true, true],
    );
    for d in &v.dimensions.dimensions {
        let vs_given = d.skin_mm - d.given_mm;
        t.rows.push(vec![
            Cell::new(d.name.replace('_', " ")),
            Cell::new(f2(d.skin_mm)),
            Cell::new(f2(d.given_mm)),
            Cell::new(d.true_mm.map(f2).unwrap_or_else(|| "–".into())),
            Cell::flagged(signed(vs_given, 3), vs_given.abs() > FLAG_DIMENSION_MM),
            Cell::flagged(
                d.true_mm
                    .map(|x| signed(d.skin_mm - x, 2))
                    .unwrap_or_else(|| "–".into()),
                d.true_mm
                    .is_some_and(|x| (d.skin_mm - x).abs() > FLAG_DIMENSION_TRUE_MM),
            ),
        ]);
    }
    let (tm, ts) = v.dimensions.vs_true_mm.unwrap_or((f64::NAN, f64::NAN));
    t.rows.push(vec![
        Cell::new("mean ± SD"),
        Cell::new(""),
        Cell::new(""),
        Cell::new(""),
        Cell::new(format!(
            "{} ± {:.3}",
            signed(v.dimensions.mean_vs_given_mm, 3),
            v.dimensions.sd_vs_given_mm
        )),
        Cell::new(format!("{} ± {:.2}", signed(tm, 2), ts)),
    ]);
    t.summary_rows = 1;
    let definitions = "Measured by their definitions (sections of the skin at the joints, the styloids and the metacarpal heads; see the README), not by the template's vertex pairs the fit met (reconstruct's report.json).";
    let unmeasured: String = v
        .dimensions
        .not_measured
        .iter()
        .map(|(k, why)| format!(" Not measured: {k} ({why})."))
        .collect();
    t.note = format!(
        "{definitions}{unmeasured} The seed paper: 0.04 ± 0.13 mm against the given dimensions. Highlighted: differences above {FLAG_DIMENSION_MM} mm from the given, {FLAG_DIMENSION_TRUE_MM} mm from the true values. The given values are simulated caliper readings, so skin − true includes the caliper's own error."
    );
    if v.dimensions.vs_true_mm.is_none() {
        // No truth.json: the true columns would be empty.
        for r in t.rows.iter_mut() {
            r.remove(5);
            r.remove(3);
        }
        for k in [5, 3] {
            t.head.remove(k);
            t.numeric.remove(k);
        }
        t.head[3] = "skin − given (mm)".into();
        t.note = format!(
            "{definitions}{unmeasured} The seed paper: 0.04 ± 0.13 mm against the given dimensions. Highlighted: differences above {FLAG_DIMENSION_MM} mm from the given caliper values."
        );
    }
    t
}

/// Link lengths between consecutive joint centres, estimated and true (estimated only
/// without `truth.json`).
pub fn link_length_table(v: &SubjectValidation) -> Table {
    let Some(link) = &v.link else {
        return model_link_length_table(v);
    };
    let mut t = Table::new(
        &["link", "estimated", "true", "difference", "SD (mm)"],
        &[false, true, true, true, true],
    );
    // Digit order (thumb to little), proximal first, as the joints are numbered.
    let mut links: Vec<(&String, &(f64, f64))> = link.link_lengths.iter().collect();
    links.sort_by_key(|(k, _)| digit_order(k));
    for (k, (m, tr)) in links {
        t.rows.push(vec![
            Cell::new(k.replace('-', " – ")),
            Cell::new(f2(*m)),
            Cell::new(f2(*tr)),
            Cell::flagged(signed(m - tr, 2), (m - tr).abs() > FLAG_CENTRE_MM),
            length_sd_cell(v, k),
        ]);
    }
    t.note = LINK_LENGTH_NOTE.into();
    t
}

/// A link length's bootstrap SD, flagged above the link model's warning level
/// ([`crate::link::estimate::MAX_LENGTH_SD_MM`]); a dash when the model has none.
fn length_sd_cell(v: &SubjectValidation, key: &str) -> Cell {
    match v.link_length_sd_mm.get(key) {
        Some(&sd) => Cell::flagged(f2(sd), sd > crate::link::estimate::MAX_LENGTH_SD_MM),
        None => Cell::new("–"),
    }
}

const LINK_LENGTH_NOTE: &str = "SD: the spread of the link length over block-bootstrap resamplings of the calibration trial's frames (link_model.json, link_lengths); it covers the noise of the motion, not a bias such as a plate sliding with its own joint. Repeatability (mean and SD over repeated sessions of one hand) needs repeats: ergohand validate --suite reports it for the suite's repeated subjects. The seed paper: index MCP–PIP 45.54 ± 0.52 mm, PIP–DIP 24.60 ± 0.92 mm over five recordings of the calibration motions (trial repeats: reports/link-repeatability.md).";

/// Digit order (thumb to little), proximal first, as the joints are numbered, of a link
/// length's key (`I_MCP-I_PIP`).
fn digit_order(key: &str) -> usize {
    key.split('-')
        .next()
        .and_then(Joint::from_name)
        .map_or(usize::MAX, |j| j.index())
}

/// [`link_length_table`] of a subject without truth: the model's own lengths.
fn model_link_length_table(v: &SubjectValidation) -> Table {
    let mut t = Table::new(&["link", "estimated", "SD (mm)"], &[false, true, true]);
    let mut links: Vec<(&String, &f64)> = v.link_lengths_mm.iter().collect();
    links.sort_by_key(|(k, _)| digit_order(k));
    for (k, m) in links {
        t.rows.push(vec![
            Cell::new(k.replace('-', " – ")),
            Cell::new(f2(*m)),
            length_sd_cell(v, k),
        ]);
    }
    t.note = LINK_LENGTH_NOTE.into();
    t
}

/// Figure 9 in numbers: every child marker's distance to its joint centre.
pub fn marker_radius_table(v: &SubjectValidation) -> Table {
    let mut t = Table::new(
        &["joint", "marker", "frames", "mean radius", "SD (mm)"],
        &[false, false, true, true, true],
    );
    for f in &v.joint_fits {
        for (k, m) in f.markers.iter().enumerate() {
            t.rows.push(vec![
                Cell::new(if k == 0 { f.joint.as_str() } else { "" }),
                Cell::new(&m.marker),
                Cell::new(m.frames.to_string()),
                Cell::new(f2(m.mean_mm)),
                Cell::new(format!("{:.3}", m.sd_mm)),
            ]);
        }
    }
    t.note = "Distances to the centre found from motion (for 1-DOF joints, before section 3.6 moved it along the axis). A rigid plate on an ideal joint gives SD 0; soft-tissue slide and noise raise it.".into();
    t
}

/// Time per stage: `reconstruct`'s (from its `report.json`) and this report's.
pub fn runtime_table(v: &SubjectValidation) -> Table {
    let mut t = Table::new(&["command", "stage", "time (s)"], &[false, false, true]);
    // Pipeline order; stages this report does not know come last, by name.
    let order = ["link", "skin", "tet", "hand"];
    let mut stages: Vec<(&String, &f64)> = v.reconstruct_timings_s.iter().collect();
    stages.sort_by_key(|(k, _)| order.iter().position(|o| o == k).unwrap_or(order.len()));
    for (k, s) in stages {
        t.rows.push(vec![
            Cell::new("reconstruct"),
            Cell::new(k),
            Cell::new(f2(*s)),
        ]);
    }
    for (k, s) in &v.validate_timings_s {
        t.rows
            .push(vec![Cell::new("validate"), Cell::new(k), Cell::new(f2(*s))]);
    }
    let r: f64 = v.reconstruct_timings_s.values().sum();
    let w: f64 = v.validate_timings_s.iter().map(|x| x.1).sum();
    t.rows.push(vec![
        Cell::new("total"),
        Cell::new(format!("reconstruct {r:.2} s, validate {w:.2} s")),
        Cell::new(f2(r + w)),
    ]);
    t.summary_rows = 1;
    if v.reconstruct_timings_s.is_empty() {
        t.note = "No report.json in the model folder: reconstruct's timings are unknown.".into();
    }
    t
}

/// Centre errors of a tracked motion above this are highlighted, mm (the tracking goal's).
pub(crate) const FLAG_MOTION_CENTRE_MM: f64 = 2.0;
/// Fingertip errors of a tracked motion above this are highlighted, mm (the tracking goal's).
pub(crate) const FLAG_MOTION_TIP_MM: f64 = 3.0;
/// Contact area ratios farther than this from 1 are highlighted (the tracking goal's 20 %).
pub(crate) const FLAG_CONTACT_RATIO: f64 = 0.2;

fn rms_cells(r: Option<&super::motion_accuracy::Rms>, flag_mm: f64) -> [Cell; 2] {
    match r {
        Some(r) => [
            Cell::flagged(f2(r.rms_mm), r.rms_mm > flag_mm),
            Cell::new(f2(r.max_mm)),
        ],
        None => [Cell::new("–"), Cell::new("–")],
    }
}

/// A summary row: `label`, then [`rms_cells`].
fn rms_row(
    label: impl Into<String>,
    r: Option<&super::motion_accuracy::Rms>,
    flag_mm: f64,
) -> Vec<Cell> {
    std::iter::once(Cell::new(label))
        .chain(rms_cells(r, flag_mm))
        .collect()
}

/// Per tracked motion: a summary (centres, their groups, fingertips, marker residuals,
/// frames), the joints and tips, and the hold's contact areas per link against the truth.
pub fn motion_tables(m: &super::motion_accuracy::MotionAccuracy) -> Vec<Table> {
    let mut summary = Table::new(&["quantity", "RMS (mm)", "max (mm)"], &[false, true, true]);
    let rows = &mut summary.rows;
    rows.push(rms_row(
        "joint centres, all solved frames",
        m.centre.as_ref(),
        FLAG_MOTION_CENTRE_MM,
    ));
    for (k, r) in &m.dof_groups {
        rows.push(rms_row(
            format!("{k}-DOF joints"),
            Some(r),
            FLAG_MOTION_CENTRE_MM,
        ));
    }
    rows.push(rms_row("fingertips", m.tip.as_ref(), FLAG_MOTION_TIP_MM));
    for (k, r) in &m.tips {
        rows.push(rms_row(
            format!("fingertip {k}"),
            Some(r),
            FLAG_MOTION_TIP_MM,
        ));
    }
    rows.push(rms_row(
        "marker residuals",
        m.marker_residual.as_ref(),
        f64::INFINITY,
    ));
    let lost = match &m.lost_frames {
        Some(l) if l.is_empty() => "none".to_string(),
        Some(l) => format!("{} ({})", l.len(), crate::track::ranges(l)),
        None => "unknown (the trial was not read)".to_string(),
    };
    summary.note = format!(
        "{} of {} frames unsolved; lost although at least {} palm and {} markers per digit were \
         seen: {lost}. Worst joint: {}.",
        m.unsolved_frames,
        m.frames,
        super::motion_accuracy::GOAL_PALM_MARKERS,
        super::motion_accuracy::GOAL_DIGIT_MARKERS,
        m.worst_joint.as_deref().unwrap_or("–")
    );
    let mut joints = Table::new(
        &["joint", "DOF", "centre RMS (mm)", "max (mm)", "frames"],
        &[false, true, true, true, true],
    );
    for j in &m.joints {
        let [a, b] = rms_cells(Some(&j.error), FLAG_MOTION_CENTRE_MM);
        joints.rows.push(vec![
            Cell::new(j.joint.clone()),
            Cell::new(j.dof.to_string()),
            a,
            b,
            Cell::new(j.error.samples.to_string()),
        ]);
    }
    let mut out = vec![summary, joints];
    if let Some(h) = &m.hold_contacts {
        let mut t = Table::new(
            &[
                "link",
                "tracked (mm²)",
                "true (mm²)",
                "tracked / true",
                "tracked depth (mm)",
                "true depth (mm)",
            ],
            &[false, true, true, true, true, true],
        );
        for l in &h.links {
            let ratio = match l.ratio {
                Some(r) => Cell::flagged(f2(r), (r - 1.0).abs() > FLAG_CONTACT_RATIO),
                None => Cell::new("–"),
            };
            t.rows.push(vec![
                Cell::new(l.link.clone()),
                Cell::new(format!("{:.1}", l.tracked_mm2)),
                Cell::new(format!("{:.1}", l.true_mm2)),
                ratio,
                Cell::new(f2(l.tracked_depth_mm)),
                Cell::new(f2(l.true_depth_mm)),
            ]);
        }
        t.summary_rows = 1;
        t.note = format!(
            "Mean contact area per link over the hold (frames {}-{}, {} of them with the hand \
             and the part tracked), the tracked skin against the true skin.",
            h.first, h.last, h.frames
        );
        out.push(t);
    }
    out
}

/// A grasp's figures as a table (one row per figure), then its contact area per link.
pub fn grasp_tables(g: &super::grasp_pose_sections::GraspSection) -> [Table; 2] {
    let yes = |b: bool| if b { "yes" } else { "no" };
    let figures = Table {
        head: vec!["figure".into(), "value".into()],
        rows: [
            ("scene", g.scene.clone(), false),
            ("grasp type", g.grasp_type.clone(), false),
            (
                "force closure",
                yes(g.force_closure).into(),
                !g.force_closure,
            ),
            ("epsilon", format!("{:.4}", g.epsilon), false),
            (
                "holds (gravity directions held)",
                format!(
                    "{} ({} of {})",
                    yes(g.holds),
                    g.directions_held,
                    g.directions
                ),
                !g.holds,
            ),
            (
                "contact area",
                format!("{:.0} mm²", g.total_contact_area_mm2),
                false,
            ),
            (
                "deepest penetration",
                format!("{:.1} mm", g.max_penetration_mm),
                false,
            ),
        ]
        .into_iter()
        .map(|(k, v, flag)| vec![Cell::new(k), Cell::flagged(v, flag)])
        .collect(),
        numeric: vec![false, true],
        summary_rows: 0,
        note: format!("From {}/grasp.json.", g.folder),
    };
    let areas = Table {
        head: vec!["link".into(), "contact area (mm²)".into()],
        rows: g
            .contact_area_mm2
            .iter()
            .map(|(l, a)| vec![Cell::new(l.clone()), Cell::new(format!("{a:.1}"))])
            .collect(),
        numeric: vec![false, true],
        summary_rows: 0,
        note: "Links that touch the part.".into(),
    };
    [figures, areas]
}

/// The posed hands of the model folder, one row each.
pub fn pose_table(poses: &[super::grasp_pose_sections::PoseRecord]) -> Table {
    Table {
        head: ["pose", "file", "deepest finger-finger penetration (mm)", "angles changed or clamped"]
            .map(String::from)
            .to_vec(),
        rows: poses
            .iter()
            .map(|p| {
                vec![
                    Cell::new(p.pose.clone()),
                    Cell::new(p.file.clone()),
                    Cell::flagged(format!("{:.2}", p.penetration_mm), p.penetration_mm > 2.0),
                    Cell::new(p.warnings.len().to_string()),
                ]
            })
            .collect(),
        numeric: vec![false, false, true, true],
        summary_rows: 0,
        note: "As `pose` measured them on the hand it wrote (NAME.pose.json beside NAME.glb): the deepest entry of one digit's skin into another's, and the angles it clamped to their limits or changed to keep the digits apart (flagged beyond 2 mm).".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::validate::dimension_accuracy::{DimensionAccuracy, DimensionError};
    use crate::validate::subject_validation::References;
    use std::collections::BTreeMap;

    fn validation(reference_ply: bool, truth_json: bool) -> SubjectValidation {
        let true_mm = truth_json.then_some(20.0);
        SubjectValidation {
            subject: "S".into(),
            hand: Side::Right,
            references: References {
                reference_ply,
                truth_json,
            },
            link: None,
            link_lengths_mm: BTreeMap::from([("I_MCP-I_PIP".to_string(), 45.0)]),
            link_length_sd_mm: BTreeMap::new(),
            surface: None,
            surface_regions: None,
            surface_reverse: None,
            reference_vertices: None,
            reference_stride: None,
            colour_scale_top_mm: None,
            dimensions: DimensionAccuracy {
                dimensions: vec![DimensionError {
                    name: "wrist_breadth".into(),
                    skin_mm: 21.0,
                    given_mm: 20.0,
                    true_mm,
                }],
                not_measured: BTreeMap::new(),
                mean_vs_given_mm: 1.0,
                sd_vs_given_mm: 0.0,
                vs_true_mm: true_mm.map(|_| (1.0, 0.0)),
            },
            joint_fits: Vec::new(),
            reconstruct_timings_s: BTreeMap::new(),
            validate_timings_s: Vec::new(),
            warnings: Vec::new(),
            motions: Vec::new(),
            grasps: Vec::new(),
            poses: Vec::new(),
            files: Vec::new(),
            thumbnail_png: None,
        }
    }

    /// One sentence per combination naming exactly the absent references; none for a
    /// subject with both.
    #[test]
    fn references_sentence_names_what_is_missing() {
        for (reference, truth) in [(true, true), (true, false), (false, true), (false, false)] {
            let s = references_sentence(&validation(reference, truth));
            let Some(s) = s else {
                assert!(reference && truth);
                continue;
            };
            assert!(!(reference && truth));
            assert!(s.ends_with('.') && !s.contains(". "), "{s}");
            assert_eq!(s.contains("reference.ply absent"), !reference, "{s}");
            assert_eq!(s.contains("truth.json absent"), !truth, "{s}");
            assert_eq!(s.contains("section 1"), !reference, "{s}");
            assert_eq!(s.contains("section 3"), !truth, "{s}");
        }
    }

    /// Without truth the dimension table has no true columns (rather than columns of dashes)
    /// and the same skin − given figures; without truth nothing needs `link` to be present.
    #[test]
    fn tables_without_truth_drop_the_true_columns() {
        let with = dimension_table(&validation(true, true));
        let without = dimension_table(&validation(true, false));
        assert_eq!(with.head.len(), 6);
        assert_eq!(
            without.head,
            ["dimension", "on skin", "given", "skin − given (mm)"]
        );
        assert_eq!(without.numeric.len(), 4);
        for (a, b) in with.rows.iter().zip(&without.rows) {
            assert_eq!(b.len(), 4);
            assert_eq!((&a[0], &a[1], &a[2], &a[4]), (&b[0], &b[1], &b[2], &b[3]));
        }
        assert_eq!(without.rows[0][3].text, "+1.000");
        assert!(joint_table(&validation(true, false)).is_none());
        assert!(surface_table(&validation(false, false)).is_none());
        let links = link_length_table(&validation(false, false));
        // The model's own lengths and their bootstrap SD (a dash: none recorded).
        assert_eq!(links.head.len(), 3);
        assert_eq!(links.rows[0][1].text, "45.00");
        assert_eq!(links.rows[0][2].text, "–");
    }
}
