"""Where the observations of flown episodes lie against the observation Box, feature by feature.

For each dispersion set and guidance law this flies episodes through the vector env, as
``rventry evaluate`` does (one episode per copy, seeds S .. S + N - 1), records every
observation feature *before* the env clips it into the Box, and prints per set and law: the
steps and episodes the env clipped (``info["observation_clipped"]``), each feature's range seen
against its bounds, and for the clipped steps the true altitude and the navigation's vertical
error (navigated minus true altitude).

On the sets with navigation errors (``flight``) the altitude feature is the *navigated*
altitude: near impact the navigation can put the vehicle below the ground while it is still
flying, and the feature then falls below its bound; docs/env.md says when, with these figures.

    nice -n 19 python studies/observation_bounds.py                       # flight, 2000 episodes per law
    python studies/observation_bounds.py --sets none standard wide flight peer --episodes 500
    python studies/observation_bounds.py --json out/observation_bounds.json
"""

from __future__ import annotations

import argparse
import contextlib
import time

import numpy as np

LAWS = ("reference", "lqr-est", "learned", "zero")


class ZeroRates:
    """Holds alpha and the bank angle where they start (zero rates): a vehicle gliding unguided."""

    episodes_per_task = None
    provenance = None

    def reset(self, n_episodes: int) -> None:
        self.n = n_episodes

    def episode_stats(self) -> list[dict]:
        return [{} for _ in range(self.n)]

    def __call__(self, measurement) -> np.ndarray:
        return np.zeros((measurement.n, 2), np.float32)


@contextlib.contextmanager
def raw_features():
    """Record the observation features the vector env computes before it clips them (a list of (N, 26))."""
    from rventry_env.envs import common

    seen = []
    clip = common.observation_batch

    def recording(features, low, high):
        seen.append(np.stack([np.broadcast_to(np.asarray(f, np.float32), np.shape(features[0])) for f in features],
                             axis=1))  # fmt: skip
        return clip(features, low, high)

    common.observation_batch = recording
    try:
        yield seen
    finally:
        common.observation_batch = clip


def measure(law_name: str, dispersion: str, seeds: list[int]) -> dict:
    """Fly ``seeds`` with the law; the Box figures of every step flown (see the module docstring)."""
    from gymnasium.vector import AutoresetMode

    from rventry_env.envs.observation import features
    from rventry_env.envs.vector import RvEntryVectorEnv
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.guidance.law import Measurement

    n = len(seeds)
    with raw_features() as raw:
        venv = RvEntryVectorEnv(num_envs=n, dispersion=dispersion, autoreset_mode=AutoresetMode.DISABLED)
        law = ZeroRates() if law_name == "zero" else load_agent(law_name, venv.task)
        obs, info = venv.reset(seed=seeds)
        law.reset(n)
        table = features(venv.task, venv.model.planet.radius)
        lo, hi = venv.single_observation_space.low, venv.single_observation_space.high
        k = len(table)
        out = {"min": np.full(k, np.inf), "max": np.full(k, -np.inf), "below": np.zeros(k, int),
               "above": np.zeros(k, int), "clipped_steps": 0, "steps": 0, "clipped_episodes": np.zeros(n, bool),
               "true_altitude_m": [], "nav_vertical_error_m": []}  # fmt: skip
        done = np.zeros(n, bool)
        t = np.zeros(n)
        raw.clear()
        while not done.all():
            m = Measurement(obs, t.copy(), info["navigation_state"].copy(), info["sensed_accel_b"].copy(), ~done)
            obs, _, term, trunc, info = venv.step(np.asarray(law(m), np.float32))
            t = info["time_s"]
            r = raw[-1][~done]
            raw.clear()
            out["min"] = np.minimum(out["min"], r.min(0))
            out["max"] = np.maximum(out["max"], r.max(0))
            out["below"] += (r < lo).sum(0)
            out["above"] += (r > hi).sum(0)
            out["steps"] += int((~done).sum())
            clipped = info["observation_clipped"] & ~done
            out["clipped_steps"] += int(clipped.sum())
            out["clipped_episodes"] |= clipped
            if clipped.any():
                radius = venv.model.planet.radius
                nav_h = info["navigation_state"][clipped, 0] - radius
                out["true_altitude_m"] += info["altitude_m"][clipped].tolist()
                out["nav_vertical_error_m"] += (nav_h - info["altitude_m"][clipped]).tolist()
            done |= term | trunc
    out["names"] = [f.name for f in table]
    out["low"], out["high"] = lo, hi
    out["clipped_episodes"] = int(out["clipped_episodes"].sum())
    out["episodes"] = n
    return out


def main(argv=None) -> int:
    from rventry_env.util.args import positive_int, seed
    from rventry_env.util.files import check_writable
    from rventry_env.util.provenance import start_run, write_record

    start_run(None if argv is None else ["python", __file__, *argv])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="+", default=["flight"])
    ap.add_argument("--laws", nargs="+", default=list(LAWS), help=f"agent names, or 'zero' [{' '.join(LAWS)}]")
    ap.add_argument("--episodes", type=positive_int, default=2000, help="episodes per set and law [2000]")
    ap.add_argument("--batch", type=positive_int, default=500, help="copies flown side by side [500]")
    ap.add_argument("--seed", type=seed, default=0)
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    check_writable(args.json)
    report = {}
    for dispersion in args.sets:
        for law in args.laws:
            t0 = time.time()
            parts = []
            for start in range(args.seed, args.seed + args.episodes, args.batch):
                seeds = list(range(start, min(start + args.batch, args.seed + args.episodes)))
                parts.append(measure(law, dispersion, seeds))
            m = _merge(parts)
            report[f"{dispersion}/{law}"] = m
            _print(dispersion, law, m, time.time() - t0)
    if args.json:
        write_record(args.json, {k: {**v, "low": v["low"].tolist(), "high": v["high"].tolist()} for k, v in report.items()})
    return 0


def _merge(parts: list[dict]) -> dict:
    out = dict(parts[0])
    for p in parts[1:]:
        out["min"] = np.minimum(out["min"], p["min"])
        out["max"] = np.maximum(out["max"], p["max"])
        for key in ("below", "above", "clipped_steps", "steps", "clipped_episodes", "episodes"):
            out[key] = out[key] + p[key]
        out["true_altitude_m"] = out["true_altitude_m"] + p["true_altitude_m"]
        out["nav_vertical_error_m"] = out["nav_vertical_error_m"] + p["nav_vertical_error_m"]
    return out


def _print(dispersion: str, law: str, m: dict, seconds: float) -> None:
    print(f"{dispersion} / {law}: {m['episodes']} episodes, {m['steps']} steps ({seconds:.0f} s): "
          f"{m['clipped_steps']} clipped steps in {m['clipped_episodes']} episodes")  # fmt: skip
    for i, name in enumerate(m["names"]):
        if m["below"][i] or m["above"][i]:
            print(f"  {name}: Box [{m['low'][i]:.4g}, {m['high'][i]:.4g}], seen [{m['min'][i]:.4g}, {m['max'][i]:.4g}]"
                  f", {m['below'][i]} step(s) below, {m['above'][i]} above")  # fmt: skip
    if m["clipped_steps"]:
        h, e = np.array(m["true_altitude_m"]), np.array(m["nav_vertical_error_m"])
        print(f"  at the clipped steps: true altitude {h.min():.0f} to {h.max():.0f} m (median {np.median(h):.0f}); "
              f"navigation's vertical error {e.min():.0f} to {e.max():.0f} m (median {np.median(e):.0f})")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
