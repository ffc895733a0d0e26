//! Loading the vendored `generic-hand` template (WebXR input-profiles assets, MIT): weld the
//! texture-seam splits, convert metres to millimetres, derive the link tree from the WebXR joint
//! names, carry the artist's skin weights over to the links of the spec.

use crate::anatomy::{Finger, Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::io::gltf::{read_gltf_slice, Skin};
use crate::io::Units;
use crate::skeleton::Skeleton;
use std::path::Path;

/// The left-hand template GLB, embedded so the toolkit needs no files at run time; the right
/// hand is its mirror image ([`load_base_hand`]).
pub(crate) const LEFT_GLB: &[u8] = include_bytes!("../../assets/generic-hand/left.glb");

/// Sparse per-vertex skinning weights: `(link index, weight)` pairs summing to 1.
pub type LinkWeights = Vec<Vec<(usize, f64)>>;

/// The base (welded, unsubdivided) generic hand.
#[derive(Clone, Debug)]
pub struct BaseHand {
    /// Which hand.
    pub side: Side,
    /// Welded, closed, 2-manifold surface in mm.
    pub mesh: TriMesh,
    /// Skinning weights per vertex over [`Link::ALL`].
    pub weights: LinkWeights,
    /// The link tree with the artist's joint centres and frames.
    pub skeleton: Skeleton,
    /// Base (carpometacarpal end) of the index, middle, ring and little metacarpals: the WebXR
    /// `*-metacarpal` nodes, which the spec's tree folds into the rigid palm.
    pub metacarpal_bases: [Point; 4],
}

/// The WebXR joint name of each spec joint (the node sits at the joint, at the proximal end of
/// the bone it names), and of each fingertip.
fn webxr_prefix(f: Finger) -> &'static str {
    match f {
        Finger::Thumb => "thumb",
        Finger::Index => "index-finger",
        Finger::Middle => "middle-finger",
        Finger::Ring => "ring-finger",
        Finger::Little => "pinky-finger",
    }
}

/// WebXR node name of spec joint `j`.
pub(crate) fn webxr_joint_name(j: Joint) -> String {
    match j.finger() {
        None => "wrist".into(),
        Some(Finger::Thumb) => {
            let bone = ["metacarpal", "phalanx-proximal", "phalanx-distal"][j.rank()];
            format!("thumb-{bone}")
        }
        Some(f) => {
            let bone = ["phalanx-proximal", "phalanx-intermediate", "phalanx-distal"][j.rank()];
            format!("{}-{bone}", webxr_prefix(f))
        }
    }
}

/// The link a WebXR joint's weight belongs to. Finger metacarpal bones are rigid parts of the
/// palm in the spec's link tree; the wrist node's weight is split between ARM and PALM by
/// [`wrist_split`]. Returns `None` for the wrist (handled separately) and for unknown names.
fn link_of_webxr(name: &str) -> Option<Link> {
    if name == "wrist" {
        return None;
    }
    for f in Finger::ALL {
        let p = webxr_prefix(f);
        if let Some(bone) = name.strip_prefix(p).and_then(|s| s.strip_prefix('-')) {
            let links = f.links();
            return match (f, bone) {
                (Finger::Thumb, "metacarpal") => Some(links[0]),
                (Finger::Thumb, "phalanx-proximal") => Some(links[1]),
                (Finger::Thumb, "phalanx-distal" | "tip") => Some(links[2]),
                (_, "metacarpal") => Some(Link::Palm),
                (_, "phalanx-proximal") => Some(links[0]),
                (_, "phalanx-intermediate") => Some(links[1]),
                (_, "phalanx-distal" | "tip") => Some(links[2]),
                _ => None,
            };
        }
    }
    None
}

/// Half-width (mm) of the band across the wrist joint over which the artist's wrist weight
/// blends from ARM (proximal) to PALM (distal): linear blend skinning needs a band, not a step,
/// or the skin tears when the wrist flexes.
pub const WRIST_BAND_MM: f64 = 8.0;

/// Fraction of the wrist node's weight that goes to ARM for a point at signed distance `s`
/// (mm) distal of the wrist centre along the palm's long axis.
pub(crate) fn wrist_split(s: f64) -> f64 {
    (0.5 - s / (2.0 * WRIST_BAND_MM)).clamp(0.0, 1.0)
}

/// Load the embedded template of `side`: the left asset, and for the right hand its mirror
/// image ([`mirror_base_hand`]). The asset's own `right.glb` has the same surface mirrored but
/// not the same skeleton: its index MCP stands 3.4 mm proximal of the left one's mirror image
/// (an index proximal phalanx 45.3 mm long beside the middle's 46.9, where hands measure it
/// about 11 % shorter; the left asset's is 41.9) and its thumb's joint frames are turned, so
/// the landmark rule put seven landmarks of one hand 2-6 mm from where it put the other's, and
/// a hand was fitted as another hand than its mirror image.
pub fn load_base_hand(side: Side) -> Result<BaseHand> {
    let left = base_hand_from_glb(
        LEFT_GLB,
        Side::Left,
        Path::new("assets/generic-hand/left.glb"),
    )?;
    match side {
        Side::Left => Ok(left),
        Side::Right => mirror_base_hand(&left),
    }
}

/// `mesh` mirrored across its frame's sagittal plane (x -> -x), vertex for vertex, its faces
/// turned over so that they still point outward.
pub fn mirror_mesh(mesh: &TriMesh) -> TriMesh {
    mesh.affine_transformed(&nalgebra::Matrix4::new_nonuniform_scaling(&Vec3::new(
        -1.0, 1.0, 1.0,
    )))
}

/// The mirror image of a hand across its frame's sagittal plane (x -> -x): the other hand,
/// with the same vertices in the same order (vertex `i` of one is vertex `i` of the other, so
/// that a landmark, a caliper pair or a field per vertex, such as a shape prior's, means the
/// same on both), faces turned over to stay outward, the same weights, and a skeleton built
/// from the mirrored joint centres, tips and dorsal directions (x = y × z stays right-handed,
/// as every hand's frames are).
pub fn mirror_base_hand(hand: &BaseHand) -> Result<BaseHand> {
    let m = |p: &Point| Point::new(-p.x, p.y, p.z);
    let mv = |v: &Vec3| Vec3::new(-v.x, v.y, v.z);
    let side = match hand.side {
        Side::Left => Side::Right,
        Side::Right => Side::Left,
    };
    let sk = &hand.skeleton;
    let centres: [Point; 16] = std::array::from_fn(|i| m(&sk.joints[i].centre));
    let dorsal: [Vec3; 16] = std::array::from_fn(|i| mv(&sk.joints[i].y()));
    let skeleton = Skeleton::from_centres(side, &centres, sk.tips.map(|t| m(&t)), &dorsal)?;
    Ok(BaseHand {
        side,
        mesh: mirror_mesh(&hand.mesh),
        weights: hand.weights.clone(),
        skeleton,
        metacarpal_bases: hand.metacarpal_bases.map(|p| m(&p)),
    })
}

/// Build a [`BaseHand`] from the bytes of a generic-hand GLB (metres, WebXR joint names).
/// `label` names the file in errors.
pub fn base_hand_from_glb(bytes: &[u8], side: Side, label: &Path) -> Result<BaseHand> {
    let scene = read_gltf_slice(bytes, Units::Metres, label)?;
    let sm = scene
        .meshes
        .into_iter()
        .find(|m| m.skin.is_some())
        .ok_or_else(|| {
            Error::input(
                label,
                "no skinned mesh: the template needs joints and weights",
            )
        })?;
    let skin = sm.skin.as_ref().expect("found above");

    // The skeleton from the joint nodes' rest world transforms.
    let find = |name: &str| -> Result<usize> {
        skin.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| Error::input(label, format!("joint node '{name}' is missing")))
    };
    let world_pos = |i: usize| -> Point {
        let m = skin.joints[i].world;
        Point::new(m[(0, 3)], m[(1, 3)], m[(2, 3)])
    };
    // WebXR joint spaces: +Y out of the back of the hand (for the thumb: its nail side).
    let world_y = |i: usize| -> Vec3 {
        let m = skin.joints[i].world;
        Vec3::new(m[(0, 1)], m[(1, 1)], m[(2, 1)])
    };
    let mut centres = [Point::origin(); 16];
    let mut dorsal = [Vec3::zeros(); 16];
    for j in Joint::ALL {
        let i = find(&webxr_joint_name(j))?;
        centres[j.index()] = world_pos(i);
        dorsal[j.index()] = world_y(i);
    }
    let mut tips = [Point::origin(); 5];
    for f in Finger::ALL {
        tips[f as usize] = world_pos(find(&format!("{}-tip", webxr_prefix(f)))?)
    }
    let skeleton =
        Skeleton::from_centres(side, &centres, tips, &dorsal).map_err(|e| e.in_file(label))?;
    let mut metacarpal_bases = [Point::origin(); 4];
    for (k, f) in Finger::ALL[1..].iter().enumerate() {
        metacarpal_bases[k] = world_pos(find(&format!("{}-metacarpal", webxr_prefix(*f)))?);
    }

    // Weld the seams and carry the weights (identical on both sides of a seam; averaged to be safe).
    let (mesh, remap) = sm.mesh.weld(0.0);
    mesh.check_closed_manifold().map_err(|e| e.in_file(label))?;
    let link_w = link_weights(skin, &sm.mesh.vertices, &skeleton, label)?;
    let mut acc = vec![vec![0.0; Link::ALL.len()]; mesh.n_vertices()];
    let mut count = vec![0usize; mesh.n_vertices()];
    for (v, w) in link_w.iter().enumerate() {
        let t = remap[v];
        count[t] += 1;
        for &(l, x) in w {
            acc[t][l] += x;
        }
    }
    let weights = acc
        .into_iter()
        .zip(count)
        .map(|(row, n)| {
            let mut w: Vec<(usize, f64)> = row
                .into_iter()
                .enumerate()
                .filter(|(_, x)| *x > 0.0)
                .map(|(l, x)| (l, x / n as f64))
                .collect();
            let s: f64 = w.iter().map(|x| x.1).sum();
            w.iter_mut().for_each(|x| x.1 /= s);
            w.sort_by(|a, b| b.1.total_cmp(&a.1));
            w
        })
        .collect::<Vec<_>>();
    if let Some(v) = weights.iter().position(|w| w.is_empty()) {
        return Err(Error::input(
            label,
            format!("vertex {v} has no skin weight"),
        ));
    }
    Ok(BaseHand {
        side,
        mesh,
        weights,
        skeleton,
        metacarpal_bases,
    })
}

/// The artist's per-joint weights of every stored vertex, mapped to spec links.
fn link_weights(
    skin: &Skin,
    positions: &[Point],
    skeleton: &Skeleton,
    label: &Path,
) -> Result<LinkWeights> {
    let wrist = skeleton.joint(Joint::Wrist);
    let mut out = Vec::with_capacity(positions.len());
    for (v, (ws, p)) in skin.weights.iter().zip(positions).enumerate() {
        let mut row: Vec<(usize, f64)> = Vec::with_capacity(4);
        let mut add = |l: Link, w: f64| match row.iter_mut().find(|x| x.0 == l.index()) {
            Some(x) => x.1 += w,
            None => row.push((l.index(), w)),
        };
        for &(ji, w) in ws {
            let name = &skin.joints[ji].name;
            match link_of_webxr(name) {
                Some(l) => add(l, w),
                None if name == "wrist" => {
                    let a = wrist_split((p - wrist.centre).dot(&wrist.z()));
                    add(Link::Arm, w * a);
                    add(Link::Palm, w * (1.0 - a));
                }
                None => {
                    return Err(Error::input(
                        label,
                        format!(
                        "vertex {v} is weighted to joint '{name}', which is not a WebXR hand joint"
                    ),
                    ))
                }
            }
        }
        row.retain(|x| x.1 > 0.0);
        out.push(row);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_hands_load_welded_closed_and_in_mm() {
        for side in [Side::Right, Side::Left] {
            let h = load_base_hand(side).unwrap();
            // Measured facts of the asset (assets/generic-hand/README.md).
            assert_eq!(h.mesh.n_vertices(), 1159, "{side}");
            assert_eq!(h.mesh.n_faces(), 2314, "{side}");
            let topo = h.mesh.topology();
            assert_eq!(topo.euler_characteristic(), 2);
            assert!(h.mesh.signed_volume() > 0.0, "{side}: faces point outward");
            // About 19 cm from the wrist cut to the middle fingertip: millimetres, not metres.
            let (lo, hi) = h.mesh.bounds().unwrap();
            assert!(
                (150.0..260.0).contains(&(hi.y - lo.y)),
                "{side}: {}",
                hi.y - lo.y
            );
            for w in &h.weights {
                let s: f64 = w.iter().map(|x| x.1).sum();
                assert!((s - 1.0).abs() < 1e-9);
            }
        }
    }

    /// The right template is built by mirroring the left asset; that stands for the right asset
    /// because its surface is the left one's mirror image, vertex for vertex up to the order
    /// (checked here on the welded asset, up to the assets' placement).
    #[test]
    fn the_right_asset_is_the_left_surface_mirrored() {
        let label = Path::new("assets/generic-hand/right.glb");
        let asset = base_hand_from_glb(
            include_bytes!("../../assets/generic-hand/right.glb"),
            Side::Right,
            label,
        )
        .unwrap();
        let mirrored = load_base_hand(Side::Right).unwrap();
        let (a, b) = (&asset.mesh.vertices, &mirrored.mesh.vertices);
        assert_eq!(a.len(), b.len());
        let centroid = |v: &[Point]| v.iter().map(|p| p.coords).sum::<Vec3>() / v.len() as f64;
        let shift = centroid(a) - centroid(b);
        let mut hit = vec![false; a.len()];
        for p in b {
            let q = p + shift;
            let (i, d) = a
                .iter()
                .enumerate()
                .map(|(i, x)| (i, (x - q).norm()))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap();
            assert!(d < 0.01, "{d} mm");
            hit[i] = true;
        }
        assert!(
            hit.iter().all(|h| *h),
            "one asset vertex for each mirrored one"
        );
        // The mirror keeps the vertex order and turns the faces, so they still point outward.
        let left = load_base_hand(Side::Left).unwrap();
        assert_eq!(mirrored.weights, left.weights);
        assert!((mirrored.mesh.signed_volume() - left.mesh.signed_volume()).abs() < 1e-6);
        for j in Joint::ALL {
            let (l, r) = (mirrored.skeleton.joint(j), left.skeleton.joint(j));
            assert!((l.centre.x + r.centre.x).abs() < 1e-12 && l.centre.y == r.centre.y);
            assert!((l.y().x + r.y().x).abs() < 1e-9 && (l.z().z - r.z().z).abs() < 1e-9);
        }
    }

    #[test]
    fn template_anatomy_matches_the_side() {
        for side in [Side::Right, Side::Left] {
            let h = load_base_hand(side).unwrap();
            let sk = &h.skeleton;
            // Fingers along -Y on both assets; the left is the right mirrored in X, so the back
            // of the hand faces +X on the right and -X on the left.
            let mirror = if side == Side::Right { 1.0 } else { -1.0 };
            assert!(sk.joint(Joint::Wrist).y().x * mirror > 0.9, "{side}");
            assert!(sk.joint(Joint::MPip).z().y < -0.9, "{side}");
            // x = y × z is radial on a right hand (thumb side), ulnar on a left one.
            let radial = sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp);
            let d = sk.joint(Joint::MMcp).x().dot(&radial);
            assert_eq!(d > 0.0, side == Side::Right, "{side}");
            // The wrist weight goes to ARM proximally and PALM distally.
            assert!((wrist_split(-20.0) - 1.0).abs() < 1e-12);
            assert!(wrist_split(20.0).abs() < 1e-12);
        }
    }

    #[test]
    fn webxr_names_map_to_links() {
        assert_eq!(link_of_webxr("index-finger-metacarpal"), Some(Link::Palm));
        assert_eq!(link_of_webxr("thumb-metacarpal"), Some(Link::TMeta));
        assert_eq!(
            link_of_webxr("pinky-finger-phalanx-intermediate"),
            Some(Link::LMid)
        );
        assert_eq!(
            link_of_webxr("ring-finger-phalanx-distal"),
            Some(Link::RDist)
        );
        assert_eq!(link_of_webxr("wrist"), None);
        assert_eq!(link_of_webxr("elbow"), None);
        assert_eq!(webxr_joint_name(Joint::TIp), "thumb-phalanx-distal");
        assert_eq!(
            webxr_joint_name(Joint::LMcp),
            "pinky-finger-phalanx-proximal"
        );
    }

    /// A template whose surface is open (a face removed) or non-manifold is refused with the
    /// file and the offending edge named, never loaded into a silently wrong model.
    #[test]
    fn open_or_non_manifold_template_is_refused() {
        use crate::io::gltf::{glb_bytes, read_gltf_slice};
        let label = Path::new("bad-hand.glb");
        let mut scene = read_gltf_slice(LEFT_GLB, Units::Metres, label).unwrap();
        scene.meshes[0].mesh.faces.pop();
        let bytes = glb_bytes(&scene, Units::Metres).unwrap();
        let e = base_hand_from_glb(&bytes, Side::Left, label)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("bad-hand.glb:") && e.contains("open") && e.contains("edge"),
            "{e}"
        );

        let mut scene = read_gltf_slice(LEFT_GLB, Units::Metres, label).unwrap();
        let f = scene.meshes[0].mesh.faces[0];
        scene.meshes[0].mesh.faces.push(f);
        let bytes = glb_bytes(&scene, Units::Metres).unwrap();
        let e = base_hand_from_glb(&bytes, Side::Left, label)
            .unwrap_err()
            .to_string();
        assert!(e.contains("manifold") || e.contains("oriented"), "{e}");
    }
}
