"""Runs of ``rventry train ppo-scratch`` side by side: the selection set's success chunk by chunk.

    python studies/curves.py LABEL=RUN [LABEL=RUN ...] --out out/curves [--from STEPS] [--window]

Each RUN's ``evaluations.json`` gives, after every chunk, the deterministic policy's success on the
run's selection set (256 of the rung's own episodes, seeds apart from the held-out ones). The
script plots them against the training steps (from ``--from`` on: a stage started from another
run's state at that step) in ``OUT.png``, and writes ``OUT.json`` with, for each run: the best
chunk (the one the run selects) and its step, the last chunk, the mean and the lowest of the last
10 chunks, and the lowest after the first 5 (a fall within the stage). Labels group runs whose
names share the text before the last space (``"constant s2"``, ``"constant s3"``: one colour,
a line style each, with a marker from a group's fifth run on).

With ``--window`` a second panel plots the reverse curriculum's window (how far before impact its
starts reach) after each chunk, and the record gives, for each run, the step and the wall time at
which each window was first trained on: where a curriculum stood, and how long.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rventry_env.util.files import output_set
from rventry_env.util.provenance import start_run, write_record

LAST = 10  # the chunks the end of a run is read over
SETTLE = 5  # the first chunks of a stage, left out of its lowest point


def chunks(run: Path, start: int = 0) -> list[dict]:
    """``run``'s evaluation after each of its chunks past ``start`` (at least one)."""
    rows = [h for h in json.loads((run / "evaluations.json").read_text()) if h["timesteps"] > start]
    if not rows:
        raise ValueError(f"{run}: no chunk past {start:,d} steps")
    return rows


def curve(run: Path, start: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(steps, selection success) of each of ``run``'s chunks past ``start``."""
    rows = chunks(run, start)
    steps = np.asarray([h["timesteps"] for h in rows], float)
    return steps, np.asarray([h["select"]["success_rate"] for h in rows], float)


def windows(run: Path, start: int = 0) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """(steps, window in s) of each of ``run``'s chunks past ``start``, and each window's first chunk:
    ``{"window_s", "timesteps", "wall_s"}``, the window the chunk after it trains on."""
    rows = chunks(run, start)
    missing = [h["timesteps"] for h in rows if not (h.get("curriculum") or {}).get("window_s")]
    if missing:
        raise ValueError(f"{run}: no curriculum window in the chunk at {missing[0]:,d} steps (a run without "
                         f"the reverse curriculum)")  # fmt: skip
    steps = np.asarray([h["timesteps"] for h in rows], float)
    window = np.asarray([h["curriculum"]["window_s"] for h in rows], float)
    first = [{"window_s": float(w), "timesteps": int(h["timesteps"]), "wall_s": float(h["wall_s"])}
             for i, (h, w) in enumerate(zip(rows, window)) if i == 0 or w != window[i - 1]]  # fmt: skip
    return steps, window, first


def summary(steps: np.ndarray, success: np.ndarray) -> dict:
    """The best chunk, the last, the mean and the lowest of the last ``LAST`` chunks, and the lowest
    after the first ``SETTLE``."""
    best = int(np.argmax(success))  # the first of equals, as the run's selection ranks them
    tail = success[-LAST:]
    return {"chunks": len(success), "best": float(success[best]), "best_at": int(steps[best]),
            "last": float(success[-1]), "last_at": int(steps[-1]), "last10_mean": float(tail.mean()),
            "last10_min": float(tail.min()),
            "min_after_settling": float(success[SETTLE:].min()) if len(success) > SETTLE else None}  # fmt: skip


def plot(curves: dict, path: Path, title: str, windows: dict | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = sorted({label.rsplit(" ", 1)[0] for label in curves})
    colours = {g: f"C{i}" for i, g in enumerate(groups)}
    if windows:
        fig, (wax, ax) = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True)
    else:
        fig, ax = plt.subplots(figsize=(9, 4.5))
    members: dict[str, int] = {}
    for label, (steps, success) in curves.items():
        group = label.rsplit(" ", 1)[0]
        k = members[group] = members.get(group, -1) + 1  # each run of a group its own line style, past four a marker
        style = {"color": colours[group], "ls": ("-", "--", ":", "-.")[k % 4], "lw": 1.2,
                 "marker": ("", "o", "s", "^")[(k // 4) % 4], "markevery": 0.06, "ms": 3.5}
        ax.plot(steps / 1e6, success, label=label, **style)
        if windows:
            w_steps, window = windows[label]
            wax.step(w_steps / 1e6, window, where="post", label=label, **style)
    if windows:
        wax.set_ylabel("curriculum window (s before impact)")
        wax.grid(alpha=0.3)
        wax.legend(fontsize=8, ncol=2)
        wax.set_title(title, fontsize=10)
    ax.set_xlabel("training steps (millions)")
    ax.set_ylabel("success on the selection set")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    if not windows:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    start_run()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", help="LABEL=RUN")
    ap.add_argument("--out", type=Path, required=True, help="OUT.png and OUT.json are written")
    ap.add_argument("--from", dest="start", type=int, default=0, help="plot the chunks past this step")
    ap.add_argument("--title", help="the plot's title (default: what it plots)")
    ap.add_argument("--window", action="store_true", help="also plot the curriculum's window after each chunk")
    args = ap.parse_args()
    if args.title is None:
        what = "the selection set's success after each chunk"
        args.title = f"the curriculum's window and {what}" if args.window else what
    curves, rows, wins = {}, {}, {}
    for item in args.runs:
        label, sep, run = item.partition("=")
        if not sep or not label or not run:
            ap.error(f"{item!r}: give LABEL=RUN")
        curves[label] = curve(Path(run), args.start)
        rows[label] = {"run": run, **summary(*curves[label])}
        r = rows[label]
        print(f"{label}: best {r['best']:.2f} at {r['best_at'] / 1e6:,.1f}M, last {r['last']:.2f}, last {LAST} mean "
              f"{r['last10_mean']:.2f} (lowest {r['last10_min']:.2f}), lowest after {SETTLE} chunks "
              f"{r['min_after_settling']}")  # fmt: skip
        if args.window:
            w_steps, window, first = windows(Path(run), args.start)
            wins[label] = (w_steps, window)
            r["windows"] = first
            print("  window first trained on: " + ", ".join(
                f"{w['window_s']:.0f} s at {w['timesteps'] / 1e6:,.1f}M ({w['wall_s']:,.0f} s)" for w in first))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with output_set():  # the plot and its record together, or neither
        plot(curves, args.out.with_suffix(".png"), args.title, wins or None)
        write_record(args.out.with_suffix(".json"), {"about": args.title, "from_timesteps": args.start, "runs": rows})


if __name__ == "__main__":
    main()
