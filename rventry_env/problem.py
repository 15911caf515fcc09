"""The paper's Example 2 entry problem: boundary conditions, cost and path-constraint constants.

One definition shared by the environment, the collocation reference and the
evaluation (PROBLEM.md defaults, every value configurable). SI units and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.physics.model import EntryModel

SQRT_HALF = math.sqrt(0.5)


@dataclass(frozen=True)
class EntryProblem:
    """The optimal-control problem of the paper's Example 2 (PROBLEM.md defaults), SI units.

    Initial state: Table ``tab:Ex2-BCs``. ``initial_alpha`` / ``initial_sigma``
    ``None`` means "take the shipped collocation reference's values" (the paper
    leaves them free). Final conditions: r = R_e + ``final_altitude``,
    v = ``final_speed``, alpha = ``final_alpha``, vertical impact, position on the
    target (Eq. ``Ex2-endpoint``). Cost Eq. ``Ex2-Cost``; path constraints Eq.
    ``Ex2-path``. The collocation reference (:mod:`rventry_env.reference`) and the
    environment (:mod:`rventry_env.envs`) both read these values from here.
    """

    initial_altitude: float = 37e3
    initial_speed: float = 7138.0
    initial_e_a: tuple = (0.0, 0.0, 0.0, 1.0)
    initial_e_b: tuple = (0.0, 0.0, SQRT_HALF, SQRT_HALF)
    initial_alpha: float | None = None
    initial_sigma: float | None = None
    target_longitude: float = math.radians(25.15)
    target_latitude: float = 0.0
    final_altitude: float = 0.0
    final_speed: float = 1219.0
    final_alpha: float = 0.0
    # cost, Eq. Ex2-Cost
    k1: float = 1.0
    k2: float = 1.0
    k3: float = 1.0
    alpha_bar: float = math.radians(11.86)
    alpha_max: float = math.radians(25.0)
    u_alpha_max: float = math.radians(10.0)
    u_sigma_max: float = math.radians(30.0)
    # path constraints, Eq. Ex2-path
    a_max_g: float = 12.0
    q_min: float = 12e3

    def __post_init__(self):
        positive = ("alpha_max", "u_alpha_max", "u_sigma_max", "a_max_g", "initial_speed", "final_speed")
        for name in positive:
            val = getattr(self, name)
            if not (math.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be positive and finite, got {val}")
        for name in ("k1", "k2", "k3", "q_min"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be >= 0 and finite, got {val}")
        if not 0 <= self.alpha_bar <= self.alpha_max:
            raise ValueError(f"alpha_bar ({math.degrees(self.alpha_bar):g} deg) must lie in [0, alpha_max]")
        if not 0 <= self.final_alpha <= self.alpha_max:
            raise ValueError(f"final_alpha ({math.degrees(self.final_alpha):g} deg) must lie in [0, alpha_max]")
        for name in ("initial_e_a", "initial_e_b"):
            q = np.asarray(getattr(self, name), dtype=float)
            if q.shape != (4,) or abs(np.linalg.norm(q) - 1.0) > 1e-12:
                raise ValueError(f"{name} must be 4 Euler parameters of unit norm, got {getattr(self, name)}")
        if self.initial_altitude <= self.final_altitude:
            raise ValueError(f"initial_altitude ({self.initial_altitude}) must exceed final_altitude ({self.final_altitude})")
        if not abs(self.target_latitude) <= math.pi / 2:
            raise ValueError(f"target_latitude must lie in [-pi/2, pi/2] rad, got {self.target_latitude}")

    def target_unit_vector(self) -> np.ndarray:
        """The target's direction in E (planet-fixed), Eq. ``Ex2-endpoint``."""
        cl = math.cos(self.target_latitude)
        return np.array(
            [cl * math.cos(self.target_longitude), cl * math.sin(self.target_longitude), math.sin(self.target_latitude)]
        )

    def initial_state(self, model: EntryModel) -> np.ndarray:
        """The nominal 12-component initial state (float64)."""
        alpha, sigma = self.initial_alpha, self.initial_sigma
        if alpha is None or sigma is None:
            from rventry_env.reference import load_reference  # the reference's own free initial values

            ref_alpha, ref_sigma = load_reference().x[0, 10:12]
            alpha = ref_alpha if alpha is None else alpha
            sigma = ref_sigma if sigma is None else sigma
        return np.array(
            [model.planet.radius + self.initial_altitude, *self.initial_e_a, self.initial_speed,
             *self.initial_e_b, alpha, sigma],
            dtype=float,
        )  # fmt: skip


__all__ = ["EntryProblem"]
