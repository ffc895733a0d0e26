//! `report.md`: the report's tables in Markdown, with the pictures and charts linked as the
//! PNG files written beside it (SVG versions linked too), for reading on a code host or in an
//! editor.

use super::charts::Figure;
use super::report_tables::{self as tables, Table};
use super::subject_validation::{ReportFigures, SubjectValidation};

/// Where the runtime table goes until the report's own time is known.
pub const RUNTIME_PLACEHOLDER: &str = "<!--ergohand:runtime-md-->";

fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// A table as GitHub-flavoured Markdown (highlighted cells in bold).
pub fn table_markdown(t: &Table) -> String {
    let mut s = format!(
        "| {} |\n|{}|\n",
        t.head
            .iter()
            .map(|h| cell(h))
            .collect::<Vec<_>>()
            .join(" | "),
        t.numeric
            .iter()
            .map(|&n| if n { "---:" } else { "---" })
            .collect::<Vec<_>>()
            .join("|")
    );
    for row in &t.rows {
        let cells: Vec<String> = row
            .iter()
            .map(|c| {
                if c.flag {
                    format!("**{}**", cell(&c.text))
                } else {
                    cell(&c.text)
                }
            })
            .collect();
        s.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    if !t.note.is_empty() {
        s.push_str(&format!("\n{}\n", t.note));
    }
    s.push('\n');
    s
}

fn file(p: &std::path::Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn chart(f: &Figure) -> String {
    format!(
        "![{}]({})\n\n([SVG]({}))\n\n",
        f.title,
        file(&f.png),
        file(&f.svg)
    )
}

/// The runtime table (filled in once the report's own time is measured).
pub fn runtime_markdown(v: &SubjectValidation) -> String {
    table_markdown(&tables::runtime_table(v))
}

/// The Markdown report of one subject.
pub fn subject_markdown(v: &SubjectValidation, figs: &ReportFigures) -> String {
    let mut s = format!(
        "# Validation report: {} ({} hand)\n\nMade by `ergohand validate`. The self-contained version of this report is `report.html`; the numbers are in `metrics.json`.\n\n",
        v.subject, v.hand
    );
    s.push_str("| key figure | value | |\n|---|---:|---|\n");
    for (l, val, n) in tables::key_figures(v) {
        s.push_str(&format!("| {l} | {val} | {n} |\n"));
    }
    if let Some(r) = tables::references_sentence(v) {
        s.push_str(&format!("\n{r}\n"));
    }
    s.push_str("\n## 1. Error map: skin against the CT-like reference\n\n");
    if let (Some((path, _)), Some(distances), Some(table), Some(top)) = (
        &figs.error_map,
        &figs.distances,
        tables::surface_table(v),
        v.colour_scale_top_mm,
    ) {
        s.push_str(&format!(
            "![error map]({})\n\nDistance of every `skin.obj` vertex to `reference.ply`; dorsal, palmar, radial and ulnar views, colour scale 0 to {:.1} mm. Also as a vertex-coloured GLB: [error-map.glb](error-map.glb).\n\n",
            file(path),
            top
        ));
        s.push_str(&table_markdown(&table));
        s.push_str(&chart(distances));
        if let Some(regions) = tables::region_table(v) {
            s.push_str("### Skin → reference per region\n\n");
            s.push_str(&table_markdown(&regions));
        }
    } else {
        s.push_str(&format!("{}\n\n", tables::SKIPPED_SURFACE));
    }
    s.push_str("## 2. Joint fits (the seed paper's Figures 8 and 9)\n\nThe child marker farthest from each centre, in the parent's reference pose and the joint's frame, with the fitted circle or sphere outline, and the histogram of its distance to the centre minus the mean.\n\n");
    for f in &figs.fits {
        s.push_str(&format!("### {}\n\n", f.title));
        s.push_str(&chart(f));
    }
    s.push_str("### Distance of every marker to its centre\n\n");
    s.push_str(&chart(&figs.radii));
    s.push_str(&table_markdown(&tables::marker_radius_table(v)));
    s.push_str("## 3. Joint centres and axes against the truth\n\n");
    if let (Some(joint_errors), Some(table)) = (&figs.joint_errors, tables::joint_table(v)) {
        s.push_str(&chart(joint_errors));
        s.push_str(&table_markdown(&table));
    } else {
        s.push_str(&format!("{}\n\n", tables::SKIPPED_TRUTH));
    }
    s.push_str("## 4. Dimensions\n\n");
    s.push_str(&table_markdown(&tables::dimension_table(v)));
    s.push_str("## 5. Link lengths\n\n");
    s.push_str(&table_markdown(&tables::link_length_table(v)));
    s.push_str("## 6. Runtime\n\n");
    s.push_str(RUNTIME_PLACEHOLDER);
    s.push_str("## 7. Warnings\n\n");
    if v.warnings.is_empty() {
        s.push_str("None.\n");
    } else {
        for w in &v.warnings {
            s.push_str(&format!("- {w}\n"));
        }
    }
    if !v.motions.is_empty() {
        s.push_str("\n## 8. Tracked motions against the truth\n\n");
        for m in &v.motions {
            s.push_str(&format!(
                "### {}\n\n`{}` against `truth_motion/{}.json`.\n\n",
                m.motion,
                m.file.display(),
                m.motion
            ));
            for t in tables::motion_tables(m) {
                s.push_str(&table_markdown(&t));
            }
        }
    }
    if !v.grasps.is_empty() {
        s.push_str("\n## 9. Grasps\n\n");
        for g in &v.grasps {
            s.push_str(&format!("### {} ({})\n\n", g.folder, g.grasp_type));
            for t in super::report_tables::grasp_tables(g) {
                s.push_str(&table_markdown(&t));
            }
        }
    }
    if !v.poses.is_empty() {
        s.push_str("\n## 10. Posed hands\n\n");
        s.push_str(&table_markdown(&super::report_tables::pose_table(&v.poses)));
    }
    s
}
