//! `report.html`: one self-contained page (inline CSS, every picture embedded as a base64
//! `data:` URI, no script, nothing fetched) that a designer or an ergonomics lab reads in any
//! browser, offline, or attaches to an email.

use super::charts::Figure;
use super::report_tables::{self as tables, Table};
use super::subject_validation::{ReportFigures, SubjectValidation};

/// Where the runtime table goes until the report's own time is known.
pub const RUNTIME_PLACEHOLDER: &str = "<!--ergohand:runtime-->";

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding (RFC 4648, section 4).
pub fn base64(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Decode standard base64 (RFC 4648, section 4; padding required); `None` on any other
/// character or a bad length.
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let t = text.as_bytes();
    if !t.len().is_multiple_of(4) {
        return None;
    }
    let val = |c: u8| ALPHABET.iter().position(|&a| a == c).map(|p| p as u32);
    let mut out = Vec::with_capacity(t.len() / 4 * 3);
    for (i, q) in t.chunks(4).enumerate() {
        let last = i + 1 == t.len() / 4;
        let pad = q.iter().rev().take_while(|&&c| c == b'=').count();
        if pad > 2 || (pad > 0 && !last) {
            return None;
        }
        let mut n = 0u32;
        for &c in &q[..4 - pad] {
            n = n << 6 | val(c)?;
        }
        n <<= 6 * pad as u32;
        let bytes = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
        out.extend_from_slice(&bytes[..3 - pad]);
    }
    Some(out)
}

/// A PNG as an `<img>` source.
pub fn png_data_uri(png: &[u8]) -> String {
    format!("data:image/png;base64,{}", base64(png))
}

/// Escape text for HTML element content and attribute values.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Check that a page needs nothing outside itself: every `<img>` source is a base64 `data:`
/// URI that decodes to a PNG (by its signature) or an SVG document, and no stylesheet, script
/// or frame is loaded from elsewhere. Returns the number of images, or what is wrong.
pub fn check_self_contained(html: &str) -> std::result::Result<usize, String> {
    let lower = html.to_ascii_lowercase();
    for bad in ["<link", "<script", "<iframe", "<object", "<embed", "url("] {
        if lower.contains(bad) {
            return Err(format!("the page loads something with {bad}"));
        }
    }
    let mut n = 0;
    let mut rest = html;
    while let Some(i) = rest.find("<img") {
        let tag_end = rest[i..].find('>').ok_or("an <img> tag is not closed")? + i;
        let tag = &rest[i..tag_end];
        let src = tag
            .split_once("src=\"")
            .and_then(|(_, s)| s.split_once('"'))
            .map(|(s, _)| s)
            .ok_or_else(|| format!("image {} has no src", n + 1))?;
        let (kind, data) = if let Some(d) = src.strip_prefix("data:image/png;base64,") {
            ("png", d)
        } else if let Some(d) = src.strip_prefix("data:image/svg+xml;base64,") {
            ("svg", d)
        } else {
            return Err(format!(
                "image {} is not an embedded PNG or SVG: {}",
                n + 1,
                &src[..src.len().min(60)]
            ));
        };
        let bytes =
            base64_decode(data).ok_or_else(|| format!("image {} is not valid base64", n + 1))?;
        let ok = match kind {
            "png" => bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.len() > 57,
            _ => std::str::from_utf8(&bytes).is_ok_and(|s| s.contains("<svg")),
        };
        if !ok {
            return Err(format!("image {} does not decode to a {kind}", n + 1));
        }
        n += 1;
        rest = &rest[tag_end..];
    }
    Ok(n)
}

const CSS: &str = r#"
:root{--ink:#1d2733;--muted:#5d6b7b;--line:#e2e6ec;--accent:#1f5ab4;--head:#14213d;--warn:#fff0d4;--warnink:#8a5300;--bg:#f4f6f9}
*{box-sizing:border-box}
body{margin:0;background:var(--bg);color:var(--ink);font:15px/1.55 "DejaVu Sans",-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif}
header.top{background:var(--head);color:#fff;padding:26px 0 22px}
header.top .in,main,footer{max-width:1300px;margin:0 auto;padding-left:32px;padding-right:32px}
header.top h1{margin:0;font-size:27px;font-weight:600;letter-spacing:.01em}
header.top p{margin:6px 0 0;color:#c5d0e2;font-size:14px}
nav{margin-top:14px;display:flex;flex-wrap:wrap;gap:6px}
nav a{color:#fff;text-decoration:none;font-size:13px;padding:4px 10px;border:1px solid #3b4c73;border-radius:999px}
nav a:hover{background:#2a3b63}
.cards{display:grid;grid-template-columns:repeat(auto-fit,minmax(190px,1fr));gap:12px;margin:22px 0 6px}
.card{background:#fff;border:1px solid var(--line);border-radius:10px;padding:13px 16px}
.card .l{font-size:11.5px;text-transform:uppercase;letter-spacing:.07em;color:var(--muted)}
.card .v{font-size:23px;font-weight:600;color:var(--accent);margin:2px 0}
.card .n{font-size:12.5px;color:var(--muted)}
section{background:#fff;border:1px solid var(--line);border-radius:12px;padding:20px 26px 16px;margin:20px 0}
h2{font-size:20px;margin:0 0 4px;font-weight:600}
h3{font-size:15.5px;margin:18px 0 6px;font-weight:600}
p.lead{color:var(--muted);margin:0 0 14px;max-width:980px}
figure{margin:10px 0 18px}
figure img{display:block;max-width:100%;height:auto;border:1px solid var(--line);border-radius:6px;background:#fff}
figcaption{font-size:13px;color:var(--muted);margin-top:6px;max-width:980px}
table{border-collapse:collapse;width:100%;font-size:13.5px;margin:6px 0 4px}
th{text-align:left;font-weight:600;border-bottom:2px solid var(--line);padding:6px 9px;background:#f8f9fb;white-space:nowrap}
td{padding:5px 9px;border-bottom:1px solid var(--line)}
th.num,td.num{text-align:right;font-variant-numeric:tabular-nums}
tbody tr:hover td{background:#f7f9fc}
tr.sum td{font-weight:600;background:#eef3fa;border-top:2px solid var(--line)}
td.flag{background:var(--warn);color:var(--warnink);font-weight:600}
p.note{font-size:12.5px;color:var(--muted);margin:4px 0 10px;max-width:980px}
.grid2{display:grid;grid-template-columns:repeat(auto-fit,minmax(520px,1fr));gap:8px 28px}
details{margin:8px 0}
details summary{cursor:pointer;color:var(--accent);font-size:14px}
ul.warn{margin:6px 0;padding-left:20px;font-size:13.5px}
ul.files{columns:3;font-size:13px;padding-left:18px}
a{color:var(--accent)}
code{font-size:12.5px;background:#f0f2f5;padding:1px 4px;border-radius:4px}
header.top code{background:#24345a;color:#e8eef9}
.scroll{overflow-x:auto}
footer{color:var(--muted);font-size:12.5px;padding-top:8px;padding-bottom:40px}
"#;

/// A whole page around `body`, with the report's style.
pub fn page(title: &str, header: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{CSS}</style>\n</head>\n<body>\n<header class=\"top\"><div class=\"in\">{header}</div></header>\n<main>\n{body}\n</main>\n<footer>Made by <code>ergohand</code> (Endo, Tada &amp; Mochimaru, Reconstructing individual hand models from motion capture data, J. Comput. Des. Eng. 2014). Every number on this page is measured by the toolkit from the files named; nothing is copied from elsewhere except the seed paper's figures, marked as such.</footer>\n</body>\n</html>\n",
        esc(title)
    )
}

/// A table as HTML.
pub fn table_html(t: &Table) -> String {
    let mut s = String::from("<table>\n<thead><tr>");
    for (k, h) in t.head.iter().enumerate() {
        let c = if t.numeric.get(k) == Some(&true) {
            " class=\"num\""
        } else {
            ""
        };
        s.push_str(&format!("<th{c}>{}</th>", esc(h)));
    }
    s.push_str("</tr></thead>\n<tbody>\n");
    let first_sum = t.rows.len().saturating_sub(t.summary_rows);
    for (r, row) in t.rows.iter().enumerate() {
        s.push_str(if r >= first_sum {
            "<tr class=\"sum\">"
        } else {
            "<tr>"
        });
        for (k, c) in row.iter().enumerate() {
            let mut classes = Vec::new();
            if t.numeric.get(k) == Some(&true) {
                classes.push("num");
            }
            if c.flag {
                classes.push("flag");
            }
            if classes.is_empty() {
                s.push_str(&format!("<td>{}</td>", esc(&c.text)));
            } else {
                s.push_str(&format!(
                    "<td class=\"{}\">{}</td>",
                    classes.join(" "),
                    esc(&c.text)
                ));
            }
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n");
    if !t.note.is_empty() {
        s.push_str(&format!("<p class=\"note\">{}</p>\n", esc(&t.note)));
    }
    s
}

fn figure(img_png: &[u8], alt: &str, caption: &str, links: &[(&str, String)]) -> String {
    let links: Vec<String> = links
        .iter()
        .map(|(label, href)| format!("<a href=\"{}\">{}</a>", esc(href), esc(label)))
        .collect();
    let files = if links.is_empty() {
        String::new()
    } else {
        format!(" Files: {}.", links.join(", "))
    };
    format!(
        "<figure><img src=\"{}\" alt=\"{}\" loading=\"eager\"><figcaption>{}{files}</figcaption></figure>\n",
        png_data_uri(img_png),
        esc(alt),
        esc(caption)
    )
}

fn name(p: &std::path::Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn chart(f: &Figure, caption: &str) -> String {
    figure(
        &f.png_bytes,
        &f.title,
        caption,
        &[("PNG", name(&f.png)), ("SVG", name(&f.svg))],
    )
}

/// The runtime table (filled in once the report's own time is measured).
pub fn runtime_html(v: &SubjectValidation) -> String {
    table_html(&tables::runtime_table(v))
}

/// The page of one subject.
/// The subject's report page; `report` is the folder it is written to (for relative links to
/// the other commands' outputs).
pub fn subject_html(
    v: &SubjectValidation,
    figs: &ReportFigures,
    report: &std::path::Path,
) -> String {
    let against = match (v.references.truth_json, v.references.reference_ply) {
        (true, true) => "the simulated subject's truth and its CT-like reference surface",
        (true, false) => "the simulated subject's truth and the caliper dimensions",
        (false, true) => "the CT-like reference surface and the caliper dimensions",
        (false, false) => "the caliper dimensions and the trials",
    };
    let header = format!(
        "<h1>Validation report · {}</h1><p>{} hand · skin, link model and dimensions of the reconstruction against {against}</p><nav>{}</nav>",
        esc(&v.subject),
        v.hand,
        [
            ("error-map", "Error map"),
            ("joint-fits", "Joint fits"),
            ("joint-centres", "Joint centres and axes"),
            ("dimensions", "Dimensions"),
            ("link-lengths", "Link lengths"),
            ("runtime", "Runtime"),
            ("warnings", "Warnings and files"),
        ]
        .iter()
        .map(|(id, t)| format!("<a href=\"#{id}\">{t}</a>"))
        .collect::<String>()
    );
    let mut b = String::new();
    b.push_str("<div class=\"cards\">");
    for (l, val, n) in tables::key_figures(v) {
        b.push_str(&format!(
            "<div class=\"card\"><div class=\"l\">{}</div><div class=\"v\">{}</div><div class=\"n\">{}</div></div>",
            esc(&l),
            esc(&val),
            esc(&n)
        ));
    }
    b.push_str("</div>\n");
    if let Some(r) = tables::references_sentence(v) {
        b.push_str(&format!(
            "<p class=\"note\" id=\"references\">{}</p>\n",
            esc(&r)
        ));
    }

    // 1. Error map.
    b.push_str("<section id=\"error-map\"><h2>1 · Skin against the CT-like reference</h2>");
    if let (Some((_, png)), Some(distances), Some(table), Some(top)) = (
        &figs.error_map,
        &figs.distances,
        tables::surface_table(v),
        v.colour_scale_top_mm,
    ) {
        b.push_str(&format!("<p class=\"lead\">Every vertex of the fitted skin (<code>skin.obj</code>) coloured by its distance to the reference surface (<code>reference.ply</code>, {}), as the seed paper's Figure 10(e). Yellow areas are where the reconstruction is furthest from the hand. The same colours are in <code>error-map.glb</code> for any glTF viewer, and in 3-D with its legend in <a href=\"view.html\">view.html</a>.</p>",
        if v.references.truth_json { "a simulated CT of the true hand" } else { "a CT-like scan of the hand" }
    ));
        b.push_str(&figure(
        png,
        "error map: dorsal, palmar, radial and ulnar views",
        &format!(
            "Views from the back of the hand, the palm, the thumb side and the little-finger side, all at one scale. Colour scale 0 to {:.1} mm (the 99th percentile rounded up; larger distances take the top colour).",
            top
        ),
        &[("PNG", "error-map.png".into()), ("GLB with vertex colours", "error-map.glb".into()), ("3-D page", "view.html".into())],
    ));
        b.push_str(&table_html(&table));
        b.push_str(&chart(
        distances,
        "Distribution of the distances in both directions: the share of each direction's points in each bin, side by side.",
    ));
        if let Some(regions) = tables::region_table(v) {
            b.push_str("<h3>Skin → reference per region</h3>");
            b.push_str(&table_html(&regions));
        }
    } else {
        b.push_str(&format!(
            "<p class=\"lead\">{}</p>",
            esc(tables::SKIPPED_SURFACE)
        ));
    }
    b.push_str("</section>\n");

    // 2. Joint fits.
    b.push_str("<section id=\"joint-fits\"><h2>2 · Joint fits</h2>");
    b.push_str("<p class=\"lead\">The seed paper's Figure 8: for each joint, the trajectory of the child marker farthest from the joint centre (red), expressed in the parent link's reference pose (equation 1) and in the joint's frame, with the fitted circle (1-DOF joints, in the plane of motion) or the sphere's outline (3-DOF joints) in blue and the centre as a cross; on the right the histogram of the marker's distance to the centre minus its mean, the fitted radius. A thin band means the model's rigid-joint assumption holds.</p>");
    for f in &figs.fits {
        b.push_str(&format!("<h3>{}</h3>", esc(&f.title)));
        b.push_str(&chart(f, "Left and middle: two projections (mm, about the centre). Right: histogram of distance errors."));
    }
    b.push_str("<h3>Distance of every marker to its centre</h3>");
    b.push_str(&chart(
        &figs.radii,
        "The seed paper's Figure 9: mean distance of each child marker to its joint centre with ± SD bars (top), and the SD alone (bottom), which is the error the fits leave.",
    ));
    b.push_str("<details><summary>Table of every marker's radius</summary>");
    b.push_str(&table_html(&tables::marker_radius_table(v)));
    b.push_str("</details></section>\n");

    // 3. Joint centres and axes.
    b.push_str(
        "<section id=\"joint-centres\"><h2>3 · Joint centres and axes against the truth</h2>",
    );
    if let (Some(joint_errors), Some(table)) = (&figs.joint_errors, tables::joint_table(v)) {
        b.push_str("<p class=\"lead\">Distance between each estimated joint centre (<code>link_model.json</code>) and the true one (<code>truth.json</code>), and the angle between estimated and true hinge axes.</p>");
        b.push_str(&chart(
            joint_errors,
            "Left: distance between estimated and true centre per joint. Right: angle between estimated and true axis per hinge joint.",
        ));
        b.push_str(&table_html(&table));
    } else {
        b.push_str(&format!(
            "<p class=\"lead\">{}</p>",
            esc(tables::SKIPPED_TRUTH)
        ));
    }
    b.push_str("</section>\n");

    // 4. Dimensions.
    b.push_str("<section id=\"dimensions\"><h2>4 · Dimensions</h2>");
    b.push_str(if v.dimensions.vs_true_mm.is_some() {
        "<p class=\"lead\">The 22 caliper dimensions measured on the fitted skin between the template's vertex pairs, against the values given in <code>subject.toml</code> and the error-free values of the truth.</p>"
    } else {
        "<p class=\"lead\">The caliper dimensions measured on the fitted skin between the template's vertex pairs, against the values given in <code>subject.toml</code>.</p>"
    });
    b.push_str(&table_html(&tables::dimension_table(v)));
    b.push_str("</section>\n");

    // 5. Link lengths.
    b.push_str("<section id=\"link-lengths\"><h2>5 · Link lengths</h2>");
    b.push_str("<p class=\"lead\">Distance between consecutive joint centres of each digit.</p>");
    b.push_str(&table_html(&tables::link_length_table(v)));
    b.push_str("</section>\n");

    // 6. Runtime.
    b.push_str("<section id=\"runtime\"><h2>6 · Runtime</h2>");
    b.push_str("<p class=\"lead\">Wall-clock time per stage on this machine.</p>");
    b.push_str(RUNTIME_PLACEHOLDER);
    b.push_str("</section>\n");

    // 7. Warnings and files.
    b.push_str("<section id=\"warnings\"><h2>7 · Warnings and files</h2>");
    if v.warnings.is_empty() {
        b.push_str("<p>The link model raised no warning.</p>");
    } else {
        b.push_str("<p>The link model's warnings:</p><ul class=\"warn\">");
        for w in &v.warnings {
            b.push_str(&format!("<li>{}</li>", esc(w)));
        }
        b.push_str("</ul>");
    }
    b.push_str("<p>Written beside this page:</p><ul class=\"files\">");
    for f in &v.files {
        b.push_str(&format!("<li><a href=\"{0}\">{0}</a></li>", esc(f)));
    }
    b.push_str("</ul></section>\n");

    // 8. Tracked motions, when any was found.
    if !v.motions.is_empty() {
        b.push_str("<section id=\"motions\"><h2>8 · Tracked motions against the truth</h2>");
        for m in &v.motions {
            b.push_str(&format!(
                "<h3>{}</h3><p class=\"lead\"><code>{}</code> against <code>truth_motion/{}.json</code>: joint centres and fingertips per solved frame, marker residuals, lost frames, and the hold's contact areas of the tracked skin against the true skin.</p>",
                esc(&m.motion),
                esc(&m.file.display().to_string()),
                esc(&m.motion)
            ));
            for t in tables::motion_tables(m) {
                b.push_str(&table_html(&t));
            }
        }
        b.push_str("</section>\n");
    }
    grasp_and_pose_sections(v, report, &mut b);
    page(&format!("ergohand validation · {}", v.subject), &header, &b)
}

/// 9 and 10: the grasps given to `validate` and the posed hands of the model folder, as their
/// commands wrote them; `report` is where the page is written (links are relative to it).
fn grasp_and_pose_sections(v: &SubjectValidation, report: &std::path::Path, b: &mut String) {
    use super::grasp_pose_sections::relative_link;
    use super::report_tables::{grasp_tables, pose_table};
    if !v.grasps.is_empty() {
        b.push_str("<section id=\"grasps\"><h2>9 · Grasps</h2><p class=\"lead\">The hand closed on a part by <code>ergohand grasp</code>: force closure, the Ferrari-Canny epsilon, the hold test in rapier (gravity from six directions), the contact area per link, and the contact picture seen from the side that carries the contacts (red: touching or inside).</p>");
        for g in &v.grasps {
            let folder = std::path::Path::new(&g.folder);
            let name = folder
                .file_name()
                .map_or_else(|| g.folder.clone(), |n| n.to_string_lossy().into_owned());
            b.push_str(&format!("<h3>{} ({})</h3>", esc(&name), esc(&g.grasp_type)));
            for t in grasp_tables(g) {
                b.push_str(&table_html(&t));
            }
            let link = relative_link(report, folder);
            let mut links = vec![("grasp.json", format!("{link}/grasp.json"))];
            if g.view_page {
                links.push(("3-D page", format!("{link}/view.html")));
            }
            if let Some(png) = &g.contact_png {
                b.push_str(&figure(
                    png,
                    "the grasp's contacts",
                    "The posed hand from the side that carries its contacts, the part not drawn.",
                    &links,
                ));
            } else {
                for (label, href) in links {
                    b.push_str(&format!(
                        "<p><a href=\"{}\">{}</a></p>",
                        esc(&href),
                        esc(label)
                    ));
                }
            }
        }
        b.push_str("</section>\n");
    }
    if !v.poses.is_empty() {
        b.push_str("<section id=\"poses\"><h2>10 · Posed hands</h2>");
        b.push_str(&table_html(&pose_table(&v.poses)));
        b.push_str("</section>\n");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the `base64` crate (an independent implementation) on every length mod 3, and
    /// our decoder inverts it.
    #[test]
    fn base64_agrees_with_the_reference_crate() {
        for n in 0..40usize {
            let bytes: Vec<u8> = (0..n).map(|i| (i * 37 + 11) as u8).collect();
            let ours = base64(&bytes);
            assert_eq!(ours, ::base64::encode(&bytes), "{n}");
            assert_eq!(base64_decode(&ours).unwrap(), bytes);
        }
        assert!(base64_decode("abc").is_none());
        assert!(base64_decode("ab=c").is_none());
        assert!(base64_decode("a*==").is_none());
    }

    /// The checker accepts embedded PNG and SVG images and refuses a file reference, a
    /// broken payload and a stylesheet from elsewhere.
    #[test]
    fn self_contained_check_finds_missing_and_broken_images() {
        let png = crate::render::Image::new(3, 2, [1, 2, 3]).to_png().unwrap();
        let svg = base64(b"<svg xmlns=\"http://www.w3.org/2000/svg\"></svg>");
        let good = format!(
            "<p><img src=\"{}\" alt=\"a\"><img alt=\"b\" src=\"data:image/svg+xml;base64,{svg}\"></p>",
            png_data_uri(&png)
        );
        assert_eq!(check_self_contained(&good), Ok(2));
        for bad in [
            "<img src=\"error-map.png\">".to_string(),
            format!(
                "<img src=\"data:image/png;base64,{}\">",
                base64(b"not a png")
            ),
            "<img src=\"data:image/png;base64,@@@@\">".to_string(),
            "<img alt=\"x\">".to_string(),
            format!("<link rel=\"stylesheet\" href=\"x.css\">{good}"),
        ] {
            assert!(check_self_contained(&bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn tables_escape_and_mark_numbers() {
        let t = Table {
            head: vec!["a<b".into(), "n".into()],
            rows: vec![vec![
                super::super::report_tables::Cell {
                    text: "x & y".into(),
                    flag: false,
                },
                super::super::report_tables::Cell {
                    text: "1.5".into(),
                    flag: true,
                },
            ]],
            numeric: vec![false, true],
            summary_rows: 0,
            note: String::new(),
        };
        let h = table_html(&t);
        assert!(h.contains("<th>a&lt;b</th>") && h.contains("<td>x &amp; y</td>"));
        assert!(h.contains("<td class=\"num flag\">1.5</td>"));
    }
}
