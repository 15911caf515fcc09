"""Every shipped law on the flight-grade dispersion sets: basic and precision success with 95 %
Wilson intervals, miss percentiles, and the oracle's ceiling beside them.

For each set and law this runs what ``rventry evaluate --agent LAW --dispersion SET`` runs (seeds
0 .. N-1) and prints one Markdown table per set (the README's). The ceiling column reads
``out/oracle_SET.json`` (``rventry oracle --dispersion SET --episodes 50 --json out/oracle_SET.json``)
when it is there.

Run: ``python scripts/bench_sets.py [--sets flight peer peer-0.1] [--laws ...] [--episodes 200]
[--mpc-episodes 20] [--workers 2] --json out/bench_sets.json``
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

LAWS = ("reference", "lqr", "lqr-est", "mpc", "learned")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sets", nargs="+", default=["flight", "peer", "peer-0.1"])
    ap.add_argument("--laws", nargs="+", default=list(LAWS))
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--mpc-episodes", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", required=True)
    args = ap.parse_args()

    from rventry_env.evaluation.cli import run_agent
    from rventry_env.util.files import write_json

    out: dict = {"episodes": args.episodes, "mpc_episodes": args.mpc_episodes, "sets": {}}
    for s in args.sets:
        rows = {}
        for law in args.laws:
            n = args.mpc_episodes if law == "mpc" else args.episodes
            t0 = time.time()
            _, summary = run_agent(law, n, s, 0, history=False, workers=args.workers)
            rows[law] = {k: summary[k] for k in ("episodes", "success_rate", "success_rate_ci", "precision_success_rate",
                                                 "precision_success_rate_ci", "miss_m", "endings",
                                                 "constraint_violation_rate")}  # fmt: skip
            rows[law]["wall_s"] = time.time() - t0
            print(f"{s:9s} {law:10s} {n:4d} ep: success {summary['success_rate']:.2f} {summary['success_rate_ci']}, "
                  f"precision {summary['precision_success_rate']:.2f}, {time.time() - t0:.0f} s", flush=True)  # fmt: skip
        ceiling = None
        path = Path("out") / f"oracle_{s}.json"
        if path.exists():
            ceiling = json.loads(path.read_text())["summary"]
        out["sets"][s] = {"laws": rows, "oracle": ceiling}
        write_json(args.json, out)
        print(table(s, rows, ceiling))


def table(name: str, rows: dict, ceiling: dict | None) -> str:
    def ci(v, c):
        return f"{v:.2f} [{c[0]:.2f}, {c[1]:.2f}]"

    lines = [f"`{name}`" + (f" (oracle: flyable {ci(ceiling['flyable_fraction'], ceiling['flyable_fraction_ci'])} on "
                             f"{ceiling['draws']} draws)" if ceiling else ""),  # fmt: skip
             "", "| law | episodes | success [95 % CI] | precision [95 % CI] | miss p50 / p95 (m) | path-bound breaches |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for law, r in rows.items():
        m = r["miss_m"]
        lines.append(f"| `{law}` | {r['episodes']} | {ci(r['success_rate'], r['success_rate_ci'])} | "
                     f"{ci(r['precision_success_rate'], r['precision_success_rate_ci'])} | "
                     f"{m['p50']:.0f} / {m['p95']:.0f} | {r['constraint_violation_rate']:.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
