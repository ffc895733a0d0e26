//! `report.html` of a tracked trial: a self-contained page (pictures as data URIs) with the
//! trial's summary read from its `motion.json` (frames, rate, solved, held joints, rejected
//! markers, the part's source, warnings), a table of the contacts per link and the pictures
//! of the contact map and the charts against time.

use super::report_html::{esc, page, png_data_uri, table_html};
use super::report_tables::{Cell, Table};
use crate::anatomy::Link;
use crate::track::{ranges, MotionFile};

/// One link's contacts over a trial.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkContacts {
    /// The link.
    pub link: Link,
    /// Frames with contact on this link.
    pub frames: usize,
    /// Mean contact area over those frames, mm².
    pub mean_area_mm2: f64,
    /// Largest contact area in one frame, mm².
    pub max_area_mm2: f64,
    /// Deepest penetration over the trial, mm.
    pub max_depth_mm: f64,
}

/// Per link with any contact (in link order), from the contact records of `file`.
pub fn link_contacts(file: &MotionFile) -> Vec<LinkContacts> {
    let mut by: Vec<LinkContacts> = Link::ALL
        .iter()
        .map(|&link| LinkContacts {
            link,
            frames: 0,
            mean_area_mm2: 0.0,
            max_area_mm2: 0.0,
            max_depth_mm: 0.0,
        })
        .collect();
    for c in &file.contacts {
        let Some(l) = Link::from_name(&c.link) else {
            continue;
        };
        let e = &mut by[l.index()];
        // One record per link and frame (motion.json's contract), so records count frames.
        e.frames += 1;
        e.mean_area_mm2 += c.area_mm2;
        e.max_area_mm2 = e.max_area_mm2.max(c.area_mm2);
        e.max_depth_mm = e.max_depth_mm.max(c.depth_mm);
    }
    by.into_iter()
        .filter(|e| e.frames > 0)
        .map(|mut e| {
            e.mean_area_mm2 /= e.frames as f64;
            e
        })
        .collect()
}

fn cell(text: impl Into<String>) -> Cell {
    Cell {
        text: text.into(),
        flag: false,
    }
}

/// The table of [`link_contacts`], with the whole hand's frames in contact below.
pub fn link_table(file: &MotionFile) -> Table {
    let rows = link_contacts(file);
    let mut t = Table {
        head: [
            "link",
            "frames in contact",
            "share of tracked frames",
            "mean area (mm²)",
            "max area (mm²)",
            "max depth (mm)",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect(),
        rows: Vec::new(),
        numeric: vec![false, true, true, true, true, true],
        summary_rows: 0,
        note: "Mean area: over the frames in which the link touches the part. Depth: how far \
               the skin reaches inside the part's surface (tracked digits are placed by their \
               markers, not stopped at the surface)."
            .into(),
    };
    let tracked = tracked_frames(file).max(1) as f64;
    for r in &rows {
        t.rows.push(vec![
            cell(r.link.name()),
            cell(r.frames.to_string()),
            cell(format!("{:.0} %", 100.0 * r.frames as f64 / tracked)),
            cell(format!("{:.0}", r.mean_area_mm2)),
            cell(format!("{:.0}", r.max_area_mm2)),
            cell(format!("{:.2}", r.max_depth_mm)),
        ]);
    }
    let any: std::collections::BTreeSet<usize> = file.contacts.iter().map(|c| c.frame).collect();
    let mut per_frame = vec![0.0f64; file.frames];
    for c in &file.contacts {
        if let Some(a) = per_frame.get_mut(c.frame) {
            *a += c.area_mm2;
        }
    }
    let total: f64 = any.iter().map(|&f| per_frame[f]).sum();
    t.rows.push(vec![
        cell("whole hand"),
        cell(any.len().to_string()),
        cell(format!("{:.0} %", 100.0 * any.len() as f64 / tracked)),
        cell(format!("{:.0}", total / any.len().max(1) as f64)),
        cell(format!(
            "{:.0}",
            per_frame.iter().copied().fold(0.0, f64::max)
        )),
        cell(format!(
            "{:.2}",
            rows.iter().map(|r| r.max_depth_mm).fold(0.0, f64::max)
        )),
    ]);
    t.summary_rows = 1;
    t
}

/// Frames whose contacts are known: solved, with the part's pose known (0 without a part).
pub fn tracked_frames(file: &MotionFile) -> usize {
    let Some(p) = &file.part else { return 0 };
    (0..file.frames)
        .filter(|f| {
            !file.unsolved_frames.contains(f) && p.pose.get(*f).is_some_and(Option::is_some)
        })
        .count()
}

/// A picture of the page: PNG bytes, its file name, a caption.
#[derive(Clone, Debug)]
pub struct PagePicture {
    pub png: Vec<u8>,
    pub file: String,
    pub caption: String,
}

/// The whole page: `title` (e.g. the subject and the motion), `sources` (what was read, one
/// line each), the summary of `file`, its contacts per link and `pictures` in order.
pub fn motion_report_html(
    title: &str,
    sources: &[String],
    file: &MotionFile,
    pictures: &[PagePicture],
) -> String {
    let solved = file.frames - file.unsolved_frames.len();
    let header = format!(
        "<h1>{}</h1><p>Tracked trial: {} frames at {} Hz ({:.2} s), replayed with the \
         subject's reconstructed hand.</p>",
        esc(title),
        file.frames,
        file.rate,
        file.frames as f64 / file.rate.max(1e-9)
    );
    let mut body = String::new();
    let contact_frames: std::collections::BTreeSet<usize> =
        file.contacts.iter().map(|c| c.frame).collect();
    let card = |l: &str, v: String, n: &str| {
        format!(
            "<div class=\"card\"><div class=\"l\">{}</div><div class=\"v\">{}</div><div \
             class=\"n\">{}</div></div>",
            esc(l),
            esc(&v),
            esc(n)
        )
    };
    body.push_str("<div class=\"cards\">");
    body.push_str(&card(
        "frames",
        file.frames.to_string(),
        &format!("{} Hz", file.rate),
    ));
    body.push_str(&card(
        "solved",
        format!("{solved}"),
        &format!("{} unsolved", file.unsolved_frames.len()),
    ));
    body.push_str(&card(
        "tracked with the part",
        tracked_frames(file).to_string(),
        "frames whose contacts are known",
    ));
    body.push_str(&card(
        "frames in contact",
        contact_frames.len().to_string(),
        "any link touching the part",
    ));
    body.push_str("</div>\n");

    // Summary.
    let mut rows: Vec<(String, String)> = vec![
        ("frames".into(), file.frames.to_string()),
        ("rate".into(), format!("{} Hz", file.rate)),
        ("solved".into(), format!("{solved} of {}", file.frames)),
        (
            "unsolved frames".into(),
            if file.unsolved_frames.is_empty() {
                "none".into()
            } else {
                ranges(&file.unsolved_frames)
            },
        ),
    ];
    let held: Vec<String> = file
        .joints
        .iter()
        .filter(|(_, t)| !t.held_frames.is_empty())
        .map(|(j, t)| format!("{j} ({} frames)", t.held_frames.len()))
        .collect();
    rows.push((
        "joints held".into(),
        if held.is_empty() {
            "none".into()
        } else {
            held.join(", ")
        },
    ));
    let rejected: Vec<String> = file
        .rejected_frames
        .iter()
        .map(|(m, f)| format!("{m} ({} frames)", f.len()))
        .collect();
    rows.push((
        "markers rejected".into(),
        if rejected.is_empty() {
            "none".into()
        } else {
            rejected.join(", ")
        },
    ));
    rows.push((
        "part".into(),
        match &file.part {
            None => "none (no scene given)".into(),
            Some(p) => {
                let unknown = p.pose.iter().filter(|p| p.is_none()).count();
                let mut s = format!("pose from the {}", p.source);
                if unknown > 0 {
                    s.push_str(&format!("; unknown in {unknown} frames"));
                }
                if !p.filled_frames.is_empty() {
                    s.push_str(&format!(
                        "; interpolated across gaps in {} frames",
                        p.filled_frames.len()
                    ));
                }
                s
            }
        },
    ));
    body.push_str("<section id=\"summary\"><h2>Summary</h2>\n<table><tbody>\n");
    for (k, v) in &rows {
        body.push_str(&format!(
            "<tr><th>{}</th><td>{}</td></tr>\n",
            esc(k),
            esc(v)
        ));
    }
    body.push_str("</tbody></table>\n");
    if !sources.is_empty() {
        body.push_str("<p class=\"note\">Read: ");
        body.push_str(
            &sources
                .iter()
                .map(|s| format!("<code>{}</code>", esc(s)))
                .collect::<Vec<_>>()
                .join(", "),
        );
        body.push_str("</p>\n");
    }
    body.push_str(&format!("<h3>Warnings ({})</h3>\n", file.warnings.len()));
    if file.warnings.is_empty() {
        body.push_str("<p class=\"note\">None.</p>\n");
    } else {
        body.push_str("<ul class=\"warn\">\n");
        for w in &file.warnings {
            body.push_str(&format!("<li>{}</li>\n", esc(w)));
        }
        body.push_str("</ul>\n");
    }
    body.push_str("</section>\n");

    body.push_str("<section id=\"contacts\"><h2>Contacts per link</h2>\n");
    if file.part.is_none() {
        body.push_str("<p class=\"lead\">No part was given (<code>--scene</code>), so there are no contacts.</p>\n");
    } else if file.contacts.is_empty() {
        body.push_str("<p class=\"lead\">No link touched the part in any tracked frame.</p>\n");
    } else {
        body.push_str(&table_html(&link_table(file)));
    }
    body.push_str("</section>\n");

    if !pictures.is_empty() {
        body.push_str("<section id=\"pictures\"><h2>Pictures</h2>\n");
        for p in pictures {
            body.push_str(&format!(
                "<figure><img src=\"{}\" alt=\"{}\" loading=\"eager\"><figcaption>{} File: \
                 <a href=\"{}\">{}</a>.</figcaption></figure>\n",
                png_data_uri(&p.png),
                esc(&p.file),
                esc(&p.caption),
                esc(&p.file),
                esc(&p.file)
            ));
        }
        body.push_str("</section>\n");
    }
    page(&format!("ergohand track: {title}"), &header, &body)
}

#[cfg(test)]
mod tests {
    use super::super::motion_plots::tests::sample;
    use super::super::report_html::check_self_contained;
    use super::*;

    #[test]
    fn links_count_frames_and_average_over_their_contact_frames() {
        let m = sample();
        let rows = link_contacts(&m);
        let links: Vec<Link> = rows.iter().map(|r| r.link).collect();
        assert_eq!(links, vec![Link::Palm, Link::TDist, Link::IDist]);
        let i = &rows[2];
        // Frames 20-39: areas 40 + f, mean 40 + 29.5; depths 0.1 to 2.0.
        assert_eq!(i.frames, 20);
        assert!((i.mean_area_mm2 - 69.5).abs() < 1e-9);
        assert!((i.max_area_mm2 - 79.0).abs() < 1e-9);
        assert!((i.max_depth_mm - 2.0).abs() < 1e-9);
        // Tracked: 50 frames less 3 unsolved and 1 without the part.
        assert_eq!(tracked_frames(&m), 46);
        let t = link_table(&m);
        let whole = t.rows.last().unwrap();
        assert_eq!(whole[1].text, "20");
        // 100 + 300 + (40 + f) per frame, mean over frames 20-39.
        assert_eq!(whole[3].text, format!("{:.0}", 400.0 + 69.5));
    }

    #[test]
    fn page_is_self_contained_and_escapes() {
        let m = sample();
        let png = crate::render::Image::new(4, 3, [1, 2, 3]).to_png().unwrap();
        let pics = vec![
            PagePicture {
                png: png.clone(),
                file: "angles.png".into(),
                caption: "a".into(),
            },
            PagePicture {
                png,
                file: "contact_area.png".into(),
                caption: "b".into(),
            },
        ];
        let html = motion_report_html("s1 <x>", &["trials/a.c3d".into()], &m, &pics);
        assert_eq!(check_self_contained(&html), Ok(2));
        assert!(html.contains("a &lt;warning&gt; &amp; more"));
        assert!(html.contains("s1 &lt;x&gt;") && !html.contains("<x>"));
        for s in [
            "I_DIST",
            "T_DIST",
            "PALM",
            "M_NAIL (3 frames)",
            "L_DIP (2 frames)",
            "10-12",
        ] {
            assert!(html.contains(s), "{s}");
        }
    }
}
