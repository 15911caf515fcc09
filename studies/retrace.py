"""Does a from-scratch run retrace another's training? Its chunks' evaluations, compared to the bit.

A ``rventry train ppo-scratch`` run records, after every chunk, the selection set's success and
median miss, the curriculum's window and its frontier's success, and the exploration noise
(``evaluations.json``). Two runs of the same recipe on the same platform and thread count should
give the same floats at every chunk they share; the first chunk where they part says where the
recipe, or the platform, stopped reproducing.

    python studies/retrace.py runs/ppo_scratch/evaluations.json
    python studies/retrace.py runs/a/evaluations.json runs/b/evaluations.json --json out/retrace.json

The second file defaults to the shipped ``ppo-scratch`` policy's history. Exit status 0 when
every shared chunk is identical, 1 when one differs, 2 on a file that is not a run's history.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rventry_env.util.provenance import start_run, write_record

SHIPPED = Path(__file__).resolve().parent.parent / "rventry_agents" / "data" / "ppo_scratch" / "evaluations.json"


def fingerprint(chunk: dict) -> tuple:
    """The figures of one chunk that two runs of one recipe must share exactly."""
    s, c = chunk["select"], chunk["curriculum"]
    return (s["success_rate"], s["miss_km_p50"], c["window_s"], c["frontier_success"], tuple(chunk["exploration_std"]))


def read_history(path: Path) -> dict[int, dict]:
    """A run's chunks by their step count."""
    try:
        rows = json.loads(Path(path).read_text())
        for r in rows:
            fingerprint(r)  # every figure compared is there
        return {int(r["timesteps"]): r for r in rows}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"retrace: {path} is not a ppo-scratch run's evaluations.json ({type(exc).__name__}: {exc})",
              file=sys.stderr)  # fmt: skip
        raise SystemExit(2) from None


def compare(run: dict[int, dict], other: dict[int, dict]) -> tuple[list[int], int | None]:
    """(the step counts both runs evaluated, in order; the first where they differ, or None)."""
    shared = sorted(set(run) & set(other))
    return shared, next((t for t in shared if fingerprint(run[t]) != fingerprint(other[t])), None)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="the run's evaluations.json")
    ap.add_argument("other", type=Path, nargs="?", default=SHIPPED,
                    help="the history to compare with (default: the shipped ppo-scratch policy's)")  # fmt: skip
    ap.add_argument("--json", type=Path, default=None, help="write the comparison here as a record")
    args = ap.parse_args(argv)
    start_run(None if argv is None else ["python", __file__, *argv])
    run, other = read_history(args.run), read_history(args.other)
    shared, first = compare(run, other)
    if args.json is not None:
        write_record(args.json, {"run": str(args.run), "other": str(args.other), "run_chunks": len(run),
                                 "other_chunks": len(other), "shared_chunks": len(shared),
                                 "through_steps": shared[-1] if shared else None, "first_difference_steps": first,
                                 "identical": bool(shared) and first is None}, indent=2)  # fmt: skip
    if not shared:
        print(f"retrace: {args.run} and {args.other} share no chunk", file=sys.stderr)
        return 1
    if first is not None:
        print(f"the runs part at {first:,} steps (chunk {shared.index(first) + 1} of {len(shared)} shared):")
        print(f"  {args.run}: {fingerprint(run[first])}")
        print(f"  {args.other}: {fingerprint(other[first])}")
        return 1
    print(f"{len(shared)} of {len(shared)} shared chunks identical, through {shared[-1]:,} steps "
          f"({len(run)} chunks in {args.run}, {len(other)} in {args.other})")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
