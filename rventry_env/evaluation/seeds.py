"""Statistics over training seeds, with rliable: IQM and mean with stratified-bootstrap intervals,
and performance profiles.

A learned policy is a sample from its training procedure. Its figures on a set mean little for the
procedure unless several seeds are trained and the spread between them is reported (Agarwal et al.,
"Deep Reinforcement Learning at the Edge of the Statistical Precipice", NeurIPS 2021). The scores
here are a ``(runs, tasks)`` matrix per method: one row per training seed, one column per evaluated
set (or set and tier), each entry a success rate in [0, 1].

* :func:`seed_statistics`: the interquartile mean (IQM) over all runs and tasks, and the mean, each
  with rliable's stratified-bootstrap interval (runs resampled within each task);
* :func:`performance_profiles`: the fraction of (run, task) scores above each threshold tau, with
  its interval;
* :func:`plot_performance_profiles`: those profiles as a PNG.

rliable's bootstrap draws its run indices from NumPy's *global* generator (``np.random.choice``),
whatever ``random_state`` it is given, so none is passed. Each call here seeds that generator for
its own duration and restores the caller's state afterwards, so the intervals are reproducible and
nothing else's randomness is disturbed.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rventry_env.util.files import save_figure

CONFIDENCE = 0.95
REPS = 20_000


def _check_scores(scores: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    if not scores:
        raise ValueError("seed statistics need the scores of at least one method")
    out = {}
    for name, s in scores.items():
        a = np.asarray(s, float)
        if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"scores of {name!r} must be a (runs, tasks) matrix with at least one of each, "
                             f"got shape {a.shape}")  # fmt: skip
        if not np.all(np.isfinite(a)):
            raise ValueError(f"scores of {name!r} hold NaN or infinite values")
        out[str(name)] = a
    return out


@contextlib.contextmanager
def _global_rng(seed: int):
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


def seed_statistics(scores: Mapping[str, np.ndarray], *, reps: int = REPS, seed: int = 0,
                    confidence: float = CONFIDENCE) -> dict[str, dict]:  # fmt: skip
    """The IQM and the mean of each method's scores over runs and tasks, with intervals.

    :param scores: per method, a ``(runs, tasks)`` matrix (one row per training seed).
    :returns: per method ``{"runs", "tasks", "iqm", "iqm_ci", "mean", "mean_ci"}``; the intervals
        are ``[low, high]`` from rliable's stratified bootstrap (percentile method, ``reps``
        resamples, seeded by ``seed``).
    """
    from rliable import library as rly
    from rliable import metrics

    scores = _check_scores(scores)

    def aggregates(x):
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)])

    with _global_rng(seed):
        point, ci = rly.get_interval_estimates(scores, aggregates, reps=reps, confidence_interval_size=confidence)
    out = {}
    for name, s in scores.items():
        p, c = np.asarray(point[name], float), np.asarray(ci[name], float)
        out[name] = {"runs": int(s.shape[0]), "tasks": int(s.shape[1]),
                     "iqm": float(p[0]), "iqm_ci": [float(c[0, 0]), float(c[1, 0])],
                     "mean": float(p[1]), "mean_ci": [float(c[0, 1]), float(c[1, 1])]}  # fmt: skip
    return out


def performance_profiles(scores: Mapping[str, np.ndarray], taus: Sequence[float], *, reps: int = 2_000,
                         seed: int = 0, confidence: float = CONFIDENCE) -> dict[str, dict]:  # fmt: skip
    """Each method's score distribution: the fraction of its (run, task) scores above each tau.

    :returns: per method ``{"tau", "fraction", "low", "high"}`` (lists of the same length).
    """
    from rliable import library as rly

    scores = _check_scores(scores)
    taus = np.asarray(taus, float)
    if taus.ndim != 1 or taus.size < 2 or not np.all(np.isfinite(taus)) or np.any(np.diff(taus) <= 0):
        raise ValueError(f"taus must be at least two finite, increasing thresholds, got {taus!r}")
    with _global_rng(seed):
        prof, ci = rly.create_performance_profile(scores, taus, reps=reps, confidence_interval_size=confidence)
    return {name: {"tau": taus.tolist(), "fraction": np.asarray(prof[name], float).tolist(),
                   "low": np.asarray(ci[name], float)[0].tolist(), "high": np.asarray(ci[name], float)[1].tolist()}
            for name in scores}  # fmt: skip


def plot_performance_profiles(profiles: Mapping[str, dict], path: str | Path, *, xlabel: str = "success rate tau",
                              title: str = "performance profiles over seeds and sets") -> Path:  # fmt: skip
    """Write :func:`performance_profiles` as a PNG: each method's fraction of runs above tau, with its
    interval shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.0), dpi=120)
    for name, p in profiles.items():
        (line,) = ax.plot(p["tau"], p["fraction"], label=name, lw=2)
        ax.fill_between(p["tau"], p["low"], p["high"], color=line.get_color(), alpha=0.2, lw=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction of (seed, set) scores > tau")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    ax.set_title(title, fontsize=10)
    return save_figure(fig, path, dpi=120)
