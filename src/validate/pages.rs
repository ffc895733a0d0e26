//! The 3-D pages (`view.html`, [`super::view_page`]) of the outputs other than a single grasp:
//! a validation's skin error map, a tracked trial and a scene run over many hands. Each page
//! shows what its command wrote (its GLBs byte for byte, its figures as they are in its JSON):
//! a page reads outputs, it measures nothing.

use super::subject_validation::SubjectValidation;
use super::view_page::{
    Gradient, Legend, Swatch, ViewFrame, ViewGlb, ViewPage, ViewTable, ViewValue,
};
use crate::render::viridis;

/// `%.2` of a length in mm.
fn mm(x: f64) -> String {
    format!("{x:.2} mm")
}

/// The page of `validate`: `error-map.glb` (the skin coloured by its distance to the reference
/// surface, viridis from 0 to `top` mm, as the report's pictures), the surface statistics both
/// ways, the per-region table, the calipers on the skin and, with a truth, the joint centres;
/// opened from the three-quarter dorsal-radial view in the hand's frame `frame`.
pub fn validate_page(v: &SubjectValidation, glb: Vec<u8>, top: f64, frame: ViewFrame) -> ViewPage {
    let mut facts: Vec<(String, String)> = vec![("subject".into(), v.subject.clone())];
    if let Some(s) = &v.surface {
        facts.push((
            "skin to reference".into(),
            format!(
                "mean {}, SD {:.2}, 95th pct {:.2}, max {:.2} mm ({} vertices)",
                mm(s.mean_mm),
                s.sd_mm,
                s.p95_mm,
                s.max_mm,
                s.n
            ),
        ));
    }
    if let Some(s) = &v.surface_reverse {
        facts.push((
            "reference to skin".into(),
            format!(
                "mean {}, 95th pct {:.2}, max {:.2} mm ({} vertices)",
                mm(s.mean_mm),
                s.p95_mm,
                s.max_mm,
                s.n
            ),
        ));
    }
    let d = &v.dimensions;
    facts.push((
        "calipers on the skin − given".into(),
        format!(
            "{:+.2} ± {:.2} mm ({} dimensions)",
            d.mean_vs_given_mm,
            d.sd_vs_given_mm,
            d.dimensions.len()
        ),
    ));
    if let Some(l) = &v.link {
        let mut c: Vec<f64> = l.joints.iter().map(|j| j.centre_mm).collect();
        c.sort_by(f64::total_cmp);
        if let (Some(med), Some(max)) = (c.get(c.len() / 2), c.last()) {
            facts.push((
                "joint centres vs truth".into(),
                format!(
                    "median {}, max {:.2} mm ({} joints)",
                    mm(*med),
                    max,
                    c.len()
                ),
            ));
        }
    }
    let mut tables = Vec::new();
    if let Some(r) = &v.surface_regions {
        tables.push(ViewTable {
            title: "skin to reference per region".into(),
            columns: [
                "region",
                "vertices",
                "mean (mm)",
                "95th pct (mm)",
                "max (mm)",
            ]
            .map(String::from)
            .to_vec(),
            rows: r
                .regions
                .iter()
                .chain(std::iter::once(&r.hand_distal_of_wrist))
                .map(|e| {
                    vec![
                        e.region.clone(),
                        e.vertices.to_string(),
                        format!("{:.2}", e.mean_mm),
                        format!("{:.2}", e.p95_mm),
                        format!("{:.2}", e.max_mm),
                    ]
                })
                .collect(),
        });
    }
    tables.push(ViewTable {
        title: "calipers on the skin".into(),
        columns: ["dimension", "on skin (mm)", "given (mm)"]
            .map(String::from)
            .to_vec(),
        rows: d
            .dimensions
            .iter()
            .map(|e| {
                vec![
                    e.name.clone(),
                    format!("{:.2}", e.skin_mm),
                    format!("{:.2}", e.given_mm),
                ]
            })
            .collect(),
    });
    if let Some(l) = &v.link {
        tables.push(ViewTable {
            title: "joint centres against the truth".into(),
            columns: ["joint", "centre (mm)", "axis (°)"]
                .map(String::from)
                .to_vec(),
            rows: l
                .joints
                .iter()
                .map(|e| {
                    vec![
                        e.joint.clone(),
                        format!("{:.2}", e.centre_mm),
                        e.axis_deg.map_or("-".into(), |a| format!("{a:.2}")),
                    ]
                })
                .collect(),
        });
    }
    ViewPage {
        title: format!("validate: {}, skin against the reference", v.subject),
        kind: "validate",
        glbs: vec![ViewGlb {
            name: "skin error map".into(),
            role: "hand",
            bytes: glb,
            value: Some(ViewValue {
                attribute: super::error_map::ERROR_ATTRIBUTE.into(),
                label: "distance to the reference".into(),
                unit: "mm".into(),
            }),
        }],
        part_nodes: Vec::new(),
        legend: Some(Legend {
            title: "skin distance to the reference surface".into(),
            unit: "mm".into(),
            entries: Vec::new(),
            gradient: Gradient {
                colormap: "viridis",
                min: 0.0,
                max: top,
            },
            // The map clamps: a vertex beyond the scale's top takes its colour.
            beyond: Swatch::rgb(viridis(1.0), format!("{top} mm or farther")),
        }),
        facts,
        tables,
        frame: Some(frame),
        view: None,
        part_opacity: None,
        rig: None,
    }
}

/// The trial's figures as `motion.json` gives them: frames, rate, solved frames, the markers'
/// residuals over every solved frame, frames with contact and the deepest contact.
fn track_facts(file: &crate::track::MotionFile) -> Vec<(String, String)> {
    let solved = file.frames - file.unsolved_frames.len();
    let res: Vec<f64> = file
        .marker_residual_mm
        .values()
        .flat_map(|r| r.iter().flatten().copied())
        .collect();
    let rms = (res.iter().map(|r| r * r).sum::<f64>() / res.len().max(1) as f64).sqrt();
    let worst = res.iter().copied().fold(0.0, f64::max);
    let mut frames_with_contact: Vec<usize> = file.contacts.iter().map(|c| c.frame).collect();
    frames_with_contact.dedup();
    let deepest = file.contacts.iter().map(|c| c.depth_mm).fold(0.0, f64::max);
    let mut f = vec![
        (
            "frames".into(),
            format!(
                "{} at {} Hz ({:.2} s)",
                file.frames,
                file.rate,
                file.frames as f64 / file.rate.max(1e-9)
            ),
        ),
        (
            "solved".into(),
            format!("{solved} of {} frames", file.frames),
        ),
        (
            "marker residuals".into(),
            format!("RMS {rms:.2} mm, worst {worst:.1} mm"),
        ),
    ];
    if file.part.is_some() {
        f.push((
            "frames with contact".into(),
            frames_with_contact.len().to_string(),
        ));
        f.push(("deepest contact".into(), mm(deepest)));
    }
    f
}

/// Contact area per link over the trial (`motion.json`'s contacts): frames in contact, the
/// mean area over those frames and the largest.
fn track_contact_table(file: &crate::track::MotionFile) -> Option<ViewTable> {
    let mut per: std::collections::BTreeMap<&str, (usize, f64, f64)> = Default::default();
    for c in &file.contacts {
        let e = per.entry(&c.link).or_default();
        e.0 += 1;
        e.1 += c.area_mm2;
        e.2 = e.2.max(c.area_mm2);
    }
    (!per.is_empty()).then(|| ViewTable {
        title: "contact area per link over the trial".into(),
        columns: [
            "link",
            "frames",
            "mean area while touching (mm²)",
            "largest (mm²)",
        ]
        .map(String::from)
        .to_vec(),
        rows: per
            .iter()
            .map(|(l, (n, sum, max))| {
                vec![
                    l.to_string(),
                    n.to_string(),
                    format!("{:.1}", sum / *n as f64),
                    format!("{max:.1}"),
                ]
            })
            .collect(),
    })
}

/// The animated page of `track`: `motion.glb` (the subject's hand and the part over the trial,
/// with the viewer's play button and time slider), the trial's figures and the contact area
/// per link.
pub fn track_motion_page(title: &str, file: &crate::track::MotionFile, glb: Vec<u8>) -> ViewPage {
    ViewPage {
        title: format!("track: {title}"),
        kind: "track",
        glbs: vec![ViewGlb {
            name: "hand and part over the trial".into(),
            role: "scene",
            bytes: glb,
            value: None,
        }],
        part_nodes: vec!["part".into()],
        legend: None,
        facts: track_facts(file),
        tables: track_contact_table(file).into_iter().collect(),
        frame: None,
        view: None,
        part_opacity: None,
        rig: None,
    }
}

/// The contact-map page of `track`: `contact_map.glb` (the hand at the frame of most contact
/// and the part there, every vertex coloured by the share of the tracked frames it touched),
/// its legend in %, the trial's figures and the contact area per link; opened on the palm with
/// the part see-through, in the hand's frame `frame` at that frame.
pub fn track_contact_page(
    title: &str,
    file: &crate::track::MotionFile,
    glb: Vec<u8>,
    known_frames: usize,
    shown_frame: Option<usize>,
    frame: ViewFrame,
) -> ViewPage {
    let mut facts = track_facts(file);
    facts.push((
        "frames with known contacts".into(),
        known_frames.to_string(),
    ));
    facts.push((
        "shown at".into(),
        shown_frame.map_or("the reference posture (no contact)".into(), |f| {
            format!("frame {f} (most contact area)")
        }),
    ));
    ViewPage {
        title: format!("track: {title}, contact over the trial"),
        kind: "track",
        glbs: vec![ViewGlb {
            name: "contact map over the trial".into(),
            role: "scene",
            bytes: glb,
            value: None,
        }],
        part_nodes: vec!["part".into()],
        legend: Some(Legend {
            title: "share of the tracked frames in contact".into(),
            unit: "%".into(),
            entries: Vec::new(),
            gradient: Gradient {
                colormap: "viridis",
                min: 0.0,
                max: 100.0,
            },
            beyond: Swatch::rgb(super::motion_contact_map::NEVER, "never touched"),
        }),
        facts,
        tables: track_contact_table(file).into_iter().collect(),
        frame: Some(frame),
        view: Some("palmar"),
        part_opacity: Some(0.35),
        rig: None,
    }
}

/// The custom vertex attribute of the population's `contact_frequency.glb`: the share of the
/// hands touching each part vertex, %.
pub const HAND_SHARE_ATTRIBUTE: &str = "_HAND_SHARE_PCT";

/// The colour of a part vertex touched by `count` of `hands` hands: viridis of the share,
/// [`super::motion_contact_map::NEVER`] grey for none (as the tracked trial's map).
pub fn hand_share_colours(counts: &[u32], hands: usize) -> Vec<[u8; 3]> {
    super::motion_contact_map::share_colours(counts, hands)
}

/// The page of a scene run over many hands: `glb` (the part in its own frame, every vertex
/// coloured by the share of the hands whose skin touches it), the legend in %, the
/// population's figures and one row per hand (holds, force closure, epsilon, contact area,
/// hand length).
pub fn population_page(
    s: &crate::grasp::population::PopulationSummary,
    glb: Vec<u8>,
    grasped: usize,
    tolerance_mm: f64,
) -> ViewPage {
    let yes = |b: bool| if b { "yes" } else { "no" }.to_string();
    let scene_name = std::path::Path::new(&s.scene)
        .file_stem()
        .map_or_else(|| s.scene.clone(), |n| n.to_string_lossy().into_owned());
    ViewPage {
        title: format!("population: {scene_name}, {} hands", s.hands),
        kind: "population",
        glbs: vec![ViewGlb {
            name: "part: share of hands touching".into(),
            role: "scene",
            bytes: glb,
            value: Some(ViewValue {
                attribute: HAND_SHARE_ATTRIBUTE.into(),
                label: "share of hands touching".into(),
                unit: "%".into(),
            }),
        }],
        part_nodes: Vec::new(),
        legend: Some(Legend {
            title: format!(
                "share of hands whose skin touches the part (within {tolerance_mm} mm or inside)"
            ),
            unit: "%".into(),
            entries: Vec::new(),
            gradient: Gradient {
                colormap: "viridis",
                min: 0.0,
                max: 100.0,
            },
            beyond: Swatch::rgb(super::motion_contact_map::NEVER, "no hand"),
        }),
        facts: vec![
            ("scene".into(), s.scene.clone()),
            ("grasp".into(), s.grasp_type.clone()),
            (
                "hands".into(),
                format!("{} ({grasped} with a grasp found)", s.hands),
            ),
            ("hold".into(), format!("{} of {}", s.holding, s.hands)),
            (
                "force closure".into(),
                format!("{} of {}", s.force_closure, s.hands),
            ),
        ],
        tables: vec![ViewTable {
            title: "every hand".into(),
            columns: [
                "hand",
                "holds",
                "force closure",
                "epsilon",
                "contact (mm²)",
                "hand length (mm)",
            ]
            .map(String::from)
            .to_vec(),
            rows: s
                .outcomes
                .iter()
                .map(|o| {
                    vec![
                        o.name.clone(),
                        yes(o.holds),
                        yes(o.force_closure),
                        format!("{:.4}", o.epsilon),
                        format!("{:.0}", o.contact_area_mm2),
                        format!("{:.0}", o.hand_length_mm),
                    ]
                })
                .collect(),
        }],
        frame: None,
        view: None,
        part_opacity: None,
        rig: None,
    }
}

/// A frame for a part's page that faces the touched side: "dorsal" (the preset the page opens
/// on) from the part's centre towards the count-weighted centre of its touched vertices,
/// "distal" (up on the screen) its longest bounding-box axis made square to that; `None` when
/// nothing is touched or the two coincide.
pub fn touched_side_frame(part: &crate::geometry::TriMesh, counts: &[u32]) -> Option<ViewFrame> {
    use crate::geometry::{Point, Vec3};
    let n = part.vertices.len().max(1) as f64;
    let centre = Point::from(part.vertices.iter().map(|p| p.coords).sum::<Vec3>() / n);
    let total: f64 = counts.iter().map(|&c| c as f64).sum();
    if total == 0.0 {
        return None;
    }
    let touched = part
        .vertices
        .iter()
        .zip(counts)
        .map(|(p, &c)| p.coords * c as f64)
        .sum::<Vec3>()
        / total;
    let dorsal = (Point::from(touched) - centre).try_normalize(1e-6)?;
    let (lo, hi) = part.bounds()?;
    let ext = hi - lo;
    let k = (0..3).max_by(|&a, &b| ext[a].total_cmp(&ext[b]))?;
    let mut up = Vec3::zeros();
    up[k] = 1.0;
    let distal = (up - dorsal * up.dot(&dorsal)).try_normalize(1e-6)?;
    Some(ViewFrame {
        origin: centre,
        dorsal,
        radial: dorsal.cross(&distal),
        distal,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::icosphere;

    /// The page faces the touched cap of a sphere stretched along z, z up; nothing touched, no
    /// frame.
    #[test]
    fn the_part_page_faces_the_touched_side() {
        let mut s = icosphere(20.0, 3);
        for p in &mut s.vertices {
            p.z *= 3.0;
        }
        let counts: Vec<u32> = s.vertices.iter().map(|p| (p.x > 10.0) as u32).collect();
        let f = touched_side_frame(&s, &counts).unwrap();
        assert!(f.dorsal.x > 0.99, "{:?}", f.dorsal);
        assert!(f.distal.z.abs() > 0.99, "{:?}", f.distal);
        assert!(f.radial.dot(&f.dorsal).abs() < 1e-9 && f.radial.dot(&f.distal).abs() < 1e-9);
        assert!(touched_side_frame(&s, &vec![0; s.vertices.len()]).is_none());
    }
}
