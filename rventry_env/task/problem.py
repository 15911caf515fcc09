"""The paper's Example 2 entry problem: boundary conditions, cost and path-constraint constants.

One definition shared by the environment, the collocation reference, the guidance
laws and the evaluation (the defaults of ``docs/conventions.md``, every value
configurable). SI units and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SQRT_HALF = math.sqrt(0.5)


@dataclass(frozen=True)
class EntryProblem:
    """The optimal-control problem of the paper's Example 2 (``docs/conventions.md`` defaults), SI units.

    Initial state: Table ``tab:Ex2-BCs``. The paper leaves the initial alpha and
    sigma free; the defaults here are the values the shipped collocation optimum
    chose (``rventry reference show``: 11.8845 deg and 271.2381 deg, a test keeps
    them equal to the shipped file's). Final conditions: r = R_e + ``final_altitude``,
    v = ``final_speed``, alpha = ``final_alpha``, vertical impact, position on the
    target (Eq. ``Ex2-endpoint``). Cost Eq. ``Ex2-Cost``; path constraints Eq.
    ``Ex2-path``. The collocation reference (:mod:`rventry_env.reference`) and the
    environment (:mod:`rventry_env.envs`) both read these values from here.
    """

    initial_altitude: float = 37e3
    initial_speed: float = 7138.0
    initial_e_a: tuple = (0.0, 0.0, 0.0, 1.0)
    initial_e_b: tuple = (0.0, 0.0, SQRT_HALF, SQRT_HALF)
    initial_alpha: float = 0.20742414957518163  # rad; the shipped optimum's alpha(0)
    initial_sigma: float = 4.733997792450303  # rad; its sigma(0) (paper's bank, 271.2 deg)
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
        if not 0 <= self.initial_alpha <= self.alpha_max:
            raise ValueError(f"initial_alpha ({math.degrees(self.initial_alpha):g} deg) must lie in [0, alpha_max]")
        if not math.isfinite(self.initial_sigma):
            raise ValueError(f"initial_sigma must be finite, got {self.initial_sigma}")
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

    def initial_state(self, radius: float, alpha: float | None = None, sigma: float | None = None) -> np.ndarray:
        """The 12-component initial state of Table ``tab:Ex2-BCs`` (float64).

        :param radius: the planet's radius R_e (m); r(0) = R_e + ``initial_altitude``.
        :param alpha: alpha(0) in rad (default ``initial_alpha``).
        :param sigma: sigma(0) in rad (default ``initial_sigma``).
        """
        alpha = self.initial_alpha if alpha is None else alpha
        sigma = self.initial_sigma if sigma is None else sigma
        return np.array(
            [radius + self.initial_altitude, *self.initial_e_a, self.initial_speed, *self.initial_e_b, alpha, sigma],
            dtype=float,
        )

    def cost_integrand(self, alpha, u_alpha, u_sigma):
        """The running cost of Eq. ``Ex2-Cost`` (floats, arrays or CasADi symbols)."""
        return (
            self.k1 * ((alpha - self.alpha_bar) / self.alpha_max) ** 2
            + self.k2 * (u_alpha / self.u_alpha_max) ** 2
            + self.k3 * (u_sigma / self.u_sigma_max) ** 2
        )

    def cost_over_hold(self, alpha0, u_alpha_applied, u_alpha_cmd, u_sigma_cmd, tau):
        """Eq. ``Ex2-Cost`` integrated exactly over [0, tau] with alpha = alpha0 + u_alpha_applied t.

        The rate terms charge the *commanded* rates (what the controller asked for,
        held over the interval), the alpha term the applied motion (which may stop at
        a saturation bound).
        """
        d0 = alpha0 - self.alpha_bar
        ua = u_alpha_applied
        int_da2 = d0 * d0 * tau + d0 * ua * tau * tau + ua * ua * tau * tau * tau / 3.0
        rates = self.k2 * (u_alpha_cmd / self.u_alpha_max) ** 2 + self.k3 * (u_sigma_cmd / self.u_sigma_max) ** 2
        return self.k1 * int_da2 / (self.alpha_max * self.alpha_max) + rates * tau


__all__ = ["EntryProblem"]
