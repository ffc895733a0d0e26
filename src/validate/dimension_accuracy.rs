//! The caliper dimensions measured on a fitted skin (`skin.obj`) by the template's vertex pairs
//! (homology: the pairs' indices hold on every fitted skin), against the values the subject
//! gave (`subject.toml`) and, for simulated subjects, the error-free values of `truth.json`:
//! the seed paper's dimension error (section 5.2: 0.04 ± 0.13 mm).

use crate::anatomy::{Dimension, Side};
use crate::error::{Error, Result};
use crate::geometry::TriMesh;
use crate::template::TemplateSpec;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// One dimension.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DimensionError {
    /// Spec name (`hand_breadth_diagonal`, ...).
    pub name: String,
    /// Measured on the skin, mm.
    pub skin_mm: f64,
    /// Given by the subject (caliper), mm.
    pub given_mm: f64,
    /// Error-free value, when known, mm.
    pub true_mm: Option<f64>,
}

/// Every given dimension and the statistics of `skin − given` (and `skin − true`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DimensionAccuracy {
    /// Per dimension, in the spec's order.
    pub dimensions: Vec<DimensionError>,
    /// Mean of `skin − given`, mm.
    pub mean_vs_given_mm: f64,
    /// SD of `skin − given`, mm.
    pub sd_vs_given_mm: f64,
    /// Mean and SD of `skin − true`, mm, when truth is known.
    pub vs_true_mm: Option<(f64, f64)>,
}

fn mean_sd(x: &[f64]) -> (f64, f64) {
    let n = x.len().max(1) as f64;
    let m = x.iter().sum::<f64>() / n;
    (
        m,
        (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt(),
    )
}

/// Measure the dimensions of `given` on `skin` (homologous to the template of `side`), with
/// `truth` (name -> mm) when known. Errors: a skin whose vertex count is not the template's
/// (it is not homologous; `skin_path` named).
pub fn dimension_accuracy(
    skin: &TriMesh,
    skin_path: &Path,
    side: Side,
    given: &BTreeMap<Dimension, f64>,
    truth: Option<&BTreeMap<String, f64>>,
) -> Result<DimensionAccuracy> {
    let spec = TemplateSpec::embedded()?.hand(side).clone();
    if skin.n_vertices() != spec.vertices {
        return Err(Error::input(
            skin_path,
            format!(
                "has {} vertices, the {side} template {}: it is not homologous to the template",
                skin.n_vertices(),
                spec.vertices
            ),
        ));
    }
    let mut out = Vec::new();
    for d in Dimension::all() {
        let (Some(&g), Some([a, b])) = (given.get(&d), spec.dimension(d)) else {
            continue;
        };
        out.push(DimensionError {
            name: d.name(),
            skin_mm: (skin.vertices[a] - skin.vertices[b]).norm(),
            given_mm: g,
            true_mm: truth.and_then(|t| t.get(&d.name()).copied()),
        });
    }
    let (mean, sd) = mean_sd(
        &out.iter()
            .map(|e| e.skin_mm - e.given_mm)
            .collect::<Vec<_>>(),
    );
    let vs_true: Vec<f64> = out
        .iter()
        .filter_map(|e| e.true_mm.map(|t| e.skin_mm - t))
        .collect();
    Ok(DimensionAccuracy {
        vs_true_mm: (!vs_true.is_empty()).then(|| mean_sd(&vs_true)),
        dimensions: out,
        mean_vs_given_mm: mean,
        sd_vs_given_mm: sd,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::template::load_template;

    /// The template measured against its own pair lengths is exact; a uniformly scaled copy
    /// is off by the scale times each length.
    #[test]
    fn template_measures_itself_and_scaling_shows() {
        let t = load_template(Side::Right).unwrap();
        let given: BTreeMap<Dimension, f64> = Dimension::all()
            .into_iter()
            .map(|d| {
                let [a, b] = t.spec.dimension(d).unwrap();
                (d, (t.mesh.vertices[a] - t.mesh.vertices[b]).norm())
            })
            .collect();
        let acc =
            dimension_accuracy(&t.mesh, Path::new("t.obj"), Side::Right, &given, None).unwrap();
        assert_eq!(acc.dimensions.len(), 22);
        assert!(acc.mean_vs_given_mm.abs() < 1e-12 && acc.sd_vs_given_mm < 1e-12);
        let big = t.mesh.scaled(1.01);
        let acc = dimension_accuracy(&big, Path::new("t.obj"), Side::Right, &given, None).unwrap();
        for e in &acc.dimensions {
            assert!((e.skin_mm - 1.01 * e.given_mm).abs() < 1e-9);
        }
        let e = dimension_accuracy(&t.base.mesh, Path::new("b.obj"), Side::Right, &given, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.obj") && e.contains("homologous"), "{e}");
    }
}
