//! A smooth random displacement of the skin along its normals: the individual bumps and hollows
//! (fat pads, tendons, creases) that no affine or per-segment scaling can represent.
//!
//! Random Fourier features (Rahimi & Recht 2007): `d(p) = Σ_k a_k cos(2π/λ_k · u_k·p + φ_k)`
//! with random unit directions `u_k`, wavelengths `λ_k` uniform in a band and random phases,
//! a stationary Gaussian-like field with spectrum in that band; scaled so its largest magnitude
//! over the surface equals the requested amplitude.

use crate::geometry::{Point, TriMesh};
use crate::rng::Rng;

/// Parameters of the field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldParams {
    /// Largest |displacement| over the surface, mm.
    pub amplitude_mm: f64,
    /// Shortest wavelength, mm.
    pub min_wavelength_mm: f64,
    /// Longest wavelength, mm.
    pub max_wavelength_mm: f64,
    /// Number of Fourier features.
    pub features: usize,
}

impl Default for FieldParams {
    fn default() -> Self {
        FieldParams {
            amplitude_mm: 1.0,
            min_wavelength_mm: 10.0,
            max_wavelength_mm: 40.0,
            features: 32,
        }
    }
}

/// Displace every vertex of `mesh` along its normal by the field; returns the displacements.
pub fn displace_along_normals(mesh: &mut TriMesh, params: &FieldParams, rng: &mut Rng) -> Vec<f64> {
    let feats: Vec<(nalgebra::Vector3<f64>, f64, f64)> = (0..params.features)
        .map(|_| {
            let u = rng.unit_vector();
            let lambda = rng.range(params.min_wavelength_mm, params.max_wavelength_mm);
            let phase = rng.range(0.0, std::f64::consts::TAU);
            (
                u * (std::f64::consts::TAU / lambda),
                phase,
                rng.range(0.5, 1.0),
            )
        })
        .collect();
    let field = |p: &Point| -> f64 {
        feats
            .iter()
            .map(|(k, phase, a)| a * (k.dot(&p.coords) + phase).cos())
            .sum()
    };
    let raw: Vec<f64> = mesh.vertices.iter().map(field).collect();
    let peak = raw.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    let scale = if peak > 0.0 {
        params.amplitude_mm / peak
    } else {
        0.0
    };
    let normals = mesh.vertex_normals();
    let d: Vec<f64> = raw.iter().map(|x| x * scale).collect();
    for ((p, n), di) in mesh.vertices.iter_mut().zip(&normals).zip(&d) {
        *p += n * *di;
    }
    d
}
