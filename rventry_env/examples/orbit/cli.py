"""``rventry orbit``: the paper's Example 1 from the command line."""

from __future__ import annotations

import argparse
from pathlib import Path

from rventry_env.util.args import positive_int
from rventry_env.util.files import check_writable, write_json


def _print_report(report: dict) -> None:
    from rventry_env.examples.orbit.numerics import PLATEAU_N

    print(f"period T = {report['period_s']:.3f} s, fixed-step RK4, no quaternion renormalization")
    print(f"{'N':>7} {'rv-Euler e_r,max (km)':>22} {'spherical e_r,max (km)':>23} {'ratio':>9}")
    for row in report["results"]:
        ratio = row["spherical_km"] / row["rv_euler_km"] if row["rv_euler_km"] > 0 else float("inf")
        print(f"{row['n']:>7d} {row['rv_euler_km']:>22.3e} {row['spherical_km']:>23.3e} {ratio:>9.1f}")
    r = report["n1000"]
    print(
        f"N = 1000: e_r(sph)/e_r(rv) median after the South-Pole pass {r['median_ratio_after_south_pole']:.0f}, "
        f"at t = T {r['ratio_at_T']:.0f}, ratio of maxima {r['ratio_of_max']:.0f}"
    )
    for form, fl in report["floor_km"].items():
        plateau = "n/a" if fl["plateau_median"] is None else f"{fl['plateau_median']:.2e} km"
        print(f"floor {form}: smallest e_r,max {fl['min']:.2e} km, median over N >= {PLATEAU_N}: {plateau}")
    print(f"sweep wall time {report['sweep_wall_time_s']:.1f} s ({report['total_steps_per_form']} steps per form)")


def _command(args: argparse.Namespace) -> int:
    from rventry_env.examples.orbit.numerics import CircularOrbit, run_example
    from rventry_env.examples.orbit.plots import plot_results

    check_writable(args.json, folders=(args.plots,))
    orbit = CircularOrbit()
    report, runs_1000 = run_example(args.n, orbit, progress=not args.quiet)
    _print_report(report)
    if args.json:
        print(f"wrote {write_json(args.json, report, indent=2)}")
    if args.plots:
        for path in plot_results(runs_1000, report["results"], orbit, Path(args.plots)):
            print(f"wrote {path}")
    from rventry_env.task.glossary import terms_line

    print(terms_line(["e_r,max"]))
    return 0


def register(subparsers) -> None:
    """Add the ``orbit`` subcommand (the paper's Example 1).

    :param subparsers: the object returned by ``ArgumentParser.add_subparsers``.
    """
    p = subparsers.add_parser(
        "orbit",
        help="Example 1: one orbit period in rv-Euler vs spherical coordinates (RK4, error vs N)",
        description="Example 1 of the paper (Section sect:Ex1): one period of a circular polar orbit "
        "integrated with fixed-step RK4 in rv-Euler parameters and in spherical coordinates.",
    )
    p.add_argument(
        "--n", type=positive_int, action="append", metavar="N",
        help="number of RK4 steps per period (repeat for several; default: 30 log-spaced values in [10, 1e5])",
    )  # fmt: skip
    p.add_argument("--json", metavar="PATH", help="write the results as JSON")
    p.add_argument("--plots", metavar="DIR", help="write the two panels of Fig. fig:Ex1-res as PNG")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_command)


__all__ = ["register"]
