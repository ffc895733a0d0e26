//! Joint angles from a pose file or a built-in name.
//!
//! `POSE.toml` maps joint names (spec section 2, e.g. `I_MCP`) to degrees: an array
//! `[flexion, abduction, axial rotation]` for a 3-DOF joint (WRIST, T_CMC, the finger MCPs),
//! one number for a 1-DOF joint. Joints not named stay at 0 (the reference posture). Angle
//! conventions are those of [`crate::skeleton`] (positive flexion palmar, positive abduction
//! away from the middle finger, the same on both hands).
//!
//! ```toml
//! I_MCP = [60, 0, 0]
//! I_PIP = 80
//! ```
//!
//! Angles outside the anatomical limits ([`crate::skeleton::limits`]) are clamped; every clamp
//! is returned as a [`LimitViolation`] naming the joint, for the warning.

use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::skeleton::{clamp_pose, LimitViolation, Pose};
use std::path::Path;

/// The built-in poses, by name.
pub const NAMED_POSES: [&str; 5] = ["open", "fist", "power-grasp", "pinch", "tripod"];

/// Largest pose file read, bytes: a pose names at most 16 joints.
const MAX_POSE_FILE: u64 = 64 * 1024;

/// Parse pose-file text (see the module documentation); `path` names it in errors. Returns the
/// pose clamped to the limits and the clamps made.
pub fn parse_pose_toml(text: &str, path: &Path) -> Result<(Pose, Vec<LimitViolation>)> {
    let table: toml::Table = toml::from_str(text).map_err(|e| Error::toml(path, text, &e))?;
    let mut pose = Pose::zero();
    for (name, value) in &table {
        let j = Joint::from_name(name).ok_or_else(|| {
            let all: Vec<&str> = Joint::ALL.iter().map(|j| j.name()).collect();
            Error::input(
                path,
                format!("unknown joint '{name}' (joints: {})", all.join(", ")),
            )
        })?;
        let number = |v: &toml::Value, what: &str| -> Result<f64> {
            let x = match v {
                toml::Value::Float(x) => *x,
                toml::Value::Integer(i) => *i as f64,
                other => {
                    return Err(Error::input(
                        path,
                        format!(
                            "joint {j}: {what} must be a number of degrees, not {}",
                            other.type_str()
                        ),
                    ))
                }
            };
            if x.is_finite() {
                Ok(x)
            } else {
                Err(Error::input(
                    path,
                    format!("joint {j}: {what} is not finite"),
                ))
            }
        };
        let deg = match (j.dof(), value) {
            (3, toml::Value::Array(a)) if a.len() == 3 => [
                number(&a[0], "flexion")?,
                number(&a[1], "abduction")?,
                number(&a[2], "axial rotation")?,
            ],
            (3, toml::Value::Array(a)) => {
                return Err(Error::input(
                    path,
                    format!(
                        "joint {j} has 3 DOF: give [flexion, abduction, axial rotation] in degrees, not {} value(s)",
                        a.len()
                    ),
                ))
            }
            (3, _) => {
                return Err(Error::input(
                    path,
                    format!("joint {j} has 3 DOF: give [flexion, abduction, axial rotation] in degrees"),
                ))
            }
            (_, toml::Value::Array(a)) => {
                return Err(Error::input(
                    path,
                    format!(
                        "joint {j} has 1 DOF: give one number of degrees, not an array of {}",
                        a.len()
                    ),
                ))
            }
            (_, v) => [number(v, "the angle")?, 0.0, 0.0],
        };
        pose = pose.with_deg(j, deg);
    }
    Ok(clamp_pose(&pose))
}

/// Read a pose file (see [`parse_pose_toml`]).
pub fn read_pose_file(path: &Path) -> Result<(Pose, Vec<LimitViolation>)> {
    let len = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    if len > MAX_POSE_FILE {
        return Err(Error::input(
            path,
            format!("{len} bytes is too large for a pose file (at most {MAX_POSE_FILE})"),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_pose_toml(&text, path)
}

/// A built-in pose by name (one of [`NAMED_POSES`]), degrees chosen by hand within the limits
/// of [`crate::skeleton::limits`] after the functional postures of the grasp literature
/// (Feix et al. 2016, "The GRASP taxonomy of human grasp types", IEEE THMS 46(1)):
///
/// | name | digits II-V (MCP flex / PIP / DIP) | thumb (CMC [flex, abd, axial], MCP, IP) |
/// | --- | --- | --- |
/// | `open` | all 0: the reference posture | 0 |
/// | `fist` | MCP 85-90, PIP 100-105, DIP 55-65 | [0, 10, 30], 50, 30: the thumb flexed alongside the index (on the template, thumbs crossing over the curled fingers entered them by 6-12 mm) |
/// | `power-grasp` | MCP 45-55, PIP 55-65, DIP 25-35: around a cylinder of about 40 mm | [20, 45, 20], 20, 15 |
/// | `pinch` | index 45 / 45 / 20 to meet the thumb; middle to little 20-35 / 30-45 / 15-25 | [25, 50, 30], 15, 15 |
/// | `tripod` | index and middle 45 / 45 / 20; ring and little 60 / 70 / 40 tucked | [25, 50, 30], 15, 10 |
pub fn named_pose(name: &str) -> Option<Pose> {
    use Joint::*;
    let p = Pose::zero();
    let fingers = |p: Pose, f: [(Joint, Joint, Joint, f64, f64, f64, f64); 4]| {
        f.into_iter().fold(p, |p, (m, pi, d, a, fm, fp, fd)| {
            p.with_deg(m, [fm, a, 0.0])
                .with_deg(pi, [fp, 0.0, 0.0])
                .with_deg(d, [fd, 0.0, 0.0])
        })
    };
    Some(match name {
        "open" => p,
        "fist" => fingers(
            p,
            [
                (IMcp, IPip, IDip, 0.0, 85.0, 100.0, 55.0),
                (MMcp, MPip, MDip, 0.0, 88.0, 102.0, 60.0),
                (RMcp, RPip, RDip, 0.0, 90.0, 104.0, 62.0),
                (LMcp, LPip, LDip, 0.0, 90.0, 105.0, 65.0),
            ],
        )
        .with_deg(TCmc, [0.0, 10.0, 30.0])
        .with_deg(TMcp, [50.0, 0.0, 0.0])
        .with_deg(TIp, [30.0, 0.0, 0.0]),
        "power-grasp" => fingers(
            p,
            [
                (IMcp, IPip, IDip, 0.0, 45.0, 55.0, 25.0),
                (MMcp, MPip, MDip, 0.0, 50.0, 60.0, 30.0),
                (RMcp, RPip, RDip, 0.0, 52.0, 62.0, 32.0),
                (LMcp, LPip, LDip, 0.0, 55.0, 65.0, 35.0),
            ],
        )
        .with_deg(TCmc, [20.0, 45.0, 20.0])
        .with_deg(TMcp, [20.0, 0.0, 0.0])
        .with_deg(TIp, [15.0, 0.0, 0.0]),
        "pinch" => fingers(
            p,
            [
                (IMcp, IPip, IDip, 0.0, 45.0, 45.0, 20.0),
                (MMcp, MPip, MDip, 0.0, 20.0, 30.0, 15.0),
                (RMcp, RPip, RDip, 0.0, 28.0, 38.0, 20.0),
                (LMcp, LPip, LDip, 0.0, 35.0, 45.0, 25.0),
            ],
        )
        .with_deg(TCmc, [25.0, 50.0, 30.0])
        .with_deg(TMcp, [15.0, 0.0, 0.0])
        .with_deg(TIp, [15.0, 0.0, 0.0]),
        "tripod" => fingers(
            p,
            [
                (IMcp, IPip, IDip, 0.0, 45.0, 45.0, 20.0),
                (MMcp, MPip, MDip, 0.0, 45.0, 45.0, 20.0),
                (RMcp, RPip, RDip, 0.0, 60.0, 70.0, 40.0),
                (LMcp, LPip, LDip, 0.0, 60.0, 70.0, 40.0),
            ],
        )
        .with_deg(TCmc, [25.0, 50.0, 30.0])
        .with_deg(TMcp, [15.0, 0.0, 0.0])
        .with_deg(TIp, [10.0, 0.0, 0.0]),
        _ => return None,
    })
}

/// A pose from the command line: a built-in name (see [`named_pose`]) or else a pose file.
/// Returns the clamped pose and the clamps made.
pub fn resolve_pose(arg: &str) -> Result<(Pose, Vec<LimitViolation>)> {
    if let Some(p) = named_pose(arg) {
        return Ok(clamp_pose(&p));
    }
    let path = Path::new(arg);
    if !path.exists() {
        return Err(Error::input(
            path,
            format!(
                "no such pose file, and not a built-in pose ({})",
                NAMED_POSES.join(", ")
            ),
        ));
    }
    read_pose_file(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::joint_limits_deg;
    use proptest::prelude::*;

    fn parse(text: &str) -> Result<(Pose, Vec<LimitViolation>)> {
        parse_pose_toml(text, Path::new("POSE.toml"))
    }

    #[test]
    fn reads_the_issue_example() {
        let (p, v) = parse("I_MCP = [60, 0, 0]\nI_PIP = 80\nWRIST = [-10.5, 5, 2]\n").unwrap();
        assert!(v.is_empty());
        assert_eq!(
            p.angles[Joint::IMcp.index()],
            [60f64.to_radians(), 0.0, 0.0]
        );
        assert_eq!(
            p.angles[Joint::IPip.index()],
            [80f64.to_radians(), 0.0, 0.0]
        );
        assert_eq!(
            p.angles[Joint::Wrist.index()],
            [-10.5f64.to_radians(), 5f64.to_radians(), 2f64.to_radians()]
        );
        assert_eq!(p.angles[Joint::MMcp.index()], [0.0; 3]);
    }

    #[test]
    fn errors_name_the_file_and_the_joint() {
        let cases = [
            ("I_MPC = 3", "I_MPC"),
            ("I_MCP = 60", "I_MCP has 3 DOF"),
            ("I_MCP = [60, 0]", "not 2 value"),
            ("I_PIP = [80, 0, 0]", "I_PIP has 1 DOF"),
            ("I_PIP = \"80\"", "I_PIP"),
            ("I_PIP = nan", "not finite"),
            ("I_PIP = 80\nI_PIP = 10", "line 2"),
            ("[I_PIP", "line 1"),
        ];
        for (text, want) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains("POSE.toml") && e.contains(want), "{text:?}: {e}");
            assert!(!e.contains('\n'), "one line: {e}");
        }
    }

    #[test]
    fn out_of_range_angles_are_clamped_with_the_joint_named() {
        let (p, v) = parse("I_PIP = 150\nT_CMC = [0, -40, 0]").unwrap();
        assert_eq!(v.len(), 2);
        let names: Vec<String> = v.iter().map(|x| x.to_string()).collect();
        assert!(names.iter().any(|s| s.contains("I_PIP")), "{names:?}");
        assert!(names.iter().any(|s| s.contains("T_CMC")), "{names:?}");
        let [lo, hi] = joint_limits_deg(Joint::IPip)[0];
        assert!((p.angles[Joint::IPip.index()][0].to_degrees() - hi).abs() < 1e-9 && lo < 0.0);
    }

    /// Every built-in pose lies within the limits (clamping changes nothing) and is not the
    /// reference posture, except `open`.
    #[test]
    fn named_poses_are_within_limits() {
        for name in NAMED_POSES {
            let p = named_pose(name).unwrap();
            let (_, v) = clamp_pose(&p);
            assert!(v.is_empty(), "{name}: {v:?}");
            let moved = p.angles.iter().flatten().any(|a| *a != 0.0);
            assert_eq!(moved, name != "open", "{name}");
            assert_eq!(resolve_pose(name).unwrap().0, p);
        }
        assert!(named_pose("wave").is_none());
        let e = resolve_pose("no/such/pose.toml").unwrap_err().to_string();
        assert!(e.contains("pose.toml") && e.contains("fist"), "{e}");
    }

    #[test]
    fn reads_a_file() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.toml");
        std::fs::write(&f, "M_PIP = 45.5").unwrap();
        let (p, _) = resolve_pose(f.to_str().unwrap()).unwrap();
        assert_eq!(p.angles[Joint::MPip.index()][0], 45.5f64.to_radians());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Truncated and mutated pose files give a pose or an error, never a panic.
        #[test]
        fn mutated_files_never_panic(cut in 0usize..80, pos in 0usize..80, byte in any::<u8>()) {
            let valid = b"I_MCP = [60, 0, 0]\nI_PIP = 80\nT_CMC = [10, 20, -5]\n".to_vec();
            let mut b = valid[..cut.min(valid.len())].to_vec();
            if !b.is_empty() {
                let i = pos % b.len();
                b[i] = byte;
            }
            let text = String::from_utf8_lossy(&b);
            let _ = parse(&text);
        }
    }
}
