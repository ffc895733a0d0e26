//! Calibration motions of the seed paper (section 3.3): each trial starts seated in the
//! reference posture, then circumducts the proximal joint, then flexes the distal joints
//! together from open to a "drag rake" posture; the thumb moves CMC, MCP and IP; the wrist
//! trial circumducts the hand.
//!
//! Angles are degrees relative to the subject's reference posture, as functions of time.

use crate::anatomy::{Finger, Joint};

/// Which calibration trial.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trial {
    /// The wrist trial.
    Wrist,
    /// One digit's trial.
    Finger(Finger),
}

/// Seconds seated still at the start (the reference frame lies in it).
pub const SEATED_S: f64 = 1.0;
/// Seconds to ramp a motion's amplitude in, so it starts smoothly from rest.
const RAMP_S: f64 = 2.0;

fn ramp(t: f64) -> f64 {
    let x = (t / RAMP_S).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Joint angles (degrees; `[flexion, abduction, axial]`) at time `t` seconds of a trial of
/// length `duration` s; `rom` scales every range of motion (1 = typical, 0.5 = small).
pub fn trial_angles(trial: Trial, t: f64, duration: f64, rom: f64) -> Vec<(Joint, [f64; 3])> {
    let moving = (t - SEATED_S).max(0.0);
    let span = (duration - SEATED_S).max(1.0);
    // First half: proximal circumduction; second half: distal flexion.
    let half = span * 0.5;
    let tau = std::f64::consts::TAU;
    match trial {
        Trial::Wrist => {
            // Wrist circumduction: flexion/extension ±60°, radial/ulnar deviation ±20°
            // (centred slightly ulnar, as wrists are), period 5 s.
            let w = tau / 5.0;
            let e = ramp(moving) * rom;
            vec![(
                Joint::Wrist,
                [
                    e * 60.0 * (w * moving).sin(),
                    e * (20.0 * (w * moving).cos() - 5.0),
                    0.0,
                ],
            )]
        }
        Trial::Finger(f) => {
            let [j0, j1, j2] = f.joints();
            let (prox, dist) = if moving < half {
                (moving, 0.0)
            } else {
                (half, moving - half)
            };
            // Proximal circumduction: a loop in (flexion, abduction) starting at rest. Fingers:
            // MCP flexion 0-80°, abduction ±20°, period 4 s. Thumb CMC: flexion 0-40°, palmar
            // abduction 0-50°.
            let w = tau / 4.0;
            let back = if moving < half {
                1.0
            } else {
                (1.0 - (dist / RAMP_S)).max(0.0)
            };
            let e = ramp(prox) * rom * back;
            let phase = w * prox;
            let proximal = if f == Finger::Thumb {
                [
                    e * 20.0 * (1.0 - phase.cos()),
                    e * 25.0 * (1.0 + phase.sin()),
                    0.0,
                ]
            } else {
                [e * 40.0 * (1.0 - phase.cos()), e * 20.0 * phase.sin(), 0.0]
            };
            // Distal flexion together, period 3 s: PIP 0-100° with DIP 0-70° (thumb: MCP 0-50°,
            // IP 0-70°).
            let wd = tau / 3.0;
            let ed = ramp(dist) * rom;
            let s = 0.5 * (1.0 - (wd * dist).cos());
            let (a1, a2) = if f == Finger::Thumb {
                (50.0, 70.0)
            } else {
                (100.0, 70.0)
            };
            vec![
                (j0, proximal),
                (j1, [ed * a1 * s, 0.0, 0.0]),
                (j2, [ed * a2 * s, 0.0, 0.0]),
            ]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trials_start_at_rest_and_reach_their_ranges() {
        for trial in [
            Trial::Wrist,
            Trial::Finger(Finger::Index),
            Trial::Finger(Finger::Thumb),
        ] {
            let at = |t: f64| trial_angles(trial, t, 60.0, 1.0);
            for (_, a) in at(0.0).into_iter().chain(at(0.5)) {
                assert!(a.iter().all(|x| x.abs() < 1e-12), "{trial:?}");
            }
            let mut maxes = [[0.0f64; 3]; 3];
            for k in 0..6000 {
                for (i, (_, a)) in at(k as f64 / 100.0).into_iter().enumerate() {
                    for d in 0..3 {
                        maxes[i][d] = maxes[i][d].max(a[d].abs());
                    }
                }
            }
            match trial {
                Trial::Finger(Finger::Index) => {
                    assert!(maxes[0][0] > 75.0 && maxes[0][1] > 18.0);
                    assert!(maxes[1][0] > 95.0 && maxes[2][0] > 65.0);
                }
                Trial::Wrist => assert!(maxes[0][0] > 55.0),
                _ => assert!(maxes[1][0] > 45.0),
            }
        }
    }

    #[test]
    fn small_rom_halves_the_ranges() {
        let t = 10.0;
        let full = trial_angles(Trial::Finger(Finger::Ring), t, 60.0, 1.0);
        let half = trial_angles(Trial::Finger(Finger::Ring), t, 60.0, 0.5);
        for ((_, a), (_, b)) in full.iter().zip(&half) {
            for d in 0..3 {
                assert!((a[d] * 0.5 - b[d]).abs() < 1e-9);
            }
        }
    }
}
