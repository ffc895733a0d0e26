#!/usr/bin/env python3
"""ergohand's elastic tet solve against a Bullet soft body on the same mesh.

Usage: python3 validation/tools/softbody_compare.py EXPORT_DIR [--out FILE.json] [options]

EXPORT_DIR is written by `cargo run --release --example tet_softbody_export`: `rest.vtk` (the
template's tetrahedral mesh), `boundary.json` (held nodes and their targets on the subject's
fitted skin), `arap.vtk` (ergohand's volumetric ARAP equilibrium) and `ergohand.json` (its
solver statistics and wall times).

The same rest mesh is loaded into pybullet's deformable world (Neo-Hookean soft body, no
gravity, no collision partner). Every boundary node is anchored to the world (which makes it
kinematic) and moved, by `resetMeshData`, from its rest position to its target over `--ramp`
steps; then the body is stepped until the interior's geometric decay (its largest motion per
step and the contraction of that motion over 20 steps) leaves less than `--tol` mm to go (or
`--max-steps`). Both engines then hold the same boundary, so what differs is the interior:
node distances (mean, 95th percentile, max over interior nodes), per-tetrahedron volume ratio
(deformed / rest), inverted tetrahedra, the ARAP energy of both results, and wall times.

The subject's fitted skin lies in the subject's capture frame, far from the template's; a
rigid motion does not change either energy, so the targets are first brought back onto the
rest shape by the best rigid fit of the boundary (Kabsch), the soft body is simulated there,
and its result is moved forward by the same rigid motion before comparing.

Needs `pip install pybullet numpy`. Writes one JSON with every figure (`--out`) and prints a
Markdown table row set on stdout.
"""
import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pybullet as p


def read_vtk(path):
    """Nodes (n, 3) and tetrahedra (m, 4) of a legacy ASCII VTK unstructured grid."""
    lines = Path(path).read_text().splitlines()
    i = 0
    nodes = tets = None
    while i < len(lines):
        w = lines[i].split()
        if w and w[0] == "POINTS":
            n = int(w[1])
            nodes = np.loadtxt(lines[i + 1 : i + 1 + n], dtype=float).reshape(n, 3)
            i += n
        elif w and w[0] == "CELLS":
            m = int(w[1])
            cells = np.loadtxt(lines[i + 1 : i + 1 + m], dtype=np.int64).reshape(m, 5)
            if (cells[:, 0] != 4).any():
                sys.exit(f"{path}: CELLS: only tetrahedra (4 points) are supported")
            tets = cells[:, 1:]
            i += m
        i += 1
    if nodes is None or tets is None:
        sys.exit(f"{path}: no POINTS or no CELLS section")
    return nodes, tets


def kabsch(a, b):
    """Rotation r and translation t minimising |r a + t - b| (rows are points)."""
    ca, cb = a.mean(0), b.mean(0)
    h = (a - ca).T @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, cb - r @ ca


def tet_volumes(x, tets):
    a, b, c, d = (x[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0


def arap_energy(rest, x, tets):
    """Sum over tets of V |F - R|_F^2 (the energy ergohand minimises), R nearest rotation."""
    dm = np.stack([rest[tets[:, k]] - rest[tets[:, 0]] for k in (1, 2, 3)], axis=2)
    ds = np.stack([x[tets[:, k]] - x[tets[:, 0]] for k in (1, 2, 3)], axis=2)
    f = ds @ np.linalg.inv(dm)
    u, s, vt = np.linalg.svd(f)
    det = np.linalg.det(u @ vt)
    s_rot = np.ones_like(s)
    s_rot[:, 2] = np.sign(det)  # reflection removed on the smallest singular value
    # |F - R|^2 = sum (s_i - s_rot_i)^2 in the SVD basis.
    vol = np.abs(np.linalg.det(dm)) / 6.0
    return float((vol * ((s - s_rot) ** 2).sum(1)).sum())


def volume_ratio_stats(rest, x, tets):
    r = tet_volumes(x, tets) / tet_volumes(rest, tets)
    q = np.percentile(r, [1, 50, 99])
    return {
        "min": float(r.min()),
        "p1": float(q[0]),
        "median": float(q[1]),
        "p99": float(q[2]),
        "max": float(r.max()),
        "inverted": int((r <= 0).sum()),
    }


class Quiet:
    """Silence C-level stdout (Bullet's VTK loader prints every tetrahedron)."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.close(devnull)

    def __exit__(self, *exc):
        os.dup2(self.saved, 1)
        os.close(self.saved)


# pybullet 3.2.7's loadSoftBody serialises the new body into its fixed 8 MB client buffer
# without a size check (btSoftBody::serialize from createBodyInfoStream) and crashes beyond it:
# measured, 47,301 tetrahedra (10,224 nodes) load and 66,859 (14,095 nodes) crash.
MAX_PYBULLET_TETS = 55_000


def simulate(args, rest, tets, vtk_path, held, targets_local):
    """Bullet's equilibrium (rest frame) and its timings and convergence history."""
    if len(tets) > MAX_PYBULLET_TETS and not args.try_large:
        sys.exit(
            f"{vtk_path}: {len(tets)} tetrahedra is more than pybullet's loadSoftBody survives "
            f"(its 8 MB body-info buffer overflows above about {MAX_PYBULLET_TETS}); use a "
            "coarser --spacing in the exporter, or --try-large"
        )
    timings = {}
    p.connect(p.DIRECT)
    p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD)
    p.setGravity(0, 0, 0)
    p.setPhysicsEngineParameter(fixedTimeStep=args.dt)
    t0 = time.perf_counter()
    with Quiet():
        body = p.loadSoftBody(
            str(vtk_path),
            basePosition=[0, 0, 0],
            scale=1.0,
            mass=args.mass,
            useNeoHookean=1,
            NeoHookeanMu=args.mu,
            NeoHookeanLambda=args.lam,
            NeoHookeanDamping=args.damping,
            collisionMargin=args.margin,
            useSelfCollision=0,
            frictionCoeff=0.0,
        )
    timings["load_s"] = time.perf_counter() - t0

    def nodes():
        return np.asarray(p.getMeshData(body, -1, flags=p.MESH_DATA_SIMULATION_MESH)[1])

    x0 = nodes()
    if x0.shape != rest.shape:
        sys.exit(f"pybullet loaded {len(x0)} nodes, {vtk_path} has {len(rest)}")
    # Node order: Bullet keeps the VTK's, checked here; else map by rest position.
    order_err = float(np.abs(x0 - rest).max())
    perm = None
    if order_err > 1e-6 * max(1.0, float(np.abs(rest).max())):
        key = {tuple(np.round(q, 4)): i for i, q in enumerate(x0)}
        try:
            perm = np.array([key[tuple(np.round(q, 4))] for q in rest])
        except KeyError:
            sys.exit("pybullet's nodes are neither in the VTK's order nor at its positions")
    # Our node i is Bullet's node sim[i]: ours = bullet[sim], and bullet = ours[inv].
    sim = perm if perm is not None else np.arange(len(rest))
    inv = np.empty_like(sim)
    inv[sim] = np.arange(len(sim))

    t0 = time.perf_counter()
    for v in held:
        p.createSoftBodyAnchor(body, int(sim[v]), -1, -1)
    timings["anchor_s"] = time.perf_counter() - t0

    interior = np.setdiff1d(np.arange(len(rest)), held)
    step_s = 0.0
    history = []
    t_run, cpu_run = time.perf_counter(), time.process_time()
    x = x0[sim]
    start = rest[held]
    for s in range(1, args.ramp + 1):
        x[held] = start + (s / args.ramp) * (targets_local - start)
        p.resetMeshData(body, vertices=x[inv].tolist())
        t0 = time.perf_counter()
        p.stepSimulation()
        step_s += time.perf_counter() - t0
        x = nodes()[sim]
    steps = args.ramp
    residual = math.inf
    converged = False
    while steps < args.max_steps:
        prev = x
        t0 = time.perf_counter()
        p.stepSimulation()
        step_s += time.perf_counter() - t0
        x = nodes()[sim]
        steps += 1
        move = np.linalg.norm(x[interior] - prev[interior], axis=1)
        residual = float(move.max())
        history.append((steps, residual, float(move.mean())))
        if not args.quiet and steps % 10 == 0:
            print(f"step {steps}: interior moved up to {residual:.2e} mm", file=sys.stderr)
        if not np.isfinite(x).all():
            break
        # Settled when the distance still to go, residual * q / (1 - q) for the geometric
        # contraction q per step measured over the last 20 steps, is below the tolerance.
        if len(history) > 20:
            q = (residual / history[-21][1]) ** 0.05 if history[-21][1] > 0 else 0.0
            if q < 1.0 and residual * q / (1.0 - q) < args.tol:
                converged = True
                break
    timings["run_s"] = time.perf_counter() - t_run
    timings["run_cpu_s"] = time.process_time() - cpu_run
    timings["step_s"] = step_s
    boundary_err = float(np.linalg.norm(x[held] - targets_local, axis=1).max())
    p.disconnect()
    # Contraction per step over the last 20 steps, and the distance still to go it implies.
    tail = [h[1] for h in history[-21:]]
    rate = (tail[-1] / tail[0]) ** (1.0 / (len(tail) - 1)) if len(tail) > 1 and tail[0] > 0 else 0.0
    to_go = residual * rate / (1.0 - rate) if 0.0 < rate < 1.0 else math.inf
    sim_info = {
        "node_order_max_diff_mm": order_err,
        "node_order": "vtk" if perm is None else "mapped by rest position",
        "steps": steps,
        "ramp_steps": args.ramp,
        "converged": converged,
        "last_residual_mm_per_step": residual,
        "contraction_per_step": rate,
        "estimated_remaining_mm": to_go,
        "boundary_max_error_mm": boundary_err,
        "timings": timings,
        "residual_history": history[:: max(1, len(history) // 50)] + history[-1:],
    }
    return x, sim_info


def stats(d):
    return {
        "mean": float(d.mean()),
        "p95": float(np.percentile(d, 95)),
        "max": float(d.max()),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("export_dir", type=Path)
    ap.add_argument("--out", type=Path, help="JSON with every figure")
    ap.add_argument("--mu", type=float, default=100.0, help="Neo-Hookean mu (default 100)")
    ap.add_argument("--poisson", type=float, default=0.3, help="sets lambda = 2 mu nu / (1 - 2 nu)")
    ap.add_argument("--damping", type=float, default=0.003,
                    help="Neo-Hookean damping (default 0.003: overdamped, fastest settling found)")
    ap.add_argument("--mass", type=float, default=1.0, help="total mass (default 1)")
    ap.add_argument("--dt", type=float, default=1.0 / 240.0, help="time step, s (default 1/240)")
    ap.add_argument("--margin", type=float, default=0.01, help="collision margin (no partner)")
    ap.add_argument("--ramp", type=int, default=20, help="steps to move the boundary (default 20)")
    ap.add_argument("--max-steps", type=int, default=3000)
    ap.add_argument("--try-large", action="store_true",
                    help=f"load meshes above {MAX_PYBULLET_TETS} tetrahedra anyway (may crash)")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    ap.add_argument("--affine-check", action="store_true",
                    help="replace the subject by an affine map of the rest shape and compare "
                    "Bullet with that map's exact equilibrium (the map itself) instead of ergohand")
    ap.add_argument("--tol", type=float, default=1e-3,
                    help="settled: estimated interior distance still to go, mm (default 1e-3)")
    args = ap.parse_args()
    args.lam = 2.0 * args.mu * args.poisson / (1.0 - 2.0 * args.poisson)

    d = args.export_dir
    for f in ("rest.vtk", "arap.vtk", "boundary.json", "ergohand.json"):
        if not (d / f).is_file():
            sys.exit(f"{d / f}: missing (run the tet_softbody_export example first)")
    rest, tets = read_vtk(d / "rest.vtk")
    arap, arap_tets = read_vtk(d / "arap.vtk")
    if arap.shape != rest.shape or not np.array_equal(arap_tets, tets):
        sys.exit(f"{d / 'arap.vtk'}: not the same mesh as rest.vtk")
    bnd = json.loads((d / "boundary.json").read_text())
    held = np.asarray(bnd["nodes"], dtype=np.int64)
    targets = np.asarray(bnd["targets"], dtype=float)
    if targets.shape != (len(held), 3) or held.max() >= len(rest):
        sys.exit(f"{d / 'boundary.json'}: field `targets` must hold one point per node in `nodes`")
    ergo = json.loads((d / "ergohand.json").read_text())

    if args.affine_check:
        # Calibration: an affine boundary map's equilibrium is the same affine map of the whole
        # body for any homogeneous elastic material, so Bullet's distance to it is its own error.
        c = rest.mean(0)
        a = np.array([[1.08, 0.05, 0.0], [0.0, 0.95, 0.04], [0.03, 0.0, 1.02]])
        arap = (rest - c) @ a.T + c
        targets = arap[held]
    r, t = kabsch(rest[held], targets)
    targets_local = (targets - t) @ r  # r^T (targets - t), row-wise
    bullet_local, sim_info = simulate(args, rest, tets, d / "rest.vtk", held, targets_local)
    bullet = bullet_local @ r.T + t

    interior = np.setdiff1d(np.arange(len(rest)), held)
    dist = np.linalg.norm(bullet - arap, axis=1)
    disp = np.linalg.norm(arap - (rest @ r.T + t), axis=1)
    result = {
        "mesh": {
            "spacing_mm": ergo["spacing_mm"],
            "nodes": len(rest),
            "tets": len(tets),
            "boundary_nodes": len(held),
            "interior_nodes": len(interior),
        },
        "subject": "affine check (exact equilibrium in place of ergohand)"
        if args.affine_check
        else ergo["subject"],
        "rigid_alignment": {
            "boundary_rms_mm": float(
                np.sqrt((((rest[held] @ r.T + t) - targets) ** 2).sum(1).mean())
            ),
        },
        "interior_displacement_from_rigid_rest_mm": stats(disp[interior]),
        "distance_bullet_vs_ergohand_interior_mm": stats(dist[interior]),
        "distance_bullet_vs_ergohand_boundary_max_mm": float(dist[held].max()),
        "volume_ratio": {
            "ergohand": volume_ratio_stats(rest, arap, tets),
            "bullet": volume_ratio_stats(rest, bullet, tets),
        },
        "arap_energy_mm3": {
            "ergohand": arap_energy(rest, arap, tets),
            "bullet": arap_energy(rest, bullet, tets),
        },
        "ergohand": {
            "factor_s": ergo["factor_s"],
            "solve_s": min(ergo["solve_s"]),
            "total_s": ergo["factor_s"] + min(ergo["solve_s"]),
            "iterations": ergo["stats"]["iterations"],
            "converged": ergo["stats"]["converged"],
            "threads": ergo["threads"],
        },
        "bullet": {
            "pybullet_api": p.getAPIVersion(),
            "material": {
                "model": "Neo-Hookean (pybullet useNeoHookean)",
                "mu": args.mu,
                "lambda": args.lam,
                "poisson": args.poisson,
                "damping": args.damping,
                "mass": args.mass,
                "dt_s": args.dt,
            },
            **sim_info,
        },
    }
    if args.out:
        args.out.write_text(json.dumps(result, indent=1))
    ref = "exact affine" if args.affine_check else "ergohand"
    m, dd, vr = result["mesh"], result["distance_bullet_vs_ergohand_interior_mm"], result["volume_ratio"]
    b, e = result["bullet"], result["ergohand"]
    print(
        f"mesh {m['spacing_mm']} mm: {m['nodes']} nodes, {m['tets']} tets, {m['boundary_nodes']} held\n"
        f"interior displacement from rigid rest: mean {result['interior_displacement_from_rigid_rest_mm']['mean']:.3f} "
        f"max {result['interior_displacement_from_rigid_rest_mm']['max']:.3f} mm\n"
        f"bullet vs {ref}, interior nodes: mean {dd['mean']:.4f} p95 {dd['p95']:.4f} max {dd['max']:.4f} mm; "
        f"boundary max {result['distance_bullet_vs_ergohand_boundary_max_mm']:.2e} mm\n"
        f"volume ratio {ref} {vr['ergohand']['min']:.3f}..{vr['ergohand']['max']:.3f} "
        f"(p1 {vr['ergohand']['p1']:.3f}, p99 {vr['ergohand']['p99']:.3f}, inverted {vr['ergohand']['inverted']}); "
        f"bullet {vr['bullet']['min']:.3f}..{vr['bullet']['max']:.3f} "
        f"(p1 {vr['bullet']['p1']:.3f}, p99 {vr['bullet']['p99']:.3f}, inverted {vr['bullet']['inverted']})\n"
        f"ARAP energy {ref} {result['arap_energy_mm3']['ergohand']:.3f}, bullet {result['arap_energy_mm3']['bullet']:.3f} mm^3\n"
        f"time ergohand {e['factor_s']:.3f} s factorise + {e['solve_s']:.3f} s solve ({e['iterations']} iterations); "
        f"bullet {b['timings']['load_s']:.2f} s load + {b['timings']['run_s']:.1f} s run "
        f"({b['timings']['run_cpu_s']:.1f} s CPU) "
        f"({b['timings']['step_s']:.1f} s in stepSimulation, {b['steps']} steps, converged {b['converged']}, "
        f"last residual {b['last_residual_mm_per_step']:.2e} mm/step, contraction {b['contraction_per_step']:.4f}, "
        f"~{b['estimated_remaining_mm']:.2e} mm to go)"
    )


if __name__ == "__main__":
    main()
