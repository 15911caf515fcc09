"""Random-action sweep: every episode of RvEntry-v0 ends cleanly, whatever the actions.

Flies uniformly random actions in [-1.2, 1.2] (out-of-range ones included, to exercise the
clipping) through the vector env, in batches, at several control steps, with the standard
and wide dispersions; and a share of the same episodes through the single env. It counts:

* exceptions (crashes), NumPy's RuntimeWarnings included;
* non-finite observations or rewards;
* observations outside the observation Box (the env clips and flags them; none should need it);
* ended episodes that lack an end-of-episode key (``failure``, ``is_success``, ``miss_km``, ...);
* how the episodes ended (impact, skip-out, stall, non-finite state, time limit).

    python scripts/bench_random_actions.py                    # 100,000 episodes
    python scripts/bench_random_actions.py --episodes 5000 --json out/sweep.json
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter

import numpy as np

from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import TERMINAL_KEYS, RvEntryVectorEnv
from rventry_env.util.args import positive_int, seed
from rventry_env.util.files import write_json

CASES = ((1.0, "standard"), (1.0, "wide"), (10.0, "standard"), (50.0, "wide"))


def sweep_vector(n_episodes: int, dt: float, dispersion: str, batch: int, seed0: int, counts: Counter, progress) -> None:
    done_total = 0
    rng = np.random.default_rng(seed0)
    start = seed0
    while done_total < n_episodes:
        n = min(batch, n_episodes - done_total)
        venv = RvEntryVectorEnv(num_envs=n, dt=dt, dispersion=dispersion)
        obs, _ = venv.reset(seed=start)
        low, high = venv.single_observation_space.low, venv.single_observation_space.high
        ended = np.zeros(n, bool)
        while not ended.all():
            try:
                obs, reward, term, trunc, info = venv.step(rng.uniform(-1.2, 1.2, (n, 2)))
            except Exception as exc:  # noqa: BLE001 - a crash is what this sweep counts
                counts["crash"] += int((~ended).sum())
                counts[f"crash: {type(exc).__name__}: {exc}"] += 1
                break
            live = ~ended
            counts["non-finite observation"] += int((~np.isfinite(obs[live])).any(axis=1).sum())
            counts["non-finite reward"] += int((~np.isfinite(reward[live])).sum())
            counts["observation out of bounds"] += int(((obs[live] < low) | (obs[live] > high)).any(axis=1).sum())
            counts["observation clipped"] += int(info["observation_clipped"][live].sum())
            new = (term | trunc) & live
            for k in TERMINAL_KEYS:
                counts["end without " + k] += int((new & ~info["_" + k]).sum())
            for f in info["failure"][new]:
                counts["ending: " + (f or "impact")] += 1
            ended |= new
        done_total += n
        start += n
        progress(n)


def sweep_single(n_episodes: int, dt: float, dispersion: str, seed0: int, counts: Counter, progress) -> None:
    rng = np.random.default_rng(seed0 + 7)
    env = RvEntryEnv(dt=dt, dispersion=dispersion)
    low, high = env.observation_space.low, env.observation_space.high
    for i in range(n_episodes):
        obs, _ = env.reset(seed=seed0 + i)
        while True:
            try:
                obs, reward, term, trunc, info = env.step(rng.uniform(-1.2, 1.2, 2).astype(np.float32))
            except Exception as exc:  # noqa: BLE001
                counts["crash"] += 1
                counts[f"crash: {type(exc).__name__}: {exc}"] += 1
                break
            counts["non-finite observation"] += int(not np.all(np.isfinite(obs)))
            counts["non-finite reward"] += int(not np.isfinite(reward))
            counts["observation out of bounds"] += int(np.any((obs < low) | (obs > high)))
            counts["observation clipped"] += int(info["observation_clipped"])
            if term or trunc:
                counts["end without a key"] += int(not set(TERMINAL_KEYS) <= set(info))
                counts["ending: " + (info.get("failure") or "impact")] += 1
                break
        progress(1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=positive_int, default=100_000, help="vector-env episodes in all (100,000)")
    ap.add_argument("--single-share", type=float, default=0.02, help="share flown through the single env too (0.02)")
    ap.add_argument("--batch", type=positive_int, default=4096, help="vector-env copies per batch (4096)")
    ap.add_argument("--seed", type=seed, default=0)
    ap.add_argument("--json", help="write the counts here")
    args = ap.parse_args(argv)
    import warnings

    from rich.progress import Progress

    # a NumPy overflow warning is a silent non-finite value: count it as a crash
    warnings.simplefilter("error", RuntimeWarning)
    per_case = args.episodes // len(CASES)
    n_single = max(1, int(per_case * args.single_share))
    report = {"episodes_vector": per_case * len(CASES), "episodes_single": n_single * len(CASES), "cases": {}}
    t0 = time.time()
    total = Counter()
    with Progress() as bar:
        job = bar.add_task("random-action episodes", total=len(CASES) * (per_case + n_single))
        for dt, disp in CASES:
            counts = Counter()
            sweep_vector(per_case, dt, disp, args.batch, args.seed, counts, lambda n: bar.advance(job, n))
            single = Counter()
            sweep_single(n_single, dt, disp, args.seed, single, lambda n: bar.advance(job, n))
            report["cases"][f"dt={dt:g} s, {disp}"] = {"vector": dict(counts), "single": dict(single)}
            total.update(counts)
            total.update(single)
    report["wall_time_s"] = time.time() - t0
    checks = ("crash", "non-finite observation", "non-finite reward", "observation out of bounds")
    missing = sum(v for k, v in total.items() if k.startswith("end without"))
    report["totals"] = {**{k: total[k] for k in checks}, "ended without an end key": missing,
                        "endings": {k[8:]: v for k, v in sorted(total.items()) if k.startswith("ending: ")}}  # fmt: skip
    for case, c in report["cases"].items():
        for env, counts in c.items():
            nonzero = {k: v for k, v in sorted(counts.items()) if v}
            print(f"{case:20s} {env:6s} {nonzero}")
    print(f"\n{report['episodes_vector']:,} vector-env and {report['episodes_single']:,} single-env episodes "
          f"in {report['wall_time_s']:.0f} s")  # fmt: skip
    for k in checks:
        print(f"  {k:28s} {total[k]}")
    print(f"  {'ended without an end key':28s} {missing}")
    print(f"  endings: {report['totals']['endings']}")
    if args.json:
        print(f"wrote {write_json(args.json, report)}")
    bad = sum(total[k] for k in checks) + missing
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
