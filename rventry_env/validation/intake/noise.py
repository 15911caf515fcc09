"""Noise of a record, observation groups, and how far the initial state may move.

See :mod:`rventry_env.validation.search.statistics` for the estimators themselves.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.replay.record_replay import Replay
from rventry_env.validation.search.statistics import difference_noise, robust_difference_noise

# observation groups: name, unit suffix, columns; each group has its own noise level
GROUPS = {
    "ecef": (("position", "m", (0, 1, 2)), ("velocity", "mps", (3, 4, 5))),
    "reduced": (("altitude", "m", (0,)), ("speed", "mps", (1,))),
}
# provisional weights when the record does not allow a difference estimate of its noise
PROVISIONAL_SIGMA = {"position": 100.0, "velocity": 1.0, "altitude": 100.0, "speed": 1.0}
INIT_BOUND_SIGMAS = 5.0  # the initial state may move this many noise levels from what was measured


def record_noise(replay: Replay, kind: str) -> tuple[dict, dict]:
    """Per-group noise from the record's differences (NaN where the sampling does not allow it).

    Also says whether the differences are noise-dominated: white noise gives the
    same estimate from 3rd and 4th differences, a signal sampled too coarsely
    (a sparse trajectory table) gives estimates that fall with the order. Then
    the estimate is only an upper bound of the noise, and is reported as such.
    """
    out, kind_of = {}, {}
    for name, _, cols in GROUPS[kind]:
        kind_of[name] = "none (too few uniformly sampled values)"
        est, ratios = [], []
        for c in cols:
            e4 = difference_noise(replay.t_obs, replay.y[:, c])
            if np.isfinite(e4):
                est.append(e4)
                ratios.append(difference_noise(replay.t_obs, replay.y[:, c], order=3) / e4)
        out[name] = float(np.median(est)) if est else math.nan
        if est:
            r = float(np.median(ratios))
            ok = 0.8 < r < 1.25
            kind_of[name] = "noise" if ok else f"upper bound (3rd/4th difference estimates {r:.2f})"
    return out, kind_of


def record_robust_noise(replay: Replay, kind: str) -> dict:
    """Per-group robust noise scale from the record's differences (1.4826 MAD; NaN where not possible)."""
    out = {}
    for name, _, cols in GROUPS[kind]:
        est = [e for e in (robust_difference_noise(replay.t_obs, replay.y[:, c]) for c in cols) if np.isfinite(e)]
        out[name] = float(np.median(est)) if est else math.nan
    return out


def init_bounds(replay: Replay, kind: str, noise: dict) -> np.ndarray | None:
    """Half-widths within which the initial state may move: :data:`INIT_BOUND_SIGMAS` noise levels.

    "Fitted within its noise": without a bound, a model that lacks an effect
    would bend the initial state far from what the first samples measured to
    hide the effect (on Apollo 4 a drag-only capsule moves the entry point 9 km
    down and 940 m/s faster). A reduced record does not measure the flight-path
    angle; its bound is what the altitude noise allows over the first three
    samples, sqrt(2) sigma_h / (v0 dt).
    """
    k = INIT_BOUND_SIGMAS
    if kind == "ecef":
        sp, sv = noise["position"], noise["velocity"]
        if not (np.isfinite(sp) and np.isfinite(sv)):
            return None
        return np.array([k * sp] * 3 + [k * sv] * 3)
    sh, sv = noise["altitude"], noise["speed"]
    if not (np.isfinite(sh) and np.isfinite(sv)):
        return None
    dt = float(replay.t_obs[min(2, len(replay.t_obs) - 1)] - replay.t0)
    v0 = replay.init.reference[3]
    return np.array([k * sh, k * sv, k * math.sqrt(2.0) * sh / (v0 * max(dt, 1e-3))])


def is_noise(kind_text: str) -> bool:
    """True when a difference estimate is the noise itself (not an upper bound, not missing)."""
    return kind_text == "noise"


__all__ = ["GROUPS", "INIT_BOUND_SIGMAS", "PROVISIONAL_SIGMA", "init_bounds", "is_noise", "record_noise"]
