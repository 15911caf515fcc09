"""Benchmark of the collocation reference: cold-start entry solve and Betts' shuttle.

Each measurement runs in a fresh Python process, so "cold start" includes building
the CasADi functions, generating the guess and every mesh pass (module imports
are timed separately). Reported per run: wall time, CPU time of the process (the
machine may be shared; CPU time is what the solve itself costs), IPOPT iterations
per mesh pass, peak resident memory (ru_maxrss, the whole process), J*, tf and
the final mesh error. Then the shipped optimum's controls replayed open loop through
``entry_rhs`` (DOP853, rtol 1e-11): the position error at impact and along the flight.
Then the two Betts cases against the published optimum.

    python benchmarks/reference_solve.py [--repeat 3] [--json bench.json] [--skip-betts]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from rventry_env.util.provenance import start_run, write_record

os.environ.setdefault("OMP_NUM_THREADS", "1")


def _one_entry() -> dict:
    t0 = time.perf_counter()
    import resource

    from rventry_env.reference.pipeline import solve_reference

    t_import = time.perf_counter() - t0
    rs = solve_reference()
    sol = rs.solution
    return {
        "import_s": t_import,
        "wall_s": rs.timings["solve_time_s"],
        "cpu_s": rs.timings["solve_cpu_s"],
        "guess_s": rs.timings["guess_s"],
        "iterations_per_pass": [r.nlp_iterations for r in rs.records],
        "nodes_per_pass": [r.n_nodes for r in rs.records],
        "pass_labels": [f"{r.iteration}{r.label}" for r in rs.records],
        "rss_peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "cost": sol.cost,
        "tf_s": sol.tf,
        "mesh_error": sol.max_error,
        "max_violation": sol.max_violation,
        "converged": rs.converged,
        "stages": rs.stages,
    }


def _one_replay() -> dict:
    """The shipped optimum's controls through the NumPy entry dynamics, open loop (no timing target)."""
    from rventry_env.reference import load_reference
    from rventry_env.reference.open_loop import replay_record

    t0 = time.perf_counter()
    return replay_record(load_reference()) | {"wall_s": time.perf_counter() - t0}


def _one_betts(limit) -> dict:
    import resource

    from rventry_env.reference.betts_shuttle import solve_shuttle

    cpu = time.process_time()
    try:
        res = solve_shuttle(None if limit == "none" else float(limit))
    except RuntimeError as err:  # not converged: reported as such, never as figures
        return {"case": "no_heating_limit" if limit == "none" else f"heating_limit_{float(limit):g}", "error": str(err)}
    return {
        "case": res.case,
        "tf_s": res.tf_s,
        "latitude_deg": res.latitude_deg,
        "published": res.published,
        "tf_rel_error": res.tf_rel_error,
        "latitude_rel_error": res.latitude_rel_error,
        "mesh_error": res.mesh_error,
        "n_nodes": res.n_nodes,
        "wall_s": res.solve_time_s,
        "cpu_s": time.process_time() - cpu,
        "iterations_per_pass": res.nlp_iterations,
        "rss_peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def _run_child(kind: str, arg: str = "") -> dict:
    cmd = [sys.executable, __file__, "--child", kind, arg]
    out = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"benchmark child {kind} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=1, help="cold entry solves (median reported)")
    parser.add_argument("--json", default=None, help="write all figures as JSON here")
    parser.add_argument("--skip-betts", action="store_true")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        kind, arg = args.child
        print(json.dumps({"entry": _one_entry, "replay": _one_replay}.get(kind, lambda: _one_betts(arg))()))
        return 0
    if args.repeat < 1:
        parser.error("--repeat must be >= 1")
    start_run(None if argv is None else ["python", __file__, *argv])

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    omp = os.environ["OMP_NUM_THREADS"]
    print(f"machine: {os.cpu_count()} cores, load average {load:.2f} at start, OMP_NUM_THREADS={omp}")
    runs = [_run_child("entry") for _ in range(args.repeat)]
    print("\nEntry problem (paper Example 2, exact vertical impact), cold start in a fresh process")
    print(f"{'run':>3s} {'wall s':>7s} {'cpu s':>7s} {'import s':>8s} {'guess s':>7s} {'rss MB':>7s} "
          f"{'J*':>10s} {'tf s':>10s} {'mesh err':>9s}  pass: iterations (nodes)")  # fmt: skip
    for i, r in enumerate(runs):
        passes = ", ".join(f"{lab}: {it} ({n})" for lab, it, n in zip(r["pass_labels"], r["iterations_per_pass"],
                                                                   r["nodes_per_pass"]))
        print(f"{i:3d} {r['wall_s']:7.2f} {r['cpu_s']:7.2f} {r['import_s']:8.2f} {r['guess_s']:7.2f} "
              f"{r['rss_peak_mb']:7.1f} {r['cost']:10.6f} {r['tf_s']:10.3f} {r['mesh_error']:9.2e}  {passes}")  # fmt: skip
        print(f"    converged: {r['converged']}, stages: {', '.join(r['stages'])}")
    wall = statistics.median(r["wall_s"] for r in runs)
    cpu = statistics.median(r["cpu_s"] for r in runs)
    print(f"median wall {wall:.2f} s (target < 30 s), median CPU {cpu:.2f} s")

    replay = _run_child("replay")
    print(f"\nThe shipped optimum's controls replayed open loop (DOP853, rtol {replay['rtol']:g}): position error "
          f"{replay['position_error_at_impact_m']:.2f} m at impact (target <= 100 m), "
          f"{replay['max_position_error_m']:.2f} m at most along the flight")  # fmt: skip

    betts = []
    if not args.skip_betts:
        betts = [_run_child("betts", "none"), _run_child("betts", "70")]
        print("\nBetts Example 6.1, Space Shuttle maximum crossrange (published optimum in brackets)")
        print(f"{'case':18s} {'tf s':>22s} {'rel err':>8s} {'latitude deg':>24s} {'rel err':>8s} {'mesh err':>9s} "
              f"{'nodes':>5s} {'wall s':>7s}")  # fmt: skip
        for b in betts:
            if "error" in b:
                print(f"{b['case']:18s} NOT CONVERGED: {b['error']}")
                continue
            p = b["published"]
            print(f"{b['case']:18s} {b['tf_s']:10.3f} [{p['tf_s']:9.2f}] {b['tf_rel_error']:8.1e} "
                  f"{b['latitude_deg']:11.5f} [{p['latitude_deg']:9.4f}] {b['latitude_rel_error']:8.1e} "
                  f"{b['mesh_error']:9.2e} {b['n_nodes']:5d} {b['wall_s']:7.2f}")  # fmt: skip
    if args.json:
        write_record(args.json, {"load_average": load, "entry": runs, "replay": replay, "betts": betts}, indent=2)
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
