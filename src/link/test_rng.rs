//! Deterministic random numbers for the link estimators' tests (SplitMix64 + Box-Muller), so the
//! synthetic trials are reproducible without an extra dependency.

use crate::geometry::Vec3;
use nalgebra::{Quaternion, UnitQuaternion};

/// SplitMix64 generator (Steele, Lea & Flood 2014).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Standard normal (Box-Muller).
    pub fn gaussian(&mut self) -> f64 {
        let (a, b) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    /// Isotropic Gaussian vector with standard deviation `sd` per component.
    pub fn gaussian_vec(&mut self, sd: f64) -> Vec3 {
        Vec3::new(self.gaussian(), self.gaussian(), self.gaussian()) * sd
    }

    /// Uniformly distributed unit vector.
    pub fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.gaussian_vec(1.0);
            let n = v.norm();
            if n > 1e-6 {
                return v / n;
            }
        }
    }

    /// Uniformly distributed rotation (normalised Gaussian quaternion).
    pub fn rotation(&mut self) -> UnitQuaternion<f64> {
        loop {
            let q = Quaternion::new(
                self.gaussian(),
                self.gaussian(),
                self.gaussian(),
                self.gaussian(),
            );
            if q.norm() > 1e-6 {
                return UnitQuaternion::from_quaternion(q);
            }
        }
    }
}
