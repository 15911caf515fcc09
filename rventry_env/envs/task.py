"""The entry task: the paper's Example 2 problem (:mod:`rventry_env.problem`) plus
the RL reward weights, success thresholds, dispersions and episode limits.

SI units and radians; the ``*_deg`` / ``*_km`` names are user-facing thresholds
and weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rventry_env.problem import EntryProblem


@dataclass(frozen=True)
class RewardWeights:
    """Reward weights. Each step pays -(running cost of Eq. Ex2-Cost over the step);
    the terminal step also pays -(terminal penalty); path violations are charged
    each step.

    Terminal penalty = miss_per_km * miss [km] + vertical_per_deg * vertical error [deg]
    + speed_per_mps * |v - v_f| [m/s] + alpha_per_deg * |alpha(t_f)| [deg].
    Linear, so a gradient survives far from the target and nothing explodes.
    Path penalty per second = load_violation * max(0, n/n_max - 1 - tol)
    + q_violation * max(0, 1 - q/q_min - tol), sampled at every RK4 node, with
    tol the 1 % margin of :class:`SuccessThresholds` (what counts as a violation).
    ``failure`` is added when an episode ends without impact (skip-out, non-finite
    state, stall). ``success_bonus`` (default 0) is *paid* at a successful impact
    (:class:`SuccessThresholds`): a learner's handle on the threshold-shaped task
    metric, off in the environment's own definition.
    """

    miss_per_km: float = 0.2
    vertical_per_deg: float = 0.2
    speed_per_mps: float = 0.02
    alpha_per_deg: float = 0.1
    load_violation: float = 10.0
    q_violation: float = 10.0
    failure: float = 200.0
    success_bonus: float = 0.0


@dataclass(frozen=True)
class SuccessThresholds:
    """When an impact counts as a success (the benchmark's criteria)."""

    miss_km: float = 5.0
    vertical_error_deg: float = 5.0
    speed_error_mps: float = 100.0
    # A path constraint counts as violated beyond this relative margin. The optimal
    # collocation reference meets both bounds exactly at its nodes but, replayed,
    # reaches 12.05 g (+0.45 %) and 11.90 kPa (-0.82 %) between them, so a tighter
    # margin would call the optimum itself infeasible.
    constraint_tolerance: float = 0.01


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


@dataclass(frozen=True)
class EntryTask:
    """Problem, reward weights, success thresholds and episode limits together.

    :param dt: control step (s); the action is held over it.
    :param substeps: RK4 substeps per control step.
    :param ceiling_altitude: skip-out: an episode ends (failure) above this altitude (m).
    :param min_speed: stall: an episode ends (failure) below this speed (m/s); the
        equations are singular at v = 0.
    """

    problem: EntryProblem = field(default_factory=EntryProblem)
    weights: RewardWeights = field(default_factory=RewardWeights)
    success: SuccessThresholds = field(default_factory=SuccessThresholds)
    dt: float = 1.0
    substeps: int = 1
    ceiling_altitude: float = 80e3
    min_speed: float = 50.0

    def __post_init__(self):
        if not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {self.dt!r}")
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, (int, float)) or not (
            math.isfinite(self.substeps) and int(self.substeps) == self.substeps and self.substeps >= 1
        ):
            raise ValueError(f"substeps must be a positive integer, got {self.substeps!r}")
        object.__setattr__(self, "substeps", int(self.substeps))
        object.__setattr__(self, "dt", float(self.dt))
        for name in ("ceiling_altitude", "min_speed"):
            val = getattr(self, name)
            if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be a positive finite number, got {val!r}")
        if self.ceiling_altitude <= self.problem.initial_altitude:
            raise ValueError(
                f"ceiling_altitude ({self.ceiling_altitude:g} m) must lie above the initial altitude "
                f"({self.problem.initial_altitude:g} m)"
            )

    def check_dispersion(self, dispersion: "Dispersion") -> None:
        """Refuse a dispersion that can start a vehicle underground, above the ceiling or without speed.

        :raises ValueError: naming the dispersion field and its largest admissible half-width.
        """
        p = self.problem
        room_down = p.initial_altitude - p.final_altitude
        room_up = self.ceiling_altitude - p.initial_altitude
        if dispersion.altitude_m >= min(room_down, room_up):
            raise ValueError(
                f"dispersion altitude_m = {dispersion.altitude_m:g} m could start the vehicle "
                f"{'underground' if room_down <= room_up else 'above the skip-out ceiling'}: the initial altitude "
                f"is {p.initial_altitude:g} m, so the half-width must stay below {min(room_down, room_up):g} m"
            )
        if dispersion.speed_mps >= p.initial_speed - self.min_speed:
            raise ValueError(
                f"dispersion speed_mps = {dispersion.speed_mps:g} m/s could start the vehicle below the stall "
                f"speed ({self.min_speed:g} m/s): the initial speed is {p.initial_speed:g} m/s, so the half-width "
                f"must stay below {p.initial_speed - self.min_speed:g} m/s"
            )
        for name in ("flight_path_deg", "heading_deg"):
            if getattr(dispersion, name) >= 90.0:
                raise ValueError(f"dispersion {name} = {getattr(dispersion, name):g} deg must stay below 90 deg")
        alpha_room = math.degrees(min(p.initial_alpha, p.alpha_max - p.initial_alpha))
        if dispersion.alpha_deg > alpha_room:
            raise ValueError(
                f"dispersion alpha_deg = {dispersion.alpha_deg:g} deg would start alpha outside [0, alpha_max]: "
                f"alpha(0) is {math.degrees(p.initial_alpha):g} deg, so the half-width must stay within {alpha_room:g} deg"
            )
