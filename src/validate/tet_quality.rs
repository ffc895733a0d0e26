//! The tetrahedral mesh's quality per subject, read from the `tet` section `reconstruct` writes in `report.json`.

use crate::error::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// One subject's tetrahedral mesh against the template's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TetQualityRow {
    /// Smallest dihedral angle of the template's mesh, degrees.
    pub template_min_dihedral_deg: f64,
    /// Smallest dihedral angle of the subject's mesh, degrees.
    pub subject_min_dihedral_deg: f64,
    /// Largest dihedral angle of the subject's mesh, degrees.
    pub subject_max_dihedral_deg: f64,
    /// Largest radius-edge ratio of the template's mesh.
    pub template_max_radius_edge: f64,
    /// Largest radius-edge ratio of the subject's mesh.
    pub subject_max_radius_edge: f64,
    /// Inverted (or flat) subject tetrahedra.
    pub inverted: u64,
    /// Largest distance of a boundary node to the fitted skin, mm.
    pub boundary_max_distance_mm: f64,
    /// Tet volume against the skin's enclosed volume, %.
    pub volume_error_percent: f64,
    /// ARAP iterations of the elastic solve.
    pub elastic_iterations: u64,
}

/// Read the `tet` section of `report.json` in the `reconstruct` folder `model`. Errors name
/// the file and the missing field.
pub fn read_tet_quality(model: &Path) -> Result<TetQualityRow> {
    let path = model.join("report.json");
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::input(&path, format!("not JSON: {e}")))?;
    let num = |p: &str| -> Result<f64> {
        v.pointer(p)
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| Error::input(&path, format!("no number at '{p}' (re-run reconstruct)")))
    };
    Ok(TetQualityRow {
        template_min_dihedral_deg: num("/tet/template_quality/min_dihedral_deg/min")?,
        subject_min_dihedral_deg: num("/tet/subject_quality/min_dihedral_deg/min")?,
        subject_max_dihedral_deg: num("/tet/subject_quality/max_dihedral_deg/max")?,
        template_max_radius_edge: num("/tet/template_quality/radius_edge/max")?,
        subject_max_radius_edge: num("/tet/subject_quality/radius_edge/max")?,
        inverted: num("/tet/inverted")? as u64,
        boundary_max_distance_mm: num("/tet/boundary_max_distance_mm")?,
        volume_error_percent: num("/tet/volume_error_percent")?,
        elastic_iterations: num("/tet/elastic/iterations")? as u64,
    })
}

/// A markdown section with one row per `(subject, row)`.
pub fn tet_quality_markdown(rows: &[(String, TetQualityRow)]) -> String {
    let mut md = String::from(
        "\n## Tetrahedral mesh (section 3.7)\n\nFrom each subject's `report.json`. The goals: \
         no inverted tetrahedron, the subject's quality not much worse than the template's, \
         boundary within 0.05 mm of the skin, volume within 1 %.\n\n\
         | subject | inverted | min dihedral template / subject (deg) | max dihedral subject (deg) \
         | max radius-edge template / subject | boundary to skin max (mm) | volume vs skin (%) \
         | ARAP iterations |\n|---|---|---|---|---|---|---|---|\n",
    );
    for (name, r) in rows {
        md.push_str(&format!(
            "| {name} | {} | {:.1} / {:.1} | {:.1} | {:.2} / {:.2} | {:.1e} | {:+.2} | {} |\n",
            r.inverted,
            r.template_min_dihedral_deg,
            r.subject_min_dihedral_deg,
            r.subject_max_dihedral_deg,
            r.template_max_radius_edge,
            r.subject_max_radius_edge,
            r.boundary_max_distance_mm,
            r.volume_error_percent,
            r.elastic_iterations
        ));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report's tet section is read field by field; a missing field is named.
    #[test]
    fn reads_the_tet_section_and_names_a_missing_field() {
        let dir = tempfile::tempdir().unwrap();
        let q = |lo: f64, hi: f64, re: f64| {
            serde_json::json!({"n_tets": 10, "min_dihedral_deg": {"min": lo, "median": 40.0, "max": 70.0},
                "max_dihedral_deg": {"min": 80.0, "median": 100.0, "max": hi},
                "radius_edge": {"min": 0.6, "median": 0.8, "max": re}, "inverted": 0})
        };
        let doc = serde_json::json!({"tet": {
            "template_quality": q(6.9, 170.2, 2.9), "subject_quality": q(5.8, 171.6, 3.1),
            "inverted": 0, "boundary_max_distance_mm": 1e-13, "volume_error_percent": -0.3,
            "elastic": {"iterations": 9}}});
        std::fs::write(dir.path().join("report.json"), doc.to_string()).unwrap();
        let r = read_tet_quality(dir.path()).unwrap();
        assert_eq!(r.subject_min_dihedral_deg, 5.8);
        assert_eq!(r.template_max_radius_edge, 2.9);
        assert_eq!(r.elastic_iterations, 9);
        let md = tet_quality_markdown(&[("s".into(), r)]);
        assert!(
            md.contains("| s | 0 | 6.9 / 5.8 | 171.6 | 2.90 / 3.10 |"),
            "{md}"
        );
        let mut bad = doc.clone();
        bad["tet"].as_object_mut().unwrap().remove("inverted");
        std::fs::write(dir.path().join("report.json"), bad.to_string()).unwrap();
        let e = read_tet_quality(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("report.json") && e.contains("/tet/inverted"),
            "{e}"
        );
    }
}
