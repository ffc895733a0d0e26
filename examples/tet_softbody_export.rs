//! Export one subject's tetrahedral deformation problem (seed paper section 3.7) for
//! a side-by-side run in a physics engine (`validation/tools/softbody_compare.py`).
//!
//! ```sh
//! cargo run --release --example tet_softbody_export -- RECONSTRUCT_DIR OUT_DIR [--spacing MM]
//! ```
//!
//! `RECONSTRUCT_DIR` is an `ergohand reconstruct` folder (its `skin.obj` and the `hand` of its
//! `link_model.json`). Writes to `OUT_DIR`:
//! * `rest.vtk`: the template's tetrahedral mesh (isosurface stuffing at `--spacing`, default
//!   the module's 3 mm), the rest shape;
//! * `boundary.json`: the held (boundary) node indices and their target positions on the
//!   subject's fitted skin, mm;
//! * `arap.vtk`: ergohand's volumetric ARAP equilibrium (same nodes and tetrahedra);
//! * `ergohand.json`: sizes, the solver's statistics and its wall times (factorisation, solve).

use ergohand::anatomy::Side;
use ergohand::io::atomic::write_bytes_atomic;
use ergohand::io::{obj, vtk, Units};
use ergohand::tet::{
    bind_boundary, place_boundary, template_tet_mesh_with, ArapOptions, ElasticSolver,
    StuffingParams, TetMesh,
};
use ergohand::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    if let Err(e) = run() {
        eprintln!("tet_softbody_export: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<()> {
    let usage = "usage: tet_softbody_export RECONSTRUCT_DIR OUT_DIR [--spacing MM]";
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dirs: Vec<PathBuf> = Vec::new();
    let mut params = StuffingParams::default();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--spacing" {
            params.spacing = it.next().and_then(|s| s.parse().ok()).ok_or_else(|| {
                Error::invalid(format!("--spacing needs a number in mm; {usage}"))
            })?;
        } else {
            dirs.push(a.into());
        }
    }
    let [recon, out] = <[PathBuf; 2]>::try_from(dirs).map_err(|_| Error::invalid(usage))?;

    let side = read_side(&recon.join("link_model.json"))?;
    let template = ergohand::template::load_template(side)?;
    let skin = obj::read_obj(&recon.join("skin.obj"), Units::Millimetres)?;
    let rest = template_tet_mesh_with(&template.mesh, &params, None)?;
    let binding = bind_boundary(&rest, &template.mesh)?;
    let held = place_boundary(&binding, &skin)?;

    let t0 = Instant::now();
    let solver = ElasticSolver::new(&rest, &binding.nodes)?;
    let factor_s = t0.elapsed().as_secs_f64();
    // Three solves, so that the time reported is not one cold sample.
    let timed_solve = || -> Result<_> {
        let t1 = Instant::now();
        let r = solver.solve(&held, &ArapOptions::default())?;
        Ok((t1.elapsed().as_secs_f64(), r))
    };
    let (first_s, (nodes, stats)) = timed_solve()?;
    let mut solve_s = vec![first_s];
    for _ in 0..2 {
        solve_s.push(timed_solve()?.0);
    }
    let arap = TetMesh {
        nodes,
        tets: rest.tets.clone(),
    };

    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    vtk::write_vtk(&out.join("rest.vtk"), &rest, Units::Millimetres, None)?;
    vtk::write_vtk(&out.join("arap.vtk"), &arap, Units::Millimetres, None)?;
    let boundary = serde_json::json!({
        "units": "mm",
        "nodes": binding.nodes,
        "targets": held.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
    });
    write_json(&out.join("boundary.json"), &boundary)?;
    let info = serde_json::json!({
        "subject": recon.display().to_string(),
        "hand": side.as_str(),
        "spacing_mm": params.spacing,
        "n_nodes": rest.n_nodes(),
        "n_tets": rest.n_tets(),
        "n_boundary_nodes": binding.nodes.len(),
        "threads": rayon::current_num_threads(),
        "factor_s": factor_s,
        "solve_s": solve_s,
        "stats": stats,
        "inverted": arap.inverted_count(),
    });
    write_json(&out.join("ergohand.json"), &info)?;
    eprintln!(
        "{} nodes, {} tets ({} held) at {} mm: factorised in {factor_s:.3} s, solved in {:.3} s \
         ({} iterations, converged {}) -> {}",
        rest.n_nodes(),
        rest.n_tets(),
        binding.nodes.len(),
        params.spacing,
        solve_s.iter().cloned().fold(f64::INFINITY, f64::min),
        stats.iterations,
        stats.converged,
        out.display()
    );
    Ok(())
}

/// The `hand` of a `link_model.json`.
fn read_side(path: &Path) -> Result<Side> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let v: serde_json::Value = serde_json::from_slice(&bytes)
        .map_err(|e| Error::invalid(format!("{}: not JSON: {e}", path.display())))?;
    serde_json::from_value(v["hand"].clone()).map_err(|_| {
        Error::invalid(format!(
            "{}: field `hand` must be \"right\" or \"left\"",
            path.display()
        ))
    })
}

fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    let text =
        serde_json::to_string(v).map_err(|e| Error::invalid(format!("{}: {e}", path.display())))?;
    write_bytes_atomic(path, text.as_bytes())
}
