//! Calibration motions of the seed paper (section 3.3): each trial starts seated in the
//! reference posture, then circumducts the proximal joint, then flexes the distal joints
//! together from open to a "drag rake" posture; the thumb moves CMC, MCP and IP; the wrist
//! trial circumducts the hand.
//!
//! Angles are degrees relative to the subject's reference posture, as functions of time.

use crate::anatomy::{Finger, Joint};
use crate::rng::Rng;

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

/// How one recording of a calibration motion departs from the protocol's nominal motion: a
/// subject who repeats a voluntary motion reaches somewhat different amplitudes, flexes the PIP
/// and DIP in a somewhat different ratio and keeps a somewhat different pace. Every factor is 1
/// for [`MotionVariation::NOMINAL`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionVariation {
    /// Amplitude factors of the proximal joint's two directions (flexion, abduction; wrist:
    /// flexion, deviation).
    pub proximal: [f64; 2],
    /// Amplitude factors of the two distal joints' flexion (PIP and DIP; thumb MCP and IP).
    pub distal: [f64; 2],
    /// Period factors of the proximal circumduction and of the distal flexion.
    pub period: [f64; 2],
}

impl MotionVariation {
    /// The protocol's motion exactly.
    pub const NOMINAL: MotionVariation = MotionVariation {
        proximal: [1.0; 2],
        distal: [1.0; 2],
        period: [1.0; 2],
    };

    /// Draw one recording's variation: every amplitude 85-105 % of the protocol's (subjects
    /// aim at their full range and mostly fall a little short of it), every period 85-115 %.
    /// An assumption of the simulator, not a measured distribution.
    pub fn draw(rng: &mut Rng) -> MotionVariation {
        let mut amp = || rng.range(0.85, 1.05);
        let (proximal, distal) = ([amp(), amp()], [amp(), amp()]);
        MotionVariation {
            proximal,
            distal,
            period: [rng.range(0.85, 1.15), rng.range(0.85, 1.15)],
        }
    }
}

/// The seated posture of one recording relative to the static reference posture, degrees per
/// joint ([`Joint::ALL`] order): every voluntary joint angle (flexion; abduction or deviation of
/// the 3-DOF joints) off by N(0, `sd_deg`), axial rotations 0 (not held voluntarily at these
/// joints). A subject who settles the hand before each trial does not reproduce the static
/// posture exactly, so a trial's seated second is only close to the static trial's posture.
pub fn seated_posture(rng: &mut Rng, sd_deg: f64) -> Vec<[f64; 3]> {
    Joint::ALL
        .iter()
        .map(|j| {
            if sd_deg <= 0.0 {
                return [0.0; 3];
            }
            let flexion = rng.gauss(0.0, sd_deg);
            let abduction = if j.dof() == 3 {
                rng.gauss(0.0, sd_deg)
            } else {
                0.0
            };
            [flexion, abduction, 0.0]
        })
        .collect()
}

/// Joint angles (degrees; `[flexion, abduction, axial]`) at time `t` seconds of a trial of
/// length `duration` s; `rom` scales every range of motion (1 = typical, 0.5 = small). The
/// protocol's nominal motion ([`trial_angles_varied`] with [`MotionVariation::NOMINAL`]).
pub fn trial_angles(trial: Trial, t: f64, duration: f64, rom: f64) -> Vec<(Joint, [f64; 3])> {
    trial_angles_varied(trial, t, duration, rom, &MotionVariation::NOMINAL)
}

/// [`trial_angles`] of one recording whose motion departs from the protocol by `var`. The
/// factors multiply amplitudes and periods, so `NOMINAL` gives exactly the nominal angles.
pub fn trial_angles_varied(
    trial: Trial,
    t: f64,
    duration: f64,
    rom: f64,
    var: &MotionVariation,
) -> Vec<(Joint, [f64; 3])> {
    let moving = (t - SEATED_S).max(0.0);
    let span = (duration - SEATED_S).max(1.0);
    // First half: proximal circumduction; second half: distal flexion.
    let half = span * 0.5;
    let tau = std::f64::consts::TAU;
    match trial {
        Trial::Wrist => {
            // Wrist circumduction: flexion/extension ±60°, radial/ulnar deviation ±20°
            // (centred slightly ulnar, as wrists are), period 5 s.
            let w = tau / (5.0 * var.period[0]);
            let e = ramp(moving) * rom;
            let [fx, dv] = var.proximal;
            vec![(
                Joint::Wrist,
                [
                    e * fx * 60.0 * (w * moving).sin(),
                    e * dv * (20.0 * (w * moving).cos() - 5.0),
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
            let w = tau / (4.0 * var.period[0]);
            let back = if moving < half {
                1.0
            } else {
                (1.0 - (dist / RAMP_S)).max(0.0)
            };
            let e = ramp(prox) * rom * back;
            let phase = w * prox;
            let [fx, ab] = var.proximal;
            let proximal = if f == Finger::Thumb {
                [
                    e * fx * 20.0 * (1.0 - phase.cos()),
                    e * ab * 25.0 * (1.0 + phase.sin()),
                    0.0,
                ]
            } else {
                [
                    e * fx * 40.0 * (1.0 - phase.cos()),
                    e * ab * 20.0 * phase.sin(),
                    0.0,
                ]
            };
            // Distal flexion together, period 3 s: PIP 0-100° with DIP 0-70° (thumb: MCP 0-50°,
            // IP 0-70°).
            let wd = tau / (3.0 * var.period[1]);
            let ed = ramp(dist) * rom;
            let s = 0.5 * (1.0 - (wd * dist).cos());
            let (a1, a2) = if f == Finger::Thumb {
                (50.0, 70.0)
            } else {
                (100.0, 70.0)
            };
            let [d1, d2] = var.distal;
            vec![
                (j0, proximal),
                (j1, [ed * d1 * a1 * s, 0.0, 0.0]),
                (j2, [ed * d2 * a2 * s, 0.0, 0.0]),
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

    /// A repeated recording reaches the protocol's ranges times its factors, and the drawn
    /// factors stay in their documented ranges and differ from draw to draw.
    #[test]
    fn a_repeated_recording_scales_the_ranges() {
        let trial = Trial::Finger(Finger::Index);
        let maxes = |var: &MotionVariation| {
            let mut m = [[0.0f64; 2]; 3];
            for k in 0..6000 {
                let a = trial_angles_varied(trial, k as f64 / 100.0, 60.0, 1.0, var);
                for (i, (_, a)) in a.into_iter().enumerate() {
                    m[i][0] = m[i][0].max(a[0].abs());
                    m[i][1] = m[i][1].max(a[1].abs());
                }
            }
            m
        };
        let var = MotionVariation {
            proximal: [0.9, 1.05],
            distal: [0.85, 1.0],
            period: [1.1, 0.9],
        };
        let (n, v) = (maxes(&MotionVariation::NOMINAL), maxes(&var));
        for (got, want) in [
            (v[0][0] / n[0][0], 0.9),
            (v[0][1] / n[0][1], 1.05),
            (v[1][0] / n[1][0], 0.85),
            (v[2][0] / n[2][0], 1.0),
        ] {
            assert!((got - want).abs() < 0.01, "{got} vs {want}");
        }
        let mut rng = Rng::new(5);
        let (d1, d2) = (
            MotionVariation::draw(&mut rng),
            MotionVariation::draw(&mut rng),
        );
        assert_ne!(d1, d2);
        for d in [d1, d2] {
            for f in d.proximal.iter().chain(&d.distal) {
                assert!((0.85..=1.05).contains(f), "{d:?}");
            }
            assert!(d.period.iter().all(|f| (0.85..=1.15).contains(f)), "{d:?}");
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
