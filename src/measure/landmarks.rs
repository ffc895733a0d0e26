//! Landmark skin points from the markers of the static reference trial: the point of the skin
//! under each marker.

use crate::geometry::closest_point::AabbTree;
use crate::geometry::{Point, TriMesh};
use std::collections::BTreeMap;

/// Every marker of `markers` (name -> position, mm) projected onto `skin` by the closest point.
/// A marker sits `marker_offset_mm` off its landmark along the skin's normal (spec section 1),
/// so its closest skin point is that landmark wherever the skin is smooth at the scale of the
/// offset. Markers of an empty skin are left out.
pub fn landmarks_on_skin(
    skin: &TriMesh,
    markers: &BTreeMap<String, Point>,
) -> BTreeMap<String, Point> {
    let tree = AabbTree::new(skin);
    markers
        .iter()
        .filter_map(|(name, p)| Some((name.clone(), tree.closest_point(p)?.point)))
        .collect()
}
