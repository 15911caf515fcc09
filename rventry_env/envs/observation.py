"""Observation features and terminal metrics, for one vehicle (floats) or a batch (arrays).

Every feature of the true state is bounded by construction or by the episode-end rules,
so the Box bounds are finite and honest. The observation is built from the *navigated*
state, which with navigation errors can lie below the ground near impact: the altitude
feature is then clipped at its low bound and the environments report it
(``info["observation_clipped"]``; docs/env.md gives how often). The table :data:`FEATURES` is the single source of
the names and bounds; the environment's docstring reproduces it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rventry_env.core.targeting import surface_angle, target_in_a
from rventry_env.task import EntryTask
from rventry_env.physics.entry import EntryForces

ALTITUDE_SCALE = 40e3  # m
SPEED_SCALE = 7000.0  # m/s
TIME_SCALE = 1000.0  # s
RANGE_SCALE = 2.8e6  # m: the nominal range to go, so the feature starts near 1
EPS = 1e-9


class Feature(NamedTuple):
    name: str
    meaning: str
    low: float
    high: float


def features(task: EntryTask, radius: float) -> tuple[Feature, ...]:
    """The observation table (index order)."""
    h_hi = (task.ceiling_altitude + 10e3) / ALTITUDE_SCALE  # a substep can overshoot the ceiling
    range_hi = math.pi * radius / RANGE_SCALE
    los_hi = (2 * radius + task.ceiling_altitude + 10e3) / RANGE_SCALE
    return (
        Feature("altitude", "h / 40 km", -0.01, h_hi),
        Feature("speed", "v / 7000 m/s", 0.0, 1.5),
        Feature("sin_gamma", "sine of flight-path angle, C_BA(1,1)", -1.0, 1.0),
        Feature("eA1", "C_AE Euler parameter", -1.0, 1.0),
        Feature("eA2", "C_AE Euler parameter", -1.0, 1.0),
        Feature("eA3", "C_AE Euler parameter", -1.0, 1.0),
        Feature("etaA", "C_AE Euler parameter", -1.0, 1.0),
        Feature("eB1", "C_BA Euler parameter", -1.0, 1.0),
        Feature("eB2", "C_BA Euler parameter", -1.0, 1.0),
        Feature("eB3", "C_BA Euler parameter", -1.0, 1.0),
        Feature("etaB", "C_BA Euler parameter", -1.0, 1.0),
        Feature("alpha", "2 alpha / alpha_max - 1", -1.0, 1.0),
        Feature("sin_sigma", "sin of the paper's bank angle sigma", -1.0, 1.0),
        Feature("cos_sigma", "cos sigma", -1.0, 1.0),
        Feature("lift_up", "cos(mu) cos(gamma): vertical lift share (mu = conventional bank)", -1.0, 1.0),
        Feature("lift_right", "sin(mu) cos(gamma): lift toward the right of the flight direction", -1.0, 1.0),
        Feature("time", "t / 1000 s", 0.0, 10.0),
        Feature("range_to_go", "great-circle distance to the target / 2800 km", 0.0, range_hi),
        Feature("cos_heading_error", "cos of the heading change needed to face the target", -1.0, 1.0),
        Feature("sin_heading_error", "sin of it, positive = target to the right", -1.0, 1.0),
        Feature("los_b1", "line of sight to the target, unit, along b1 (velocity)", -1.0, 1.0),
        Feature("los_b2", "line of sight along b2", -1.0, 1.0),
        Feature("los_b3", "line of sight along b3", -1.0, 1.0),
        Feature("los_distance", "straight-line distance to the target / 2800 km", 0.0, los_hi),
        Feature("dynamic_pressure", "q / (q + q_min): 0.5 on the q_min bound", 0.0, 1.0),
        Feature("load_factor", "n / (n + n_max), n = sqrt(L^2+D^2)/(m g0): 0.5 on the bound", 0.0, 1.0),
    )


def feature_names() -> tuple[str, ...]:
    """The observation features' names, in index order (the order never depends on the task)."""
    return tuple(f.name for f in features(EntryTask(), 6378137.0))


def feature_index(name: str) -> int:
    """Index of a feature by name (the order never depends on the task)."""
    names = feature_names()
    if name not in names:
        raise KeyError(f"no observation feature {name!r}; features are {list(names)}")
    return names.index(name)


def observe(x: tuple, forces: EntryForces, c_ae, t, task: EntryTask, target_e, radius: float, g0: float, ns) -> tuple:
    """The observation components (floats or arrays), in :func:`features` order.

    ``c_ae`` is C_AE at ``x`` (the environments form it once per step).
    """
    p = task.problem
    c_ba = forces.c_ba
    sigma = x[11]
    ss, cs = ns.sin(sigma), ns.cos(sigma)
    # lift-up direction in B is (0, C_BA(2,1), C_BA(3,1)) / cos(gamma); see conversions.lift_up_angle
    u2, u3 = c_ba[1][0], c_ba[2][0]
    lift_up = u2 * cs + u3 * ss
    lift_right = u2 * ss - u3 * cs
    ta = target_in_a(c_ae, target_e)
    theta = surface_angle(ta, ns)
    # heading change about the local vertical, clockwise seen from above (like azimuth)
    vh2, vh3 = c_ba[0][1], c_ba[0][2]
    dot = vh2 * ta[1] + vh3 * ta[2]
    cross = vh3 * ta[1] - vh2 * ta[2]
    m = ns.fmax(ns.sqrt(dot * dot + cross * cross), EPS)
    # line of sight from the vehicle to the target, A then B components
    r = x[0]
    rho_a = (radius * ta[0] - r, radius * ta[1], radius * ta[2])
    rho_b = tuple(c_ba[i][0] * rho_a[0] + c_ba[i][1] * rho_a[1] + c_ba[i][2] * rho_a[2] for i in range(3))
    d = ns.sqrt(rho_b[0] * rho_b[0] + rho_b[1] * rho_b[1] + rho_b[2] * rho_b[2])
    dd = ns.fmax(d, EPS)
    q = forces.dynamic_pressure
    n = forces.aero_accel / g0
    return (
        (r - radius) / ALTITUDE_SCALE,
        x[5] / SPEED_SCALE,
        c_ba[0][0],
        x[1], x[2], x[3], x[4],
        x[6], x[7], x[8], x[9],
        2.0 * x[10] / p.alpha_max - 1.0,
        ss, cs,
        lift_up, lift_right,
        t / TIME_SCALE,
        radius * theta / RANGE_SCALE,
        dot / m, cross / m,
        rho_b[0] / dd, rho_b[1] / dd, rho_b[2] / dd,
        d / RANGE_SCALE,
        q / (q + p.q_min),
        n / (n + p.a_max_g),
    )  # fmt: skip


def observation_box(task: EntryTask, radius: float) -> tuple[np.ndarray, np.ndarray]:
    table = features(task, radius)
    return (
        np.array([f.low for f in table], dtype=np.float32),
        np.array([f.high for f in table], dtype=np.float32),
    )


__all__ = [
    "Feature",
    "features",
    "feature_index",
    "feature_names",
    "observe",
    "observation_box",
]
