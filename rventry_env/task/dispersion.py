"""Dispersions: what the benchmark draws at each reset, and how a draw perturbs the initial state.

Every draw comes from the episode's ``np_random``, so a seed names one episode exactly,
in the single and in the vector environment alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.core.backend import NUMPY
from rventry_env.core import euler_parameters as ep
from rventry_env.core.euler_parameters import dcm_column, rates_from_omega
from rventry_env.task.flight_grade import FlightGradeErrors

# the nine numbers every reset draws, in this order (always nine, whatever the set)
SCALAR_FIELDS = ("density", "lift", "drag", "altitude_m", "speed_mps", "flight_path_deg", "heading_deg", "alpha_deg",
                 "sigma_deg")  # fmt: skip
SHAPES = ("uniform", "gaussian")
SINGULAR_TOL = 1e-9  # cos(latitude) or cos(flight-path angle) at or below this: a pole, vertical flight


@dataclass(frozen=True)
class Dispersion:
    """The dispersions drawn at each reset from ``np_random``.

    Model dispersions scale the density and the lift and drag coefficients by
    (1 + d); state dispersions add d to the initial altitude, speed, flight-path angle,
    heading, alpha and sigma. With ``shape="uniform"`` (the standard and wide sets) each field
    is a half-width and d = U(-x, x); with ``shape="gaussian"`` each is a standard deviation and
    d = x N(0, 1) clipped at ``clip_sigmas``.

    ``mass`` scales the vehicle's mass by (1 + d) (same shape), and ``flight`` adds the
    flight-grade errors of :class:`~rventry_env.task.flight_grade.FlightGradeErrors` (density and wind
    profiles, Mach-dependent aerodynamics, accelerometer and navigation errors). Neither
    draws anything when zero, so the standard and wide sets draw exactly what they always did.
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
    shape: str = "uniform"
    clip_sigmas: float = 3.0
    mass: float = 0.0
    flight: FlightGradeErrors | None = field(default=None)

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
    def flight_set(cls) -> "Dispersion":
        """The flight set: what a flight project's Monte Carlo draws (magnitudes and sources in
        docs/uncertainty.md). Gaussian, clipped at 3 sigma."""
        return cls(
            density=0.0, lift=0.05, drag=0.05, altitude_m=100.0, speed_mps=2.0, flight_path_deg=0.05,
            heading_deg=0.05, shape="gaussian", mass=0.01, flight=FLIGHT_GRADE_ERRORS,
        )  # fmt: skip

    @classmethod
    def peer(cls, factor: float = 1.0) -> "Dispersion":
        """RLReentry's set mapped onto this entry (docs/uncertainty.md): clipped Gaussians with
        altitude sigma 5 km, speed 60 m/s, flight-path angle 0.25 deg, heading 1 deg, mass 5 %,
        C_L and C_D 20 %, density 25 %; every sigma times ``factor``."""
        return cls(
            density=0.25 * factor, lift=0.20 * factor, drag=0.20 * factor, altitude_m=5000.0 * factor,
            speed_mps=60.0 * factor, flight_path_deg=0.25 * factor, heading_deg=1.0 * factor, shape="gaussian",
            mass=0.05 * factor,
        )  # fmt: skip

    @classmethod
    def named(cls, name: str) -> "Dispersion":
        """A named set: ``"none"`` or one of :data:`NAMED_SETS`."""
        if name == "none":
            return cls()
        if name not in _MAKERS:
            raise ValueError(f"no dispersion set {name!r}; named sets: {sorted(['none', *_MAKERS])}")
        return _MAKERS[name](cls)

    @classmethod
    def parse(cls, value) -> "Dispersion":
        """A Dispersion from None, a Dispersion, a set's name (``"none"``, ``"standard"``, ``"wide"``) or a dict of fields."""
        if value is None or value == "none":
            return cls()
        if isinstance(value, Dispersion):
            return value
        if isinstance(value, str) and value in NAMED_SETS:
            return cls.named(value)
        if isinstance(value, dict):
            unknown = set(value) - set(cls.__dataclass_fields__)
            if unknown:
                raise ValueError(f"unknown dispersion field(s) {sorted(unknown)}; known: {sorted(cls.__dataclass_fields__)}")
            values = {}
            for k, v in value.items():
                if k == "shape":
                    values[k] = v
                elif k == "flight":
                    values[k] = FlightGradeErrors.parse(v)
                elif isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ValueError(f"dispersion {k} must be a number, got {v!r}")
                else:
                    values[k] = float(v)
            return cls(**values)
        names = ", ".join(repr(n) for n in ("none", *NAMED_SETS))
        raise ValueError(f"cannot make a Dispersion from {value!r}: give {names}, a Dispersion or a dict of its fields")

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f"dispersion shape must be one of {SHAPES}, got {self.shape!r}")
        what = "half-width" if self.shape == "uniform" else "standard deviation"
        for k in (*SCALAR_FIELDS, "mass"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"dispersion {k} must be a finite {what} >= 0, got {v!r}")
        c = self.clip_sigmas
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) or c <= 0:
            raise ValueError(f"dispersion clip_sigmas must be a positive number, got {c!r}")
        if self.flight is not None and not isinstance(self.flight, FlightGradeErrors):
            raise ValueError(f"dispersion flight must be FlightGradeErrors or None, got {self.flight!r}")
        for k in ("density", "lift", "drag", "mass"):
            if self.largest(k) >= 1:
                raise ValueError(
                    f"dispersion {k} = {getattr(self, k):g} is relative and its largest draw "
                    f"({self.largest(k):g}) must be below 1 (100 %)"
                )

    def largest(self, name: str) -> float:
        """The largest |d| a field can draw: its half-width, or clip_sigmas standard deviations."""
        return getattr(self, name) * (1.0 if self.shape == "uniform" else self.clip_sigmas)

    @property
    def name(self) -> str:
        """The named set this equals (``"none"``, ``"standard"``, ...), else ``"custom"``."""
        if self.is_zero:
            return "none"
        return next((n for n in NAMED_SETS if Dispersion.named(n) == self), "custom")

    def describe(self) -> dict:
        """A JSON-friendly description of every field (the flight errors as a dict)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "flight"}
        out["flight"] = None if self.flight is None else self.flight.describe()
        return out

    @property
    def has_extras(self) -> bool:
        """Whether a reset draws more than the nine scalars (a mass or flight-grade errors)."""
        return self.mass > 0 or (self.flight is not None and not self.flight.is_zero)

    @property
    def has_sensing(self) -> bool:
        """Whether the vehicle's sensors or navigation err (what a law sees differs from the truth)."""
        return self.flight is not None and self.flight.has_sensing

    @property
    def is_zero(self) -> bool:
        return all(getattr(self, k) == 0 for k in SCALAR_FIELDS) and not self.has_extras


def draw_dispersion(rng: np.random.Generator, dispersion: Dispersion) -> np.ndarray:
    """One draw of the 9 scalar dispersion variables, in :data:`SCALAR_FIELDS` order (always 9
    numbers, so single and vector environments stay in step draw for draw)."""
    half = np.array([getattr(dispersion, f) for f in SCALAR_FIELDS])
    if dispersion.shape == "uniform":
        return rng.uniform(-1.0, 1.0, size=half.shape) * half
    c = dispersion.clip_sigmas
    return np.clip(rng.standard_normal(half.shape), -c, c) * half


def draw_extras(rng: np.random.Generator, dispersion: Dispersion, problem) -> dict | None:
    """What a reset draws after the nine scalars: the mass factor's offset and the flight-grade
    errors (:func:`~rventry_env.task.flight_grade.draw_flight_grade`); None, drawing nothing, for a set
    without them."""
    if not dispersion.has_extras:
        return None
    from rventry_env.task.flight_grade import draw_flight_grade

    z = rng.uniform(-1.0, 1.0) if dispersion.shape == "uniform" else float(np.clip(rng.standard_normal(), -dispersion.clip_sigmas, dispersion.clip_sigmas))
    out = {"mass": np.float64(z * dispersion.mass)}
    flight = dispersion.flight if dispersion.flight is not None else FlightGradeErrors()
    out.update(draw_flight_grade(rng, flight, problem))
    return out


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
    (tests/envs/test_jax.py). Undefined at a pole and in vertical flight, like the angles themselves
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



# The flight set's flight-grade magnitudes (1 sigma; sources in docs/uncertainty.md)
# every named set, written once: name -> maker (``Dispersion.named``, ``parse``, the commands' choices)
_MAKERS = {"standard": Dispersion.standard.__func__, "wide": Dispersion.wide.__func__,
           "flight": Dispersion.flight_set.__func__, "peer": Dispersion.peer.__func__,
           "peer-0.1": lambda cls: cls.peer(0.1)}  # fmt: skip
NAMED_SETS = tuple(_MAKERS)
# what a command's --dispersion accepts: no dispersion, or a named set
SET_CHOICES = ("none", *NAMED_SETS)

FLIGHT_GRADE_ERRORS = FlightGradeErrors(
    climatology=True,
    # ln-density Gauss-Markov: (band top m, rms, correlation length m)
    density_bands=((10e3, 0.02, 5e3), (30e3, 0.03, 8e3), (50e3, 0.05, 10e3), (100e3, 0.08, 12e3)),
    wind_mean_mps=10.0,
    wind_bands=((10e3, 5.0, 3e3), (30e3, 8.0, 4e3), (50e3, 12.0, 5e3), (100e3, 20.0, 6e3)),
    lift_mach=0.03,
    drag_mach=0.03,
    accel_bias_mps2=50e-6 * 9.80665,
    accel_scale=100e-6,
    accel_misalignment_rad=math.radians(20.0 / 3600.0),
    accel_noise_mps2=3e-4,
    nav_position_m=100.0,
    nav_velocity_mps=0.5,
)

__all__ = ["NAMED_SETS", "SET_CHOICES", "SCALAR_FIELDS", "FLIGHT_GRADE_ERRORS", "Dispersion", "draw_dispersion",
           "draw_extras", "apply_state_dispersion", "disperse_state"]  # fmt: skip
