//! `view.html`: a self-contained 3-D page of an output (the hand, the part, the contact map)
//! that opens from `file://` with no network: the GLBs are embedded as base64, the viewer
//! (three.js with its glTF loader and orbit controls, bundled once into
//! `assets/viewer/viewer.bundle.js`) is inlined, and the page's data (facts, tables, legend,
//! the hand's frame for the view presets) is JSON in the page. The contract between this writer
//! and the viewer is `assets/viewer/README.md`.

use super::report_html::{base64, esc};
use crate::anatomy::{Joint, Link};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::{joint_limits_deg, Skeleton};
use crate::template::LinkWeights;
use nalgebra::Isometry3;
use serde::Serialize;

/// The page template (placeholders `{{TITLE}}`, `{{DATA_JSON}}`, `{{GLB_SCRIPTS}}`,
/// `{{BUNDLE}}`).
const TEMPLATE: &str = include_str!("../../assets/viewer/view-template.html");

/// The viewer: three.js r187 (MIT, `assets/viewer/LICENSE-three.txt`) and the page's code.
const BUNDLE: &str = include_str!("../../assets/viewer/viewer.bundle.js");

/// One GLB of the page.
#[derive(Clone, Debug)]
pub struct ViewGlb {
    /// What it shows (the readout names it).
    pub name: String,
    /// `scene` (hand and part in one), `hand` or `part` (the whole GLB is the part).
    pub role: &'static str,
    /// The GLB's bytes (metres, as glTF).
    pub bytes: Vec<u8>,
    /// A per-vertex float attribute of its meshes that a click reads out (`None`: none).
    pub value: Option<ViewValue>,
}

/// A custom glTF vertex attribute (FLOAT SCALAR, name with a leading `_`) that the page reads
/// out at a clicked point, interpolated over the hit triangle.
#[derive(Clone, Debug, Serialize)]
pub struct ViewValue {
    /// The attribute's glTF name, e.g. `_DISTANCE_MM`.
    pub attribute: String,
    /// What it is, e.g. `distance to the part`.
    pub label: String,
    /// Its unit, e.g. `mm`.
    pub unit: String,
}

/// A colour legend: named swatches, a viridis ramp from `min` to `max`, and what lies beyond.
#[derive(Clone, Debug, Serialize)]
pub struct Legend {
    pub title: String,
    pub unit: String,
    pub entries: Vec<Swatch>,
    pub gradient: Gradient,
    pub beyond: Swatch,
}

/// One colour of a legend, `#rrggbb`.
#[derive(Clone, Debug, Serialize)]
pub struct Swatch {
    pub colour: String,
    pub label: String,
}

impl Swatch {
    /// A swatch of an 8-bit colour.
    pub fn rgb(c: [u8; 3], label: impl Into<String>) -> Swatch {
        Swatch {
            colour: format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]),
            label: label.into(),
        }
    }
}

/// A colour ramp of a legend (only `viridis`: the toolkit's one ramp).
#[derive(Clone, Debug, Serialize)]
pub struct Gradient {
    pub colormap: &'static str,
    pub min: f64,
    pub max: f64,
}

/// A table of the page's side panel.
#[derive(Clone, Debug, Serialize)]
pub struct ViewTable {
    pub title: String,
    pub columns: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

/// The hand's anatomical directions at the wrist, for the view presets (dorsal, palmar,
/// radial, ulnar), in the GLBs' frame and millimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewFrame {
    pub origin: Point,
    pub dorsal: Vec3,
    pub radial: Vec3,
    pub distal: Vec3,
}

/// A skinned hand that the page poses itself, with one slider per joint angle within the
/// anatomical limits ([`joint_limits_deg`]): the page first shows `shown` (the geometry the
/// command wrote) and, once a slider moves, the rest skin posed by the toolkit's own
/// forward kinematics ([`crate::skeleton::forward_kinematics::link_transforms`]) and
/// dual-quaternion skinning ([`crate::pose::SkinBinding::dual_quaternion`]), ported to the page
/// (`assets/viewer/src/viewer.js`, `rig.js`; `validation/tools/check_view.sh --rig` checks that
/// the two agree).
#[derive(Clone, Debug)]
pub struct ViewRig {
    /// The skin in the reference posture, mm.
    pub rest: TriMesh,
    /// Per vertex of `rest`, its `(link, weight)` pairs in the order the toolkit blends them.
    pub weights: LinkWeights,
    /// The link model: joint centres and frames in the reference posture.
    pub skeleton: Skeleton,
    /// The forearm's rigid motion from the reference posture.
    pub root: Isometry3<f64>,
    /// The angles `shown` was posed with, degrees, in [`Joint::ALL`] order.
    pub angles_deg: [[f64; 3]; 16],
    /// What the command wrote, mm, one point per vertex of `rest`.
    pub shown: Vec<Point>,
    /// What `shown` is (how it was posed).
    pub shown_label: String,
    /// What the sliders show.
    pub live_label: String,
}

/// Everything a page shows.
#[derive(Clone, Debug)]
pub struct ViewPage {
    pub title: String,
    /// `grasp`, `pose`, `validate`, `population` or `track`.
    pub kind: &'static str,
    pub glbs: Vec<ViewGlb>,
    /// Node names in the GLBs that are the part (hide and see-through controls).
    pub part_nodes: Vec<String>,
    pub legend: Option<Legend>,
    /// Label and value, in order.
    pub facts: Vec<(String, String)>,
    pub tables: Vec<ViewTable>,
    pub frame: Option<ViewFrame>,
    /// The first view: `dorsal`, `palmar`, `radial` or `ulnar` (`None`: a three-quarter view
    /// from the dorsal-radial side).
    pub view: Option<&'static str>,
    /// The part's opacity at first, 0-1 (`None`: opaque).
    pub part_opacity: Option<f64>,
    /// A hand the page poses with joint sliders.
    pub rig: Option<ViewRig>,
}

#[derive(Serialize)]
struct Data<'a> {
    title: &'a str,
    kind: &'a str,
    glb_units: &'static str,
    meshes: Vec<MeshEntry<'a>>,
    part_nodes: &'a [String],
    #[serde(skip_serializing_if = "Option::is_none")]
    legend: Option<&'a Legend>,
    facts: Vec<[&'a str; 2]>,
    tables: &'a [ViewTable],
    #[serde(skip_serializing_if = "Option::is_none")]
    frame: Option<FrameEntry>,
    #[serde(skip_serializing_if = "Option::is_none")]
    view: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    part_opacity: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rig: Option<RigEntry<'a>>,
}

/// The rig's JSON part; its arrays are in the binary element `bin` (little endian, each
/// array at `[byte offset, element count]`).
#[derive(Serialize)]
struct RigEntry<'a> {
    bin: &'static str,
    units: &'static str,
    vertices: usize,
    /// `f32` xyz per vertex, the reference posture.
    rest: [usize; 2],
    /// `f32` xyz per vertex, the written geometry.
    shown: [usize; 2],
    /// `u32` three per triangle.
    faces: [usize; 2],
    /// `u32`, vertices + 1: vertex `i`'s weights are entries `offsets[i]..offsets[i + 1]`.
    offsets: [usize; 2],
    /// `f32` per entry.
    weights: [usize; 2],
    /// `u8` per entry: the link.
    links: [usize; 2],
    link_names: Vec<&'static str>,
    joints: Vec<RigJoint>,
    /// The forearm's motion: unit quaternion `[w, x, y, z]` and translation, mm.
    root: RigRoot,
    shown_label: &'a str,
    live_label: &'a str,
}

#[derive(Serialize)]
struct RigRoot {
    rotation: [f64; 4],
    translation: [f64; 3],
}

/// One joint of the rig: its rotation is the product over its DOFs of rotations by the angle
/// about `axes[k]` (the frame's axes with the sign that makes a positive angle the anatomical
/// motion), applied about `centre`, between `parent` and `child` links.
#[derive(Serialize)]
struct RigJoint {
    name: &'static str,
    parent: usize,
    child: usize,
    centre: [f64; 3],
    axes: Vec<[f64; 3]>,
    dof_names: Vec<&'static str>,
    limits_deg: Vec<[f64; 2]>,
    deg: Vec<f64>,
}

/// The rig's JSON and its binary arrays.
fn rig_entry(rig: &ViewRig) -> (RigEntry<'_>, Vec<u8>) {
    let mut bin = Vec::new();
    let push_f32 = |bin: &mut Vec<u8>, values: &mut dyn Iterator<Item = f64>| {
        let start = bin.len();
        let mut n = 0;
        for v in values {
            bin.extend_from_slice(&(v as f32).to_le_bytes());
            n += 1;
        }
        [start, n]
    };
    let xyz = |pts: &[Point]| pts.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
    let rest = push_f32(&mut bin, &mut xyz(&rig.rest.vertices).into_iter());
    let shown = push_f32(&mut bin, &mut xyz(&rig.shown).into_iter());
    let push_u32 = |bin: &mut Vec<u8>, values: &[u32]| {
        let start = bin.len();
        for v in values {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        [start, values.len()]
    };
    let faces: Vec<u32> = rig.rest.faces.iter().flatten().map(|&i| i as u32).collect();
    let faces = push_u32(&mut bin, &faces);
    let mut offsets = vec![0u32];
    for w in &rig.weights {
        offsets.push(offsets[offsets.len() - 1] + w.len() as u32);
    }
    let offsets = push_u32(&mut bin, &offsets);
    let weights = push_f32(&mut bin, &mut rig.weights.iter().flatten().map(|&(_, w)| w));
    let links = [bin.len(), weights[1]];
    bin.extend(rig.weights.iter().flatten().map(|&(l, _)| l as u8));
    let sk = &rig.skeleton;
    let joints = Joint::ALL
        .iter()
        .map(|&j| {
            let (jf, s, dof) = (sk.joint(j), sk.signs(j), j.dof());
            let axes = [jf.x(), jf.y(), jf.z()];
            let limits = joint_limits_deg(j);
            RigJoint {
                name: j.name(),
                parent: j.parent_link().index(),
                child: j.child_link().index(),
                centre: sk.centre(j).coords.into(),
                axes: (0..dof).map(|k| (axes[k] * s[k]).into()).collect(),
                dof_names: ["flexion", "abduction", "axial"][..dof].to_vec(),
                limits_deg: limits[..dof].to_vec(),
                deg: rig.angles_deg[j.index()][..dof].to_vec(),
            }
        })
        .collect();
    let q = rig.root.rotation.quaternion();
    let entry = RigEntry {
        bin: "ergohand-bin-0",
        units: "mm",
        vertices: rig.rest.vertices.len(),
        rest,
        shown,
        faces,
        offsets,
        weights,
        links,
        link_names: Link::ALL.iter().map(|l| l.name()).collect(),
        joints,
        root: RigRoot {
            rotation: [q.w, q.i, q.j, q.k],
            translation: rig.root.translation.vector.into(),
        },
        shown_label: &rig.shown_label,
        live_label: &rig.live_label,
    };
    (entry, bin)
}

#[derive(Serialize)]
struct MeshEntry<'a> {
    glb: String,
    role: &'a str,
    name: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    value: Option<&'a ViewValue>,
}

#[derive(Serialize)]
struct FrameEntry {
    origin: [f64; 3],
    dorsal: [f64; 3],
    radial: [f64; 3],
    distal: [f64; 3],
}

/// The page's HTML.
pub fn view_html(page: &ViewPage) -> String {
    let rig = page.rig.as_ref().map(rig_entry);
    let rig_bin = rig.as_ref().map(|(_, bin)| base64(bin));
    let to_m = |p: &Point| [p.x / 1000.0, p.y / 1000.0, p.z / 1000.0];
    let dir = |v: &Vec3| {
        let u = v.normalize();
        [u.x, u.y, u.z]
    };
    let data = Data {
        title: &page.title,
        kind: page.kind,
        glb_units: "m",
        meshes: page
            .glbs
            .iter()
            .enumerate()
            .map(|(i, g)| MeshEntry {
                glb: format!("ergohand-glb-{i}"),
                role: g.role,
                name: &g.name,
                value: g.value.as_ref(),
            })
            .collect(),
        part_nodes: &page.part_nodes,
        legend: page.legend.as_ref(),
        facts: page
            .facts
            .iter()
            .map(|(k, v)| [k.as_str(), v.as_str()])
            .collect(),
        tables: &page.tables,
        frame: page.frame.map(|f| FrameEntry {
            origin: to_m(&f.origin),
            dorsal: dir(&f.dorsal),
            radial: dir(&f.radial),
            distal: dir(&f.distal),
        }),
        view: page.view,
        part_opacity: page.part_opacity,
        rig: rig.map(|(entry, _)| entry),
    };
    // Every `<` escaped: no text of the data can end or reopen a script element.
    let json = serde_json::to_string(&data)
        .expect("serialisable")
        .replace('<', "\\u003c");
    let glbs: String = page
        .glbs
        .iter()
        .enumerate()
        .map(|(i, g)| {
            format!(
                "<script id=\"ergohand-glb-{i}\" type=\"application/octet-stream\">{}</script>\n",
                base64(&g.bytes)
            )
        })
        .chain(rig_bin.map(|b| {
            format!(
                "<script id=\"ergohand-bin-0\" type=\"application/octet-stream\">{b}</script>\n"
            )
        }))
        .collect();
    let title = esc(&page.title);
    fill(TEMPLATE, |name| match name {
        "TITLE" => Some(&title),
        "DATA_JSON" => Some(&json),
        "GLB_SCRIPTS" => Some(&glbs),
        "BUNDLE" => Some(BUNDLE),
        _ => None,
    })
}

/// `template` with each `{{NAME}}` replaced by `value(NAME)` in one pass (inserted text is not
/// scanned again); a placeholder with no value stays as it is.
fn fill<'a>(template: &str, value: impl Fn(&str) -> Option<&'a str>) -> String {
    let mut out = String::with_capacity(template.len());
    let mut rest = template;
    while let Some(at) = rest.find("{{") {
        out.push_str(&rest[..at]);
        let after = &rest[at + 2..];
        match after
            .find("}}")
            .and_then(|end| Some((end, value(&after[..end])?)))
        {
            Some((end, v)) => {
                out.push_str(v);
                rest = &after[end + 2..];
            }
            None => {
                out.push_str("{{");
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_is_one_pass_and_keeps_unknown_placeholders() {
        let out = fill("a{{X}}b{{Y}}c{{", |n| match n {
            "X" => Some("{{Y}}"),
            _ => None,
        });
        assert_eq!(out, "a{{Y}}b{{Y}}c{{");
    }

    #[test]
    fn the_page_embeds_everything_and_no_data_can_close_its_script() {
        let page = ViewPage {
            title: "a </script><!--<script> & {{BUNDLE}}".into(),
            kind: "grasp",
            glbs: vec![ViewGlb {
                name: "hand".into(),
                role: "scene",
                bytes: b"glTF....".to_vec(),
                value: Some(ViewValue {
                    attribute: "_ERROR_MM".into(),
                    label: "error".into(),
                    unit: "mm".into(),
                }),
            }],
            part_nodes: vec!["part".into()],
            legend: None,
            facts: vec![("x".into(), "</script>".into())],
            tables: vec![],
            frame: Some(ViewFrame {
                origin: Point::new(1000.0, 0.0, 0.0),
                dorsal: Vec3::new(0.0, 2.0, 0.0),
                radial: Vec3::x(),
                distal: Vec3::z(),
            }),
            view: Some("palmar"),
            part_opacity: None,
            rig: None,
        };
        let html = view_html(&page);
        // The data element holds no `<` at all, and parses back to the same strings.
        let start = html.find("type=\"application/json\">").unwrap() + 24;
        let end = start + html[start..].find("</script>").unwrap();
        let json = &html[start..end];
        assert!(!json.contains('<'));
        let v: serde_json::Value = serde_json::from_str(json).unwrap();
        assert_eq!(v["title"], page.title);
        assert_eq!(v["facts"][0][1], "</script>");
        assert_eq!(v["frame"]["origin"][0], 1.0, "metres, as the GLBs");
        assert_eq!(v["frame"]["dorsal"][1], 1.0, "a unit vector");
        assert_eq!(v["view"], "palmar");
        assert_eq!(v["meshes"][0]["value"]["attribute"], "_ERROR_MM");
        assert!(v.get("part_opacity").is_none());
        assert!(html.contains(
            "<script id=\"ergohand-glb-0\" type=\"application/octet-stream\">Z2xURi4uLi4=</script>"
        ));
        // The bundle once, the title escaped, nothing left to fill.
        assert_eq!(html.matches(BUNDLE).count(), 1);
        assert!(html.contains("a &lt;/script&gt;&lt;!--&lt;script&gt; &amp; {{BUNDLE}}"));
        for p in ["{{DATA_JSON}}", "{{GLB_SCRIPTS}}", "{{TITLE}}"] {
            assert!(!html.contains(p), "{p}");
        }
    }
}
