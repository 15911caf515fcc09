"""Benchmark of ``rventry identify``: wall time next to the targets.

Targets: a 300 s ECEF record at 10 Hz (3001 samples) identified in at most 30 s (worst case),
at 50 Hz in at most 60 s, and the Apollo 4 loop (the shipped record, drag-only start) in at most
20 s. The Apollo 10 record (digitised from the report's figures, its sidecar 4 km off) runs beside
it, with its altitude rms against the published 3-DOF replay's 3.19 km. Records are generated through the independent truth model (one per case), then the full
loop runs on each (the residual trace included, where the residual is not noise) and the script
prints the wall and CPU time, the replays, what was found and where the trace points.

    OMP_NUM_THREADS=1 python benchmarks/identify_speed.py [--cases drag_coefficient=1.1 none ...]
        [--duration 300] [--rate 10] [--no-apollo] [--target S] [--json out.json]

A case is effect specs joined by '+' (or ``none``), optionally followed by ``@POS_M,VEL_MPS``
for its own noise level, e.g. ``wind=-60,90@5,0.05``, and by ``~t3`` for Student-t noise with
3 degrees of freedom (same standard deviation), e.g. ``none~t3``. CPU time is printed beside
the wall time: on a shared machine it is the steadier figure.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from rventry_env.util.args import interval, number_list, positive_float

RECORD_TARGETS_S = {10.0: 30.0, 50.0: 60.0}  # by sampling rate (Hz); other rates: the next higher rate's
APOLLO_TARGET_S = 20.0
DEFAULT_CASES = ("drag_coefficient=1.1", "density_profile=0.2", "none", "drag_coefficient=1.05+wind=80",
                 "us76_density+lift_coefficient=0.96", "mass=1.06", "mass=0.95+j2_gravity@5,0.05", "none~t3",
                 "lift_band=0.8,50,53", "time_offset=0.5", "bank_bias=2", "density_wave=0.08,6@5,0.05")  # fmt: skip


def _case(text: str):
    text, _, tails = text.partition("~")
    effects, _, noise_text = text.partition("@")
    noise = number_list(positive_float, 2, 2)(noise_text) if noise_text else None
    if tails not in ("", "t3"):
        raise ValueError(f"case {text!r}: the noise suffix is ~t3 (Student-t, 3 degrees of freedom)")
    return ([] if effects == "none" else effects.split("+")), noise, "student-t3" if tails else "normal"


def record_target(rate: float) -> float:
    """The benchmark's target for a 300 s record at ``rate`` Hz (s)."""
    higher = [r for r in sorted(RECORD_TARGETS_S) if r >= rate - 1e-9]
    return RECORD_TARGETS_S[higher[0] if higher else max(RECORD_TARGETS_S)]


def _trace_text(rep: dict) -> str:
    """The attribution, or the leading correction marked as not significant."""
    leading = (rep.get("trace") or {}).get("leading") if not rep.get("attribution") else None
    parts = []
    for a in rep.get("attribution") or (leading or {}).get("attribution") or []:
        lo, hi = a["band"]
        band = f"{lo / 1e3:.1f}-{hi / 1e3:.1f} km" if a["axis"] == "altitude" else f"{lo:.0f}-{hi:.0f} s"
        parts.append(f"{a['channel']} {a['size']:+.3g} @ {band}")
    text = "; ".join(parts)
    return f"leading, not significant (BIC gain {leading['bic_gain']:.1f}): {text}" if leading else text


def _after_trace(rep: dict, key: str):
    trace = rep.get("trace") or {}
    return (trace.get("after_trace") or (trace.get("leading") or {}).get("after_leading") or {}).get(key)


def _trace_facts(rep: dict) -> dict:
    """What the trace points to, the bank offset it reads, and the effects it found standing in for it."""
    trace = rep.get("trace") or {}
    banks = [a["bank_offset_deg"] for a in rep.get("attribution") or [] if "bank_offset_deg" in a]
    return {"points_to": trace.get("points_to") or [], "bank_offset_deg": banks[0] if banks else None,
            "surrogates_removed": trace.get("surrogates_removed") or []}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), help="effect specs joined by '+', or none")
    p.add_argument("--duration", type=interval(0.0, 3600.0, low_open=True), default=300.0)
    p.add_argument("--rate", type=interval(0.0, 100.0, low_open=True), default=10.0)
    p.add_argument("--noise", type=number_list(positive_float, 2, 2), default=(20.0, 0.2),
                   help="default noise POS_M,VEL_MPS")  # fmt: skip
    p.add_argument("--h-max", type=interval(0.0, 10.0, low_open=True), default=1.0,
                   help="longest RK4 step of the replay (s)")  # fmt: skip
    p.add_argument("--no-apollo", action="store_true", help="skip the Apollo 4 and Apollo 10 loops")
    p.add_argument("--no-cases", action="store_true", help="run only the flight records (Apollo 4 and Apollo 10)")
    p.add_argument("--target", type=positive_float, help="wall-time target per record, s (default: by --rate)")
    p.add_argument("--json", type=Path, help="write the figures here")
    args = p.parse_args(argv)

    from rventry_env.util.files import check_writable
    from rventry_env.util.provenance import start_run, write_record

    start_run(None if argv is None else ["python", __file__, *argv])
    from rventry_env.validation import apollo4, apollo10, identify_record
    from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record

    if args.json:
        check_writable(args.json)
    if args.no_cases and args.no_apollo:
        p.error("--no-cases with --no-apollo leaves nothing to run")
    cases = [] if args.no_cases else [(c, *_case(c)) for c in args.cases]
    load_start = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    load = f"; load average {load_start:.2f}" if load_start is not None else ""
    print(f"python {platform.python_version()}, {os.cpu_count()} cpu(s) visible, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}{load}")  # fmt: skip
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, (case, specs, noise, tails) in enumerate(cases):
            rec = simulate_record(Path(tmp) / f"rec{i}.csv", parse_effects(specs), noise=noise or args.noise,
                                  duration=args.duration, rate=args.rate, seed=i, noise_tails=tails)  # fmt: skip
            t0, cpu0 = time.perf_counter(), time.process_time()
            rep = identify_record(rec, progress=True, h_max=args.h_max).report
            rows.append({"case": case, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - cpu0,
                         "replays": rep["replays"], "samples": rep["record"]["samples"],
                         "effects": rep["effects"], "unexplained": rep["unexplained"],
                         "rms_before": rep["before"]["position_rms_m"],
                         "rms_after": rep["after"]["position_rms_m"], "trace": _trace_text(rep),
                         "rms_after_trace": _after_trace(rep, "position_rms_m"),
                         "parameters": rep["parameters"], **_trace_facts(rep)})  # fmt: skip
    flights = []
    for module in () if args.no_apollo else (apollo4, apollo10):
        name = module.__name__.rsplit(".", 1)[-1]
        t0, cpu0 = time.perf_counter(), time.process_time()
        rep = identify_record(module.record_path(), progress=True).report
        offset = (rep.get("entry_state_offset") or {}).get("offsets", {}).get("dh0_m")
        flights.append({"case": name, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - cpu0,
                        "replays": rep["replays"], "samples": rep["record"]["samples"], "effects": rep["effects"],
                        "unexplained": rep["unexplained"], "rms_before": rep["before"]["altitude_rms_m"],
                        "rms_after": rep["after"]["altitude_rms_m"], "trace": _trace_text(rep),
                        "rms_after_trace": _after_trace(rep, "altitude_rms_m"), "parameters": rep["parameters"],
                        **_trace_facts(rep),
                        "entry_altitude_offset_m": offset,
                        "entry_offset_explained_by": (rep.get("entry_state_offset") or {}).get("explained_by")})  # fmt: skip
    apollo = next((f for f in flights if f["case"] == "apollo4"), None)

    print(f"\n{'case':38s} {'wall s':>7s} {'cpu s':>6s} {'replays':>7s}  {'found':40s} {'rms before m':>12s} "
          f"{'after m':>8s}  trace (rms after it)")  # fmt: skip
    for r in rows + flights:
        found = "+".join(r["effects"]) or "none"
        if r["unexplained"]:
            found += " (unexplained)"
        trace = f"{r['trace']} ({r['rms_after_trace']:.1f} m)" if r["trace"] else ""
        print(f"{r['case']:38s} {r['wall_s']:7.1f} {r['cpu_s']:6.1f} {r['replays']:7d}  {found:40s} "
              f"{r['rms_before']:12.1f} {r['rms_after']:8.1f}  {trace}")  # fmt: skip
    target = args.target or record_target(args.rate)
    if rows:
        worst = max(r["wall_s"] for r in rows)
        worst_cpu = max(r["cpu_s"] for r in rows)
        print(f"\n{args.duration:g} s record at {args.rate:g} Hz ({rows[0]['samples']} samples): worst {worst:.1f} s "
              f"wall, {worst_cpu:.1f} s CPU (target {target:g} s): {'PASS' if worst <= target else 'FAIL'} on wall time"
              f"{'' if worst <= target else (', PASS on CPU time' if worst_cpu <= target else ', FAIL on CPU time')}")  # fmt: skip
    if apollo:
        print(f"Apollo 4 loop: {apollo['wall_s']:.1f} s wall, {apollo['cpu_s']:.1f} s CPU (target "
              f"{APOLLO_TARGET_S:g} s): {'PASS' if apollo['wall_s'] <= APOLLO_TARGET_S else 'FAIL'} on wall time")  # fmt: skip
    a10 = next((f for f in flights if f["case"] == "apollo10"), None)
    if a10:
        off = a10["entry_altitude_offset_m"]
        print(f"Apollo 10: altitude rms {a10['rms_after'] / 1e3:.2f} km (published 3-DOF replay "
              f"{apollo10.PUBLISHED_RMS_ALTITUDE_M / 1e3:.2f} km); entry altitude offset {off['value']:+.0f} +/- "
              f"{off['stderr']:.0f} m, explained by {', '.join(a10['entry_offset_explained_by']) or 'no reference'}")  # fmt: skip
    load_end = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    if load_end is not None:
        print(f"load average at the end {load_end:.2f}")
    if args.json:
        write_record(args.json, {"duration_s": args.duration, "rate_hz": args.rate, "record_target_s": target,
                                 "apollo_target_s": APOLLO_TARGET_S, "cases": rows, "apollo4": apollo,
                                 "apollo10": a10}, indent=2)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
