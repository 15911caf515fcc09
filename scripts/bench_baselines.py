"""The plain-RL baselines on RvEntry-v0: held-out evaluation, one table, one learning-curve figure.

Each baseline is a finished training run (``rventry train ppo | recurrent-ppo | sac --config
rventry_agents/baselines/<algorithm>.toml``), shipped or not. This script flies each run's selected
model on the evaluation's seeds (never the selection's): the nominal flight, 200 standard-set and
200 wide-set episodes from seed 0, and prints the table the manual's learned-policies results quote. It also draws every
run's selection-set learning curve in one figure.

    python scripts/bench_baselines.py --json out/bench_baselines.json --plot out/baselines_learning_curves.png

Defaults: the runs shipped in ``rventry_agents/data/baselines/``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from rventry_env.util.args import positive_int
from rventry_env.util.files import check_writable, save_figure, write_json

SHIPPED = Path(__file__).resolve().parent.parent / "rventry_agents" / "data" / "baselines"
NAMES = {"ppo": "PPO", "recurrent_ppo": "RecurrentPPO", "sac": "SAC"}


def _runs(paths: list[str] | None) -> list[Path]:
    runs = [Path(p) for p in paths] if paths else sorted(p for p in SHIPPED.iterdir() if (p / "model.zip").is_file())
    for run in runs:
        missing = [f for f in ("model.zip", "policy.json", "metadata.json", "evaluations.json") if not (run / f).is_file()]
        if missing:
            raise SystemExit(f"error: {run} is not a finished training run: missing {', '.join(missing)}")
    if not runs:
        raise SystemExit(f"error: no runs given and none shipped in {SHIPPED}")
    return runs


def evaluate_run(run: Path, episodes: int, seed: int, workers: int) -> dict:
    from rventry_env.evaluation.cli import run_agent

    out = {}
    for case, n, dispersion in (("nominal", 1, "none"), ("standard", episodes, "standard"), ("wide", episodes, "wide")):
        t0 = time.time()
        _, summary = run_agent(str(run), n, dispersion, seed, history=False, workers=workers)
        out[case] = summary
        print(f"  {case}: success {summary['success_rate']:.2f} in {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    return out


def _pct(s: dict, key: str, p: int) -> float:
    return s["percentiles"][key][f"p{p}"]


def table(results: dict) -> str:
    head = ("| baseline | steps | wall | standard success | wide success | miss p50 / p95 (km), standard "
            "| vertical error p50 (deg), standard | no path violation, standard | J/J* nominal | nominal miss (km) |")  # fmt: skip
    lines = [head, "|" + "---|" * 10]
    for name, r in results.items():
        m, st, wd, nom = r["training"], r["standard"], r["wide"], r["nominal"]
        lines.append(
            f"| {NAMES.get(r['algorithm'], r['algorithm'])} | {m['timesteps'] / 1e6:.0f}M | {m['wall_time_s'] / 60:.0f} min "
            f"| {st['success_rate']:.2f} | {wd['success_rate']:.2f} "
            f"| {_pct(st, 'miss_km', 50):.3g} / {_pct(st, 'miss_km', 95):.3g} | {_pct(st, 'vertical_error_deg', 50):.3g} "
            f"| {1 - st['constraint_violation_rate']:.2f} | {nom['cost_ratio']:.3g} | {nom['miss_km']:.3g} |"
        )  # fmt: skip
    return "\n".join(lines)


def plot(results: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    for name, r in results.items():
        h = r["evaluations"]
        steps = np.array([e["timesteps"] for e in h]) / 1e6
        label = NAMES.get(r["algorithm"], r["algorithm"])
        ax[0].plot(steps, [e["success_rate"] for e in h], "o-", ms=3, label=label)
        ax[1].semilogy(steps, [e["median_miss_km"] for e in h], "o-", ms=3, label=label)
        ax[2].plot(steps, [e["vertical_error_deg"] for e in h], "o-", ms=3, label=label)
    ax[0].set(xlabel="environment steps (M)", ylabel="success rate", ylim=(-0.02, 1.02))
    ax[1].set(xlabel="environment steps (M)", ylabel="median miss (km)")
    ax[2].set(xlabel="environment steps (M)", ylabel="mean vertical-impact error (deg)")
    for a in ax:
        a.grid(alpha=0.3)
    ax[0].legend()
    fig.suptitle("Plain-RL baselines on RvEntry-v0: the selection set (100 standard episodes, seed 100000) during training")
    save_figure(fig, path)


def main(argv=None) -> int:
    from rventry_env.evaluation.parallel import default_workers

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="*", help="training run directories (default: the shipped baselines)")
    ap.add_argument("--episodes", type=positive_int, default=200, help="dispersed episodes per set (default 200)")
    ap.add_argument("--seed", type=int, default=0, help="first evaluation seed (default 0, held out from selection)")
    ap.add_argument("--workers", type=positive_int, default=default_workers())
    ap.add_argument("--json", required=True, metavar="PATH")
    ap.add_argument("--plot", metavar="PNG", help="the learning curves of every run in one figure")
    args = ap.parse_args(argv)
    runs = _runs(args.runs)
    check_writable(args.json, args.plot)
    results = {}
    for run in runs:
        meta = json.loads((run / "metadata.json").read_text())
        algorithm = json.loads((run / "policy.json").read_text()).get("algorithm", "ppo")
        print(f"{run} ({algorithm})", file=sys.stderr, flush=True)
        results[str(run)] = {
            "algorithm": algorithm,
            "training": {k: meta.get(k) for k in ("command", "seed", "timesteps", "wall_time_s")},
            "evaluations": json.loads((run / "evaluations.json").read_text()),
            **evaluate_run(run, args.episodes, args.seed, args.workers),
        }
    write_json(args.json, {"seed": args.seed, "episodes": args.episodes, "runs": results})
    if args.plot:
        plot(results, args.plot)
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
