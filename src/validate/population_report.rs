//! The page of a scene run over many hands (`population.json` of `ergohand grasp --models`):
//! the share that holds, overall and by size third, why the others fail, a chart of epsilon
//! against hand length, every hand's row and its contact picture. `population.html` is
//! self-contained (pictures as data URIs); `population.md` has the same tables.

use super::report_html::{esc, page, png_data_uri, table_html};
use super::report_md::table_markdown;
use super::report_tables::{Cell, Table};
use crate::grasp::population::PopulationSummary;

fn share(n: usize, of: usize) -> String {
    if of == 0 {
        "-".into()
    } else {
        format!("{n}/{of} ({:.0} %)", 100.0 * n as f64 / of as f64)
    }
}

/// The share that holds by size third, with the failures by reason below.
pub fn size_table(s: &PopulationSummary) -> Table {
    let mut t = Table {
        head: ["hands", "hand length (mm)", "hold"]
            .iter()
            .map(|h| h.to_string())
            .collect(),
        rows: Vec::new(),
        numeric: vec![false, true, true],
        summary_rows: 1,
        note: format!(
            "{} by hand length (the link model's wrist centre to the middle finger's distal \
             end). Hold: the part stays within 2 mm under gravity from six directions in rapier.",
            match s.by_size.len() {
                3 => "Thirds of the hands",
                2 => "The hands in two halves",
                _ => "All hands",
            }
        ),
    };
    for g in &s.by_size {
        t.rows.push(vec![
            Cell::new(format!("{} ({})", g.label, g.hands)),
            Cell::new(format!(
                "{:.0}-{:.0}",
                g.hand_length_mm[0], g.hand_length_mm[1]
            )),
            Cell::flagged(share(g.holding, g.hands), g.holding < g.hands),
        ]);
    }
    t.rows.push(vec![
        Cell::new(format!("all ({})", s.hands)),
        Cell::new(""),
        Cell::flagged(share(s.holding, s.hands), s.holding < s.hands),
    ]);
    t
}

/// One row per hand, in the order given.
pub fn hand_table(s: &PopulationSummary) -> Table {
    let digits = ["thumb", "index", "middle", "ring", "little", "palm"];
    let mut head: Vec<String> = [
        "hand",
        "length (mm)",
        "MCP span (mm)",
        "holds",
        "force closure",
        "epsilon",
        "worst slide (mm)",
        "contact (mm²)",
    ]
    .iter()
    .map(|h| h.to_string())
    .collect();
    head.extend(digits.iter().map(|d| format!("{d} (mm²)")));
    // Only a scene whose given approach slides (`grasp.slide_mm`) moves the hands.
    let slid = s.outcomes.iter().any(|o| o.approach_slide_mm.is_some());
    if slid {
        head.push("moved along the palm (mm)".into());
    }
    head.push("wrap".into());
    head.push("at a limit".into());
    head.push("why not held".into());
    let mut numeric = vec![false, true, true, false, false, true, true, true];
    numeric.extend([true; 6]);
    if slid {
        numeric.push(true);
    }
    numeric.extend([false, false, false]);
    let mut t = Table {
        head,
        rows: Vec::new(),
        numeric,
        summary_rows: 0,
        note: "Contact areas per digit on the squeezed grasp; at a limit: joints that end within \
               2° of their anatomical limit (the grasp asked all they can give)."
            .into(),
    };
    for o in &s.outcomes {
        let mut row = vec![
            Cell::new(&o.name),
            Cell::new(format!("{:.0}", o.hand_length_mm)),
            Cell::new(format!("{:.0}", o.mcp_span_mm)),
            Cell::flagged(if o.holds { "yes" } else { "no" }, !o.holds),
            Cell::flagged(if o.force_closure { "yes" } else { "no" }, !o.force_closure),
            Cell::new(format!("{:.3}", o.epsilon)),
            Cell::new(if o.worst_displacement_mm.is_finite() {
                format!("{:.2}", o.worst_displacement_mm)
            } else {
                "-".into()
            }),
            Cell::new(format!("{:.0}", o.contact_area_mm2)),
        ];
        for d in digits {
            let a = o.contact_area_by_finger_mm2.get(d).copied().unwrap_or(0.0);
            row.push(Cell::new(format!("{a:.0}")));
        }
        if slid {
            row.push(Cell::new(match o.approach_slide_mm {
                Some(d) => format!("{d:+.0}"),
                None => "-".into(),
            }));
        }
        row.push(Cell::new(o.envelope.describe()));
        row.push(Cell::new(o.at_limit.join(", ")));
        let why = match (&o.failure, &o.error) {
            (_, Some(e)) => e.clone(),
            (Some(_), None) => o.failure_reason().unwrap_or_default(),
            (None, None) => String::new(),
        };
        row.push(Cell::flagged(why, o.failure.is_some()));
        t.rows.push(row);
    }
    t
}

/// Epsilon against hand length, one dot per hand (filled: holds; open: does not), as SVG.
pub fn epsilon_chart_svg(s: &PopulationSummary) -> String {
    // m: the margins; the left one (left) also holds the y tick labels beside the axis title.
    let (w, h, m, left) = (640.0, 320.0, 48.0, 72.0);
    let xs: Vec<f64> = s.outcomes.iter().map(|o| o.hand_length_mm).collect();
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = if lo.is_finite() && hi > lo + 1.0 {
        (lo - 2.0, hi + 2.0)
    } else {
        (lo - 10.0, lo + 10.0)
    };
    let top = s
        .outcomes
        .iter()
        .map(|o| o.epsilon)
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.1;
    let x = |v: f64| left + (v - lo) / (hi - lo) * (w - left - 0.5 * m);
    let y = |v: f64| h - m - v / top * (h - 1.6 * m);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">\
<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\
<line x1=\"{left}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"#333\"/><line x1=\"{left}\" y1=\"{t}\" x2=\"{left}\" y2=\"{b}\" stroke=\"#333\"/>\
<text x=\"{cx}\" y=\"{ly}\" text-anchor=\"middle\">hand length (mm)</text>\
<text x=\"14\" y=\"{cy}\" text-anchor=\"middle\" transform=\"rotate(-90 14 {cy})\">epsilon</text>",
        b = h - m,
        r = w - 0.5 * m,
        t = 0.6 * m,
        cx = (w + left - 0.5 * m) / 2.0,
        ly = h - 12.0,
        cy = h / 2.0,
    );
    for k in 0..=4 {
        let v = lo + (hi - lo) * k as f64 / 4.0;
        svg.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{v:.0}</text>",
            x(v),
            h - m + 16.0
        ));
        let e = top * k as f64 / 4.0;
        svg.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{e:.3}</text>",
            left - 4.0,
            y(e) + 4.0
        ));
    }
    for o in &s.outcomes {
        let (fill, stroke) = if o.holds {
            ("#2a7f3f", "#2a7f3f")
        } else {
            ("none", "#c0392b")
        };
        svg.push_str(&format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"5\" fill=\"{fill}\" stroke=\"{stroke}\" stroke-width=\"2\"><title>{}</title></circle>",
            x(o.hand_length_mm),
            y(o.epsilon),
            esc(&o.name)
        ));
    }
    svg.push_str("</svg>");
    svg
}

/// The cards at the top: hold share, force closure share, the commonest failure.
fn lead(s: &PopulationSummary) -> String {
    let failures: Vec<String> = s
        .failures
        .iter()
        .map(|(why, n)| format!("{n} {why}"))
        .collect();
    format!(
        "{} of {} hands hold the part ({}); {} are in force closure; {} wrap it with the palm and three fingers; {} end with a joint at its limit.{}",
        s.holding,
        s.hands,
        s.grasp_type,
        s.force_closure,
        s.wrapping,
        s.at_limit,
        if failures.is_empty() {
            String::new()
        } else {
            format!(" Not held: {}.", failures.join(", "))
        }
    )
}

/// A folder name as a relative URL: every byte outside the unreserved set percent-encoded,
/// so a name with spaces, `#` or `?` still links to its folder.
fn url_path(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                (b as char).to_string()
            }
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// `population.html`: `pictures` are each hand's contact picture (PNG bytes), in the order of
/// the outcomes (`None`: none written, e.g. no grasp found).
pub fn population_html(s: &PopulationSummary, pictures: &[Option<Vec<u8>>]) -> String {
    let svg = epsilon_chart_svg(s);
    let mut body = format!(
        "<section><h2>Who holds it</h2><p class=\"lead\">{}</p>{}\
<figure><img src=\"data:image/svg+xml;base64,{}\" alt=\"epsilon against hand length\"><figcaption>Epsilon (Ferrari-Canny) against hand length; filled: holds, open: does not.</figcaption></figure></section>\n\
<section><h2>Every hand</h2>{}</section>\n<section><h2>Contacts</h2><p class=\"lead\">Where the hands touch the part, in 3-D: <a href=\"view.html\">view.html</a> (the part coloured by the share of hands whose skin touches each place). Each hand on the part below, contact colours as in <code>grasp.glb</code> (red: touching or inside), and in 3-D in its own page.</p>\n",
        esc(&lead(s)),
        table_html(&size_table(s)),
        super::report_html::base64(svg.as_bytes()),
        table_html(&hand_table(s)),
    );
    for (o, png) in s.outcomes.iter().zip(pictures) {
        if let Some(png) = png {
            body.push_str(&format!(
                "<figure><img src=\"{}\" alt=\"{}\" loading=\"eager\" style=\"max-width:400px\"><figcaption>{}: {} (<a href=\"{}/view.html\">3-D</a>)</figcaption></figure>\n",
                png_data_uri(png),
                esc(&o.name),
                esc(&o.name),
                if o.holds { "holds" } else { "not held" },
                esc(&url_path(&o.name))
            ));
        }
    }
    body.push_str("</section>\n");
    page(
        &format!("ergohand population: {}", s.scene),
        &format!(
            "<h1>{} hands on {}</h1><p>{} grasp</p>",
            s.hands,
            esc(&s.scene),
            esc(&s.grasp_type)
        ),
        &body,
    )
}

/// `population.md`: the same tables; each hand's picture is its folder's `contact_map.png`.
pub fn population_markdown(s: &PopulationSummary) -> String {
    format!(
        "# {} hands on {}\n\n{}\n\n{}\n{}\n",
        s.hands,
        s.scene,
        lead(s),
        table_markdown(&size_table(s)),
        table_markdown(&hand_table(s))
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grasp::population::{summarise, Failure, HandOutcome};

    fn hand(name: &str, length: f64, holds: bool) -> HandOutcome {
        HandOutcome {
            name: name.into(),
            model: name.into(),
            hand_length_mm: length,
            mcp_span_mm: 70.0,
            holds,
            force_closure: true,
            epsilon: 0.02,
            worst_displacement_mm: if holds { 0.1 } else { 2.3 },
            contact_area_mm2: 300.0,
            contact_area_by_finger_mm2: [("thumb".to_string(), 120.0)].into_iter().collect(),
            envelope: Default::default(),
            at_limit: vec!["T_IP flexion at -20°".into()],
            approach_slide_mm: None,
            failure: (!holds).then_some(Failure::Slips),
            squeezed_toward: None,
            error: None,
            time_s: 1.0,
        }
    }

    /// The page needs nothing outside itself, shows one dot per hand and every picture given,
    /// and names each hand with its failure; the Markdown has the same rows.
    #[test]
    fn the_page_is_self_contained_and_names_every_hand() {
        let s = summarise(
            "pen.toml",
            "tripod",
            vec![
                hand("s1", 170.0, true),
                hand("s2", 185.0, false),
                hand("s3", 195.0, true),
            ],
        );
        let png = crate::render::Image::new(4, 4, [255, 255, 255])
            .to_png()
            .unwrap();
        let html = population_html(&s, &[Some(png.clone()), None, Some(png)]);
        // Two pictures and the chart.
        assert_eq!(
            super::super::report_html::check_self_contained(&html),
            Ok(3)
        );
        assert_eq!(epsilon_chart_svg(&s).matches("<circle").count(), 3);
        assert!(html.contains("2 of 3 hands hold the part"));
        // The population's 3-D page, and each pictured hand's own.
        assert!(html.contains("<a href=\"view.html\">"));
        assert!(html.contains("<a href=\"s1/view.html\">") && html.contains("s3/view.html"));
        assert!(!html.contains("s2/view.html"), "no grasp, no page");
        assert_eq!(url_path("a b#?/é"), "a%20b%23%3F%2F%C3%A9");
        let md = population_markdown(&s);
        for name in ["s1", "s2", "s3"] {
            assert!(html.contains(name) && md.contains(name), "{name}");
        }
        assert!(md.contains("slips in the hold test") && md.contains("T_IP flexion at -20°"));
        // The size groups' note names how the hands were split.
        assert!(size_table(&s).note.starts_with("Thirds"));
        let two = summarise(
            "pen.toml",
            "tripod",
            vec![hand("a", 170.0, true), hand("b", 180.0, true)],
        );
        assert!(size_table(&two).note.starts_with("The hands in two halves"));
        // The thumb's area in its column.
        assert!(md.contains("| 120 |"), "{md}");
        // No hand moved: no column for it.
        assert!(!md.contains("moved along the palm"));
    }

    /// A scene whose approach slides gets a column with each hand's move along its palm, a
    /// hand without one (no grasp found) a dash.
    #[test]
    fn hands_that_slid_along_the_palm_say_how_far() {
        let mut a = hand("a", 170.0, true);
        a.approach_slide_mm = Some(10.0);
        let mut b = hand("b", 180.0, true);
        b.approach_slide_mm = Some(-5.0);
        let c = hand("c", 190.0, false);
        let s = summarise("bottle.toml", "power", vec![a, b, c]);
        let t = hand_table(&s);
        let col = t
            .head
            .iter()
            .position(|h| h == "moved along the palm (mm)")
            .unwrap();
        assert_eq!(t.numeric.len(), t.head.len());
        let cells: Vec<&str> = t.rows.iter().map(|r| r[col].text.as_str()).collect();
        assert_eq!(cells, ["+10", "-5", "-"]);
        assert!(t.rows.iter().all(|r| r.len() == t.head.len()));
    }
}
