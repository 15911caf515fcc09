"""How an episode ends: terminal metrics, path-bound violation, success and the terminal penalty.

One rule for every consumer: the single environment evaluates it on Python floats
(``MATH``), the vector environment on arrays (``NUMPY``), and training charges a
time-limit cut with :func:`time_limit_penalty` built from the same terms.

* **Metrics** (:func:`terminal_metrics`): the miss along the surface, the
  vertical-impact error, the speed error and alpha at the end.
* **Violation**: the load factor above ``a_max_g`` or the dynamic pressure below
  ``q_min`` anywhere along the flight, each by more than
  ``SuccessThresholds.constraint_tolerance`` (1 %).
* **Success**: impact, miss <= 5 km, vertical error <= 5 deg, |speed error| <= 100 m/s
  and no violation (:class:`~rventry_env.task.SuccessThresholds`).
* **Penalty** (paid once, at a terminating step): the weighted terminal terms
  (:func:`terminal_penalty`); on a failure (skip-out, stall, non-finite state)
  ``RewardWeights.failure`` more; on a success ``success_bonus`` less. A terminal
  term that is not finite (a diverged state) counts as 0: the failure penalty
  already charges that episode. A truncated episode pays nothing here (Gymnasium
  semantics), and its failure is named ``"time limit"``.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from rventry_env.core.targeting import surface_angle, target_in_a
from rventry_env.envs.propagation import FAILURE_NAMES, IMPACT
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import EntryTask

TIME_LIMIT = "time limit"


class TerminalMetrics(NamedTuple):
    miss_km: Any
    vertical_error_deg: Any
    speed_error_mps: Any
    alpha_final_deg: Any


class Outcome(NamedTuple):
    """The end of an episode (floats for one vehicle, arrays for a batch)."""

    metrics: TerminalMetrics
    constraint_violation: Any
    is_success: Any
    terminal_penalty: Any
    failure: Any  # "" on impact, else the failure's name (None from JAX: see failure_name)


def terminal_metrics(x: tuple, c_ae, task: EntryTask, target_e, radius: float, ns) -> TerminalMetrics:
    """Miss (great-circle, at the surface), vertical-impact error, speed error and final alpha.

    The vertical error is the angle between the velocity and straight down:
    cos = -b1 . a1 = 2 (eB2^2 + eB3^2) - 1 = 1 - 2 (eB1^2 + etaB^2), i.e.
    2 asin(sqrt(eB1^2 + etaB^2)); zero exactly when eB1 = etaB = 0 (Table tab:Ex2-BCs).
    """
    return metrics_at(x, c_ae, task.problem.final_speed, target_e, radius, ns)


def metrics_at(x: tuple, c_ae, final_speed: float, target_e, radius: float, ns) -> TerminalMetrics:
    """:func:`terminal_metrics` of any state ``x``, as if the flight ended there, with the task's
    impact speed ``final_speed`` (m/s): what a potential that knows the terminal terms reads."""
    theta = surface_angle(target_in_a(c_ae, target_e), ns)
    return TerminalMetrics(
        radius * theta / 1000.0,
        angle_from_vertical(x, ns) * (180.0 / math.pi),
        x[5] - final_speed,
        x[10] * (180.0 / math.pi),
    )


def angle_from_vertical(x: tuple, ns):
    """The angle (rad) between the velocity of states ``x`` and straight down, 2 asin(sqrt(eB1^2 + etaB^2))
    (see :func:`terminal_metrics`)."""
    s = ns.sqrt(ns.fmin(x[6] * x[6] + x[9] * x[9], 1.0))
    return 2.0 * ns.arctan2(s, ns.sqrt(ns.fmax(1.0 - s * s, 0.0)))


def terminal_penalty(m: TerminalMetrics, w: RewardWeights, ns):
    """The weighted terminal terms of :class:`~rventry_env.envs.reward.RewardWeights` (linear in each error)."""
    return (
        w.miss_per_km * m.miss_km
        + w.vertical_per_deg * m.vertical_error_deg
        + w.speed_per_mps * ns.fabs(m.speed_error_mps)
        + w.alpha_per_deg * ns.fabs(m.alpha_final_deg)
    )


def path_violation(max_load_g, min_q, task: EntryTask):
    """True where the flight exceeded a path bound by more than the success margin."""
    tol = task.success.constraint_tolerance
    p = task.problem
    return (max_load_g > p.a_max_g * (1 + tol)) | (min_q < p.q_min * (1 - tol))


def episode_outcome(x: tuple, c_ae, status, terminated, max_load_g, min_q, task: EntryTask, weights: RewardWeights,
                    target_e, radius: float, ns) -> Outcome:  # fmt: skip
    """The outcome of episodes that ended at state ``x`` with propagation ``status``.

    :param terminated: whether the episode terminated (impact or failure) rather than
        being cut by the time limit.
    :param max_load_g: the largest load factor flown (g); ``min_q`` the smallest dynamic pressure (Pa).
    """
    m = terminal_metrics(x, c_ae, task, target_e, radius, ns)
    s = task.success
    w = weights
    violation = path_violation(max_load_g, min_q, task)
    impact = status == IMPACT
    within = (
        (m.miss_km <= s.miss_km) & (m.vertical_error_deg <= s.vertical_error_deg)
        & (ns.fabs(m.speed_error_mps) <= s.speed_error_mps)
    )  # fmt: skip
    if ns.array:
        success = impact & within & ns.logical_not(violation)
        with np.errstate(invalid="ignore"):
            terms = terminal_penalty(m, w, ns)
    else:
        success = bool(impact and within and not violation)
        terms = terminal_penalty(m, w, ns)
    terms = ns.where(ns.isfinite(terms), terms, 0.0)
    penalty = ns.where(terminated, ns.where(impact, terms - w.success_bonus * success, terms + w.failure), 0.0)
    # names are strings, which compiled code cannot carry: JAX's callers name the status codes on the host
    failure = failure_name(status, terminated, ns) if ns.concrete else None
    return Outcome(m, violation, success, penalty, failure)


def failure_name(status, terminated, ns):
    """``""`` on impact, the failure's name, or ``"time limit"`` where the episode was truncated."""
    if not ns.array:
        return FAILURE_NAMES.get(int(status), "") if terminated else TIME_LIMIT
    names = np.array([FAILURE_NAMES.get(int(c), "") for c in np.asarray(status).ravel()], dtype=object)
    return np.where(terminated, names, TIME_LIMIT)


def time_limit_penalty(m: TerminalMetrics, weights: RewardWeights, ns):
    """What training charges an episode cut by the time limit: the failure penalty plus the terminal terms."""
    return weights.failure + terminal_penalty(m, weights, ns)


__all__ = [
    "TIME_LIMIT",
    "TerminalMetrics",
    "Outcome",
    "terminal_metrics",
    "metrics_at",
    "angle_from_vertical",
    "terminal_penalty",
    "path_violation",
    "episode_outcome",
    "failure_name",
    "time_limit_penalty",
]
