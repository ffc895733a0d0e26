//! Construction of right-handed joint frames from anatomical directions (seed paper 3.1: "as to
//! a 1DOF joint, the local coordinate system is set to make rotation axis to be x").

use crate::geometry::Vec3;
use nalgebra::{Matrix3, Rotation3};

/// Below this sine of the angle between two directions they are treated as parallel.
const MIN_SIN: f64 = 1e-6;

/// Frame with z along the link (`long`, distal) and y as close as possible to `dorsal`
/// (Gram-Schmidt), x = y × z. Errors when either is zero or they are parallel.
pub fn frame_from_long_axis(long: &Vec3, dorsal: &Vec3) -> Result<Rotation3<f64>, String> {
    let z = long
        .try_normalize(1e-12)
        .ok_or("the link has zero length (joint and its distal end coincide)")?;
    let y = (dorsal - z * dorsal.dot(&z))
        .try_normalize(MIN_SIN * dorsal.norm().max(1e-300))
        .ok_or("the dorsal direction is parallel to the link")?;
    let x = y.cross(&z);
    Ok(Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
        x, y, z,
    ])))
}

/// Frame of a 1-DOF joint: x is the rotation `axis` exactly (sign kept), z is the direction
/// of `long` made perpendicular to it, y = z × x. Errors when the link lies along the axis.
pub fn frame_from_axis(axis: &Vec3, long: &Vec3) -> Result<Rotation3<f64>, String> {
    let x = axis
        .try_normalize(1e-12)
        .ok_or("the rotation axis has zero length")?;
    let z = (long - x * long.dot(&x))
        .try_normalize(MIN_SIN * long.norm().max(1e-300))
        .ok_or("the link is parallel to the rotation axis")?;
    let y = z.cross(&x);
    Ok(Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
        x, y, z,
    ])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_right_handed_and_aligned() {
        let long = Vec3::new(0.1, -1.0, 0.05);
        let dorsal = Vec3::new(1.0, 0.2, 0.0);
        let r = frame_from_long_axis(&long, &dorsal).unwrap();
        let m = r.matrix();
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-12);
        assert!((m.column(2) - long.normalize()).norm() < 1e-12);
        assert!(m.column(1).dot(&dorsal) > 0.9);

        let axis = Vec3::new(0.0, 0.1, 1.0);
        let r = frame_from_axis(&axis, &long).unwrap();
        let m = r.matrix();
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        assert!((m.column(0) - axis.normalize()).norm() < 1e-12);
        assert!(m.column(2).dot(&long) > 0.0);
    }

    #[test]
    fn degenerate_directions_are_errors() {
        let v = Vec3::new(0.0, 1.0, 0.0);
        assert!(frame_from_long_axis(&v, &(v * 3.0)).is_err());
        assert!(frame_from_long_axis(&Vec3::zeros(), &v).is_err());
        assert!(frame_from_axis(&v, &v).is_err());
    }
}
