"""The intake phase: outliers out, the record's noise, the weights, the entry-state check, its bound.

:func:`screen_record` runs the steps in order on a record's replay and returns a
:class:`Screened`: what the fits weigh the residual by and how far the entry state may move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rventry_env.validation.intake.consistency import check_entry_state
from rventry_env.validation.intake.noise import (
    GROUPS,
    PROVISIONAL_SIGMA,
    init_bounds,
    is_noise,
    record_noise,
    record_robust_noise,
)
from rventry_env.validation.intake.outliers import reject_outliers
from rventry_env.validation.record import RecordError


@dataclass
class Screened:
    """A record after intake.

    :param group_names: observation group names, in column-group order.
    :param groups: group index per observation column.
    :param declared: declared noise by group (the option or the sidecar), or None.
    :param estimate: the record's difference estimate of its noise by group (NaN where none).
    :param estimate_is: per group, whether the estimate is the noise or only an upper bound.
    :param sigma: the weight (noise standard deviation) of each group.
    :param weights_from: where each weight came from.
    :param rejected: the rejected outliers, by file line.
    :param entry_check: the sidecar's entry state against the first samples (reduced records).
    :param bound: half-widths within which the fitted entry state may move (None: free).
    :param robust_estimate: the record's robust (MAD) noise scale by group, what the adequacy
        test compares the residual's robust scale with.
    """

    group_names: list
    groups: np.ndarray
    declared: dict | None
    estimate: dict
    estimate_is: dict
    sigma: dict
    weights_from: dict
    rejected: list = field(default_factory=list)
    entry_check: dict = field(default_factory=dict)
    bound: np.ndarray | None = None
    robust_estimate: dict = field(default_factory=dict)

    @property
    def robust_noise(self) -> dict:
        """The noise scale the residual's robust scale is tested against: declared, else the robust estimate."""
        return dict(self.declared) if self.declared is not None else dict(self.robust_estimate)

    def sigma_vector(self) -> np.ndarray:
        """The weight of every observation column."""
        return np.array([self.sigma[self.group_names[g]] for g in self.groups])

    @property
    def noise_source(self) -> str:
        """``declared``, ``estimated`` (every group from the record's differences) or ``baseline residual``."""
        if self.declared is not None:
            return "declared"
        return "estimated" if all(w == "record differences" for w in self.weights_from.values()) else "baseline residual"


def observation_groups(kind: str, n_columns: int) -> tuple[list, np.ndarray]:
    """Group names and the group index of every observation column of a record kind."""
    groups = np.zeros(n_columns, dtype=int)
    for gi, (_, _, cols) in enumerate(GROUPS[kind]):
        groups[list(cols)] = gi
    return [g[0] for g in GROUPS[kind]], groups


def screen_outliers(replay, kind: str, say=lambda msg: None) -> tuple[dict, dict, list]:
    """Gross outliers rejected where the sampling resolves the signal; the noise estimated without them.

    :return: the difference estimate by group, what each estimate is, the rejected rows.
    """
    estimate, estimate_is = record_noise(replay, kind)
    screened = {g: (u, cols) for g, u, cols in GROUPS[kind] if is_noise(estimate_is.get(g, ""))}
    rejected = reject_outliers(replay, screened) if screened else []
    if rejected:
        say(f"{len(rejected)} outlier(s) rejected: rows {', '.join(str(r['row']) for r in rejected[:10])}")
        estimate, estimate_is = record_noise(replay, kind)
    if not np.any(np.isfinite(replay.y)):
        raise RecordError("no observation left after rejecting outliers")
    return estimate, estimate_is, rejected


def noise_weights(group_names, declared: dict | None, estimate: dict) -> tuple[dict, dict]:
    """The weight of each group: declared, else the record's estimate, else provisional (set from the baseline)."""
    sigma, source = {}, {}
    for g in group_names:
        if declared is not None:
            sigma[g], source[g] = declared[g], "declared"
        elif np.isfinite(estimate[g]):
            sigma[g], source[g] = estimate[g], "record differences"
        else:
            sigma[g], source[g] = PROVISIONAL_SIGMA[g], "provisional"
    return sigma, source


def screen_record(replay, setup, say=lambda msg: None) -> Screened:
    """Run the intake on a record's replay (its ``y`` loses the rejected outliers)."""
    kind = replay.record.kind
    group_names, groups = observation_groups(kind, replay.y.shape[1])
    estimate, estimate_is, rejected = screen_outliers(replay, kind, say)
    declared = setup.declared_noise
    sigma, weights_from = noise_weights(group_names, declared, estimate)
    known = sigma if declared is not None else estimate
    entry_check = check_entry_state(replay, setup, known)
    for w in entry_check.get("warnings", []):
        say("warning: " + w)
    bound = init_bounds(replay, kind, declared if declared is not None else estimate)
    bound = widen_bound(bound, kind, entry_check.get("widen", {}))
    return Screened(group_names, groups, declared, estimate, estimate_is, sigma, weights_from, rejected,
                    entry_check, bound, record_robust_noise(replay, kind))  # fmt: skip


def widen_bound(bound: np.ndarray | None, kind: str, widen: dict) -> np.ndarray | None:
    """The entry state's prior widened where the sidecar disagrees with the record's first samples."""
    if bound is None or not widen:
        return bound
    bound = bound.copy()
    for i, (g, _, _) in enumerate(GROUPS[kind]):
        if g in widen:
            bound[i] = max(bound[i], widen[g])
    return bound


def reweight_from_baseline(screened: Screened, base) -> bool:
    """No noise known for a group: weight it by its own baseline scatter. True if any weight changed."""
    changed = False
    for gi, g in enumerate(screened.group_names):
        if screened.weights_from[g] == "provisional" and base.n_by_group[gi]:
            screened.sigma[g] = math.sqrt(base.rss_by_group[gi] / base.n_by_group[gi]) or PROVISIONAL_SIGMA[g]
            screened.weights_from[g] = "baseline residual"
            changed = True
    return changed


__all__ = [
    "Screened",
    "noise_weights",
    "observation_groups",
    "reweight_from_baseline",
    "screen_outliers",
    "screen_record",
]  # fmt: skip
