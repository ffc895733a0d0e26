//! `reports/index.html` of `ergohand validate --suite`: every suite subject in one table (key
//! figures and a small error map, linked to the subject's own report), the suite's summary per
//! preset, and the repeatability of the link lengths over repeated sessions of one hand.

use super::report_html::{esc, page, png_data_uri, table_html};
use super::report_tables::{link_medians, signed, Cell, Table};
use super::subject_validation::SubjectValidation;
use crate::synth::SynthOptions;
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

/// One subject of the suite.
pub struct SuiteRow<'a> {
    /// Its name in `suite.toml`.
    pub name: String,
    /// How it was simulated.
    pub opts: SynthOptions,
    /// Held out of tuning (only scored).
    pub held_out: bool,
    /// What `validate` measured.
    pub validation: &'a SubjectValidation,
    /// Its `report.html`.
    pub report: PathBuf,
}

/// Repeated sessions of one simulated hand: subjects whose options differ only in `repeat`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RepeatGroup {
    /// The subjects, in suite order.
    pub subjects: Vec<String>,
    /// Link name -> (mean, sample SD, true length) over the sessions, mm.
    pub links: BTreeMap<String, (f64, f64, f64)>,
}

/// The groups of [`RepeatGroup`] with at least two sessions.
pub(crate) fn repeat_groups(rows: &[SuiteRow]) -> Vec<RepeatGroup> {
    let mut groups: Vec<(SynthOptions, Vec<&SuiteRow>)> = Vec::new();
    for r in rows {
        let key = SynthOptions {
            repeat: 0,
            ..r.opts.clone()
        };
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.1.push(r),
            None => groups.push((key, vec![r])),
        }
    }
    groups
        .into_iter()
        .filter(|g| g.1.len() >= 2)
        .map(|(_, members)| {
            let mut links = BTreeMap::new();
            // Suite subjects carry truth.json (`validate --suite` checks it); a member without
            // contributes no lengths.
            fn lengths<'a>(m: &SuiteRow<'a>) -> Option<&'a BTreeMap<String, (f64, f64)>> {
                m.validation.link.as_ref().map(|l| &l.link_lengths)
            }
            let first = members.iter().find_map(|m| lengths(m));
            for (k, &(_, truth)) in first.into_iter().flatten() {
                let v: Vec<f64> = members
                    .iter()
                    .filter_map(|m| lengths(m)?.get(k).map(|x| x.0))
                    .collect();
                let n = v.len() as f64;
                let mean = v.iter().sum::<f64>() / n;
                let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                links.insert(k.clone(), (mean, sd, truth));
            }
            RepeatGroup {
                subjects: members.iter().map(|m| m.name.clone()).collect(),
                links,
            }
        })
        .collect()
}

/// `to` relative to the folder `from` (both made absolute against the current folder), with
/// forward slashes, for links between reports.
pub(crate) fn relative_link(from: &Path, to: &Path) -> String {
    let abs = |p: &Path| -> Vec<String> {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir().unwrap_or_default().join(p)
        };
        let mut out: Vec<String> = Vec::new();
        for c in p.components() {
            match c {
                Component::ParentDir => {
                    out.pop();
                }
                Component::Normal(s) => out.push(s.to_string_lossy().into_owned()),
                _ => {}
            }
        }
        out
    };
    let (a, b) = (abs(from), abs(to));
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".to_string(); a.len() - common];
    parts.extend(b[common..].iter().cloned());
    parts.join("/")
}

/// Mean and max of `skin → reference` (NaN without `reference.ply`: never in the suite).
fn surf(v: &SubjectValidation) -> (f64, f64) {
    v.surface
        .as_ref()
        .map_or((f64::NAN, f64::NAN), |s| (s.mean_mm, s.max_mm))
}

/// Mean and max of `reference → skin` over the hand distal of the wrist (the whole reference
/// when the regions are not known; NaN without `reference.ply`).
fn surf_reverse(v: &SubjectValidation) -> (f64, f64) {
    let distal = v
        .surface_regions
        .as_ref()
        .and_then(|r| r.reverse_hand_distal_of_wrist.as_ref())
        .map(|s| (s.mean_mm, s.max_mm));
    distal.unwrap_or_else(|| {
        v.surface_reverse
            .as_ref()
            .map_or((f64::NAN, f64::NAN), |s| (s.mean_mm, s.max_mm))
    })
}

fn f2(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.2}")
    } else {
        "–".into()
    }
}

/// Per body (`groups`: body name and its subjects' validations; bodies are never pooled): the
/// mean over the subjects of each region's mean skin-to-reference distance, and of the hand
/// distal of the wrist's mean, with the largest of its maxima.
pub fn region_summary_table(groups: &[(String, Vec<&SubjectValidation>)]) -> Table {
    use super::surface_regions::Region;
    let mut head: Vec<String> = vec!["body".into(), "subjects".into()];
    head.extend(Region::ALL.iter().map(|r| format!("{} (mm)", r.name())));
    head.push("hand distal of the wrist, mean / max (mm)".into());
    let n_cols = head.len();
    let mut t = Table {
        head,
        rows: Vec::new(),
        numeric: (0..n_cols).map(|i| i > 0).collect(),
        summary_rows: 0,
        note: "Skin → reference per region of the template hand (src/validate/surface_regions.rs): per body, the mean over its subjects of each region's mean; the last column also gives the largest of the subjects' maxima.".into(),
    };
    let cell = |text: String| Cell { text, flag: false };
    for (body, g) in groups {
        let regs: Vec<&super::surface_regions::SurfaceRegions> = g
            .iter()
            .filter_map(|v| v.surface_regions.as_ref())
            .collect();
        let k = regs.len() as f64;
        let mut row = vec![cell(body.clone()), cell(regs.len().to_string())];
        for r in Region::ALL {
            let means: Vec<f64> = regs
                .iter()
                .filter_map(|s| s.get(r))
                .filter(|e| e.vertices > 0)
                .map(|e| e.mean_mm)
                .collect();
            row.push(cell(f2(means.iter().sum::<f64>() / means.len() as f64)));
        }
        row.push(cell(format!(
            "{} / {}",
            f2(regs
                .iter()
                .map(|s| s.hand_distal_of_wrist.mean_mm)
                .sum::<f64>()
                / k),
            f2(regs
                .iter()
                .map(|s| s.hand_distal_of_wrist.max_mm)
                .fold(f64::NAN, f64::max))
        )));
        t.rows.push(row);
    }
    t
}

/// The index page; `dir` is where it is written (links are relative to it).
pub fn suite_index_html(rows: &[SuiteRow], dir: &Path) -> String {
    let mut b = String::new();
    // Summary cards, one set per body: the bodies are never pooled.
    let mut cards = vec![(
        "subjects".to_string(),
        rows.len().to_string(),
        format!(
            "simulated hands with ground truth, {} held out of tuning",
            rows.iter().filter(|r| r.held_out).count()
        ),
    )];
    for body in crate::synth::Body::ALL {
        let g: Vec<&SuiteRow> = rows.iter().filter(|r| r.opts.body == body).collect();
        if g.is_empty() {
            continue;
        }
        let n = g.len() as f64;
        let mean_of = |f: &dyn Fn(&SubjectValidation) -> f64| {
            g.iter().map(|r| f(r.validation)).sum::<f64>() / n
        };
        let max_of = |f: &dyn Fn(&SubjectValidation) -> f64| {
            g.iter().map(|r| f(r.validation)).fold(0.0, f64::max)
        };
        let bn = body.name();
        cards.push((
            format!("skin → reference · {bn} body"),
            format!("{:.2} mm", mean_of(&|v| surf(v).0)),
            format!(
                "mean of the {} subjects' means; worst max {:.2} mm",
                g.len(),
                max_of(&|v| surf(v).1)
            ),
        ));
        cards.push((
            format!("centres 3-DOF / 1-DOF · {bn} body"),
            format!(
                "{:.2} / {:.2} mm",
                mean_of(&|v| link_medians(v).0),
                mean_of(&|v| link_medians(v).1)
            ),
            format!(
                "mean of the subjects' medians; axes {:.2}°",
                mean_of(&|v| link_medians(v).2)
            ),
        ));
    }
    let n = rows.len().max(1) as f64;
    cards.push((
        "reconstruct".to_string(),
        format!(
            "{:.1} s",
            rows.iter()
                .map(|r| r.validation.reconstruct_timings_s.values().sum::<f64>())
                .sum::<f64>()
                / n
        ),
        "mean time per subject".into(),
    ));
    b.push_str("<div class=\"cards\">");
    for (l, v, note) in cards {
        b.push_str(&format!(
            "<div class=\"card\"><div class=\"l\">{}</div><div class=\"v\">{}</div><div class=\"n\">{}</div></div>",
            esc(&l),
            esc(&v),
            esc(&note)
        ));
    }
    b.push_str("</div>\n");

    b.push_str("<section id=\"subjects\"><h2>Every subject</h2><p class=\"lead\">Each row links to the subject's full report (written under <code>validation/subjects/</code>, which is not committed: run the suite to get them). The picture is the subject's error map (dorsal and palmar views), coloured from 0 to the scale top in the next column.</p>");
    b.push_str("<div class=\"scroll\"><table class=\"suite\"><thead><tr><th>subject</th><th>error map</th><th class=\"num\">scale top (mm)</th><th class=\"num\">skin → ref. mean / max (mm)</th><th class=\"num\">ref. → skin mean / max, hand distal of the wrist (mm)</th><th class=\"num\">median centre error 3-DOF / 1-DOF (mm)</th><th class=\"num\">median axis error (°)</th><th class=\"num\">dimensions skin − given (mm)</th><th class=\"num\">time reconstruct / validate (s)</th></tr></thead><tbody>\n");
    for r in rows {
        let v = r.validation;
        let (c3, c1, ax) = link_medians(v);
        let link = relative_link(dir, &r.report);
        let rec: f64 = v.reconstruct_timings_s.values().sum();
        let val: f64 = v.validate_timings_s.iter().map(|x| x.1).sum();
        b.push_str(&format!(
            "<tr><td><a href=\"{}\"><b>{}</b></a><br><span class=\"n\">{} body · {}{} · {} hand · {} posture{}</span></td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{} / {}</td><td class=\"num\">{} / {}</td><td class=\"num\">{} / {}</td><td class=\"num\">{}</td><td class=\"num\">{} ± {:.3}</td><td class=\"num\">{:.1} / {:.1}</td></tr>\n",
            esc(&link),
            esc(&r.name),
            r.opts.body.name(),
            r.opts.preset.name(),
            if r.held_out { " · held out" } else { "" },
            r.opts.hand,
            format!("{:?}", r.opts.posture).to_lowercase(),
            if r.opts.repeat > 0 { format!(" · session {}", r.opts.repeat + 1) } else { String::new() },
            v.thumbnail_png.as_ref().map_or_else(
                || "–".to_string(),
                |png| format!(
                    "<img class=\"thumb\" src=\"{}\" alt=\"error map of {}\">",
                    png_data_uri(png),
                    esc(&r.name)
                )
            ),
            v.colour_scale_top_mm
                .map_or_else(|| "–".to_string(), |t| format!("{t:.1}")),
            f2(surf(v).0),
            f2(surf(v).1),
            f2(surf_reverse(v).0),
            f2(surf_reverse(v).1),
            f2(c3),
            f2(c1),
            f2(ax),
            signed(v.dimensions.mean_vs_given_mm, 3),
            v.dimensions.sd_vs_given_mm,
            rec,
            val
        ));
    }
    b.push_str("</tbody></table></div></section>\n");

    // Per body and preset: the template body can always be reached by the template, the
    // procedural one cannot, so their figures are never pooled.
    let mut groups: Vec<(&str, &str)> = Vec::new();
    for r in rows {
        let key = (r.opts.body.name(), r.opts.preset.name());
        if !groups.contains(&key) {
            groups.push(key);
        }
    }
    let mut t = Table {
        head: [
            "body · preset",
            "subjects",
            "skin → ref. mean (mm)",
            "skin → ref. max (mm)",
            "3-DOF centre (mm)",
            "1-DOF centre (mm)",
            "axis (°)",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect(),
        rows: Vec::new(),
        numeric: vec![false, true, true, true, true, true, true],
        summary_rows: 1,
        note: "Means over the group's subjects of each subject's mean (surface) or median (joints); max is the largest of the subjects' maxima. The template body is the template deformed by its own skeleton (the template can always reach it); the procedural body is independent of it. The seed paper: 1.63 mm mean, 15.13 mm max on a real hand.".into(),
    };
    let group_row = |label: &str, g: &[&SuiteRow]| -> Vec<Cell> {
        let k = g.len().max(1) as f64;
        let m = |f: &dyn Fn(&SubjectValidation) -> f64| {
            g.iter().map(|r| f(r.validation)).sum::<f64>() / k
        };
        vec![
            Cell {
                text: label.to_string(),
                flag: false,
            },
            Cell {
                text: g.len().to_string(),
                flag: false,
            },
            Cell {
                text: f2(m(&|v| surf(v).0)),
                flag: false,
            },
            Cell {
                text: f2(g.iter().map(|r| surf(r.validation).1).fold(0.0, f64::max)),
                flag: false,
            },
            Cell {
                text: f2(m(&|v| link_medians(v).0)),
                flag: false,
            },
            Cell {
                text: f2(m(&|v| link_medians(v).1)),
                flag: false,
            },
            Cell {
                text: f2(m(&|v| link_medians(v).2)),
                flag: false,
            },
        ]
    };
    for (body, preset) in &groups {
        let g: Vec<&SuiteRow> = rows
            .iter()
            .filter(|r| r.opts.body.name() == *body && r.opts.preset.name() == *preset)
            .collect();
        t.rows.push(group_row(&format!("{body} · {preset}"), &g));
    }
    for body in crate::synth::Body::ALL {
        let g: Vec<&SuiteRow> = rows.iter().filter(|r| r.opts.body == body).collect();
        if !g.is_empty() {
            t.rows
                .push(group_row(&format!("{} · all", body.name()), &g));
        }
    }
    t.summary_rows = crate::synth::Body::ALL
        .iter()
        .filter(|b| rows.iter().any(|r| r.opts.body == **b))
        .count();
    b.push_str("<section id=\"summary\"><h2>Summary per body and preset</h2>");
    b.push_str(&table_html(&t));
    b.push_str("</section>\n");

    // Per body and region.
    let groups: Vec<(String, Vec<&SubjectValidation>)> = crate::synth::Body::ALL
        .iter()
        .map(|b| {
            let g = rows
                .iter()
                .filter(|r| r.opts.body == *b)
                .map(|r| r.validation)
                .collect();
            (b.name().to_string(), g)
        })
        .filter(|g: &(String, Vec<&SubjectValidation>)| !g.1.is_empty())
        .collect();
    b.push_str("<section id=\"regions\"><h2>Skin → reference per region</h2>");
    b.push_str(&table_html(&region_summary_table(&groups)));
    b.push_str("</section>\n");

    // Repeatability.
    b.push_str("<section id=\"repeatability\"><h2>Repeatability of the link lengths</h2>");
    let groups = repeat_groups(rows);
    if groups.is_empty() {
        b.push_str("<p>The suite has no repeated sessions of one hand (subjects whose options differ only in <code>repeat</code>).</p>");
    }
    for g in &groups {
        b.push_str(&format!(
            "<p class=\"lead\">{} sessions of one simulated hand ({}): new plates, noise, soft-tissue slide and gaps each time. The seed paper, the calibration motions of a real index finger recorded five times: MCP–PIP 45.54 ± 0.52 mm, PIP–DIP 24.60 ± 0.92 mm.</p>",
            g.subjects.len(),
            esc(&g.subjects.join(", "))
        ));
        let mut t = Table {
            head: ["link", "mean", "SD", "true", "mean − true (mm)"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            rows: Vec::new(),
            numeric: vec![false, true, true, true, true],
            summary_rows: 0,
            note: "SD over the sessions (n − 1).".into(),
        };
        // Digit order (thumb to little), proximal first.
        let mut links: Vec<(&String, &(f64, f64, f64))> = g.links.iter().collect();
        links.sort_by_key(|(k, _)| {
            k.split('-')
                .next()
                .and_then(crate::anatomy::Joint::from_name)
                .map_or(usize::MAX, |j| j.index())
        });
        for (k, (m, sd, tr)) in links {
            t.rows.push(
                [
                    k.replace('-', " – "),
                    f2(*m),
                    f2(*sd),
                    f2(*tr),
                    signed(m - tr, 2),
                ]
                .into_iter()
                .map(|text| Cell { text, flag: false })
                .collect(),
            );
        }
        b.push_str(&table_html(&t));
    }
    b.push_str("</section>\n");
    let header = "<h1>Validation suite</h1><p>Every simulated subject of <code>validation/suite.toml</code>, reconstructed by <code>ergohand reconstruct</code> and measured by <code>ergohand validate</code> against its truth. Made by <code>ergohand validate --suite validation/</code>.</p><nav><a href=\"#subjects\">Subjects</a><a href=\"#summary\">Summary</a><a href=\"#repeatability\">Repeatability</a><a href=\"link-accuracy.md\">link-accuracy.md</a></nav>";
    page("ergohand validation suite", header, &b).replace(
        "</style>",
        "img.thumb{width:190px;height:auto;border:0}table.suite td{vertical-align:middle}table.suite th{white-space:normal;vertical-align:bottom}.n{color:var(--muted);font-size:12px}</style>",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped suite holds repeated sessions of one hand, which `repeat_groups` joins by
    /// their options without `repeat`.
    #[test]
    fn shipped_suite_has_a_repeatability_group() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/suite.toml");
        let suite = crate::synth::suite::read_suite(&path).unwrap();
        let key = |o: &SynthOptions| SynthOptions {
            repeat: 0,
            ..o.clone()
        };
        let biggest = suite
            .iter()
            .map(|(_, o)| suite.iter().filter(|(_, p)| key(p) == key(o)).count())
            .max()
            .unwrap();
        assert!(biggest >= 5, "{biggest}");
        let sessions: Vec<u32> = suite
            .iter()
            .filter(|(n, _)| n.starts_with("typical-r1"))
            .map(|(_, o)| o.repeat)
            .collect();
        assert_eq!(sessions, vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn relative_links_between_folders() {
        assert_eq!(
            relative_link(
                Path::new("/a/reports"),
                Path::new("/a/validation/subjects/x/out/report/report.html")
            ),
            "../validation/subjects/x/out/report/report.html"
        );
        assert_eq!(
            relative_link(Path::new("/a/b/../r"), Path::new("/a/r/x.html")),
            "x.html"
        );
    }
}
