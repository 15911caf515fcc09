"""Where a policy's flights stand in their last minute: altitude, speed, angle from vertical and alpha,
seconds before each impact, beside the shipped reference's.

A policy that misses the dive may have lost it long before the dive: a flight that reaches the last
minute low and fast (energy spent in dense air) has no height left to turn to vertical in, and no
shaping of the dive can give it back. This study flies each policy on held-out episodes of a rung,
records every flight, and reads each at fixed seconds before its impact (its last recorded state
being the impact), so that two policies, or a policy and the reference, can be set side by side:

- per policy and per time before impact: the median and the range over the episodes of the
  altitude (km), the Earth-relative speed (m/s), the angle of the velocity from straight down
  (deg) and alpha (deg), and each flight's duration;
- the reference's own values at the same times;
- a PNG with altitude, speed and angle from vertical against the time to impact.

Run: ``python studies/last_seconds.py runs/A runs/B --labels A B --rung standard --episodes 20
--out out/last_seconds`` (writes ``out/last_seconds.json`` and ``.png``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rventry_env.util.files import output_set, save_figure
from rventry_env.util.provenance import start_run, write_record

BEFORE_S = (120.0, 60.0, 40.0, 30.0, 20.0, 15.0, 10.0, 5.0, 2.0, 0.0)
EVAL_SEED = 1000  # the ladder's held-out seeds
QUANTITIES = ("altitude_km", "speed_mps", "from_vertical_deg", "alpha_deg")


def read_flight(t: np.ndarray, x: np.ndarray, radius: float, before_s=BEFORE_S) -> dict:
    """One flight's states (``t`` (n,), ``x`` (n, 12); rows past the flight's end NaN) at ``before_s``
    seconds before its last recorded state, linearly interpolated in time; NaN before the flight's start."""
    t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    if t.ndim != 1 or x.ndim != 2 or x.shape != (t.size, 12):
        raise ValueError(f"a flight is t (n,) and x (n, 12), got {t.shape} and {x.shape}")
    ok = np.isfinite(t) & np.all(np.isfinite(x), axis=1)
    if ok.sum() < 2:
        raise ValueError("a flight needs at least two finite recorded states")
    t, x = t[ok], x[ok]
    at = t[-1] - np.asarray(before_s, dtype=float)
    from rventry_env.core.backend import NUMPY
    from rventry_env.envs.outcome import angle_from_vertical  # the vertical-impact error's own formula

    values = {"altitude_km": (x[:, 0] - radius) / 1000.0, "speed_mps": x[:, 5],
              "from_vertical_deg": np.degrees(angle_from_vertical(x.T, NUMPY)), "alpha_deg": np.degrees(x[:, 10])}  # fmt: skip
    out = {k: np.where(at >= t[0], np.interp(at, t, v), np.nan) for k, v in values.items()}
    out["duration_s"] = float(t[-1] - t[0])
    return out


def summarize(flights: list[dict], before_s=BEFORE_S) -> dict:
    """Median, min and max over ``flights`` (:func:`read_flight`) at each time before impact."""
    out = {"episodes": len(flights), "before_s": list(before_s),
           "duration_s": {"p50": float(np.median([f["duration_s"] for f in flights])),
                          "min": float(min(f["duration_s"] for f in flights)),
                          "max": float(max(f["duration_s"] for f in flights))}}  # fmt: skip
    for q in QUANTITIES:
        a = np.array([f[q] for f in flights])
        seen = np.any(np.isfinite(a), axis=0)  # times some flight reached (None where every one was shorter)
        a = np.where(seen, a, 0.0)
        out[q] = {k: [float(v) if ok else None for v, ok in zip(fn(a, axis=0), seen)]
                  for k, fn in (("p50", np.nanmedian), ("min", np.nanmin), ("max", np.nanmax))}
    return out


def reference_flight(before_s=BEFORE_S) -> dict:
    """The shipped reference read as a flight (its states each second)."""
    from rventry_env.physics.model import EntryModel
    from rventry_env.reference import load_reference

    ref = load_reference()
    t = np.arange(ref.t0, ref.tf, 1.0)
    t = np.append(t, ref.tf)
    return read_flight(t, ref.state(t), EntryModel().planet.radius, before_s)


def fly(agent: str, rung: str, episodes: int, before_s=BEFORE_S) -> tuple[list[dict], dict]:
    """``agent`` on ``episodes`` held-out episodes of ``rung`` (seeds from 1000), each flight read."""
    from rventry_env.evaluation.cli import run_agent
    from rventry_env.evaluation.rungs import rung as ladder_rung
    from rventry_env.physics.model import EntryModel

    r = ladder_rung(rung)
    batch, summary = run_agent(agent, episodes, r.dispersion, EVAL_SEED, history=True, targets=r.targets, rung=rung)
    radius = EntryModel().planet.radius
    xs, ts = np.asarray(batch.history_x), np.asarray(batch.history_t)  # (steps, episodes, 12), (steps, episodes)
    flights = [read_flight(ts[:, i], xs[:, i], radius, before_s) for i in range(xs.shape[1])]
    return flights, {"success": summary["success_rate"], "miss_km_p50": summary["miss_m"]["p50"] / 1e3}


def plot(results: dict, reference: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    before = np.asarray(reference["before_s"])
    for ax, (q, label) in zip(axes, (("altitude_km", "altitude (km)"), ("speed_mps", "speed (m/s)"),
                                     ("from_vertical_deg", "angle from vertical (deg)"))):  # fmt: skip
        ax.plot(-before, reference[q], "k--", lw=2, label="reference")
        for name, r in results.items():
            s = r["flights"]
            p50, lo, hi = (np.array(s[q][k], dtype=float) for k in ("p50", "min", "max"))  # None: nan
            line = ax.plot(-before, p50, "o-", label=f"{name} (success {r['outcome']['success']:.2f})")[0]
            ax.fill_between(-before, lo, hi, color=line.get_color(), alpha=0.15)
        ax.set_xlabel("time to impact (s)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("The last seconds of each flight: median and range over the episodes, beside the reference")
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", nargs="+", help="agent names or saved policies' folders")
    ap.add_argument("--labels", nargs="+", help="a label per agent (default: the agents as given)")
    ap.add_argument("--rung", default="standard")
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--out", required=True, help="path stem: writes STEM.json and STEM.png")
    args = ap.parse_args(argv)
    labels = args.labels or args.agents
    if len(labels) != len(args.agents):
        ap.error(f"--labels gives {len(labels)} labels for {len(args.agents)} agents")
    if args.episodes < 1:
        ap.error(f"--episodes must be >= 1, got {args.episodes}")
    start_run()
    ref = reference_flight()
    reference = {"before_s": list(BEFORE_S), "duration_s": ref["duration_s"], **{q: ref[q].tolist() for q in QUANTITIES}}
    results = {}
    k = BEFORE_S.index(60.0)  # the time the printed lines read
    for label, agent in zip(labels, args.agents):
        flights, outcome = fly(agent, args.rung, args.episodes)
        results[label] = {"agent": agent, "outcome": outcome, "flights": summarize(flights)}
        s = results[label]["flights"]
        print(f"{label}: success {outcome['success']:.2f}, flights {s['duration_s']['p50']:.0f} s; 60 s before "
              f"impact {s['altitude_km']['p50'][k]:.1f} km, {s['speed_mps']['p50'][k]:.0f} m/s, "
              f"{s['from_vertical_deg']['p50'][k]:.1f} deg from vertical (medians)")  # fmt: skip
    print(f"reference: {reference['duration_s']:.0f} s; 60 s before impact {reference['altitude_km'][k]:.1f} km, "
          f"{reference['speed_mps'][k]:.0f} m/s, {reference['from_vertical_deg'][k]:.1f} deg from vertical")  # fmt: skip
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    png = out.with_suffix(".png")
    with output_set():  # the plot and its record together, or neither
        plot(results, reference, png)
        write_record(out.with_suffix(".json"), {"rung": args.rung, "episodes": args.episodes, "eval_seed": EVAL_SEED,
                                               "reference": reference, "policies": results})  # fmt: skip
    print(f"wrote {out.with_suffix('.json')} and {png}")


if __name__ == "__main__":
    main()
