"""A learned policy's training seeds on the evaluation sets, reported with rliable.

Each method is a name and one or more policies: the training runs of its seeds (run directories
or saved models), or a shipped law (one run: a law that is not trained has no seed spread). Every
policy flies what ``rventry evaluate --agent POLICY --dispersion SET --episodes N --seed 0`` flies,
on every set, so the episodes are held out from training (which draws from its own seeds) and from
selection (seeds 100000 and up). The scores are a (runs, sets) matrix of success rates per method,
one for the basic tier and one for the precision tier.

Printed and written: each run's success per set with its Wilson interval, and per method the
interquartile mean and the mean over runs and sets with rliable's stratified-bootstrap 95 %
intervals; a PNG of the performance profiles (the fraction of (run, set) success rates above each
threshold).

Run: ``python studies/seeds.py --method ppo runs/ft_flight_s0 runs/ft_flight_s1
runs/ft_flight_s2 --method dagger dagger --sets flight standard wide peer-0.1 --episodes 200
--json out/bench_seeds.json --plot out/bench_seeds.png``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rventry_env.util.provenance import start_run, write_record

TIERS = {"basic": "success_rate", "precision": "precision_success_rate"}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--method", nargs="+", action="append", required=True, metavar=("NAME", "POLICY"),
                    help="a method's name and its policies (one per training seed, or one shipped law)")
    ap.add_argument("--sets", nargs="+", default=["flight", "standard", "wide", "peer-0.1"])
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--reps", type=int, default=20_000, help="bootstrap resamples (default 20000)")
    ap.add_argument("--json", required=True)
    ap.add_argument("--plot", required=True, help="the performance profiles (PNG)")
    args = ap.parse_args()
    start_run()
    methods = {}
    for m in args.method:
        if len(m) < 2:
            ap.error(f"--method {m[0]} names no policy: give its name, then one or more policies")
        if m[0] in methods:
            ap.error(f"method {m[0]!r} is given twice")
        methods[m[0]] = m[1:]

    from rventry_env.evaluation.cli import run_agent
    from rventry_env.evaluation.seeds import performance_profiles, plot_performance_profiles, seed_statistics
    from rventry_env.util.files import check_writable, output_set

    check_writable(args.json, args.plot)
    runs: dict = {}
    scores = {t: {} for t in TIERS}
    for name, policies in methods.items():
        runs[name] = []
        for t in TIERS:
            scores[t][name] = np.zeros((len(policies), len(args.sets)))
        for i, policy in enumerate(policies):
            row: dict = {"policy": policy, "sets": {}}
            for j, s in enumerate(args.sets):
                t0 = time.time()
                _, summary = run_agent(policy, args.episodes, s, 0, history=False, workers=args.workers)
                row["sets"][s] = {k: summary[k] for k in ("episodes", "success_rate", "success_rate_ci",
                                                         "precision_success_rate", "precision_success_rate_ci",
                                                         "miss_m", "constraint_violation_rate")}  # fmt: skip
                for t, key in TIERS.items():
                    scores[t][name][i, j] = summary[key]
                c = summary["success_rate_ci"]
                print(f"{name:10s} {policy[-40:]:40s} {s:9s} success {summary['success_rate']:.3f} "
                      f"[{c[0]:.2f}, {c[1]:.2f}] precision {summary['precision_success_rate']:.3f} "
                      f"({time.time() - t0:.0f} s)", flush=True)  # fmt: skip
            runs[name].append(row)

    stats = {t: seed_statistics(scores[t], reps=args.reps) for t in TIERS}
    profiles = performance_profiles(scores["basic"], np.linspace(0.0, 1.0, 101), reps=min(args.reps, 2_000))
    out = {"episodes": args.episodes, "seed": 0, "sets": args.sets, "runs": runs,
           "scores": {t: {k: v.tolist() for k, v in scores[t].items()} for t in TIERS},
           "aggregate": stats, "performance_profiles": profiles}  # fmt: skip
    with output_set():
        write_record(args.json, out)
        plot_performance_profiles(profiles, args.plot, xlabel="basic success rate tau",
                                  title=f"sets {', '.join(args.sets)}; {args.episodes} episodes each, seed 0")
    print(table(stats, args.sets))


def table(stats: dict, sets: list[str]) -> str:
    def ci(v, c):
        return f"{v:.3f} [{c[0]:.3f}, {c[1]:.3f}]"

    lines = [f"over runs and sets ({', '.join(sets)}); rliable stratified bootstrap, 95 %", "",
             "| method | runs | IQM basic | mean basic | IQM precision | mean precision |", "|---|---|---|---|---|---|"]
    for name, b in stats["basic"].items():
        p = stats["precision"][name]
        lines.append(f"| `{name}` | {b['runs']} | {ci(b['iqm'], b['iqm_ci'])} | {ci(b['mean'], b['mean_ci'])} | "
                     f"{ci(p['iqm'], p['iqm_ci'])} | {ci(p['mean'], p['mean_ci'])} |")  # fmt: skip
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
