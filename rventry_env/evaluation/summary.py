"""Summaries of evaluated episodes: means, percentiles, success rate, and the JSON document."""

from __future__ import annotations

import dataclasses

import numpy as np

from rventry_env.envs.task import EntryTask
from rventry_env.evaluation.rollout import EpisodeBatch

METRICS = ("miss_km", "vertical_error_deg", "speed_error_mps", "abs_speed_error_mps", "alpha_final_deg",
           "cost", "cost_ratio", "max_load_factor_g", "min_dynamic_pressure_pa", "tf_s")  # fmt: skip
PERCENTILES = (5, 50, 95)


def summarize(batch: EpisodeBatch, reference_cost: float, task: EntryTask) -> dict:
    """The ``summary`` block: a mean over episodes for every metric, plus percentiles and rates.

    Keys ``miss_km``, ``vertical_error_deg``, ``speed_error_mps``, ``cost_ratio`` and
    ``success_rate`` are means over episodes (the evaluation report's schema); ``percentiles``
    holds the 5th/50th/95th percentile of each metric.
    """
    values = {
        "miss_km": batch.miss_km,
        "vertical_error_deg": batch.vertical_error_deg,
        "speed_error_mps": batch.speed_error_mps,
        "abs_speed_error_mps": np.abs(batch.speed_error_mps),
        "alpha_final_deg": batch.alpha_final_deg,
        "cost": batch.cost,
        "cost_ratio": batch.cost / reference_cost,
        "max_load_factor_g": batch.max_load_factor_g,
        "min_dynamic_pressure_pa": batch.min_dynamic_pressure_pa,
        "tf_s": batch.time_s,
    }
    out: dict = {k: _f(np.mean(values[k].astype(float))) for k in METRICS}
    out["success_rate"] = _f(np.mean(batch.is_success.astype(float)))
    out["constraint_violation_rate"] = _f(np.mean(batch.constraint_violation.astype(float)))
    out["impact_rate"] = _f(np.mean(batch.failure == ""))
    out["episodes"] = int(batch.miss_km.size)
    out["percentiles"] = {
        k: {f"p{p}": _f(np.percentile(values[k].astype(float), p)) for p in PERCENTILES} for k in METRICS
    }
    failures, counts = np.unique(batch.failure.astype(str), return_counts=True)
    out["endings"] = {("impact" if f == "" else f): int(c) for f, c in zip(failures, counts)}
    out["success_thresholds"] = dataclasses.asdict(task.success)
    return out


def _f(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None
