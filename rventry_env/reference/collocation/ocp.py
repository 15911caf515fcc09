"""A general single-phase optimal-control problem for the LGR collocation solver.

The problem is stated with plain Python callables on *components*: each receives
lists of scalar CasADi ``SX`` expressions (one per state or control) and returns
expressions, so physics written for :mod:`rventry_env.core.backend` plugs in
unchanged. Nothing is transcribed here; :mod:`.transcription` does that.

Minimise  mayer(x(t0), x(tf), t0, tf) + integral_{t0}^{tf} lagrange(x, u, t) dt
subject to::

    dx/dt = dynamics(x, u, t),
    state / control bounds, bounds on x(t0) and x(tf), t0 fixed, tf in [tf_lower, tf_upper],
    path constraints lower <= c(x, u, t) <= upper at every collocation point,
    endpoint constraints lower <= b(x(t0), x(tf), t0, tf) <= upper,
    invariants g(x) = 0 at every state node after the first.

A problem may declare *parameters*: constants of the model (a density scale, say) that
stay fixed during one solve and change between solves without rebuilding the NLP
(CasADi NLP parameters). With parameters, ``dynamics``, ``lagrange`` and every path
constraint take them as a fourth argument: ``dynamics(x, u, t, p)``.

Invariants are quantities the *exact* dynamics conserve (the unit norm of a set of
Euler parameters, say). Imposing them next to the discretised dynamics
over-determines the NLP unless the dynamics get a matching degree of freedom; see
:mod:`rventry_env.reference.entry_ocp` for how the entry problem pairs each
with a control. They are not imposed at t0: there the initial bounds must make
them hold (imposing both would be a redundant, LICQ-violating pair).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

Expr = Any  # a CasADi SX scalar (or a float)
Dynamics = Callable[[Sequence[Expr], Sequence[Expr], Expr], Sequence[Expr]]
Lagrange = Callable[[Sequence[Expr], Sequence[Expr], Expr], Expr]
Mayer = Callable[[Sequence[Expr], Sequence[Expr], Expr, Expr], Expr]


def _vec(value, n: int, what: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(n, default, dtype=float)
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{what} must have {n} entries, got shape {arr.shape}")
    if np.any(np.isnan(arr)):
        raise ValueError(f"{what} contains NaN")
    return arr


def _check_interval(lo: float, hi: float, what: str) -> None:
    if math.isnan(lo) or math.isnan(hi):
        raise ValueError(f"{what}: bounds must not be NaN")
    if lo > hi:
        raise ValueError(f"{what}: lower bound {lo} exceeds upper bound {hi}")


@dataclass(frozen=True)
class PathConstraint:
    """``lower <= fn(x, u, t) <= upper`` at every collocation point.

    :param name: label for reports.
    :param fn: callable on component lists returning one expression.
    :param lower: lower bound (``-inf`` for none).
    :param upper: upper bound (``inf`` for none).
    :param scale: typical magnitude; the NLP sees ``fn / scale``.
    """

    name: str
    fn: Callable[[Sequence[Expr], Sequence[Expr], Expr], Expr]
    lower: float = -math.inf
    upper: float = math.inf
    scale: float = 1.0

    def __post_init__(self):
        _check_constraint(self, "path constraint")


@dataclass(frozen=True)
class EndpointConstraint:
    """``lower <= fn(x(t0), x(tf), t0, tf) <= upper``.

    :param name: label for reports.
    :param fn: callable ``(x0, xf, t0, tf) -> expression``.
    :param lower: lower bound.
    :param upper: upper bound.
    :param scale: typical magnitude; the NLP sees ``fn / scale``.
    """

    name: str
    fn: Callable[[Sequence[Expr], Sequence[Expr], Expr, Expr], Expr]
    lower: float = -math.inf
    upper: float = math.inf
    scale: float = 1.0

    def __post_init__(self):
        _check_constraint(self, "endpoint constraint")


@dataclass(frozen=True)
class Invariant:
    """``fn(x) = 0`` along exact solutions; imposed at every state node after t0.

    :param name: label for reports.
    :param fn: callable ``x -> expression``.
    :param scale: typical magnitude.
    """

    name: str
    fn: Callable[[Sequence[Expr]], Expr]
    scale: float = 1.0

    def __post_init__(self):
        if not callable(self.fn):
            raise TypeError(f"invariant {self.name!r}: fn must be callable")
        if not (self.scale > 0 and math.isfinite(self.scale)):
            raise ValueError(f"invariant {self.name!r}: scale must be positive and finite, got {self.scale}")


def _check_constraint(c, kind: str) -> None:
    if not isinstance(c.name, str) or not c.name:
        raise ValueError(f"a {kind} needs a non-empty name")
    if not callable(c.fn):
        raise TypeError(f"{kind} {c.name!r}: fn must be callable")
    _check_interval(float(c.lower), float(c.upper), f"{kind} {c.name!r}")
    if math.isinf(c.lower) and math.isinf(c.upper) and c.lower < 0 < c.upper:
        raise ValueError(f"{kind} {c.name!r} has no finite bound: it constrains nothing")
    if not (c.scale > 0 and math.isfinite(c.scale)):
        raise ValueError(f"{kind} {c.name!r}: scale must be positive and finite, got {c.scale}")


@dataclass
class OptimalControlProblem:
    """A single-phase optimal-control problem with fixed t0 and free or fixed tf.

    :param name: label for reports.
    :param state_names: one name per state component.
    :param control_names: one name per control component.
    :param dynamics: ``(x, u, t) -> dx/dt`` on component lists.
    :param state_lower: lower bounds on the state along the trajectory (``-inf`` allowed).
    :param state_upper: upper bounds on the state.
    :param control_lower: lower bounds on the control.
    :param control_upper: upper bounds on the control.
    :param initial_lower: lower bounds on x(t0) (default: the state bounds); equal
        lower and upper fix a component.
    :param initial_upper: upper bounds on x(t0).
    :param final_lower: lower bounds on x(tf).
    :param final_upper: upper bounds on x(tf).
    :param t0: initial time (fixed).
    :param tf_lower: smallest final time (> t0).
    :param tf_upper: largest final time; equal to ``tf_lower`` for a fixed tf.
    :param lagrange: running cost ``(x, u, t) -> expression``, or ``None``.
    :param mayer: terminal cost ``(x0, xf, t0, tf) -> expression``, or ``None``.
    :param path_constraints: :class:`PathConstraint` s.
    :param endpoint_constraints: :class:`EndpointConstraint` s.
    :param invariants: :class:`Invariant` s.
    :param state_scale: typical range of each state (the NLP variable is
        ``(x - state_shift) / state_scale``). Default: the bound range where both
        bounds are finite, else 1.
    :param state_shift: offset of each state; default: the bound midpoint where
        both bounds are finite, else 0.
    :param control_scale: like ``state_scale`` for the controls.
    :param control_shift: like ``state_shift`` for the controls.
    :param time_scale: typical final time; default ``tf_upper`` if finite else 1.
    :param cost_scale: typical magnitude of the cost; the NLP minimises cost / cost_scale.
    :param parameter_names: names of the problem's parameters (none by default).
    :param parameter_values: their default values (zeros if not given).
    """

    name: str
    state_names: Sequence[str]
    control_names: Sequence[str]
    dynamics: Dynamics
    state_lower: Any = None
    state_upper: Any = None
    control_lower: Any = None
    control_upper: Any = None
    initial_lower: Any = None
    initial_upper: Any = None
    final_lower: Any = None
    final_upper: Any = None
    t0: float = 0.0
    tf_lower: float = 0.0
    tf_upper: float = math.inf
    lagrange: Lagrange | None = None
    mayer: Mayer | None = None
    path_constraints: Sequence[PathConstraint] = field(default_factory=tuple)
    endpoint_constraints: Sequence[EndpointConstraint] = field(default_factory=tuple)
    invariants: Sequence[Invariant] = field(default_factory=tuple)
    state_scale: Any = None
    state_shift: Any = None
    control_scale: Any = None
    control_shift: Any = None
    time_scale: float | None = None
    cost_scale: float = 1.0
    parameter_names: Sequence[str] = ()
    parameter_values: Any = None

    def __post_init__(self):
        self._check_names_and_functions()
        self._check_bounds()
        self._check_times_and_constraints()
        self._check_scales_and_parameters()

    def _check_names_and_functions(self) -> None:
        """The state and control names (unique, non-empty), the dynamics and a cost, checked."""
        self.state_names = tuple(self.state_names)
        self.control_names = tuple(self.control_names)
        for what, names in (("state", self.state_names), ("control", self.control_names)):
            if not all(isinstance(s, str) and s for s in names):
                raise ValueError(f"{what} names must be non-empty strings")
            if len(set(names)) != len(names):
                raise ValueError(f"{what} names must be unique, got {names}")
        if not self.state_names:
            raise ValueError("a problem needs at least one state")
        if not callable(self.dynamics):
            raise TypeError("dynamics must be callable (x, u, t) -> dx/dt")
        for what in ("lagrange", "mayer"):
            fn = getattr(self, what)
            if fn is not None and not callable(fn):
                raise TypeError(f"{what} must be callable or None")
        if self.lagrange is None and self.mayer is None:
            raise ValueError("a problem needs a cost: give lagrange, mayer or both")

    def _check_bounds(self) -> None:
        """The bounds as vectors (infinite where not given), the end bounds limited by the path
        bounds, and no lower bound above its upper one."""
        nx, nu = self.n_x, self.n_u
        self.state_lower = _vec(self.state_lower, nx, "state_lower", -math.inf)
        self.state_upper = _vec(self.state_upper, nx, "state_upper", math.inf)
        self.control_lower = _vec(self.control_lower, nu, "control_lower", -math.inf)
        self.control_upper = _vec(self.control_upper, nu, "control_upper", math.inf)
        self.initial_lower = _vec(self.initial_lower, nx, "initial_lower", -math.inf)
        self.initial_upper = _vec(self.initial_upper, nx, "initial_upper", math.inf)
        self.final_lower = _vec(self.final_lower, nx, "final_lower", -math.inf)
        self.final_upper = _vec(self.final_upper, nx, "final_upper", math.inf)
        # the end bounds are further limited by the path bounds
        self.initial_lower = np.maximum(self.initial_lower, self.state_lower)
        self.initial_upper = np.minimum(self.initial_upper, self.state_upper)
        self.final_lower = np.maximum(self.final_lower, self.state_lower)
        self.final_upper = np.minimum(self.final_upper, self.state_upper)
        for what, names, lo, hi in (
            ("state bounds", self.state_names, self.state_lower, self.state_upper),
            ("control bounds", self.control_names, self.control_lower, self.control_upper),
            ("initial-state bounds", self.state_names, self.initial_lower, self.initial_upper),
            ("final-state bounds", self.state_names, self.final_lower, self.final_upper),
        ):
            bad = np.nonzero(lo > hi)[0]
            if bad.size:
                i = int(bad[0])
                raise ValueError(f"{what}: {names[i]!r} has lower {lo[i]} > upper {hi[i]}")

    def _check_times_and_constraints(self) -> None:
        """The initial and final times, and the constraints as tuples of their own kinds, checked."""
        self.t0 = float(self.t0)
        if not math.isfinite(self.t0):
            raise ValueError(f"t0 must be finite, got {self.t0}")
        _check_interval(float(self.tf_lower), float(self.tf_upper), "final time")
        if not self.tf_lower > self.t0:
            raise ValueError(f"tf_lower ({self.tf_lower}) must exceed t0 ({self.t0})")
        self.path_constraints = tuple(self.path_constraints)
        self.endpoint_constraints = tuple(self.endpoint_constraints)
        self.invariants = tuple(self.invariants)
        for group, kind in (
            (self.path_constraints, PathConstraint),
            (self.endpoint_constraints, EndpointConstraint),
            (self.invariants, Invariant),
        ):
            for c in group:
                if not isinstance(c, kind):
                    raise TypeError(f"expected {kind.__name__}, got {type(c).__name__}")

    def _check_scales_and_parameters(self) -> None:
        """The state, control, time and cost scales and the parameters, checked (scales filled in
        from the bounds where not given)."""
        self.state_scale, self.state_shift = _scaling(
            self.state_scale, self.state_shift, self.state_lower, self.state_upper, "state"
        )
        self.control_scale, self.control_shift = _scaling(
            self.control_scale, self.control_shift, self.control_lower, self.control_upper, "control"
        )
        if self.time_scale is None:
            self.time_scale = float(self.tf_upper) if math.isfinite(self.tf_upper) else 1.0
        if not (self.time_scale > 0 and math.isfinite(self.time_scale)):
            raise ValueError(f"time_scale must be positive and finite, got {self.time_scale}")
        if not (self.cost_scale > 0 and math.isfinite(self.cost_scale)):
            raise ValueError(f"cost_scale must be positive and finite, got {self.cost_scale}")
        self.parameter_names = tuple(self.parameter_names)
        if len(set(self.parameter_names)) != len(self.parameter_names):
            raise ValueError(f"parameter names must be unique, got {self.parameter_names}")
        self.parameter_values = _vec(self.parameter_values, self.n_p, "parameter_values", 0.0)
        if not np.all(np.isfinite(self.parameter_values)):
            raise ValueError("parameter_values must be finite")

    def check_parameters(self, values) -> np.ndarray:
        """The parameter values to solve with (the defaults when ``values`` is None), validated."""
        if values is None:
            return self.parameter_values.copy()
        arr = _vec(values, self.n_p, "parameters", 0.0)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"parameters must be finite, got {arr}")
        return arr

    @property
    def n_x(self) -> int:
        """Number of states."""
        return len(self.state_names)

    @property
    def n_u(self) -> int:
        """Number of controls."""
        return len(self.control_names)

    @property
    def n_p(self) -> int:
        """Number of parameters."""
        return len(self.parameter_names)

    @property
    def free_final_time(self) -> bool:
        """Whether tf is a decision variable."""
        return self.tf_upper > self.tf_lower


def _scaling(scale, shift, lo, hi, what):
    finite = np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
    with np.errstate(invalid="ignore"):  # inf - inf where a bound is missing; masked below
        default_scale = np.where(finite, hi - lo, 1.0)
        default_shift = np.where(finite, 0.5 * (lo + hi), 0.0)
    scale = default_scale if scale is None else _vec(scale, lo.size, f"{what}_scale", 1.0)
    shift = default_shift if shift is None else _vec(shift, lo.size, f"{what}_shift", 0.0)
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
        raise ValueError(f"{what}_scale must be positive and finite, got {scale}")
    if np.any(~np.isfinite(shift)):
        raise ValueError(f"{what}_shift must be finite")
    return scale, shift


__all__ = [
    "OptimalControlProblem",
    "PathConstraint",
    "EndpointConstraint",
    "Invariant",
]
