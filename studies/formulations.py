"""The norm-keeping formulations of Example 2 compared: each solved from two guesses, in fresh processes.

For each norm mode of ``EntryOcpConfig(norm_mode=...)`` (``projection``, the shipped one; ``paper``,
the paper's u1..u4 within a delta band; ``none``, Eq. ``Ex2-endpoint`` verbatim) the entry problem
is solved twice, each solve in a fresh Python process (so its time is a cold start's: CasADi
functions built, every mesh pass):

* ``cold``: from the generated guess, as ``rventry reference solve --norm-mode MODE`` does
  (:func:`~rventry_env.reference.pipeline.solve_reference`, continuation included);
* ``optimum``: from the shipped optimum (:class:`~rventry_env.reference.guess.ReferenceGuess`: its
  states and rate controls, with the formulation's extra controls as the generated guess gets them).

Recorded per solve: converged or not and IPOPT's status; the first pass's IPOPT iterations and
wall time (the solver's record of that pass: transcription, IPOPT, error estimate); the iterations,
nodes and wall time of every pass; the whole solve's wall and CPU time. The solver records no CPU
time per pass: the process's CPU time at the end of each pass is recorded instead, counted from
the start of the solve (guess and CasADi functions included). Then J, tf, the final mesh error,
the unit-norm drift at the nodes (max | |q| - 1 | over both quaternions: the summary's
``norm_drift_nodes``) and between them, and the solution's (u_alpha, u_sigma) replayed open loop
through ``entry_rhs`` (DOP853, rtol 1e-11, as ``benchmarks/reference_solve.py`` replays the
shipped file): the position error at impact. A solve that fails, stops with an error or runs past
``--timeout`` is recorded with its status.

    OMP_NUM_THREADS=1 python studies/formulations.py --out docs/results/formulations.json
    python studies/formulations.py --modes paper,none --guesses cold --out out/formulations.json
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from rventry_env.util.provenance import start_run, write_record

os.environ.setdefault("OMP_NUM_THREADS", "1")
MODES = ("projection", "paper", "none")
GUESSES = ("cold", "optimum")


def comma_list(allowed: tuple[str, ...]):
    """An argparse type: a comma-separated list of names out of ``allowed``, each once."""

    def parse(text: str) -> list[str]:
        names = [s.strip() for s in text.split(",") if s.strip()]
        bad = [s for s in names if s not in allowed]
        if not names or bad:
            raise argparse.ArgumentTypeError(f"expected a comma-separated list of {', '.join(allowed)}, got {text!r}")
        if len(set(names)) != len(names):
            raise argparse.ArgumentTypeError(f"a name is given twice in {text!r}")
        return names

    return parse


class PassClock:
    """A progress reporter that stamps the wall and CPU time at the end of each mesh pass, counted from
    its :meth:`start`, and forwards each record."""

    def __init__(self, forward=None):
        self.forward, self.ends = forward, []
        self.start()  # again just before the solve

    def start(self) -> None:
        self._wall, self._cpu = time.perf_counter(), time.process_time()

    def __call__(self, record) -> None:
        self.ends.append({"wall_s": time.perf_counter() - self._wall, "cpu_s": time.process_time() - self._cpu})
        if self.forward is not None:
            self.forward(record)


def solve_row(mode: str, guess: str, rs, replay: dict, import_s: float, pass_ends: list[dict]) -> dict:
    """One solve's entry of the record, from its :class:`~rventry_env.reference.pipeline.ReferenceSolve`."""
    sol, d, records = rs.solution, rs.diagnostics, rs.records
    first = records[0] if records else None
    return {
        "norm_mode": mode,
        "guess": guess,
        "converged": bool(rs.converged),
        "status": str(sol.status),
        "nlp_success": bool(sol.success),
        "stages": list(rs.stages),
        "first_pass": None if first is None else {
            "nlp_iterations": int(first.nlp_iterations), "wall_s": float(first.solve_time_s), "status": str(first.status),
            "nodes": int(first.n_nodes),
            "cpu_s_from_start": float(pass_ends[0]["cpu_s"]) if pass_ends else None,
            "wall_s_from_start": float(pass_ends[0]["wall_s"]) if pass_ends else None},
        "pass_labels": [f"{r.iteration}{r.label}" for r in records],
        "iterations_per_pass": [int(r.nlp_iterations) for r in records],
        "nodes_per_pass": [int(r.n_nodes) for r in records],
        "wall_s_per_pass": [float(r.solve_time_s) for r in records],
        "pass_end_cpu_s": [float(e["cpu_s"]) for e in pass_ends],
        "wall_s": float(rs.timings["solve_time_s"]),
        "cpu_s": float(rs.timings["solve_cpu_s"]),
        "guess_s": float(rs.timings["guess_s"]),
        "import_s": float(import_s),
        "rss_peak_mb": float(rs.timings["rss_peak_mb"]),
        "cost": float(sol.cost),
        "tf_s": float(sol.tf),
        "mesh_error": float(sol.max_error),
        "max_violation": float(sol.max_violation),
        "norm_drift_nodes": float(d["norm_drift_nodes"]),
        "norm_drift_between_nodes": float(d["norm_drift_between_nodes"]),
        "final_flight_path_deg": float(d["final_flight_path_deg"]),
        "target_miss_m": float(d["target_miss_m"]),
        "replay": replay,
    }  # fmt: skip


def failed_row(mode: str, guess: str, status: str, wall_s: float | None = None) -> dict:
    """The entry of a solve that gave no solution (an error, a crash, a timeout): its status, never dropped."""
    return {"norm_mode": mode, "guess": guess, "converged": False, "status": status, "first_pass": None,
            "wall_s": wall_s}  # fmt: skip


def _one_solve(mode: str, guess: str, keep: str) -> dict:
    """One solve, in this (fresh) process: the record's entry."""
    import tempfile

    t0 = time.perf_counter()
    from rventry_env.reference import load_reference, read_reference
    from rventry_env.reference.collocation.progress import RichMeshTable
    from rventry_env.reference.entry_ocp import EntryOcpConfig
    from rventry_env.reference.guess import ReferenceGuess
    from rventry_env.reference.open_loop import REPLAY_RTOL, replay_record
    from rventry_env.reference.pipeline import save_reference, solve_reference

    import_s = time.perf_counter() - t0
    config = EntryOcpConfig(norm_mode=mode)
    seed = ReferenceGuess(load_reference(), config) if guess == "optimum" else None
    clock = PassClock(RichMeshTable(f"norm mode {mode}, from the {'shipped optimum' if seed else 'generated guess'}"))
    clock.start()
    rs = solve_reference(config, progress=clock, guess=seed)
    try:
        with tempfile.TemporaryDirectory() as tmp:  # the solution as `rventry reference solve --out` writes it
            npz, _ = save_reference(rs, Path(keep or tmp) / f"{mode}_{guess}.npz")
            replay = replay_record(read_reference(npz))
    except (OSError, ValueError, RuntimeError) as exc:  # the solve's figures are kept; only its replay is missing
        replay = {"rtol": REPLAY_RTOL, "method": "DOP853", "error": f"{type(exc).__name__}: {exc}"}
    return solve_row(mode, guess, rs, replay, import_s, clock.ends)


def _child(mode: str, guess: str, keep: str) -> int:
    try:
        row = _one_solve(mode, guess, keep)
    except Exception as exc:  # noqa: BLE001 (any error of the solve is the row's status, never a lost row)
        row = failed_row(mode, guess, f"error: {type(exc).__name__}: {exc}")
    print(json.dumps(row))
    return 0


def run_solve(mode: str, guess: str, timeout_s: float, keep: Path | None) -> dict:
    """One solve in a fresh process (its per-pass table on stderr): the record's entry."""
    cmd = [sys.executable, __file__, "--child", mode, guess, str(keep or "")]
    start = time.perf_counter()
    try:
        out = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, check=False, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return failed_row(mode, guess, f"timed out after {timeout_s:g} s", time.perf_counter() - start)
    lines = out.stdout.strip().splitlines()
    if out.returncode != 0 or not lines:
        return failed_row(mode, guess, f"the solve's process exited with status {out.returncode}",
                          time.perf_counter() - start)  # fmt: skip
    return json.loads(lines[-1])


def progress_line(row: dict) -> str:
    """What one solve gave, on one line."""
    head = f"{row['norm_mode']:10s} {row['guess']:7s} {'converged' if row['converged'] else 'NOT CONVERGED'} ({row['status']})"
    first = row.get("first_pass")
    if first is None:
        return head
    replay = row["replay"]
    err = replay.get("position_error_at_impact_m")
    return (f"{head}: first pass {first['nlp_iterations']} iterations, {first['wall_s']:.1f} s; passes "
            f"{', '.join(map(str, row['iterations_per_pass']))}; J {row['cost']:.6f}, tf {row['tf_s']:.2f} s, mesh error "
            f"{row['mesh_error']:.2e}, norm drift at the nodes {row['norm_drift_nodes']:.1e}, replay error at impact "
            + (f"{err:.3g} m" if err is not None else f"none ({replay.get('error')})")
            + f"; {row['wall_s']:.1f} s wall, {row['cpu_s']:.1f} s CPU")  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--modes", type=comma_list(MODES), default=list(MODES),
                        help="norm modes, comma-separated (default: projection,paper,none)")
    parser.add_argument("--guesses", type=comma_list(GUESSES), default=list(GUESSES),
                        help="first guesses, comma-separated: cold (generated), optimum (the shipped one)")
    parser.add_argument("--out", type=Path, default=None, help="write the record (JSON) here")
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds a solve may take (1800)")
    parser.add_argument("--keep", type=Path, default=None, help="keep each solution here as MODE_GUESS.npz (and .json)")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return _child(*args.child)
    if not args.timeout > 0:
        parser.error(f"--timeout must be a positive number of seconds, got {args.timeout}")
    start_run(None if argv is None else ["python", __file__, *argv])
    from rventry_env.reference import load_reference
    from rventry_env.reference.entry_ocp import EntryOcpConfig
    from rventry_env.util.files import check_writable

    check_writable(args.out, folders=tuple(f for f in (args.keep,) if f is not None))
    shipped = load_reference()
    runs = [(m, g) for m in args.modes for g in args.guesses]
    print(f"{len(runs)} solves, each in a fresh process, OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}; shipped "
          f"optimum J* = {shipped.cost:.6f}, tf = {shipped.tf:.3f} s", flush=True)  # fmt: skip
    rows = []
    for i, (mode, guess) in enumerate(runs, 1):
        print(f"[{i}/{len(runs)}] norm mode {mode}, from the {guess} guess", flush=True)
        rows.append(run_solve(mode, guess, args.timeout, args.keep))
        print(progress_line(rows[-1]), flush=True)
    if args.out is not None:
        record = {"modes": args.modes, "guesses": args.guesses, "delta": EntryOcpConfig().delta,
                  "timeout_s": args.timeout, "shipped": {"cost": shipped.cost, "tf_s": shipped.tf}, "solves": rows}
        write_record(args.out, record, indent=2)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
