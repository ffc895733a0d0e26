//! Homologous tetrahedral hand mesh (seed paper section 3.7).
//!
//! 1. The high-resolution template surface is tetrahedralised once by isosurface stuffing
//!    ([`stuffing`], Labelle & Shewchuk 2007) into `R_temp`, cached on disk by content hash
//!    ([`cache`]): [`template_tet_mesh`].
//! 2. Its boundary nodes lie on the template surface; they are bound to it by face and
//!    barycentric coordinates and carried to the fitted skin, which is homologous to the
//!    template (equation 3 for points on a face): [`transfer`].
//! 3. The interior nodes settle by a volumetric as-rigid-as-possible equilibrium with the
//!    boundary held, solved with a prefactorised sparse Cholesky ([`elastic`]), in place of the
//!    paper's Bullet soft-body simulation: [`subject_tet_mesh`].
//! 4. Where the fitted skin bends harder than the elastic step follows (a skin that folds where
//!    the template could not follow the subject), the interior nodes of inverted elements are
//!    moved until the elements are positive again ([`untangle`]).
//!
//! Every subject's mesh has the template's nodes and tetrahedra in the same order, so meshes of
//! different subjects correspond node by node.

pub mod cache;
pub mod elastic;
pub mod stuffing;
pub mod transfer;
pub mod untangle;
pub mod winslow;

pub use crate::geometry::tet_mesh::{Stats, TetGroups, TetMesh, TetQuality};
pub use elastic::{ArapOptions, ElasticSolver, ElasticStats};
pub use stuffing::{isosurface_stuffing, StuffingParams};
pub use transfer::{bind_boundary, place_boundary, place_boundary_nodes, SurfaceBinding};
pub use untangle::{untangle, UntangleOptions, UntangleStats};
pub use winslow::untangle_winslow;

use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::TriMesh;
use crate::template::TemplateHand;
use serde::Serialize;
use std::path::Path;

/// Figures of a subject's tetrahedral mesh, for the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TetReport {
    /// Nodes (same for template and subject).
    pub n_nodes: usize,
    /// Tetrahedra (same for template and subject).
    pub n_tets: usize,
    /// Nodes on the boundary (bound to the skin).
    pub n_boundary_nodes: usize,
    /// Element quality of the template's mesh.
    pub template_quality: TetQuality,
    /// Element quality of the subject's mesh.
    pub subject_quality: TetQuality,
    /// Largest distance from a subject boundary node to the fitted skin surface, mm.
    pub boundary_max_distance_mm: f64,
    /// Volume of the subject's tetrahedral mesh, mm³.
    pub tet_volume_mm3: f64,
    /// Volume enclosed by the fitted skin, mm³.
    pub skin_volume_mm3: f64,
    /// `100 (tet - skin) / skin`.
    pub volume_error_percent: f64,
    /// Inverted (or flat) subject tetrahedra.
    pub inverted: usize,
    /// How the elastic solve went.
    pub elastic: ElasticStats,
    /// What the untangling after it did (`inverted_after` is `inverted`).
    pub untangle: UntangleStats,
}

/// [`template_tet_mesh_with`] the default [`StuffingParams`].
pub fn template_tet_mesh(template: &TemplateHand, cache: Option<&Path>) -> Result<TetMesh> {
    template_tet_mesh_with(&template.mesh, &StuffingParams::default(), cache)
}

/// The tetrahedral mesh `R_temp` of a template surface by [`isosurface_stuffing`], read from
/// the cache when a valid entry for this surface and these parameters exists, else built and
/// stored. `cache`: the cache folder, or `None` for [`cache::default_cache_dir`]. The cache is
/// an optimisation only: a cache that cannot be read or written is skipped silently.
pub fn template_tet_mesh_with(
    surface: &TriMesh,
    params: &StuffingParams,
    cache: Option<&Path>,
) -> Result<TetMesh> {
    let dir = cache
        .map(Path::to_path_buf)
        .or_else(cache::default_cache_dir);
    let key = cache::cache_key(surface, params);
    if let Some(mesh) = dir.as_deref().and_then(|d| cache::load(d, key)) {
        return Ok(mesh);
    }
    let mesh = isosurface_stuffing(surface, params)?;
    if let Some(d) = dir.as_deref() {
        let _ = cache::store(d, key, &mesh);
    }
    Ok(mesh)
}

/// Everything of section 3.7 that depends on the template alone, made once: its tetrahedral
/// mesh `R_temp`, the binding of its boundary nodes to the template surface and the factorised
/// elastic solver. [`TemplateTet::deform`] then costs a subject only the boundary placement
/// and the ARAP iterations; `reconstruct` prepares it on a second thread while the link model
/// and the skin are fitted, and a batch can share one per hand.
pub struct TemplateTet {
    /// Which hand's template.
    pub side: crate::anatomy::Side,
    /// `R_temp`.
    pub tet: TetMesh,
    /// Its boundary nodes bound to the template's high-resolution surface.
    pub binding: SurfaceBinding,
    /// The prefactorised ARAP problem with the boundary held.
    pub solver: ElasticSolver,
}

impl TemplateTet {
    /// Load (or build and cache, see [`template_tet_mesh`]) the template's tet mesh, bind its
    /// boundary and factorise the solver.
    pub fn prepare(template: &TemplateHand, cache: Option<&Path>) -> Result<Self> {
        let tet = template_tet_mesh(template, cache)?;
        Self::from_mesh(template, tet)
    }

    /// [`TemplateTet::prepare`] from a tet mesh already at hand.
    pub fn from_mesh(template: &TemplateHand, tet: TetMesh) -> Result<Self> {
        let binding = bind_boundary(&tet, &template.mesh)?;
        let solver = ElasticSolver::new(&tet, &binding.nodes)?;
        Ok(TemplateTet {
            side: template.side,
            tet,
            binding,
            solver,
        })
    }

    /// The subject's tetrahedral mesh for a fitted skin homologous to the template (see
    /// [`subject_tet_mesh`]).
    pub fn deform(&self, fitted_skin: &TriMesh) -> Result<(TetMesh, TetReport)> {
        deform(&self.tet, &self.binding, &self.solver, fitted_skin)
    }
}

/// The subject's tetrahedral mesh `R_target` (section 3.7): `template_tet`'s boundary nodes,
/// bound to `template.mesh`, are placed on `fitted_skin` (homologous to it), and the interior
/// nodes follow by volumetric ARAP equilibrium ([`ElasticSolver`]). Same nodes and tetrahedra,
/// in the same order, as `template_tet`. Errors (one line) when the skin is not homologous to
/// the template or the template mesh is unusable.
pub fn subject_tet_mesh(
    template: &TemplateHand,
    template_tet: &TetMesh,
    fitted_skin: &TriMesh,
) -> Result<(TetMesh, TetReport)> {
    let binding = bind_boundary(template_tet, &template.mesh)?;
    let solver = ElasticSolver::new(template_tet, &binding.nodes)?;
    deform(template_tet, &binding, &solver, fitted_skin)
}

/// [`subject_tet_mesh`] with the binding and the factorised solver made beforehand (to deform
/// one template mesh to many subjects).
pub fn deform(
    template_tet: &TetMesh,
    binding: &SurfaceBinding,
    solver: &ElasticSolver,
    fitted_skin: &TriMesh,
) -> Result<(TetMesh, TetReport)> {
    if solver.fixed() != binding.nodes.as_slice() {
        return Err(Error::invalid(
            "tet deformation: the solver holds other nodes than the binding binds",
        ));
    }
    let held = place_boundary(binding, fitted_skin)?;
    let (nodes, stats) = solver.solve(&held, &ArapOptions::default())?;
    let mut subject = TetMesh {
        nodes,
        tets: template_tet.tets.clone(),
    };
    let reference: Vec<f64> = (0..template_tet.n_tets())
        .map(|t| template_tet.tet_volume(t))
        .collect();
    let untangled = untangle(
        &mut subject.nodes,
        &subject.tets,
        &binding.nodes,
        &reference,
        &UntangleOptions::default(),
    );
    let tree = AabbTree::new(fitted_skin);
    let boundary_max_distance_mm = binding
        .nodes
        .iter()
        .map(|&v| tree.distance(&subject.nodes[v]).unwrap_or(f64::INFINITY))
        .fold(0.0, f64::max);
    let tet_volume_mm3 = subject.volume();
    let skin_volume_mm3 = fitted_skin.signed_volume();
    let subject_quality = subject.quality();
    let report = TetReport {
        n_nodes: subject.n_nodes(),
        n_tets: subject.n_tets(),
        n_boundary_nodes: binding.nodes.len(),
        template_quality: template_tet.quality(),
        subject_quality,
        boundary_max_distance_mm,
        tet_volume_mm3,
        skin_volume_mm3,
        volume_error_percent: 100.0 * (tet_volume_mm3 - skin_volume_mm3) / skin_volume_mm3,
        inverted: subject_quality.inverted,
        elastic: stats,
        untangle: untangled,
    };
    Ok((subject, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::rng::Rng;
    use crate::skin::pipeline::fit_skin;
    use crate::synth::{simulate, Preset, SynthOptions};
    use crate::template::load_template;
    use nalgebra::{Isometry3, Translation3};
    use std::sync::OnceLock;

    /// The right template and its tet mesh (built once, not cached on disk in tests).
    fn fixture() -> &'static (TemplateHand, TetMesh) {
        static F: OnceLock<(TemplateHand, TetMesh)> = OnceLock::new();
        F.get_or_init(|| {
            let t = load_template(Side::Right).unwrap();
            let m = isosurface_stuffing(&t.mesh, &StuffingParams::default()).unwrap();
            (t, m)
        })
    }

    #[test]
    fn template_mesh_is_sound() {
        let (t, m) = fixture();
        let q = m.quality();
        eprintln!(
            "template tet: {} nodes, {} tets, {} boundary nodes, quality {q:?}",
            m.n_nodes(),
            m.n_tets(),
            m.boundary_nodes().len()
        );
        assert!((50_000..=200_000).contains(&m.n_tets()));
        assert_eq!(q.inverted, 0);
        let rel = (m.volume() - t.mesh.signed_volume()) / t.mesh.signed_volume();
        assert!(rel.abs() < 0.01, "volume error {rel}");
        let b = bind_boundary(m, &t.mesh).unwrap();
        assert!(b.max_distance < 1e-9, "{}", b.max_distance);
    }

    /// The fitted skin a rigid motion of the template: the whole tet mesh moves rigidly.
    #[test]
    fn rigid_skin_moves_mesh_rigidly() {
        let (t, m) = fixture();
        let mut rng = Rng::new(9);
        let iso = Isometry3::from_parts(Translation3::from(rng.gauss3(80.0)), rng.rotation());
        let (s, r) = subject_tet_mesh(t, m, &t.mesh.transformed(&iso)).unwrap();
        let err = s
            .nodes
            .iter()
            .zip(&m.nodes)
            .map(|(a, b)| (a - iso * b).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "{err}");
        assert_eq!(r.inverted, 0);
    }

    /// Two simulated subjects: homologous by index, no inverted tet, boundary on the skin,
    /// volume within 1 % of the skin's.
    #[test]
    fn simulated_subjects_are_homologous() {
        let (t, m) = fixture();
        let mut meshes = Vec::new();
        for seed in [61, 62] {
            let s = simulate(&SynthOptions {
                duration_s: Some(3.0),
                voxel_mm: 2.0,
                ..SynthOptions::new(seed, Preset::Typical)
            })
            .unwrap();
            assert_eq!(s.subject.hand, Side::Right);
            let fit = fit_skin(
                t,
                &s.trials["reference"],
                &s.subject.dimensions,
                s.subject.marker_offset_mm,
                None,
                &crate::skin::pipeline::SkinOptions::default(),
            )
            .unwrap();
            let (mesh, r) = subject_tet_mesh(t, m, &fit.high).unwrap();
            eprintln!("seed {seed}: {r:?}");
            assert_eq!(mesh.tets, m.tets);
            assert_eq!(mesh.n_nodes(), m.n_nodes());
            assert_eq!(r.inverted, 0);
            assert!(r.boundary_max_distance_mm < 0.05);
            assert!(r.volume_error_percent.abs() < 1.0);
            meshes.push(mesh);
        }
        // Different subjects, different shapes, same structure.
        let moved = meshes[0]
            .nodes
            .iter()
            .zip(&meshes[1].nodes)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(moved > 0.5, "{moved}");
    }

    #[test]
    fn non_homologous_skin_is_an_error() {
        let (t, m) = fixture();
        let mut skin = t.mesh.clone();
        skin.faces.swap(0, 1);
        let e = subject_tet_mesh(t, m, &skin).unwrap_err().to_string();
        assert!(e.contains("homologous") && !e.contains('\n'), "{e}");
    }
}
