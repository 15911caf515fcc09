"""Random-action sweep: every episode of RvEntry-v0 ends cleanly, whatever the actions.

Flies uniformly random actions in [-1.2, 1.2] (out-of-range ones included, to exercise the
clipping) through the vector env, in batches, at several control steps, with the standard
and wide dispersions; and a share of the same episodes through the single env. It counts:

* exceptions (crashes), NumPy's RuntimeWarnings included;
* non-finite observations or rewards;
* observations outside the observation Box (the env clips and flags them; none should need it);
* ended episodes that lack an end-of-episode key (``failure``, ``is_success``, ``miss_km``, ...);
* how the episodes ended (impact, skip-out, stall, non-finite state, time limit).

Two more sweeps try what a user can hand the environment besides actions:

* **models**: every numeric field of every force-model part set to NaN, inf, -1, 0, 1e-300,
  1e300, a string and None. Each part must either refuse it as it is built, naming the part and
  the field, or fly: then 16 episodes of random actions at dt = 10 s must stay finite;
* **extreme states**: reset states with one component pushed to an extreme (+/-1e300, 1e-300,
  0, +/-1e6, +/-1e3) and random states (altitude -1 to 200 km, speed 0 to 20 km/s, random unit
  quaternions, alpha -60 to 60 deg, sigma -1000 to 1000 deg). Each must either be refused at
  ``reset``, naming the component, or fly random actions to a clean end in the vector env.

    python studies/random_actions.py                    # 100,000 episodes
    python studies/random_actions.py --episodes 5000 --json out/sweep.json
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import Counter

import numpy as np

from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import TERMINAL_KEYS, RvEntryVectorEnv
from rventry_env.util.args import positive_int, seed
from rventry_env.util.provenance import start_run, write_record

CASES = ((1.0, "standard"), (1.0, "wide"), (10.0, "standard"), (50.0, "wide"))


def sweep_vector(n_episodes: int, dt: float, dispersion: str, batch: int, seed0: int, counts: Counter, progress) -> None:
    done_total = 0
    rng = np.random.default_rng(seed0)
    start = seed0
    while done_total < n_episodes:
        n = min(batch, n_episodes - done_total)
        _fly(RvEntryVectorEnv(num_envs=n, dt=dt, dispersion=dispersion), None, start, rng, counts)
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


def _fly(venv, options, seed0: int, rng: np.random.Generator, counts: Counter) -> None:
    """Reset ``venv`` with seed ``seed0`` and fly random actions from ``rng`` until every copy has ended.

    Counts crashes, non-finite observations and rewards, observations out of bounds or clipped,
    ended episodes without an end key, and the endings; a reset that refuses its options counts
    as "refused at reset".
    """
    n = venv.num_envs
    try:
        obs, _ = venv.reset(seed=seed0, options=options)
    except ValueError:
        counts["refused at reset"] += n
        return
    low, high = venv.single_observation_space.low, venv.single_observation_space.high
    ended = np.zeros(n, bool)
    counts["non-finite observation"] += int((~np.isfinite(obs)).any(axis=1).sum())
    while not ended.all():
        try:
            obs, reward, term, trunc, info = venv.step(rng.uniform(-1.2, 1.2, (n, 2)))
        except Exception as exc:  # noqa: BLE001 - a crash is what this sweep counts
            counts["crash"] += int((~ended).sum())
            counts[f"crash: {type(exc).__name__}: {exc}"] += 1
            return
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


BAD_VALUES = (float("nan"), float("inf"), -1.0, 0.0, 1e-300, 1e300, "x", None)


def _model_parts():
    """(part class, the EntryModel built around one of it) for every force-model part with numeric fields."""
    from rventry_env import physics as ph

    return (
        (ph.Planet, {}, lambda p: ph.EntryModel(planet=p)),
        (ph.PointMassGravity, {}, lambda p: ph.EntryModel(gravity=p)),
        (ph.J2Gravity, {}, lambda p: ph.EntryModel(gravity=p)),
        (ph.ExponentialAtmosphere, {}, lambda p: ph.EntryModel(atmosphere=p)),
        (ph.CAVHAerodynamics, {}, lambda p: ph.EntryModel(vehicle=ph.Vehicle(aerodynamics=p))),
        (ph.ConstantAerodynamics, {"cd": 1.2}, lambda p: ph.EntryModel(vehicle=ph.Vehicle(aerodynamics=p))),
        (ph.Vehicle, {}, lambda p: ph.EntryModel(vehicle=p)),
        (ph.HorizontalWind, {}, lambda p: ph.EntryModel(wind=p)),
    )


def sweep_models(seed0: int, counts: Counter, progress) -> None:
    """Every numeric field of every part set to each of :data:`BAD_VALUES`: refused naming it, or flown clean."""
    for cls, base, model_of in _model_parts():
        for f in dataclasses.fields(cls):
            if not isinstance(getattr(cls(**base), f.name), (int, float)):
                continue
            for value in BAD_VALUES:
                try:
                    model = model_of(cls(**{**base, f.name: value}))
                except ValueError as exc:
                    named = f"{cls.__name__}.{f.name}" in str(exc)
                    counts["refused, naming the field" if named else "refused without naming the field"] += 1
                    if not named:
                        counts[f"unnamed: {cls.__name__}.{f.name}={value!r}: {exc}"] += 1
                    progress(1)
                    continue
                except Exception as exc:  # noqa: BLE001
                    counts["crash"] += 1
                    counts[f"crash: {cls.__name__}.{f.name}={value!r}: {type(exc).__name__}: {exc}"] += 1
                    progress(1)
                    continue
                counts["accepted"] += 1
                try:
                    venv = RvEntryVectorEnv(num_envs=16, dt=10.0, model=model, dispersion="standard")
                except Exception as exc:  # noqa: BLE001
                    counts["crash"] += 1
                    counts[f"crash: {cls.__name__}.{f.name}={value!r}: {type(exc).__name__}: {exc}"] += 1
                else:
                    before = counts.copy()
                    _fly(venv, None, seed0, np.random.default_rng(seed0), counts)
                    counts["flown"] += venv.num_envs
                    if any(counts[k] > before[k] for k in ("crash", "non-finite observation", "non-finite reward")):
                        counts[f"not clean: {cls.__name__}.{f.name}={value!r}"] += 1
                progress(1)


def _extreme_states(env: RvEntryEnv, n_random: int, rng: np.random.Generator) -> list[np.ndarray]:
    """One component of the nominal state pushed to an extreme, and random states."""
    env.reset(seed=0)
    base = env.state
    states = []
    for i in range(12):
        for value in (1e300, -1e300, 1e-300, 0.0, 1e6, -1e6):
            x = base.copy()
            x[i] = value
            states.append(x)
        for offset in (1e3, -1e3):
            x = base.copy()
            x[i] += offset
            states.append(x)
    radius = env.unwrapped._radius
    for _ in range(n_random):
        qa, qb = rng.normal(size=4), rng.normal(size=4)
        states.append(np.concatenate([
            [radius + rng.uniform(-1e3, 200e3)], qa / np.linalg.norm(qa), [rng.uniform(0.0, 2e4)],
            qb / np.linalg.norm(qb), np.radians([rng.uniform(-60, 60), rng.uniform(-1000, 1000)]),
        ]))  # fmt: skip
    return states


def sweep_states(n_random: int, seed0: int, counts: Counter, progress) -> None:
    """Extreme reset states: refused naming the component, or flown to a clean end (vector env)."""
    rng = np.random.default_rng(seed0 + 11)
    env = RvEntryEnv()
    accepted = []
    for x in _extreme_states(env, n_random, rng):
        try:
            env.reset(seed=0, options={"state": x})
            accepted.append(x)
            counts["accepted"] += 1
        except ValueError as exc:
            named = any(w in str(exc) for w in ("radius", "altitude", "speed", "Euler parameters", "alpha", "NaN"))
            counts["refused, naming the component" if named else "refused without naming the component"] += 1
        except Exception as exc:  # noqa: BLE001
            counts["crash"] += 1
            counts[f"crash at reset: {type(exc).__name__}: {exc}"] += 1
        progress(1)
    if accepted:
        _fly(RvEntryVectorEnv(num_envs=len(accepted)), {"state": np.stack(accepted)}, seed0, np.random.default_rng(seed0),
             counts)  # fmt: skip
        counts["flown"] += len(accepted)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=positive_int, default=100_000, help="vector-env episodes in all (100,000)")
    ap.add_argument("--single-share", type=float, default=0.02, help="share flown through the single env too (0.02)")
    ap.add_argument("--batch", type=positive_int, default=4096, help="vector-env copies per batch (4096)")
    ap.add_argument("--states", type=positive_int, default=2000, help="random reset states (2000)")
    ap.add_argument("--seed", type=seed, default=0)
    ap.add_argument("--json", help="write the counts here")
    args = ap.parse_args(argv)
    start_run(None if argv is None else ["python", __file__, *argv])
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
        n_models = sum(1 for cls, base, _ in _model_parts() for f in dataclasses.fields(cls)
                       if isinstance(getattr(cls(**base), f.name), (int, float))) * len(BAD_VALUES)  # fmt: skip
        job = bar.add_task("bad model fields and extreme states", total=n_models + 96 + args.states)
        models, states = Counter(), Counter()
        sweep_models(args.seed, models, lambda n: bar.advance(job, n))
        sweep_states(args.states, args.seed, states, lambda n: bar.advance(job, n))
    report["models"], report["states"] = dict(models), dict(states)
    total.update({k: v for k, v in models.items() if k not in ("accepted", "flown")})
    total.update({k: v for k, v in states.items() if k not in ("accepted", "flown")})
    report["wall_time_s"] = time.time() - t0
    checks = ("crash", "non-finite observation", "non-finite reward", "observation out of bounds",
              "refused without naming the field", "refused without naming the component")  # fmt: skip
    missing = sum(v for k, v in total.items() if k.startswith("end without"))
    report["totals"] = {**{k: total[k] for k in checks}, "ended without an end key": missing,
                        "endings": {k[8:]: v for k, v in sorted(total.items()) if k.startswith("ending: ")}}  # fmt: skip
    for case, c in report["cases"].items():
        for env, counts in c.items():
            nonzero = {k: v for k, v in sorted(counts.items()) if v}
            print(f"{case:20s} {env:6s} {nonzero}")
    print(f"models (bad field values): {dict(sorted(models.items()))}")
    print(f"extreme reset states: {dict(sorted(states.items()))}")
    print(f"\n{report['episodes_vector']:,} vector-env and {report['episodes_single']:,} single-env episodes, "
          f"{sum(models[k] for k in ('accepted', 'refused, naming the field', 'refused without naming the field'))} "
          "bad model fields and "
          f"{sum(states[k] for k in ('accepted', 'refused, naming the component', 'refused without naming the component'))} "
          f"extreme states in {report['wall_time_s']:.0f} s")  # fmt: skip
    for k in checks:
        print(f"  {k:28s} {total[k]}")
    print(f"  {'ended without an end key':28s} {missing}")
    print(f"  endings: {report['totals']['endings']}")
    if args.json:
        print(f"wrote {write_record(args.json, report)}")
    bad = sum(total[k] for k in checks) + missing
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
