//! The fixture `tests/data/untangle_crease_fold.json`: a palmar crease of a posed fist cut out
//! of its mesh three rings around the one element the untangler's penalty sweeps leave
//! inverted. Read by the untangler's unit test and by the `tet/untangle_crease_fold` bench,
//! each of which includes this file by path (a bench cannot see test code, and a reader for a
//! test fixture does not belong in the library).

use nalgebra::Point3;

/// The crease: its nodes (mm), elements, the nodes held (the skin's and those beyond the
/// rings) and each element's reference volume.
pub struct CreaseFold {
    pub nodes: Vec<Point3<f64>>,
    pub tets: Vec<[usize; 4]>,
    pub held: Vec<usize>,
    pub reference: Vec<f64>,
}

pub fn crease_fold() -> CreaseFold {
    let fold: serde_json::Value =
        serde_json::from_str(include_str!("../data/untangle_crease_fold.json")).unwrap();
    let field = |name: &str| fold[name].clone();
    CreaseFold {
        nodes: serde_json::from_value::<Vec<[f64; 3]>>(field("nodes"))
            .unwrap()
            .into_iter()
            .map(Point3::from)
            .collect(),
        tets: serde_json::from_value(field("tets")).unwrap(),
        held: serde_json::from_value(field("held")).unwrap(),
        reference: serde_json::from_value(field("reference")).unwrap(),
    }
}
