"""Benchmark of ``rventry identify``: wall time next to the targets.

Targets: a 300 s ECEF record at 10 Hz (3001 samples) identified in at most 30 s, and the
Apollo 4 loop (the shipped record, drag-only start) in at most 20 s. Records are generated
through the independent truth model (one per case), then the full loop runs on each and the
script prints the wall and CPU time, the replays, and what was found.

    OMP_NUM_THREADS=1 python scripts/bench_identify.py [--cases drag_coefficient=1.1 none ...]
        [--duration 300] [--rate 10] [--no-apollo] [--json out.json]

A case is effect specs joined by '+' (or ``none``), optionally followed by ``@POS_M,VEL_MPS``
for its own noise level, e.g. ``wind=-60,90@5,0.05``.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

from rventry_env.util.args import interval, number_list, positive_float

RECORD_TARGET_S = 30.0
APOLLO_TARGET_S = 20.0
DEFAULT_CASES = ("drag_coefficient=1.1", "density_profile=0.2", "none", "drag_coefficient=1.05+wind=80",
                 "us76_density+lift_coefficient=0.96", "mass=1.06")  # fmt: skip


def _case(text: str):
    effects, _, noise_text = text.partition("@")
    noise = number_list(positive_float, 2, 2)(noise_text) if noise_text else None
    return ([] if effects == "none" else effects.split("+")), noise


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="effect specs joined by '+', or none")
    p.add_argument("--duration", type=interval(0.0, 3600.0, low_open=True), default=300.0)
    p.add_argument("--rate", type=interval(0.0, 100.0, low_open=True), default=10.0)
    p.add_argument("--noise", type=number_list(positive_float, 2, 2), default=(20.0, 0.2),
                   help="default noise POS_M,VEL_MPS")  # fmt: skip
    p.add_argument("--h-max", type=interval(0.0, 10.0, low_open=True), default=1.0,
                   help="longest RK4 step of the replay (s)")  # fmt: skip
    p.add_argument("--no-apollo", action="store_true", help="skip the Apollo 4 loop")
    p.add_argument("--json", type=Path, help="write the figures here")
    args = p.parse_args(argv)

    from rventry_env.util.files import check_writable, write_json
    from rventry_env.validation import apollo4, identify_record
    from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record

    if args.json:
        check_writable(args.json)
    cases = [(c, *_case(c)) for c in args.cases]
    load = f"; load average {os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else ""
    print(f"python {platform.python_version()}, {os.cpu_count()} cpu(s) visible, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}{load}")  # fmt: skip
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, (case, specs, noise) in enumerate(cases):
            rec = simulate_record(Path(tmp) / f"rec{i}.csv", parse_effects(specs), noise=noise or args.noise,
                                  duration=args.duration, rate=args.rate, seed=i)  # fmt: skip
            t0, cpu0 = time.perf_counter(), time.process_time()
            rep = identify_record(rec, progress=True, h_max=args.h_max).report
            rows.append({"case": case, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - cpu0,
                         "replays": rep["replays"], "samples": rep["record"]["samples"],
                         "effects": rep["effects"], "unexplained": rep["unexplained"],
                         "rms_before": rep["before"]["position_rms_m"],
                         "rms_after": rep["after"]["position_rms_m"]})  # fmt: skip
    apollo = None
    if not args.no_apollo:
        t0, cpu0 = time.perf_counter(), time.process_time()
        rep = identify_record(apollo4.record_path(), progress=True).report
        apollo = {"case": "apollo4", "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - cpu0,
                  "replays": rep["replays"], "samples": rep["record"]["samples"], "effects": rep["effects"],
                  "unexplained": rep["unexplained"], "rms_before": rep["before"]["altitude_rms_m"],
                  "rms_after": rep["after"]["altitude_rms_m"]}  # fmt: skip

    print(f"\n{'case':38s} {'wall s':>7s} {'cpu s':>6s} {'replays':>7s}  {'found':40s} {'rms before m':>12s} "
          f"{'after m':>8s}")  # fmt: skip
    for r in rows + ([apollo] if apollo else []):
        found = "+".join(r["effects"]) or "none"
        if r["unexplained"]:
            found += " (unexplained)"
        print(f"{r['case']:38s} {r['wall_s']:7.1f} {r['cpu_s']:6.1f} {r['replays']:7d}  {found:40s} "
              f"{r['rms_before']:12.1f} {r['rms_after']:8.1f}")  # fmt: skip
    worst = max(r["wall_s"] for r in rows)
    print(f"\n{args.duration:g} s record at {args.rate:g} Hz ({rows[0]['samples']} samples): worst {worst:.1f} s wall "
          f"(target {RECORD_TARGET_S:g} s): {'PASS' if worst <= RECORD_TARGET_S else 'FAIL'}")  # fmt: skip
    if apollo:
        print(f"Apollo 4 loop: {apollo['wall_s']:.1f} s wall (target {APOLLO_TARGET_S:g} s): "
              f"{'PASS' if apollo['wall_s'] <= APOLLO_TARGET_S else 'FAIL'}")  # fmt: skip
    if args.json:
        write_json(args.json, {"record_target_s": RECORD_TARGET_S, "apollo_target_s": APOLLO_TARGET_S,
                                "cases": rows, "apollo4": apollo}, indent=2)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
