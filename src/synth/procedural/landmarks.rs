//! Every landmark of the spec (section 2) on the procedural body, by the anatomical rules the
//! template's landmark rule uses ([`crate::template::landmark_rule`]): dorsal rays from joint
//! centres for the joint markers, from 60 % along the distal bone for the nails (the middle of
//! the nail plate), from points along the 2nd and 5th metacarpals for `PALM_1..4` (20 % and 85 %
//! of the way from the head to the base) and along the thumb's metacarpal for `T_MC_1/2` (1/3,
//! 2/3); the optional fingertip markers along the distal phalanx's long axis from the distal
//! joint's centre; the lateral landmarks `I_MCP_LAT`, `L_MCP_LAT`, `WRIST_RAD`, `WRIST_ULN` as the
//! caliper extremes of the section at the joint (the thumb left out, as a caliper across the
//! metacarpal heads or the wrist does). Points lie on the polygonised skin; normals are the
//! implicit field's gradient there.

use super::implicit::HandField;
use crate::anatomy::{Finger, Joint};
use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use crate::template::landmark_rule::caliper_extreme;
use std::collections::BTreeMap;

/// The landmarks of the posed right hand: skin point and outward normal per name.
/// `bases` are the posed metacarpal bases of the index and little fingers.
pub fn place_landmarks(
    skin: &TriMesh,
    field: &HandField,
    sk: &Skeleton,
    bases: [Point; 2],
) -> Result<BTreeMap<String, (Point, Vec3)>> {
    let tree = AabbTree::new(skin);
    let mut out = BTreeMap::new();
    let mut ray = |name: &str, origin: Point, dir: Vec3| -> Result<()> {
        let hit = tree
            .ray_cast(&origin, &dir.normalize(), 0.0, 200.0)
            .ok_or_else(|| {
                Error::invalid(format!("procedural body: no skin above landmark {name}"))
            })?;
        out.insert(name.to_string(), (hit.point, field.normal(&hit.point)));
        Ok(())
    };
    for j in Joint::ALL {
        let jf = sk.joint(j);
        ray(j.name(), jf.centre, jf.y())?;
    }
    let dorsal = sk.joint(Joint::Wrist).y();
    for (name, mcp, base, t) in [
        ("PALM_1", Joint::IMcp, bases[0], 0.2),
        ("PALM_2", Joint::LMcp, bases[1], 0.2),
        ("PALM_3", Joint::IMcp, bases[0], 0.85),
        ("PALM_4", Joint::LMcp, bases[1], 0.85),
    ] {
        let c = sk.centre(mcp);
        ray(name, c + (base - c) * t, dorsal)?;
    }
    for f in Finger::ALL {
        let dj = f.joints()[2];
        let c = sk.centre(dj);
        ray(
            f.nail_marker(),
            c + (sk.tips[f as usize] - c) * 0.6,
            sk.joint(dj).y(),
        )?;
    }
    // The optional fingertip markers: where the distal phalanx's long axis leaves the skin.
    for f in Finger::ALL {
        let c = sk.centre(f.joints()[2]);
        ray(f.tip_marker(), c, sk.tips[f as usize] - c)?;
    }
    let (cmc, mcp) = (sk.centre(Joint::TCmc), sk.centre(Joint::TMcp));
    for (k, t) in [(1, 1.0 / 3.0), (2, 2.0 / 3.0)] {
        ray(
            &format!("T_MC_{k}"),
            cmc + (mcp - cmc) * t,
            sk.joint(Joint::TCmc).y(),
        )?;
    }
    // Lateral landmarks: caliper extremes in a slab normal to the link, thumb excluded.
    // Evaluated only for the vertices inside a slab (`caliper_extreme` tests the slab first).
    let keep = |i: usize| field.distance_without_thumb(&skin.vertices[i]) < 0.2;
    let radial = {
        let r = sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp);
        (r - dorsal * r.dot(&dorsal)).normalize()
    };
    let wrist = sk.joint(Joint::Wrist);
    let wrist_radial = (radial - wrist.z() * radial.dot(&wrist.z())).normalize();
    for (name, j, dir, radius) in [
        ("I_MCP_LAT", Joint::IMcp, radial, 16.0),
        ("L_MCP_LAT", Joint::LMcp, -radial, 16.0),
        ("WRIST_RAD", Joint::Wrist, wrist_radial, 50.0),
        ("WRIST_ULN", Joint::Wrist, -wrist_radial, 50.0),
    ] {
        let jf = sk.joint(j);
        // A thick hand holds its metacarpal heads deeper than the radius allows for: the
        // neighbourhood reaches at least 6 mm past the skin nearest the joint.
        let deepest = tree
            .closest_point(&jf.centre)
            .map_or(0.0, |c| c.distance + 6.0);
        let radius = f64::max(radius, deepest);
        let v =
            caliper_extreme(skin, &jf.centre, &jf.z(), radius, &dir, &keep).ok_or_else(|| {
                Error::invalid(format!("procedural body: no skin for landmark {name}"))
            })?;
        let p = skin.vertices[v];
        out.insert(name.to_string(), (p, field.normal(&p)));
    }
    Ok(out)
}
