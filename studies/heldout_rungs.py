"""One policy on the ladder's rungs, held out: 200 episodes a rung from seed 1000 (never a training
or selection seed), its success with the 95 % interval, the median miss and vertical error.

    python studies/heldout_rungs.py RUN docs/results/wide_stage/1e-5/heldout.json nominal standard wide flight
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rventry_env.util.files import write_json  # noqa: E402
from studies.ladder import evaluate_on_rung  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("agent", help="an agent name or a saved policy's folder")
    ap.add_argument("json", help="where to write the figures")
    ap.add_argument("rungs", nargs="+", help="the rungs, e.g. nominal standard wide flight")
    ap.add_argument("--episodes", type=int, default=200)
    args = ap.parse_args(argv)
    results = {}
    for r in args.rungs:
        t0 = time.perf_counter()
        results[r] = {**evaluate_on_rung(args.agent, r, args.episodes), "eval_s": time.perf_counter() - t0}
        print(f"{args.agent} {r}: success {results[r]['success']:.3f} {results[r]['success_ci']}", flush=True)
    write_json(args.json, {"agent": args.agent, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
