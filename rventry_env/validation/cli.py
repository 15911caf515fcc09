"""``rventry identify`` and ``rventry simulate-record``.

Heavy imports (SciPy, CasADi, matplotlib) happen inside the command functions so that
``rventry --help`` stays fast. Every number goes through the shared argument checks
(:mod:`rventry_env.util.args`); every destination is checked before the run and every file is
written whole or not at all (:mod:`rventry_env.util.files`).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from rventry_env.util.args import interval, non_negative_float, non_negative_int, number_list, positive_float
from rventry_env.util.args import seed as seed_type

SHIPPED_RECORDS = {"apollo4": "the Apollo 4 entry shipped with rventry (drag-only start)",
                   "apollo10": "the Apollo 10 entry shipped with rventry (digitised from the report's figures)"}
EFFECTS_HELP = ("j2_gravity, density_profile, lift_coefficient, drag_coefficient, wind, mass, mach_drag, "
                "measured_density, time_offset")  # fmt: skip


def register(subparsers) -> None:
    """Add the model-validation subcommands to the ``rventry`` parser."""
    _register_identify(subparsers)
    _register_simulate_record(subparsers)


def _register_identify(subparsers) -> None:
    """Add ``rventry identify``: replay a record, name the effect the model lacks."""
    p = subparsers.add_parser(
        "identify",
        help="replay a flight record, name the effect the model lacks, add it",
        description="Replay a flight record (the format of docs/conventions.md) with the current model, fit "
        f"every candidate effect ({EFFECTS_HELP}) with the initial state, rank them by BIC, add what the "
        "record supports, name the aliases it cannot tell apart, and test the final residual against the "
        "noise.",
    )
    p.add_argument("record", help="record CSV, or 'apollo4' / 'apollo10' for a shipped flight record")
    p.add_argument("--vehicle", type=Path, help="vehicle JSON overriding the record's sidecar")
    p.add_argument("--start", choices=("declared", "drag-only"),
                   help="model to start from (default: the sidecar's, else declared)")  # fmt: skip
    p.add_argument("--json", type=Path, required=True, help="report file to write")
    p.add_argument("--plots", type=Path, help="folder for the PNG plots")
    p.add_argument("--model-out", type=Path, help="write the identified EntryModel as JSON")
    p.add_argument("--candidates", nargs="+", metavar="EFFECT",
                   help=f"effects to consider (default: all of {EFFECTS_HELP}; measured_density only with a "
                   "density column)")  # fmt: skip
    p.add_argument("--noise", type=number_list(positive_float, 2, 2), metavar="POS_M,VEL_MPS",
                   help="declared measurement noise, one standard deviation per component (altitude and speed "
                   "for a reduced record); default: the sidecar's 'noise', else estimated from the record")  # fmt: skip
    p.add_argument("--threshold", type=non_negative_float, default=10.0,
                   help="BIC margin to accept an effect [10]")  # fmt: skip
    p.add_argument("--max-effects", type=non_negative_int, default=3,
                   help="most effects to add; 0 only replays, ranks and tests the current model [3]")  # fmt: skip
    p.add_argument("--h-max", type=interval(0.0, 10.0, low_open=True), default=1.0,
                   help="longest RK4 step of the replay, s, in (0, 10] [1]")  # fmt: skip
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=_identify)


def _register_simulate_record(subparsers) -> None:
    """Add ``rventry simulate-record``: fly the truth model with undeclared effects, write a record."""
    s = subparsers.add_parser(
        "simulate-record",
        help="fly the CAV-H through a truth model with undeclared effects, write a flight record",
        description="Fly the CAV-H (scripted alpha and bank) through the independent Cartesian truth model "
        "containing the given effects and write a record (the format of docs/conventions.md) with "
        "measurement noise. The effects go to <out>.truth.json only, never to the record or its sidecar.",
    )
    s.add_argument("--effect", action="append", default=[], metavar="NAME[=VALUE]",
                   help="j2_gravity[=J2], density_profile[=A], lift_coefficient[=S], drag_coefficient[=S], "
                   "wind[=E[,N]], mass[=S], us76_density, mach_drag[=A], time_offset[=DT]; outside the candidate "
                   "set: lift_band, drag_band, mach_lift, wind_shear, side_force, density_wave[=A,KM], "
                   "mass_loss[=F,T0,T1], bank_bias[=DEG], alpha_bias[=DEG]; repeat for several; none for a clean "
                   "flight")  # fmt: skip
    s.add_argument("--noise", type=number_list(non_negative_float, 1, 2), default=(20.0, 0.2),
                   metavar="POS_M[,VEL_MPS]",
                   help="noise standard deviation per component [20,0.2]; one value sets VEL = POS/100")  # fmt: skip
    s.add_argument("--out", type=Path, required=True, help="record CSV to write")
    s.add_argument("--duration", type=interval(0.0, 3600.0, low_open=True), default=400.0,
                   help="seconds of flight, in (0, 3600] [400]")  # fmt: skip
    s.add_argument("--rate", type=interval(0.0, 100.0, low_open=True), default=1.0,
                   help="samples per second, in (0, 100] [1]")  # fmt: skip
    s.add_argument("--seed", type=seed_type, default=0, help="noise seed [0]")
    s.add_argument("--observe", choices=("ecef", "reduced"), default="ecef",
                   help="full ECEF state, or altitude and speed plus a sidecar [ecef]")  # fmt: skip
    s.add_argument("--noise-tails", choices=("normal", "student-t3"), default="normal",
                   help="noise distribution, both with the given standard deviation [normal]")  # fmt: skip
    s.add_argument("--start-scatter", type=number_list(non_negative_float, 2, 2), metavar="SECONDS,METRES",
                   help="the first SECONDS of positions (altitudes) scatter by a further METRES")  # fmt: skip
    s.add_argument("--entry-offset", type=number_list(interval(-50e3, 50e3), 1, 2), metavar="METRES[,MPS]",
                   help="a reduced record's sidecar declares the entry altitude (and speed) this much above the "
                   "truth, e.g. an altitude read on another reference")  # fmt: skip
    s.add_argument("--latitude", type=interval(-80.0, 80.0), metavar="DEG",
                   help="geocentric latitude of the entry point [10]")  # fmt: skip
    s.set_defaults(func=_simulate)


def _record_path(text: str) -> Path:
    path = Path(text)
    if not path.exists() and text in SHIPPED_RECORDS:
        from importlib import import_module

        return import_module(f"rventry_env.validation.{text}").record_path()
    return path


def _identify(args: argparse.Namespace) -> int:
    from rventry_env.util.files import check_writable
    from rventry_env.validation.identify import identify
    from rventry_env.validation.record import load_record, load_sidecar
    from rventry_env.validation.report.outputs import write_outputs

    # every destination first: an unwritable one fails now, not after the run
    check_writable(args.json, args.model_out, folders=(args.plots,) if args.plots else ())
    record = load_record(_record_path(args.record))
    vehicle = None
    if args.vehicle is not None:
        if args.vehicle.is_dir():
            raise ValueError(f"--vehicle {args.vehicle}: is a directory, not a vehicle JSON file")
        vehicle = load_sidecar(args.vehicle)
    kwargs = {"candidates": tuple(args.candidates)} if args.candidates else {}
    ident = identify(
        record, vehicle=vehicle, start=args.start, threshold=args.threshold, h_max=args.h_max,
        max_effects=args.max_effects, progress=not args.quiet, noise=args.noise, **kwargs,
    )  # fmt: skip
    write_outputs(ident, args.json, args.model_out, args.plots)
    rep = ident.report
    try:
        _print_summary(rep)
        sys.stdout.flush()
    except BrokenPipeError:  # the summary piped into a reader that stopped (head): the report is written
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _fmt(v, spec: str = ".4g") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return format(v, spec)


def _print_summary(rep: dict) -> None:
    kind = rep["record"]["kind"]
    key, vkey = ("position", "velocity") if kind == "ecef" else ("altitude", "speed")
    print(f"effect: {rep['effect']}   effects added: {', '.join(rep['effects']) or 'none'}"
          + ("   UNEXPLAINED residual remains" if rep["unexplained"] else ""))  # fmt: skip
    fixed = rep.get("fixed_parameters", {})
    for k, v in rep["parameters"].items():
        if k in fixed:
            print(f"  {k} = {_fmt(v, '.6g')} (known value)")
        else:
            print(f"  {k} = {_fmt(v, '.6g')} +- {_fmt(rep['parameter_stderr'].get(k), '.2g')}")
    for group in rep.get("aliases", []):
        members = "; ".join(" + ".join(m["effects"]) + (" (tied)" if m["tied"] else "") for m in group["members"])
        print(f"aliases (fit equally well): {members}")
        print(f"  because {group['reason']}")
    print("ranking (step 1, BIC on the effective sample size):")
    for r in rep["ranking"]:
        flags = []
        if r["at_bound"]:
            flags.append("on bound: " + ", ".join(r["at_bound"]))
        if r["initial_state_at_bound"]:
            flags.append("entry state on bound")
        flags.extend(r["implausible"])
        mark = "" if r["credible"] else "  NOT CREDIBLE (" + "; ".join(flags) + ")"
        print(f"  {r['effect']:18s} BIC {_fmt(r['bic'], '12.1f')}   delta {_fmt(r['delta_bic'], '10.1f')}{mark}")
    b, a = rep["before"], rep["after"]
    print(f"{key} rms: {_fmt(b[key + '_rms_m'])} m -> {_fmt(a[key + '_rms_m'])} m   "
          f"max: {_fmt(b[key + '_max_m'])} m -> {_fmt(a[key + '_max_m'])} m   "
          f"{vkey} rms: {_fmt(b[vkey + '_rms_mps'])} -> {_fmt(a[vkey + '_rms_mps'])} m/s")  # fmt: skip
    w = rep["whiteness"]
    print(f"lag-1 autocorrelation: {_fmt(w['before']['lag1_autocorrelation'], '.3f')} -> "
          f"{_fmt(w['after']['lag1_autocorrelation'], '.3f')}   Ljung-Box p: {_fmt(w['before']['ljung_box_p'], '.3g')} -> "
          f"{_fmt(w['after']['ljung_box_p'], '.3g')}")  # fmt: skip
    for w in (rep.get("entry_state_check") or {}).get("warnings", []):
        print(f"warning: {w}")
    offset = rep.get("entry_state_offset")
    if offset and (offset["prior_widened"] or offset["explained_by"]):
        print("entry state: " + offset["statement"])
    if rep.get("rejected_outliers"):
        rows = ", ".join(str(r["row"]) for r in rep["rejected_outliers"][:10])
        print(f"outliers rejected: {len(rep['rejected_outliers'])} (rows {rows})")
    print(rep["adequacy"]["statement"])
    if rep.get("trace"):  # what the residual trace found (an attribution, or a leading correction below the threshold)
        print("trace: " + rep["trace"]["statement"])
    print(f"({_fmt(rep['elapsed_s'], '.1f')} s, {rep['replays']} replays with sensitivities)")


def _simulate(args: argparse.Namespace) -> int:
    from rventry_env.util.files import check_writable
    from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record

    specs = [e for e in args.effect if e.strip().lower() != "none"]
    noise = args.noise if len(args.noise) == 2 else (args.noise[0], args.noise[0] / 100.0)
    effects = parse_effects(specs)
    out = args.out
    check_writable(out, out.with_name(out.stem + ".truth.json"),
                   out.with_suffix(".json") if args.observe == "reduced" else None)  # fmt: skip
    if args.entry_offset and args.observe != "reduced":
        raise ValueError("--entry-offset: only a reduced record (--observe reduced) has a sidecar entry state")
    from dataclasses import replace

    from rventry_env.validation.synthetic.simulate import Scenario

    scenario = Scenario() if args.latitude is None else replace(Scenario(), latitude_deg=args.latitude)
    offset = None if not args.entry_offset else (list(args.entry_offset) + [0.0])[:2]
    out = simulate_record(out, effects, noise=noise, duration=args.duration, rate=args.rate, seed=args.seed,
                          observe=args.observe, noise_tails=args.noise_tails, scenario=scenario,
                          start_scatter=tuple(args.start_scatter) if args.start_scatter else None,
                          entry_offset=None if offset is None else tuple(offset))  # fmt: skip
    print(f"wrote {out} ({', '.join(specs) or 'no effect'}; noise {noise[0]:g} m, {noise[1]:g} m/s)",
          file=sys.stderr)  # fmt: skip
    return 0


__all__ = ["register"]
