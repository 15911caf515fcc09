"""Benchmark the cost of one guidance decision: the learned policy, the PPO residual, TV-LQR (with
and without estimation) and re-planning (``mpc``), for one vehicle and for a batch.

Each law flies whole episodes of the standard set through ``rollout`` (so its per-episode memory,
its estimator and its re-plans run as in an evaluation), and every call of the law is timed.
A decision is one vehicle's action for one control step; a call for a batch of B vehicles makes
B decisions. The figures are per decision:

* mean over the episode (what a flight costs, re-solves included);
* the median call and the 99th-percentile call (for ``mpc``, the steps that re-solve).

``mpc`` solves one NLP per vehicle, so a batch costs B times a single vehicle; it is flown
with batch 1 only (``--mpc-episodes`` episodes, one at a time) and its batched cost is that
figure, not a measurement.

    OMP_NUM_THREADS=1 python benchmarks/decision_cost.py --json out/bench_decision.json

Timings depend on the machine: run it on a quiet one.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from rventry_env.task import EntryTask
from rventry_env.evaluation.agents import load_agent
from rventry_env.evaluation.rollout import rollout
from rventry_env.util.args import positive_int
from rventry_env.util.files import check_writable
from rventry_env.util.provenance import start_run, write_record

LAWS = ("learned", "dagger-flight", "dagger", "ppo-residual", "lqr", "lqr-est", "mpc")  # `learned`: the record says which


def learned_name() -> str | None:
    """The shipped policy ``learned`` names today (None where the agents package is not installed)."""
    try:
        from rventry_agents.learned import LEARNED
    except ImportError:
        return None
    return LEARNED


class TimedLaw:
    """A guidance law whose every call is timed; everything else is the law's own."""

    def __init__(self, law):
        self._law = law
        self.call_s: list[float] = []
        self.call_batch: list[int] = []

    def __getattr__(self, name):
        return getattr(self._law, name)

    def __call__(self, measurement):
        t0 = time.perf_counter()
        out = self._law(measurement)
        self.call_s.append(time.perf_counter() - t0)
        self.call_batch.append(measurement.n)
        return out


def measure(name: str, batch: int, episodes: int, seed: int, task: EntryTask) -> dict:
    """Fly ``episodes`` episodes in batches of ``batch`` and time every decision."""
    calls, sizes, steps = [], [], 0
    for start in range(0, episodes, batch):
        law = TimedLaw(load_agent(name, task))
        b = rollout(law, seeds=range(seed + start, seed + start + batch), dispersion="standard", task=task)
        calls += law.call_s
        sizes += law.call_batch
        steps += int(np.sum(b.lengths))
    calls, sizes = np.asarray(calls), np.asarray(sizes)
    per_vehicle = calls / sizes
    return {
        "batch": batch,
        "episodes": episodes,
        "calls": int(calls.size),
        "decisions": int(sizes.sum()),
        "flown_steps": steps,
        "per_decision_mean_s": float(calls.sum() / sizes.sum()),
        "per_decision_p50_s": float(np.percentile(per_vehicle, 50)),
        "per_decision_p99_s": float(np.percentile(per_vehicle, 99)),
        "per_decision_max_s": float(per_vehicle.max()),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=positive_int, default=1024, help="the batch size (default 1024)")
    ap.add_argument("--single-episodes", type=positive_int, default=20, help="episodes flown one at a time per law (20)")
    ap.add_argument("--mpc-episodes", type=positive_int, default=5, help="episodes of mpc, one at a time (5)")
    ap.add_argument("--seed", type=int, default=0, help="first seed of the standard set (0)")
    ap.add_argument("--laws", nargs="+", choices=LAWS, default=list(LAWS), help="laws to time (all)")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    run = start_run(None if argv is None else ["python", __file__, *argv])
    if args.json:
        check_writable(args.json)
    task = EntryTask()
    rows = {}
    for name in args.laws:
        rows[name] = {}
        single_eps = args.mpc_episodes if name == "mpc" else args.single_episodes
        print(f"{name}: {single_eps} episode(s) one at a time ...", flush=True)
        rows[name]["single"] = measure(name, 1, single_eps, args.seed, task)
        if name != "mpc":
            print(f"{name}: {args.batch} episodes in one batch ...", flush=True)
            rows[name]["batched"] = measure(name, args.batch, args.batch, args.seed, task)
    mpc = rows.get("mpc", {}).get("single", {}).get("per_decision_mean_s")
    print(f"\ntime per decision (mean over flown episodes, standard set; median / p99 call in brackets), "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")  # fmt: skip
    print(f"{'law':10s} {'single vehicle':>34s} {'batch of ' + str(args.batch):>34s} {'mpc / this (batched)':>22s}")

    def cell(r):
        us = 1e6
        return (f"{r['per_decision_mean_s'] * us:10.1f} us ({r['per_decision_p50_s'] * us:.1f} / "
                f"{r['per_decision_p99_s'] * us:.1f})")  # fmt: skip

    for name, r in rows.items():
        batched = r.get("batched")
        ratio = f"{mpc / batched['per_decision_mean_s']:22.0f}" if (mpc and batched) else f"{'-':>22s}"
        print(f"{name:10s} {cell(r['single']):>34s} {cell(batched) if batched else '(one NLP per vehicle)':>34s} {ratio}")
        if mpc and batched:
            r["mpc_over_batched"] = mpc / batched["per_decision_mean_s"]
    if args.json:
        omp = os.environ.get("OMP_NUM_THREADS")
        write_record(args.json, {"laws": rows, "batch": args.batch, "seed": args.seed, "dispersion": "standard",
                               "omp_num_threads": omp, "single_episodes": args.single_episodes,
                               "mpc_episodes": args.mpc_episodes, "learned": learned_name(),
                               "command": (f"OMP_NUM_THREADS={omp} " if omp else "") + run.command})  # fmt: skip
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
