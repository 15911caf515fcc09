"""Every shipped law on the flight-grade dispersion sets: basic and precision success with 95 %
Wilson intervals, miss percentiles, and the oracle's ceiling beside them.

For each set and law this runs what ``rventry evaluate --agent LAW --dispersion SET`` runs (seeds
0 .. N-1) and prints one Markdown table per set (the manual's flight-grade results). The ceiling column reads
``out/oracle_SET.json`` (``rventry oracle --dispersion SET --episodes 50 --json out/oracle_SET.json``)
when it is there.

``--targets footprint`` flies each set on the footprint task (a target per episode within
+/-300 km downrange and +/-150 km crossrange, told to the law); a law that cannot re-target is
listed as refused.

``--effects`` instead flies the laws on the ``flight`` set's parts one at a time (its scalar
dispersions alone, the climatology alone, the density perturbation alone, the winds alone, the
Mach-dependent aerodynamics alone, the sensors and navigation alone), and on the whole set with
perfect sensors and navigation: which effect breaks which law (``--effect NAME ...``: those rows only).

Run: ``python studies/flight_sets.py [--sets flight peer peer-0.1] [--laws ...] [--episodes 200]
[--mpc-episodes 20] [--workers 2] [--targets footprint] [--effects] --json out/bench_sets.json``
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rventry_env.util.provenance import start_run, write_record

LAWS = ("reference", "lqr", "lqr-est", "mpc", "mpc-flight", "learned")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sets", nargs="+", default=["flight", "peer", "peer-0.1"])
    ap.add_argument("--laws", nargs="+", default=list(LAWS))
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--mpc-episodes", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--targets", choices=("fixed", "footprint"), default="fixed")
    ap.add_argument("--effects", action="store_true", help="the flight set's effects one at a time")
    ap.add_argument("--effect", nargs="+", metavar="NAME", help="with --effects: only these rows (default: every one)")
    ap.add_argument("--json", required=True)
    args = ap.parse_args()
    start_run()
    if args.effects:
        return effects(args)

    from rventry_env.evaluation.cli import run_agent

    out: dict = {"episodes": args.episodes, "mpc_episodes": args.mpc_episodes, "targets": args.targets, "sets": {}}
    for s in args.sets:
        rows = {}
        for law in args.laws:
            n = args.mpc_episodes if law.startswith("mpc") else args.episodes
            t0 = time.time()
            try:
                _, summary = run_agent(law, n, s, 0, history=False, workers=args.workers, targets=args.targets)
            except ValueError as exc:
                if "cannot re-target" not in str(exc):
                    raise
                rows[law] = {"refused": str(exc)}
                print(f"{s:9s} {law:10s} refused: cannot re-target", flush=True)
                continue
            rows[law] = {k: summary[k] for k in ("episodes", "success_rate", "success_rate_ci", "precision_success_rate",
                                                 "precision_success_rate_ci", "miss_m", "endings",
                                                 "constraint_violation_rate")}  # fmt: skip
            rows[law]["wall_s"] = time.time() - t0
            print(f"{s:9s} {law:10s} {n:4d} ep: success {summary['success_rate']:.2f} {summary['success_rate_ci']}, "
                  f"precision {summary['precision_success_rate']:.2f}, {time.time() - t0:.0f} s", flush=True)  # fmt: skip
        ceiling = None
        path = Path("out") / f"oracle_{s}.json"
        if path.exists() and args.targets == "fixed":
            ceiling = json.loads(path.read_text())["summary"]
        out["sets"][s] = {"laws": rows, "oracle": ceiling}
        write_record(args.json, out)
        print(table(s if args.targets == "fixed" else f"{s}, footprint", rows, ceiling))


def effect_sets() -> dict:
    """The flight set's parts, each alone, and the set with perfect sensors and navigation (Dispersions)."""
    import dataclasses

    from rventry_env.evaluation.oracle import perfect_sensing
    from rventry_env.task import FLIGHT_GRADE_ERRORS as F
    from rventry_env.task import Dispersion, FlightGradeErrors
    from rventry_env.task.flight_grade import SENSING_FIELDS

    flight = Dispersion.parse("flight")
    sensing = {k: getattr(F, k) for k in SENSING_FIELDS}
    return {
        "entry state, C_L/C_D, mass": dataclasses.replace(flight, flight=None),
        "NRLMSIS climatology": Dispersion(flight=FlightGradeErrors(climatology=True)),
        "density perturbation": Dispersion(flight=FlightGradeErrors(density_bands=F.density_bands)),
        "winds": Dispersion(flight=FlightGradeErrors(wind_mean_mps=F.wind_mean_mps, wind_bands=F.wind_bands)),
        "Mach-dependent C_L/C_D": Dispersion(flight=FlightGradeErrors(lift_mach=F.lift_mach,
                                                                       drag_mach=F.drag_mach)),
        "sensors and navigation": Dispersion(flight=FlightGradeErrors(**sensing)),
        "all but sensors and navigation": perfect_sensing(flight),
    }


def effects(args) -> None:
    from rventry_env.evaluation.cli import run_agent

    out: dict = {"episodes": args.episodes, "effects": {}}
    lines = ["| effect alone | " + " | ".join(f"`{law}`" for law in args.laws) + " |",
             "|---|" + "---|" * len(args.laws)]  # fmt: skip
    sets = effect_sets()
    unknown = sorted(set(args.effect or ()) - set(sets))
    if unknown:
        raise SystemExit(f"unknown effect(s) {unknown}: choose from {sorted(sets)}")
    for name, d in sets.items():
        if args.effect and name not in args.effect:
            continue
        cells = []
        for law in args.laws:
            n = args.mpc_episodes if law.startswith("mpc") else args.episodes
            _, summary = run_agent(law, n, d.describe() | {"flight": d.flight}, 0, history=False, workers=args.workers)
            out["effects"].setdefault(name, {})[law] = {k: summary[k] for k in ("episodes", "success_rate",
                                                       "success_rate_ci", "precision_success_rate", "miss_m")}  # fmt: skip
            c = summary["success_rate_ci"]
            cells.append(f"{summary['success_rate']:.2f} [{c[0]:.2f}, {c[1]:.2f}]")
            print(f"{name:28s} {law:10s} {n:4d} ep: success {summary['success_rate']:.2f}", flush=True)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        write_record(args.json, out)
    print("\n".join(lines))


def table(name: str, rows: dict, ceiling: dict | None) -> str:
    def ci(v, c):
        return f"{v:.2f} [{c[0]:.2f}, {c[1]:.2f}]"

    lines = [f"`{name}`" + (f" (oracle: flyable {ci(ceiling['flyable_fraction'], ceiling['flyable_fraction_ci'])} on "
                             f"{ceiling['draws']} draws)" if ceiling else ""),  # fmt: skip
             "", "| law | episodes | success [95 % CI] | precision [95 % CI] | miss p50 / p95 (m) | path-bound breaches |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for law, r in rows.items():
        if "refused" in r:
            lines.append(f"| `{law}` | - | refused: cannot re-target | | | |")
            continue
        m = r["miss_m"]
        lines.append(f"| `{law}` | {r['episodes']} | {ci(r['success_rate'], r['success_rate_ci'])} | "
                     f"{ci(r['precision_success_rate'], r['precision_success_rate_ci'])} | "
                     f"{m['p50']:.0f} / {m['p95']:.0f} | {r['constraint_violation_rate']:.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
