"""Dispersions: what the benchmark draws at each reset, and how a draw perturbs the initial state.

Every draw comes from the episode's ``np_random``, so a seed names one episode exactly,
in the single and in the vector environment alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.core.backend import NUMPY
from rventry_env.core import euler_parameters as ep
from rventry_env.core.euler_parameters import dcm_column, rates_from_omega

NAMED_SETS = ("standard", "wide")
SINGULAR_TOL = 1e-9  # cos(latitude) or cos(flight-path angle) at or below this: a pole, vertical flight


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
    x = np.asarray(x0, dtype=float)
    d = np.asarray(d, dtype=float)
    if np.any(d[..., 5]) or np.any(d[..., 6]):
        # where the flight-path angle or heading is undefined, the rotation that perturbs it is too
        c_ae, c_ba = (ep.dcm_from_quaternion(x[..., s]) for s in (IDX.e_a, IDX.e_b))
        cos_lat = np.hypot(c_ae[..., 0, 0], c_ae[..., 0, 1])
        cos_gamma = np.hypot(c_ba[..., 1, 0], c_ba[..., 2, 0])
        if np.any(cos_lat <= SINGULAR_TOL) or np.any(cos_gamma <= SINGULAR_TOL):
            where = "at a pole" if np.any(cos_lat <= SINGULAR_TOL) else "in vertical flight"
            raise ValueError(
                "the dispersion of the flight-path angle or heading (Dispersion.flight_path_deg, "
                "Dispersion.heading_deg) cannot be applied to this initial state: at a pole or in vertical "
                f"flight the angle it perturbs is undefined (the state is {where}). Start it without them, or "
                "away from the pole and from vertical flight"
            )
    out = disperse_state(tuple(np.moveaxis(x, -1, 0)), tuple(np.moveaxis(d, -1, 0)), NUMPY)
    return np.stack(np.broadcast_arrays(*out), axis=-1)


def disperse_state(x: tuple, d: tuple, ns) -> tuple:
    """The state components ``x`` perturbed by the 9 dispersion draws ``d`` (components, Dispersion order).

    Altitude and speed add to r and v. The flight-path angle turns the velocity frame B
    about the horizontal normal to the velocity, n = b1 x a1 / |b1 x a1|, and the heading
    turns it about the local vertical a1 (azimuth clockwise seen from above). Both are
    exact rotations of the Euler parameters, q -> cos(t/2) q + sin(t/2) Q(k) q, with
    Q(k) q = 2 x (the rates of Eq. ``QuatRate`` at unit angular velocity k). They carry
    the lift direction along: the bank angle relative to the vertical plane (the
    conventional mu) is unchanged, as the vertical plane turns with B. This equals the
    round trip through spherical coordinates and the east-down frame rule to rounding
    (tests/test_jax.py). Undefined at a pole and in vertical flight, like the angles themselves
    (:func:`apply_state_dispersion` refuses them there; altitude and speed still apply). Plain
    component arithmetic, so NumPy and JAX (the functional environment's reset) share it.
    """
    dh, dv, dgam, dpsi, dalpha, dsigma = d[3:9]
    deg = math.pi / 180.0
    r, v, alpha, sigma = x[IDX.r], x[IDX.v], x[IDX.alpha], x[IDX.sigma]
    eb = tuple(x[IDX.e_b])
    _, u2, u3 = dcm_column(*eb, 0)  # a1 in B
    c = ns.sqrt(u2 * u2 + u3 * u3)
    c = ns.where(c > 0.0, c, 1.0)  # vertical flight: no turn to make (its angles are refused above)
    eb = _turn(eb, (0.0, -u3 / c, u2 / c), dgam * deg, ns)
    eb = _turn(eb, dcm_column(*eb, 0), -dpsi * deg, ns)
    return (r + dh, *x[IDX.e_a], v + dv, *eb, alpha + dalpha * deg, sigma + dsigma * deg)


def _turn(q: tuple, axis: tuple, angle, ns) -> tuple:
    """Euler parameters of a frame turned by ``angle`` about the unit ``axis`` (its own components)."""
    k = rates_from_omega(*q, *axis)
    cos, sin = ns.cos(0.5 * angle), ns.sin(0.5 * angle)
    return tuple(cos * qi + 2.0 * sin * ki for qi, ki in zip(q, k))


__all__ = ["NAMED_SETS", "Dispersion", "draw_dispersion", "apply_state_dispersion", "disperse_state"]
