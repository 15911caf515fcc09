"""Dispersions: what the benchmark draws at each reset, and how a draw perturbs the initial state.

Every draw comes from the episode's ``np_random``, so a seed names one episode exactly,
in the single and in the vector environment alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.core import conversions as cv

NAMED_SETS = ("standard", "wide")


@dataclass(frozen=True)
class Dispersion:
    """Half-widths of uniform dispersions drawn at each reset from ``np_random``.

    Model dispersions scale the density and the lift and drag coefficients by
    (1 + U(-x, x)); state dispersions add U(-x, x) to the initial altitude,
    speed, flight-path angle, heading, alpha and sigma.
    """

    density: float = 0.0
    lift: float = 0.0
    drag: float = 0.0
    altitude_m: float = 0.0
    speed_mps: float = 0.0
    flight_path_deg: float = 0.0
    heading_deg: float = 0.0
    alpha_deg: float = 0.0
    sigma_deg: float = 0.0

    @classmethod
    def standard(cls) -> "Dispersion":
        """The benchmark's standard set: density 5 %, C_L and C_D 3 %, altitude 0.5 km, speed 20 m/s, gamma 0.2 deg."""
        return cls(density=0.05, lift=0.03, drag=0.03, altitude_m=500.0, speed_mps=20.0, flight_path_deg=0.2)

    @classmethod
    def wide(cls) -> "Dispersion":
        """The benchmark's wide set, where laws break: density 10 %, C_L and C_D 5 %, altitude 1 km,
        speed 40 m/s, flight-path angle 0.4 deg, heading 0.2 deg."""
        return cls(density=0.10, lift=0.05, drag=0.05, altitude_m=1000.0, speed_mps=40.0, flight_path_deg=0.4,
                   heading_deg=0.2)  # fmt: skip

    @classmethod
    def parse(cls, value) -> "Dispersion":
        """A Dispersion from None, a Dispersion, a set's name (``"none"``, ``"standard"``, ``"wide"``) or a dict of fields."""
        if value is None or value == "none":
            return cls()
        if isinstance(value, Dispersion):
            return value
        if isinstance(value, str) and value in NAMED_SETS:
            return getattr(cls, value)()
        if isinstance(value, dict):
            unknown = set(value) - set(cls.__dataclass_fields__)
            if unknown:
                raise ValueError(f"unknown dispersion field(s) {sorted(unknown)}; known: {sorted(cls.__dataclass_fields__)}")
            values = {}
            for k, v in value.items():
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ValueError(f"dispersion {k} must be a number, got {v!r}")
                values[k] = float(v)
            return cls(**values)
        names = ", ".join(repr(n) for n in ("none", *NAMED_SETS))
        raise ValueError(f"cannot make a Dispersion from {value!r}: give {names}, a Dispersion or a dict of its fields")

    def __post_init__(self):
        for k, v in self.__dict__.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"dispersion {k} must be a finite half-width >= 0, got {v!r}")
        for k in ("density", "lift", "drag"):
            if getattr(self, k) >= 1:
                raise ValueError(f"dispersion {k} = {getattr(self, k):g} is relative and must be below 1 (100 %)")

    @property
    def name(self) -> str:
        """The named set this equals (``"none"``, ``"standard"``, ``"wide"``), else ``"custom"``."""
        if self.is_zero:
            return "none"
        return next((n for n in NAMED_SETS if getattr(Dispersion, n)() == self), "custom")

    @property
    def is_zero(self) -> bool:
        return all(v == 0 for v in self.__dict__.values())


def draw_dispersion(rng: np.random.Generator, dispersion: Dispersion) -> np.ndarray:
    """One draw of the 9 dispersion variables, in Dispersion field order (always 9 numbers,
    so single and vector environments stay in step draw for draw)."""
    half = np.array([getattr(dispersion, f) for f in Dispersion.__dataclass_fields__])
    return rng.uniform(-1.0, 1.0, size=half.shape) * half


def apply_state_dispersion(x0: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Initial states ``(..., 12)`` perturbed by draws ``d (..., 9)`` (see :class:`Dispersion`)."""
    x = np.array(x0, dtype=float, copy=True)
    dh, dv, dgam, dpsi, dalpha, dsigma = (d[..., i] for i in range(3, 9))
    if np.any(dh) or np.any(dv) or np.any(dgam) or np.any(dpsi):
        try:
            # keep the physical lift direction: the new frames come from the east-down rule,
            # so carry the bank across as the conventional angle mu, not as sigma
            mu = cv.conventional_bank(x, x[..., IDX.sigma])
            s = cv.spherical_from_rv_euler(x)
            s[..., 0] += dh
            s[..., 3] += dv
            s[..., 4] += np.radians(dgam)
            s[..., 5] += np.radians(dpsi)
            x[..., IDX.translation] = cv.rv_euler_from_spherical(s)
            x[..., IDX.sigma] += cv.wrap_angle(cv.paper_bank(x, mu) - x[..., IDX.sigma])
        except cv.SingularConversionError as exc:
            if np.any(dgam) or np.any(dpsi):
                raise ValueError(
                    "the dispersion of the flight-path angle or heading (Dispersion.flight_path_deg, "
                    "Dispersion.heading_deg) cannot be applied to this initial state: at a pole or in vertical "
                    f"flight the angle it perturbs is undefined ({exc}). Start it without them, or away from "
                    "the pole and from vertical flight"
                ) from None
            # altitude and speed alone are the magnitudes r and v: no angle is needed
            x = np.array(x0, dtype=float, copy=True)
            x[..., IDX.r] += dh
            x[..., IDX.v] += dv
    x[..., IDX.alpha] += np.radians(dalpha)
    x[..., IDX.sigma] += np.radians(dsigma)
    return x


__all__ = ["NAMED_SETS", "Dispersion", "draw_dispersion", "apply_state_dispersion"]
