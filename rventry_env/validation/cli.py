"""``rventry identify`` and ``rventry simulate-record``.

Heavy imports (SciPy, matplotlib) happen inside the command functions so that
``rventry --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

SHIPPED_RECORDS = {"apollo4": "the Apollo 4 entry shipped with rventry (drag-only start)"}


def register(subparsers) -> None:
    """Add the model-validation subcommands to the ``rventry`` parser."""
    p = subparsers.add_parser(
        "identify",
        help="replay a flight record, name the effect the model lacks, add it",
        description="Replay a flight record (PROBLEM.md format) with the current model, fit every candidate "
        "effect (j2_gravity, density_profile, lift_coefficient, drag_coefficient, wind) with the initial "
        "state, rank them by BIC, add what the record supports, and report the error before and after.",
    )
    p.add_argument("record", help="record CSV, or 'apollo4' for the shipped Apollo 4 record")
    p.add_argument("--vehicle", type=Path, help="vehicle JSON overriding the record's sidecar")
    p.add_argument("--start", choices=("declared", "drag-only"),
                   help="model to start from (default: the sidecar's, else declared)")  # fmt: skip
    p.add_argument("--json", type=Path, required=True, help="report file to write")
    p.add_argument("--plots", type=Path, help="folder for the PNG plots")
    p.add_argument("--model-out", type=Path, help="write the identified EntryModel as JSON")
    p.add_argument("--candidates", nargs="+", help="effects to consider (default: all five)")
    p.add_argument("--threshold", type=float, default=10.0, help="BIC margin to accept an effect [10]")
    p.add_argument("--max-effects", type=int, default=3, help="most effects to add [3]")
    p.add_argument("--h-max", type=float, default=1.0, help="longest RK4 step of the replay, s [1]")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=_identify)

    s = subparsers.add_parser(
        "simulate-record",
        help="fly the CAV-H through a truth model with undeclared effects, write a flight record",
        description="Fly the CAV-H (scripted alpha and bank) through the independent Cartesian truth model "
        "containing the given effects and write a PROBLEM.md record with measurement noise. The effects go "
        "to <out>.truth.json only, never to the record or its sidecar.",
    )
    s.add_argument("--effect", action="append", default=[], metavar="NAME[=VALUE]",
                   help="j2_gravity[=J2], density_profile[=A], lift_coefficient[=S], drag_coefficient[=S], "
                   "wind[=E[,N]]; repeat for several; none for a clean flight")  # fmt: skip
    s.add_argument("--noise", default="20,0.2", metavar="POS_M[,VEL_MPS]",
                   help="noise standard deviation per component [20,0.2]")  # fmt: skip
    s.add_argument("--out", type=Path, required=True, help="record CSV to write")
    s.add_argument("--duration", type=float, default=400.0, help="seconds of flight [400]")
    s.add_argument("--rate", type=float, default=1.0, help="samples per second [1]")
    s.add_argument("--seed", type=int, default=0, help="noise seed [0]")
    s.add_argument("--observe", choices=("ecef", "reduced"), default="ecef",
                   help="full ECEF state, or altitude and speed plus a sidecar [ecef]")  # fmt: skip
    s.set_defaults(func=_simulate)


def _record_path(text: str) -> Path:
    path = Path(text)
    if not path.exists() and text in SHIPPED_RECORDS:
        from rventry_env.validation.apollo4 import record_path

        return record_path()
    return path


def _identify(args: argparse.Namespace) -> int:
    from rventry_env.validation.identify import identify
    from rventry_env.validation.model_io import save_model
    from rventry_env.validation.plots import write_plots
    from rventry_env.validation.record import load_record, load_sidecar

    record = load_record(_record_path(args.record))
    vehicle = load_sidecar(args.vehicle) if args.vehicle else None
    kwargs = {"candidates": tuple(args.candidates)} if args.candidates else {}
    ident = identify(
        record, vehicle=vehicle, start=args.start, threshold=args.threshold, h_max=args.h_max,
        max_effects=args.max_effects, progress=not args.quiet, **kwargs,
    )  # fmt: skip
    rep = ident.report
    if args.plots:
        rep["plots"] = [str(p) for p in write_plots(ident, args.plots)]
    if args.model_out:
        save_model(ident.model, args.model_out)
        rep["model_file"] = str(args.model_out)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rep, indent=2) + "\n")
    _print_summary(rep)
    return 0


def _print_summary(rep: dict) -> None:
    kind = rep["record"]["kind"]
    key, vkey = ("position", "velocity") if kind == "ecef" else ("altitude", "speed")
    print(f"effect: {rep['effect']}   effects added: {', '.join(rep['effects']) or 'none'}")
    for k, v in rep["parameters"].items():
        print(f"  {k} = {v:.6g} +- {rep['parameter_stderr'][k]:.2g}")
    print("ranking (step 1, BIC on the effective sample size):")
    for r in rep["ranking"]:
        print(f"  {r['effect']:18s} BIC {r['bic']:12.1f}   delta {r['delta_bic']:10.1f}")
    b, a = rep["before"], rep["after"]
    print(f"{key} rms: {b[key + '_rms_m']:.4g} m -> {a[key + '_rms_m']:.4g} m   "
          f"max: {b[key + '_max_m']:.4g} m -> {a[key + '_max_m']:.4g} m   "
          f"{vkey} rms: {b[vkey + '_rms_mps']:.4g} -> {a[vkey + '_rms_mps']:.4g} m/s")  # fmt: skip
    w = rep["whiteness"]
    print(f"lag-1 autocorrelation: {w['before']['lag1_autocorrelation']:.3f} -> "
          f"{w['after']['lag1_autocorrelation']:.3f}   Ljung-Box p: {w['before']['ljung_box_p']:.3g} -> "
          f"{w['after']['ljung_box_p']:.3g}")  # fmt: skip
    print(f"({rep['elapsed_s']:.1f} s, {rep['replays']} batched replays)")


def _simulate(args: argparse.Namespace) -> int:
    from rventry_env.validation.simulate import parse_effects, simulate_record

    specs = [e for e in args.effect if e.strip().lower() != "none"]
    try:
        noise = tuple(float(x) for x in args.noise.split(","))
    except ValueError:
        raise ValueError(f"--noise: cannot read {args.noise!r}; use POS_M[,VEL_MPS]") from None
    if len(noise) == 1:
        noise = (noise[0], noise[0] / 100.0)
    if len(noise) != 2 or min(noise) < 0:
        raise ValueError("--noise takes one or two non-negative numbers")
    out = simulate_record(args.out, parse_effects(specs), noise=noise, duration=args.duration, rate=args.rate,
                          seed=args.seed, observe=args.observe)  # fmt: skip
    print(f"wrote {out} ({', '.join(specs) or 'no effect'}; noise {noise[0]:g} m, {noise[1]:g} m/s)",
          file=sys.stderr)  # fmt: skip
    return 0


__all__ = ["register"]
