"""Benchmark: identification of a 400 s record at 1 Hz (target: at most 60 s).

Generates synthetic CAV-H records through the truth model (one per case), runs
the full validation loop on each, and prints the wall time, the number of
batched replays and the result. Run with OMP_NUM_THREADS=1 on a shared machine.

    OMP_NUM_THREADS=1 python scripts/bench_identify.py [--cases drag_coefficient=1.1 none ...]
        [--json out.json]

A case is effect specs joined by '+' (or ``none``), optionally followed by
``@POS_M,VEL_MPS`` for its own noise level, e.g. ``wind=-60,90@5,0.05``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

TARGET_S = 60.0
DEFAULT_CASES = ("drag_coefficient=1.1", "density_profile=0.2", "none", "drag_coefficient=1.05+wind=80")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES),
                   help="effect specs joined by '+', or none")  # fmt: skip
    p.add_argument("--duration", type=float, default=400.0)
    p.add_argument("--rate", type=float, default=1.0)
    p.add_argument("--noise", default="20,0.2", help="default noise POS_M,VEL_MPS")
    p.add_argument("--h-max", type=float, default=1.0, help="longest RK4 step of the replay (s)")
    p.add_argument("--json", type=Path, help="write the figures here")
    args = p.parse_args(argv)

    from rventry_env.validation import identify_record
    from rventry_env.validation.simulate import parse_effects, simulate_record

    rows = []
    print(f"python {platform.python_version()}, {os.cpu_count()} cpu(s) visible, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}; load average "
          f"{os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for i, case in enumerate(args.cases):
            effects, _, noise_text = case.partition("@")
            noise = tuple(float(x) for x in (noise_text or args.noise).split(","))
            specs = [] if effects == "none" else effects.split("+")
            rec = simulate_record(Path(tmp) / f"rec{i}.csv", parse_effects(specs), noise=noise,
                                  duration=args.duration, rate=args.rate, seed=i)  # fmt: skip
            t0 = time.perf_counter()
            cpu0 = time.process_time()
            rep = identify_record(rec, progress=True, h_max=args.h_max).report
            wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
            rows.append({"case": case, "wall_s": wall, "cpu_s": cpu, "replays": rep["replays"],
                         "samples": rep["record"]["samples"], "effects": rep["effects"],
                         "position_rms_before_m": rep["before"]["position_rms_m"],
                         "position_rms_after_m": rep["after"]["position_rms_m"]})  # fmt: skip
    print(f"\n{'case':38s} {'wall s':>7s} {'cpu s':>6s} {'replays':>7s}  {'found':28s} "
          f"{'rms before m':>12s} {'after m':>8s} {'fold':>6s}")  # fmt: skip
    for r in rows:
        ok = "" if r["wall_s"] <= TARGET_S else "  SLOW"
        fold = r["position_rms_before_m"] / r["position_rms_after_m"]
        print(f"{r['case']:38s} {r['wall_s']:7.1f} {r['cpu_s']:6.1f} {r['replays']:7d}  "
              f"{'+'.join(r['effects']) or 'none':28s} {r['position_rms_before_m']:12.1f} "
              f"{r['position_rms_after_m']:8.1f} {fold:6.1f}{ok}")  # fmt: skip
    worst = max(r["wall_s"] for r in rows)
    print(f"\n{args.duration:g} s record at {args.rate:g} Hz: worst {worst:.1f} s wall "
          f"(target {TARGET_S:g} s): {'PASS' if worst <= TARGET_S else 'FAIL'}")  # fmt: skip
    if args.json:
        args.json.write_text(json.dumps({"target_s": TARGET_S, "cases": rows}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
