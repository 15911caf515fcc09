"""Summaries of evaluated episodes: means, percentiles, success rate, and the JSON document."""

from __future__ import annotations

import dataclasses

import numpy as np

from rventry_env.task import EntryTask
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
    out["success_rate_ci"] = rate_interval(batch.is_success)
    precise = precision_success(batch, task)
    out["precision_success_rate"] = _f(np.mean(precise.astype(float)))
    out["precision_success_rate_ci"] = rate_interval(precise)
    out["miss_m"] = {f"p{q}": _f(np.percentile(batch.miss_km.astype(float), q) * 1000.0) for q in (50, 95, 99)}
    out["constraint_violation_rate"] = _f(np.mean(batch.constraint_violation.astype(float)))
    out["impact_rate"] = _f(np.mean(batch.failure == ""))
    out["episodes"] = int(batch.miss_km.size)
    out["percentiles"] = {
        k: {f"p{p}": _f(np.percentile(values[k].astype(float), p)) for p in PERCENTILES} for k in METRICS
    }
    failures, counts = np.unique(batch.failure.astype(str), return_counts=True)
    out["endings"] = {("impact" if f == "" else str(f)): int(c) for f, c in zip(failures, counts)}
    out["success_thresholds"] = dataclasses.asdict(task.success)
    out["precision_thresholds"] = dataclasses.asdict(task.precision)
    out["navigation"] = navigation_summary(batch)
    out["replanning"] = replanning_summary(batch.law_stats)
    out["load_relief"] = load_relief_summary(batch.law_stats)
    return out


def navigation_summary(batch: EpisodeBatch) -> dict | None:
    """Percentiles of the navigation's position errors at the end (m) and of the miss the navigated
    position makes (the guidance's own miss, m): what of the miss navigation made. None without them."""
    nav = np.asarray(batch.navigation, dtype=float)
    if nav.size == 0 or not np.all(np.isfinite(nav)):
        return None
    cols = {"horizontal_error_m": nav[:, 0], "vertical_error_abs_m": np.abs(nav[:, 1]), "navigated_miss_m": nav[:, 2] * 1000.0}
    return {k: {f"p{q}": _f(np.percentile(v, q)) for q in (50, 95)} for k, v in cols.items()}


def precision_success(batch: EpisodeBatch, task: EntryTask) -> np.ndarray:
    """Which episodes meet the precision tier (:class:`~rventry_env.task.PrecisionThresholds`)."""
    return task.precision.met(batch.failure == "", batch.miss_km.astype(float), batch.vertical_error_deg.astype(float),
                              batch.alpha_final_deg.astype(float), batch.speed_error_mps.astype(float),
                              batch.constraint_violation)  # fmt: skip


def rate_interval(hits, confidence: float = 0.95) -> list[float]:
    """The Wilson score interval [low, high] of a success rate (scipy's binomtest)."""
    from scipy.stats import binomtest

    hits = np.asarray(hits, bool)
    if hits.size == 0:
        return [0.0, 1.0]
    ci = binomtest(int(hits.sum()), int(hits.size)).proportion_ci(confidence_level=confidence, method="wilson")
    return [float(ci.low), float(ci.high)]


def task_metric_key(success_rate: float | None, mean_miss_km: float | None) -> tuple[float, float]:
    """How evaluations rank on the task metric (training selections, scans): the success rate
    first, then the smaller mean miss; a missing figure ranks last."""
    return (success_rate or 0.0, -(mean_miss_km if mean_miss_km is not None else np.inf))


def load_relief_summary(stats: list[dict]) -> dict | None:
    """For a law with load relief: how many steps it capped the alpha rate, and in how many episodes."""
    if not stats or "load_relief_steps" not in stats[0]:
        return None
    steps = np.array([s["load_relief_steps"] for s in stats])
    return {"capped_steps": int(steps.sum()), "episodes_capped": int(np.count_nonzero(steps)),
            "capped_steps_per_episode_max": int(steps.max())}  # fmt: skip


def replanning_summary(stats: list[dict]) -> dict | None:
    """Over every solve of every episode of a re-planning law: counts and solve-time percentiles (s)."""
    if not stats or "replans" not in stats[0]:
        return None
    times = np.array([t for s in stats for t in s.get("solve_times_s", [])])
    firsts = np.array([s["first_solve_s"] for s in stats if s.get("first_solve_s") is not None])
    # the first solve of an episode starts from the nominal plan; the re-solves from the previous plan
    resolves = np.array([t for s in stats for t in s.get("solve_times_s", [])[1:]])
    pct = {f"p{q}": _f(np.percentile(resolves, q)) for q in (50, 90, 99)} if resolves.size else None
    return {
        "replans": int(sum(s["replans"] for s in stats)),
        "replan_failures": int(sum(s["replan_failures"] for s in stats)),
        "replan_timeouts": int(sum(s.get("replan_timeouts", 0) for s in stats)),
        "episodes_with_a_failure": int(sum(1 for s in stats if s["replan_failures"])),
        "solves": int(times.size),
        "solve_time_s": {**pct, "max": _f(resolves.max())} if pct else None,
        "first_solve_time_s": {"p50": _f(np.median(firsts)), "max": _f(firsts.max())} if firsts.size else None,
    }


def _f(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None
