//! The contact map of a tracked trial as pictures and as a coloured GLB: every skin vertex and
//! every part vertex coloured by the share of the trial's tracked frames it was in contact
//! (the counts of [`crate::track::replay_contacts`]), grey where it never touched.
//!
//! The paper's purpose for the individual hand is to "calculate and visualize contact areas
//! between the product models and the hand models"; over a motion the natural summary is how
//! often each place is touched.

use super::error_map::srgb_to_linear;
use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::grasp::hand::{PosableHand, SkinnedHand};
use crate::io::gltf::{Scene, SceneMesh};
use crate::render::{
    colour_bar_ticks, draw_label_sized, label_size, render_mesh_with, viridis, Image,
    RenderOptions, View,
};
use crate::skeleton::Skeleton;
use crate::track::{ContactReplay, Kinematics, Tracked};
use nalgebra::Isometry3;

/// Colour of a vertex that never touched the part: a light neutral grey, outside viridis, so
/// that even a single frame's contact (viridis' dark violet end) stands out.
pub const NEVER: [u8; 3] = [200, 200, 200];

/// The colour of each vertex from its frames in contact `counts` out of `frames` tracked
/// frames: [`NEVER`] for 0, else viridis of the share `count / frames` (0 to 1).
pub fn share_colours(counts: &[u32], frames: usize) -> Vec<[u8; 3]> {
    counts
        .iter()
        .map(|&c| {
            if c == 0 || frames == 0 {
                NEVER
            } else {
                viridis(c as f64 / frames as f64)
            }
        })
        .collect()
}

/// The contact map of a trial, with the frame it is shown at in three dimensions.
#[derive(Clone, Debug)]
pub struct ContactMap {
    /// The skin at the reference posture (the static trial's), mm, lab frame.
    pub hand_rest: TriMesh,
    /// The skin posed at `frame` (at the reference posture when no frame had contact), mm,
    /// lab frame.
    pub hand_posed: TriMesh,
    /// The part in its own frame, mm.
    pub part: TriMesh,
    /// The part's pose (part frame -> lab) at `frame`; identity when it was never tracked.
    pub part_pose: Isometry3<f64>,
    /// Per skin vertex: frames in contact.
    pub skin_count: Vec<u32>,
    /// Per part vertex: frames in contact.
    pub part_count: Vec<u32>,
    /// Frames whose contacts are known (hand solved and part pose known): the shares'
    /// denominator.
    pub frames: usize,
    /// The frame of largest total contact area, if any frame had contact.
    pub frame: Option<usize>,
    /// The direction (part frame) from the hand towards the part at `frame`, along which the
    /// part is seen from the hand's side.
    pub towards_part: Vec3,
    /// The reference posture's dorsal and distal directions (lab frame).
    pub dorsal: Vec3,
    pub distal: Vec3,
    /// The hand's frame as `hand_posed` shows it: the wrist centre and the dorsal, radial and
    /// distal directions ([`Skeleton::hand_directions`] carried by the palm), lab frame.
    pub posed_frame: (Point, [Vec3; 3]),
}

/// The dorsal and distal directions of a hand in its reference posture: the wrist frame's y
/// axis (dorsal by the skeleton's convention) and the direction from the wrist to the middle
/// MCP made orthogonal to it.
pub fn palm_directions(sk: &Skeleton) -> (Vec3, Vec3) {
    let dorsal = sk.joint(Joint::Wrist).y();
    let d = sk.centre(Joint::MMcp) - sk.centre(Joint::Wrist);
    let distal = (d - dorsal * d.dot(&dorsal))
        .try_normalize(1e-9)
        .unwrap_or_else(|| sk.joint(Joint::Wrist).z());
    (dorsal, distal)
}

/// The frame of largest total contact area (the first of equals), `None` without contact.
pub fn busiest_frame(replay: &ContactReplay) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (f, c) in replay.frames.iter().enumerate() {
        let Some(c) = c else { continue };
        let a = c.total_area_mm2();
        if a > 0.0 && best.is_none_or(|(_, b)| a > b) {
            best = Some((f, a));
        }
    }
    best.map(|(f, _)| f)
}

fn centroid(points: &[Point]) -> Point {
    Point::from(points.iter().map(|p| p.coords).sum::<Vec3>() / points.len().max(1) as f64)
}

/// Gather the contact map of `replay` (contacts of `hand`, tracked with `kin` over `tracked`,
/// with `part`, a mesh in the part's own frame).
///
/// The 3D placement is the frame of largest total contact: the skin posed there by its link
/// transforms, the part at its pose there, and the direction from the posed skin's centroid
/// to the part's centre (taken into the part's frame) is the side of the part the hand covers.
pub fn contact_map(
    hand: &SkinnedHand,
    kin: &Kinematics,
    tracked: &Tracked,
    part: &TriMesh,
    replay: &ContactReplay,
) -> Result<ContactMap> {
    let rest = hand.rest_mesh();
    if replay.skin_count.len() != rest.n_vertices() || replay.part_count.len() != part.n_vertices()
    {
        return Err(Error::invalid(format!(
            "contact map: counts for {} skin and {} part vertices, meshes of {} and {}",
            replay.skin_count.len(),
            replay.part_count.len(),
            rest.n_vertices(),
            part.n_vertices()
        )));
    }
    let frame = busiest_frame(replay);
    let part_poses = tracked.part.as_ref().map(|(p, _)| p.as_slice());
    let pose_at = |f: usize| part_poses.and_then(|p| p.get(f).copied().flatten());
    let shown = frame.or_else(|| {
        (0..tracked.frames.len())
            .find(|&f| tracked.frames[f].state.is_some() && pose_at(f).is_some())
    });
    let (origin, axes) = hand.hand.skeleton.hand_directions();
    let (hand_posed, part_pose, palm) = match shown {
        Some(f) => {
            let state = tracked.frames[f]
                .state
                .as_ref()
                .ok_or_else(|| Error::invalid("contact map: the shown frame is unsolved"))?;
            let mut v = Vec::new();
            let links = kin.evaluate(state).links;
            hand.pose_all(&links, &mut v);
            let posed = TriMesh {
                vertices: v,
                faces: rest.faces.clone(),
            };
            (
                posed,
                pose_at(f).unwrap_or_else(Isometry3::identity),
                links[crate::anatomy::Link::Palm.index()],
            )
        }
        None => (rest.clone(), Isometry3::identity(), Isometry3::identity()),
    };
    let hand_in_part = part_pose.inverse() * centroid(&hand_posed.vertices);
    let towards_part = (centroid(&part.vertices) - hand_in_part)
        .try_normalize(1e-9)
        .unwrap_or(Vec3::y());
    let (dorsal, distal) = palm_directions(&hand.hand.skeleton);
    Ok(ContactMap {
        hand_rest: rest.clone(),
        hand_posed,
        part: part.clone(),
        part_pose,
        skin_count: replay.skin_count.clone(),
        part_count: replay.part_count.clone(),
        frames: replay.frames.iter().filter(|f| f.is_some()).count(),
        frame,
        towards_part,
        dorsal,
        distal,
        posed_frame: (palm * origin, axes.map(|a| palm * a)),
    })
}

/// The part's longest bounding-box axis, the "up" of its pictures (a bottle stands upright).
fn long_axis(mesh: &TriMesh) -> Vec3 {
    let (mut lo, mut hi) = (Point::origin(), Point::origin());
    if let Some(p) = mesh.vertices.first() {
        (lo, hi) = (*p, *p);
    }
    for p in &mesh.vertices {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let ext = hi - lo;
    let k = (0..3)
        .max_by(|&a, &b| ext[a].total_cmp(&ext[b]))
        .unwrap_or(2);
    let mut up = Vec3::zeros();
    up[k] = 1.0;
    up
}

/// The picture `contact_map.png`: the hand at the reference posture seen from the palm, the
/// part seen from the hand's side and from the opposite side, each `view_px` wide and named
/// under it, a colour bar (share of frames, 0-100 %) at the right and a title above.
///
/// The hand is shown at the reference posture rather than at the frame of most contact: open
/// and seen from the palm, every fingertip, finger and palm patch is in view at once, while in
/// the grasp the curled fingers hide the palm and each other, and the contact patches face
/// the part. The part is at rest in its own frame; seen along the direction from the hand to
/// it, the palm's side faces the camera, and the opposite view shows where the fingertips and
/// thumb wrap around.
pub fn contact_map_picture(map: &ContactMap, view_px: u32) -> Result<Image> {
    let hand_c = share_colours(&map.skin_count, map.frames);
    let part_c = share_colours(&map.part_count, map.frames);
    let up = long_axis(&map.part);
    let tiles: [(&str, &TriMesh, &[[u8; 3]], View); 3] = [
        (
            "hand, palm side",
            &map.hand_rest,
            &hand_c,
            View::along(map.dorsal, map.distal),
        ),
        (
            "part, hand's side",
            &map.part,
            &part_c,
            View::along(map.towards_part, up),
        ),
        (
            "part, far side",
            &map.part,
            &part_c,
            View::along(-map.towards_part, up),
        ),
    ];
    let (vw, vh) = (view_px, (view_px as f64 * 1.3) as u32);
    let size = (view_px as f64 / 20.0).clamp(11.0, 18.0);
    let head = (size * 2.4) as u32;
    let foot = (size * 2.0) as u32;
    let bar_w = (view_px as f64 * 0.55) as u32;
    let opts = RenderOptions {
        ambient: 0.35,
        ..RenderOptions::default()
    };
    let mut img = Image::new(3 * vw + bar_w, head + vh + foot, [255, 255, 255]);
    for (k, (name, mesh, colours, view)) in tiles.iter().enumerate() {
        let view = view.fit_mesh(mesh, 0.04);
        // The tile's aspect: widen the shorter extent so the mesh is not stretched.
        let (hw, hh) = view.half_extents();
        let hw2 = hw.max(hh * vw as f64 / vh as f64);
        let hh2 = hh.max(hw * vh as f64 / vw as f64);
        let view = view.with_frame(view.center(), hw2, hh2);
        let tile = render_mesh_with(mesh, Some(colours), &view, vw, vh, &opts);
        let x = k as u32 * vw;
        img.blit(&tile, x as i64, head as i64);
        let (tw, _) = label_size(name, size)?;
        draw_label_sized(
            &mut img,
            (x + vw / 2) as i32 - tw as i32 / 2,
            (head + vh) as i32 + (size * 0.4) as i32,
            name,
            [40, 40, 40],
            size,
        )?;
    }
    let ticks: Vec<(f64, String)> = [0.0, 0.25, 0.5, 0.75, 1.0]
        .iter()
        .map(|&v| (v, format!("{:.0} %", 100.0 * v)))
        .collect();
    let bar = colour_bar_ticks(
        0.0,
        1.0,
        &ticks,
        "share of frames",
        bar_w,
        (vh as f64 * 0.8) as u32,
    )?;
    img.blit(&bar, (3 * vw) as i64, (head + vh / 10) as i64);
    // The grey of "never" under the bar.
    let (gx, gy) = (
        3 * vw + bar_w / 10,
        head + vh / 10 + (vh as f64 * 0.8) as u32 + 4,
    );
    for y in gy..gy + size as u32 {
        for x in gx..gx + (size * 1.4) as u32 {
            img.set_pixel(x as i64, y as i64, NEVER);
        }
    }
    draw_label_sized(
        &mut img,
        (gx + (size * 1.4) as u32 + 6) as i32,
        gy as i32 - 2,
        "never",
        [0, 0, 0],
        size,
    )?;
    let title = format!(
        "Contact map: share of the {} tracked frames each place touched{}",
        map.frames,
        match map.frame {
            Some(_) => "",
            None => " (no contact)",
        }
    );
    draw_label_sized(
        &mut img,
        12,
        (size * 0.5) as i32,
        &title,
        [20, 20, 20],
        size,
    )?;
    Ok(img)
}

/// The scene of `contact_map.glb`: the skin posed at the frame of most contact (mesh `hand`)
/// and the part at its pose there (mesh `part`), both in the lab frame, their vertices
/// coloured by the map (`COLOR_0`, linear RGBA as glTF wants).
pub fn contact_map_scene(map: &ContactMap) -> Scene {
    let part = TriMesh {
        vertices: map
            .part
            .vertices
            .iter()
            .map(|p| map.part_pose * p)
            .collect(),
        faces: map.part.faces.clone(),
    };
    let lin = |c: Vec<[u8; 3]>| Some(c.into_iter().map(srgb_to_linear).collect());
    // The skin smooth, the CAD part split at its creases (its colours carried to the copies).
    let part =
        crate::geometry::crease_normals(&part, crate::geometry::crease_normals::DEFAULT_CREASE_DEG);
    let part_colours = part.carry(&share_colours(&map.part_count, map.frames));
    Scene {
        meshes: vec![
            SceneMesh {
                name: "hand".into(),
                mesh: map.hand_posed.clone(),
                normals: Some(map.hand_posed.vertex_normals()),
                colors: lin(share_colours(&map.skin_count, map.frames)),
                skin: None,
                attributes: Vec::new(),
                morph_targets: Vec::new(),
            },
            SceneMesh {
                name: "part".into(),
                mesh: part.mesh,
                normals: Some(part.normals),
                colors: lin(part_colours),
                skin: None,
                attributes: Vec::new(),
                morph_targets: Vec::new(),
            },
        ],
        animations: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::geometry::mesh::tests::icosphere;
    use crate::io::gltf::{glb_bytes, read_gltf_slice};
    use crate::io::Units;
    use crate::track::fixture::{grasp_states, lab_start};
    use crate::track::{Attachment, FrameContacts, FrameSolution, HandState};
    use nalgebra::UnitQuaternion;
    use std::path::Path;

    #[test]
    fn colours_are_the_share_of_frames_and_grey_for_never() {
        let c = share_colours(&[0, 1, 5, 10, 12], 10);
        assert_eq!(c[0], NEVER);
        assert_eq!(c[1], viridis(0.1));
        assert_eq!(c[2], viridis(0.5));
        assert_eq!(c[3], viridis(1.0));
        // More frames than tracked cannot happen; were it to, it is clamped, not wrapped.
        assert_eq!(c[4], viridis(1.0));
        assert_eq!(share_colours(&[3], 0), vec![NEVER]);
        // Grey lies outside viridis, so one frame's contact is told from none.
        assert!((0..=255).all(|k| viridis(k as f64 / 255.0) != NEVER));
    }

    fn solution(state: Option<HandState>) -> FrameSolution {
        FrameSolution {
            state,
            residual_mm: Vec::new(),
            rejected: Vec::new(),
            held: Vec::new(),
            coupled: Vec::new(),
            iterations: 0,
        }
    }

    fn contacts(area: f64, skin: Vec<u32>) -> Option<FrameContacts> {
        let mut a = [0.0; 17];
        a[4] = area;
        Some(FrameContacts {
            link_area_mm2: a,
            link_depth_mm: [0.0; 17],
            skin_vertices: skin,
        })
    }

    /// A trial of six frames on the template hand: frame 1 unsolved, frame 4 without the
    /// part's pose, frame 3 the most contact. The map's denominator is the four frames whose
    /// contacts are known, its 3D placement frame 3 (the skin posed there by the link model,
    /// the part at its pose there), and the GLB's colours, read back, are those of the counts
    /// over four frames.
    #[test]
    fn map_shows_counts_over_tracked_frames_at_the_busiest_frame() {
        let hand = SkinnedHand::template(Side::Right).unwrap();
        let kin = Kinematics::full(hand.skeleton().clone());
        let n = 6;
        let states = grasp_states(n, 100.0, lab_start());
        let poses: Vec<Option<Isometry3<f64>>> = (0..n)
            .map(|f| {
                (f != 4).then(|| {
                    Isometry3::from_parts(
                        nalgebra::Translation3::new(10.0 * f as f64, 5.0, -3.0),
                        UnitQuaternion::from_euler_angles(0.1 * f as f64, 0.2, 0.0),
                    )
                })
            })
            .collect();
        let tracked = Tracked {
            attachment: Attachment {
                markers: Vec::new(),
            },
            frames: (0..n)
                .map(|f| solution((f != 1).then(|| states[f].clone())))
                .collect(),
            part: Some((poses.clone(), vec![None; n])),
            part_filled: Vec::new(),
            rate: 100.0,
            warnings: Vec::new(),
        };
        let part = icosphere(30.0, 2);
        let nv = hand.rest_mesh().n_vertices();
        let skin_count: Vec<u32> = (0..nv).map(|i| (i % 5) as u32).collect();
        let part_count: Vec<u32> = (0..part.n_vertices()).map(|i| (i % 3) as u32).collect();
        let replay = ContactReplay {
            frames: vec![
                contacts(10.0, vec![1]),
                None,
                contacts(20.0, vec![2]),
                contacts(50.0, vec![3]),
                None,
                contacts(0.0, vec![]),
            ],
            skin_count: skin_count.clone(),
            part_count: part_count.clone(),
        };
        let map = contact_map(&hand, &kin, &tracked, &part, &replay).unwrap();
        assert_eq!((map.frames, map.frame), (4, Some(3)));
        let mut want = Vec::new();
        hand.pose_all(&kin.evaluate(&states[3]).links, &mut want);
        assert!(map
            .hand_posed
            .vertices
            .iter()
            .zip(&want)
            .all(|(a, b)| (a - b).norm() < 1e-9));
        assert_eq!(map.part_pose, poses[3].unwrap());

        let scene = contact_map_scene(&map);
        let bytes = glb_bytes(&scene, Units::Metres).unwrap();
        let back = read_gltf_slice(&bytes, Units::Metres, Path::new("contact_map.glb")).unwrap();
        assert_eq!(back.meshes.len(), 2);
        let (h, p) = (&back.meshes[0], &back.meshes[1]);
        let hc = h.colors.as_ref().unwrap();
        assert_eq!((hc.len(), h.mesh.n_vertices()), (nv, nv));
        for (i, c) in hc.iter().enumerate() {
            let expect = match skin_count[i] {
                0 => srgb_to_linear(NEVER),
                k => srgb_to_linear(viridis(k as f64 / 4.0)),
            };
            assert!(
                (0..4).all(|k| (c[k] - expect[k]).abs() < 1e-6),
                "vertex {i}"
            );
        }
        let pc = p.colors.as_ref().unwrap();
        assert_eq!(pc.len(), part.n_vertices());
        assert_eq!(pc[1], srgb_to_linear(viridis(0.25)));
        // Read back in mm: the hand where frame 3 puts it, the part at its pose there.
        assert!(h
            .mesh
            .vertices
            .iter()
            .zip(&want)
            .all(|(a, b)| (a - b).norm() < 1e-3));
        let placed = poses[3].unwrap() * part.vertices[7];
        assert!((p.mesh.vertices[7] - placed).norm() < 1e-3);
    }

    /// Share of a tile's non-background pixels that show a high share of frames (viridis'
    /// yellow-green end under any shading: red and green well above blue).
    fn high_share(img: &Image, x0: u32, x1: u32, y0: u32, y1: u32) -> f64 {
        let (mut hit, mut all) = (0usize, 0usize);
        for y in y0..y1 {
            for x in x0..x1 {
                let c = img.pixel(x, y).unwrap();
                if c == [255, 255, 255] {
                    continue;
                }
                all += 1;
                let [r, g, b] = c.map(|v| v as i32);
                if r > 2 * b + 20 && g > 2 * b + 20 {
                    hit += 1;
                }
            }
        }
        hit as f64 / all.max(1) as f64
    }

    /// Contacts on the palm's side of the hand, and on the side of the part that faces the
    /// hand, are in view: every palmar-facing skin vertex touched in all frames fills most of
    /// the hand's picture, and the part's touched half fills its first view, not its second.
    #[test]
    fn pictures_show_the_sides_that_carry_the_contacts() {
        let hand = SkinnedHand::template(Side::Right).unwrap();
        let (dorsal, distal) = palm_directions(hand.skeleton());
        let rest = hand.rest_mesh().clone();
        let normals = rest.vertex_normals();
        let frames = 20;
        let skin_count: Vec<u32> = normals
            .iter()
            .map(|n| if n.dot(&-dorsal) > 0.3 { frames } else { 0 })
            .collect();
        let part = icosphere(30.0, 3);
        let towards_part = Vec3::new(1.0, 0.0, 0.0);
        let part_count: Vec<u32> = part
            .vertices
            .iter()
            .map(|p| if p.x < 0.0 { frames } else { 0 })
            .collect();
        let mut map = ContactMap {
            hand_posed: rest.clone(),
            hand_rest: rest,
            part,
            part_pose: Isometry3::identity(),
            skin_count,
            part_count,
            frames: frames as usize,
            frame: Some(0),
            towards_part,
            dorsal,
            distal,
            posed_frame: (Point::origin(), [dorsal, dorsal.cross(&distal), distal]),
        };
        let px = 200;
        let img = contact_map_picture(&map, px).unwrap();
        let (vw, vh) = (px, (px as f64 * 1.3) as u32);
        let head = (px as f64 / 20.0).clamp(11.0, 18.0) * 2.4;
        let (y0, y1) = (head as u32, head as u32 + vh);
        assert_eq!(img.width, 3 * vw + (px as f64 * 0.55) as u32);
        let palm = high_share(&img, 0, vw, y0, y1);
        let near = high_share(&img, vw, 2 * vw, y0, y1);
        let far = high_share(&img, 2 * vw, 3 * vw, y0, y1);
        assert!(palm > 0.8 && near > 0.9 && far < 0.1, "{palm} {near} {far}");
        // The legend spans the whole scale: both of viridis' ends and the grey of "never".
        let legend: Vec<[u8; 3]> = (0..img.height)
            .flat_map(|y| (3 * vw..img.width).map(move |x| (x, y)))
            .map(|(x, y)| img.pixel(x, y).unwrap())
            .collect();
        for c in [viridis(0.0), viridis(1.0), NEVER] {
            assert!(legend.contains(&c), "{c:?} not in the legend");
        }
        // Seen from the back of the hand, the same map shows little: the check above is not
        // met by any view.
        map.dorsal = -map.dorsal;
        let back = contact_map_picture(&map, px).unwrap();
        assert!(high_share(&back, 0, vw, y0, y1) < 0.1);
    }
}
