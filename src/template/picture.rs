//! A picture of a template: dorsal and palmar views of the high-resolution skin with its
//! landmarks (red, labelled), the vertex pairs of the 22 dimensions (green) and the skeleton
//! (blue joint centres and bones, drawn through the skin).

use super::TemplateHand;
use crate::anatomy::{Finger, Joint};
use crate::error::Result;
use crate::geometry::Point;
use crate::render::{
    compose_grid, draw_label, draw_label_sized, draw_points, draw_segments, render_mesh, Image,
    View,
};
use std::path::Path;

const RED: [u8; 3] = [210, 30, 30];
const GREEN: [u8; 3] = [20, 150, 60];
const BLUE: [u8; 3] = [30, 70, 200];

/// Bones of the skeleton as segments: wrist to each MCP/CMC, joint to joint, DIP/IP to tip.
pub fn bone_segments(hand: &TemplateHand) -> Vec<[Point; 2]> {
    let sk = &hand.skeleton;
    let mut segs = Vec::new();
    for f in Finger::ALL {
        let js = f.joints();
        segs.push([sk.centre(Joint::Wrist), sk.centre(js[0])]);
        for j in js {
            segs.push([sk.centre(j), sk.distal_end(j)]);
        }
    }
    segs
}

/// Render one view of the template with its annotations.
pub(crate) fn annotated_view(
    hand: &TemplateHand,
    view: View,
    labels: bool,
    size: u32,
) -> Result<Image> {
    let mesh = &hand.mesh;
    let view = view.fit_mesh(mesh, 0.06);
    let (w, h) = (size, (size as f64 * 1.25) as u32);
    let mut img = render_mesh(mesh, None, &view, w, h);
    let vtx = |i: usize| mesh.vertices[i];
    let pairs: Vec<[Point; 2]> = hand
        .spec
        .dimensions
        .values()
        .map(|&[a, b]| [vtx(a), vtx(b)])
        .collect();
    draw_segments(&mut img, &view, &pairs, 2.0, GREEN, false);
    let pair_ends: Vec<Point> = pairs.iter().flatten().copied().collect();
    draw_points(&mut img, &view, &pair_ends, 2.5, GREEN, false);
    draw_segments(&mut img, &view, &bone_segments(hand), 2.0, BLUE, true);
    let centres: Vec<Point> = hand
        .skeleton
        .centres()
        .into_iter()
        .map(|(_, c)| c)
        .collect();
    draw_points(&mut img, &view, &centres, 3.5, BLUE, true);
    let marks: Vec<(String, Point)> = hand
        .spec
        .landmarks
        .iter()
        .map(|(n, &v)| (n.clone(), vtx(v)))
        .collect();
    let pts: Vec<Point> = marks.iter().map(|m| m.1).collect();
    draw_points(&mut img, &view, &pts, 4.0, RED, false);
    if labels {
        let normals = mesh.vertex_normals();
        for (name, p) in &marks {
            let (x, y, _) = view.project(p, w, h);
            // Only labels of markers that face the camera: those drawn (not hidden) above.
            let facing = normals[hand.spec.landmarks[name]].dot(&view.forward()) < 0.0;
            if facing {
                draw_label_sized(&mut img, x as i32 + 5, y as i32 - 6, name, [90, 0, 0], 11.0)?;
            }
        }
    }
    Ok(img)
}

/// Dorsal and palmar views side by side with a legend, saved as PNG at `path`.
pub fn render_template_picture(hand: &TemplateHand, path: &Path) -> Result<()> {
    let sk = &hand.skeleton;
    let dorsal = sk.joint(Joint::Wrist).y();
    let distal = sk.centre(Joint::MMcp) - sk.centre(Joint::Wrist);
    let a = annotated_view(hand, View::along(-dorsal, distal), true, 620)?;
    let b = annotated_view(hand, View::along(dorsal, distal), true, 620)?;
    let mut img = compose_grid(&[a, b], 2);
    draw_label(
        &mut img,
        12,
        10,
        &format!(
            "{} template: {} vertices, {} faces. Dorsal (left), palmar (right).",
            hand.side,
            hand.mesh.n_vertices(),
            hand.mesh.n_faces()
        ),
        [0, 0, 0],
    )?;
    draw_label(&mut img, 12, 30, "red: landmarks", RED)?;
    draw_label(&mut img, 140, 30, "green: dimension vertex pairs", GREEN)?;
    draw_label(&mut img, 380, 30, "blue: joint centres and bones", BLUE)?;
    img.save_png(path)
}
