"""The singularity study: Example 2 in spherical coordinates beside the rv-Euler result.

Runs the same LGR solver on the spherical-coordinate problem with the terminal
flight-path angle gamma(tf) = -90 deg (exact) and relaxed values, each from two
guesses: the shipped rv-Euler optimum converted to spherical coordinates (the
best guess a spherical solver could get) and the simulated guidance-law flight
(the cold start the rv-Euler solve uses). Prints one row per case and writes the
rows as JSON.

    python studies/spherical_singularity.py [--out results.json] [--gammas -90 -89.9 -89 -85]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from rventry_env.util.provenance import start_run, write_record

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    parser.add_argument("--gammas", type=float, nargs="+", default=[-90.0, -89.9, -89.0, -85.0])
    parser.add_argument("--guesses", nargs="+", choices=("reference", "simulated"),
                        default=["reference", "simulated"])  # fmt: skip
    parser.add_argument("--max-passes", type=int, default=8)
    parser.add_argument("--max-nlp-iterations", type=int, default=1000, help="IPOPT iterations per pass")
    parser.add_argument("--rv-euler", action="store_true",
                        help="also solve the rv-Euler problem with the same relaxed terminal angles")  # fmt: skip
    args = parser.parse_args(argv)
    start_run(None if argv is None else ["python", __file__, *argv])

    from rventry_env.reference import load_reference
    from rventry_env.reference.collocation.progress import RichMeshTable
    from rventry_env.reference.collocation import SampledGuess, SolverOptions
    from rventry_env.reference.entry_ocp import EntryOcpConfig
    from rventry_env.reference.guess import generate_guess
    from rventry_env.reference.pipeline import end_clustered_mesh
    from rventry_env.reference.spherical_entry import (
        solve_spherical,
        spherical_from_entry_states,
        spherical_guess_from_reference,
    )

    import numpy as np

    ref = load_reference()
    cfg = EntryOcpConfig()
    guesses = {}
    if "reference" in args.guesses:
        guesses["reference"] = spherical_guess_from_reference(ref, cfg)
    if "simulated" in args.guesses:
        sim, _ = generate_guess(cfg)
        s = spherical_from_entry_states(sim.x)
        u_mu = np.gradient(s[:, 7], sim.t)
        guesses["simulated"] = SampledGuess(sim.t, s, np.column_stack([sim.u[:, 0], u_mu]))
    rows = []
    shipped = {"cost": ref.cost, "tf_s": ref.tf, "mesh_error": ref.summary()["mesh_error"], "status": "shipped"}
    rv_rows = {-90.0: shipped}
    if args.rv_euler:
        from rventry_env.reference.pipeline import solve_reference

        for gamma in args.gammas:
            if gamma <= -90.0:
                continue
            cfg_g = cfg.replace(final_gamma_max_deg=gamma, final_gamma_equality=True)
            rs = solve_reference(cfg_g, progress=RichMeshTable(f"rv-Euler with gamma(tf) = {gamma:g} deg"))
            rv_rows[gamma] = {"cost": rs.solution.cost, "tf_s": rs.solution.tf, "mesh_error": rs.solution.max_error,
                              "status": rs.solution.status, "time_s": rs.timings["solve_time_s"]}  # fmt: skip
            print(json.dumps({"rv_euler_gamma": gamma, **rv_rows[gamma]}), flush=True)
    table = RichMeshTable("spherical coordinates (r, lon, lat, v, gamma, psi, alpha, mu)")
    for name, guess in guesses.items():
        for gamma in args.gammas:
            mesh = end_clustered_mesh(39, 6, 0.025, 8, 4)
            opts = SolverOptions(max_mesh_iterations=args.max_passes, max_nlp_iterations=args.max_nlp_iterations)
            row = solve_spherical(gamma, guess, cfg, mesh, opts, table)
            row["guess"] = name
            rows.append(row)
            print(json.dumps(row), flush=True)
    print()
    print(f"rv-Euler (shipped): J* = {ref.cost:.6f}, tf = {ref.tf:.3f} s, gamma(tf) = -90 deg exactly, "
          f"mesh error {ref.summary()['mesh_error']:.2e}")  # fmt: skip
    for g, r in sorted(rv_rows.items()):
        print(f"rv-Euler gamma_f = {g:7.2f}: J = {r['cost']:.6f}, tf = {r['tf_s']:.3f} s, "
              f"mesh error {r['mesh_error']:.2e}")  # fmt: skip
    print(f"{'guess':10s} {'gamma_f':>8s} {'status':28s} {'J':>10s} {'dJ/J*':>9s} {'tf s':>9s} {'mesh err':>9s} "
          f"{'nodes':>6s} {'passes':>6s} {'time s':>7s}")  # fmt: skip
    for r in rows:
        j = r.get("cost", float("nan"))
        print(f"{r['guess']:10s} {r['final_gamma_deg']:8.2f} {r['status'][:28]:28s} {j:10.6f} "
              f"{(j - ref.cost) / ref.cost:9.2e} {r.get('tf_s', float('nan')):9.3f} "
              f"{r.get('mesh_error', float('nan')):9.2e} {r.get('n_nodes', 0):6d} {r.get('passes', 0):6d} "
              f"{r['time_s']:7.1f}")  # fmt: skip
    if args.out is not None:
        rv = [{"final_gamma_deg": g, **r} for g, r in sorted(rv_rows.items())]
        write_record(args.out, {"rv_euler": rv, "spherical": rows}, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
