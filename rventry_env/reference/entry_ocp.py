"""The paper's Example 2 as an optimal-control problem (OCP; Section ``sect:Ex2``).

States: the 12 entry states of docs/conventions.md (``r, eA1..etaA, v, eB1..etaB, alpha,
sigma``); controls: ``u_alpha, u_sigma`` and, in the default norm-keeping
formulation, two more (``lambda_A, lambda_B``, below). The dynamics are
:func:`rventry_env.physics.entry.entry_rhs` on CasADi symbols: one copy of the
physics (Eqs. ``Ex2-EOM`` to ``Ex2-EOM-Ftot``).

The implicit constraints (Section ``sect:Ex2-Implementation``)
--------------------------------------------------------------
The exact flow keeps |q_A| = |q_B| = 1 and omega_A1 = omega_B1 = 0, but a
collocation solution keeps them only to truncation error, and then the endpoint
equations Eq. ``Ex2-endpoint`` (three equations asking a possibly non-unit a1 to
equal a unit vector) become inconsistent. Two remedies are available here:

``norm_mode="projection"`` (default)
    Each quaternion gets one extra control along itself,
    dq/dt = (Eq. ``Ex2-EOM`` rates) + lambda q, and the unit norm is imposed as an
    equality at every state node after t0. Equivalence: along any trajectory with
    |q| = 1, d|q|^2/dt = 2 q . (rates) + 2 lambda |q|^2 = 2 lambda (the rates of
    Eq. ``Ex2-EOM`` are orthogonal to q), so the exact problem forces lambda = 0
    and the two problems have the same solutions. A radial rate adds no angular
    velocity (omega = 2 G(q) dq/dt with G(q) q = 0), so omega_A1 = omega_B1 = 0
    are untouched. Degrees of freedom balance one for one (one control, one
    equality per node), so the NLP stays square and LICQ holds, and lambda
    measures how much the discretisation wanted to drift (it tends to zero as the
    mesh is refined). The norms are then exact at every node, so Eq.
    ``Ex2-endpoint`` is consistent; of its three equations only two are
    independent on the unit sphere, and those two are imposed (a1 orthogonal to
    the target's east and north directions) with the sign fixed by a1 . target > 0.

``norm_mode="paper"``
    The paper's remedy: controls u1..u4 replace the ODEs of eA2, eA3, eB2, eB3,
    with |u_i - (Eq. ``Ex2-EOM`` rate)| <= delta (delta = 1e-6) as path
    constraints. The norms then drift within what the band allows; the endpoint
    conditions are written with the homogeneous (norm-free) direction of a1 so
    they never contradict a slightly non-unit quaternion.

``norm_mode="none"``
    No remedy, for comparison only: the plain Eq. ``Ex2-EOM`` and the three
    equations of Eq. ``Ex2-endpoint`` exactly as printed (non-homogeneous a1).
    This is the transcription the paper warns about.

The vertical impact eB1(tf) = etaB(tf) = 0 is imposed exactly as final-state
bounds in both modes. For the continuation used by the initial-guess generator
the final flight-path condition can instead be relaxed to gamma(tf) <= gamma_max
(``final_gamma_max_deg``); the shipped solution always uses the exact condition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from rventry_env.core.backend import casadi_ns
from rventry_env.physics.entry import ENTRY_STATE_NAMES, IDX, entry_forces, entry_rhs
from rventry_env.physics.model import EntryModel, with_aero_scales
from rventry_env.task.problem import EntryProblem
from rventry_env.reference.collocation.ocp import (
    EndpointConstraint,
    Invariant,
    OptimalControlProblem,
    PathConstraint,
)

DEG = math.pi / 180.0
NORM_MODES = ("projection", "paper", "none")


@dataclass(frozen=True)
class EntryOcpConfig:
    """How the collocation solver poses Example 2: the problem's constants plus solver options.

    :param problem: the Example 2 constants (:class:`rventry_env.task.problem.EntryProblem`,
        SI units), the same object the environment reads.
    :param model: the force model (default :class:`EntryModel`).
    :param norm_mode: ``"projection"``, ``"paper"`` or ``"none"`` (module docstring).
    :param delta: band of the paper's remedy.
    :param final_gamma_max_deg: ``None`` for the exact vertical impact, else the
        relaxed condition gamma(tf) <= this (continuation and the singularity study).
    :param final_gamma_equality: with ``final_gamma_max_deg``, impose gamma(tf) = that
        angle instead (the singularity study compares equal terminal angles).
    :param tf_bounds: (smallest, largest) final time (s).
    :param soft_path_penalty: ``None`` (default) for the hard path constraints of Eq.
        ``Ex2-path``; a number makes them soft: relative slacks on the load factor and
        the dynamic pressure, charged this much per unit and per second in the running
        cost (an exact penalty: above the constraints' multipliers, the optimum is that
        of the hard problem whenever that one is feasible). A re-planning law needs it: a
        vehicle already past a bound must still get a plan.
    :param aero_scale_parameters: give the problem two parameters, the logarithms of the
        drag-acceleration and lift-to-drag scale factors
        (:func:`~rventry_env.physics.model.with_aero_scales`), so that one transcription
        serves any estimate of them (re-planning guidance).
    """

    problem: EntryProblem = field(default_factory=EntryProblem)
    model: EntryModel = field(default_factory=EntryModel)
    norm_mode: str = "projection"
    delta: float = 1e-6
    final_gamma_max_deg: float | None = None
    final_gamma_equality: bool = False
    tf_bounds: tuple = (50.0, 3000.0)
    soft_path_penalty: float | None = None
    aero_scale_parameters: bool = False

    def __post_init__(self):
        if self.norm_mode not in NORM_MODES:
            raise ValueError(f"norm_mode must be one of {NORM_MODES}, got {self.norm_mode!r}")
        if not (self.delta > 0 and math.isfinite(self.delta)):
            raise ValueError(f"delta must be positive and finite, got {self.delta}")
        if self.soft_path_penalty is not None and not (self.soft_path_penalty > 0 and math.isfinite(self.soft_path_penalty)):
            raise ValueError(f"soft_path_penalty must be None or positive and finite, got {self.soft_path_penalty}")
        lo, hi = self.tf_bounds
        if not 0 < lo < hi:
            raise ValueError(f"tf_bounds must satisfy 0 < lower < upper, got {self.tf_bounds}")
        if self.final_gamma_equality and self.final_gamma_max_deg is None:
            raise ValueError("final_gamma_equality needs final_gamma_max_deg (default: exact impact)")
        if self.final_gamma_max_deg is not None and not -90.0 < self.final_gamma_max_deg <= 90.0:
            raise ValueError(f"final_gamma_max_deg must lie in (-90, 90], got {self.final_gamma_max_deg}")

    def replace(self, **changes) -> "EntryOcpConfig":
        return replace(self, **changes)

    # the problem's constants, SI
    @property
    def alpha_bar(self) -> float:
        return self.problem.alpha_bar

    @property
    def alpha_max(self) -> float:
        return self.problem.alpha_max

    @property
    def u_alpha_max(self) -> float:
        return self.problem.u_alpha_max

    @property
    def u_sigma_max(self) -> float:
        return self.problem.u_sigma_max

    @property
    def a_max(self) -> float:
        return self.problem.a_max_g * self.model.planet.g0

    def target_e(self) -> np.ndarray:
        """Unit vector to the target in E."""
        return self.problem.target_unit_vector()

    def target_frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(target, east, north) unit vectors in E at the target."""
        lon, lat = self.problem.target_longitude, self.problem.target_latitude
        east = np.array([-math.sin(lon), math.cos(lon), 0.0])
        north = np.array([-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)])
        return self.target_e(), east, north

    def initial_state(self, alpha: float, sigma: float) -> np.ndarray:
        """Table ``tab:Ex2-BCs``'s initial state with the given alpha, sigma (rad), on this model's planet."""
        return self.problem.initial_state(self.model.planet.radius, alpha, sigma)


def position_direction(e_a):
    """a1 in E components from C_AE Euler parameters, homogeneous form.

    (eta^2 + e1^2 - e2^2 - e3^2, 2(e1 e2 + e3 eta), 2(e1 e3 - e2 eta)) equals the first
    row of Eq. ``CAE-final`` when the norm is 1 and is |q|^2 a1 otherwise, so its
    direction is the position direction for any non-zero q.
    """
    e1, e2, e3, eta = e_a
    return (
        eta * eta + e1 * e1 - e2 * e2 - e3 * e3,
        2 * (e1 * e2 + e3 * eta),
        2 * (e1 * e3 - e2 * eta),
    )


def sin_flight_path(e_b):
    """sin(gamma) = b1 . a1 = 1 - 2 (eB2^2 + eB3^2) (Eq. ``Ex2-EOM``, r_dot = v sin gamma)."""
    _, e2, e3, _ = e_b
    return 1 - 2 * (e2 * e2 + e3 * e3)


def _printed_a1(e_a):
    """The first row of C_AE as printed in Eq. ``Ex2-endpoint`` (unit norm assumed)."""
    e1, e2, e3, eta = e_a
    return (1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 + e3 * eta), 2 * (e1 * e3 - e2 * eta))


def _printed_a1_component(i: int):
    return lambda x0, xf, t0, tf: _printed_a1(xf[1:5])[i]


SLACK_NAMES = ("load_excess", "q_shortfall")


def control_names(config: EntryOcpConfig) -> tuple[str, ...]:
    if config.norm_mode == "projection":
        names = ("u_alpha", "u_sigma", "lambda_A", "lambda_B")
    elif config.norm_mode == "none":
        names = ("u_alpha", "u_sigma")
    else:
        names = ("u_alpha", "u_sigma", "u1", "u2", "u3", "u4")
    return names + (SLACK_NAMES if config.soft_path_penalty is not None else ())


AERO_SCALE_PARAMETERS = ("ln_drag_accel_scale", "ln_lift_to_drag_scale")


def model_of(config: EntryOcpConfig, ns, par=()):
    """The force model, with the estimated aerodynamic scales when the problem has them as parameters.

    :param par: empty, or one list ``[ln k_D, ln k_LD]`` (the logarithms of the drag-acceleration and
        lift-to-drag scale factors, :func:`~rventry_env.physics.model.with_aero_scales`).
    """
    if not par:
        return config.model
    (p,) = par
    return with_aero_scales(config.model, ns.exp(p[0]), ns.exp(p[1]))


def entry_dynamics(config: EntryOcpConfig, ns=None):
    """The dynamics callable ``(x, u, t[, p]) -> dx/dt`` of the chosen formulation."""
    ns = ns or casadi_ns()

    if config.norm_mode == "projection":

        def f(x, u, t, *par):
            d = list(entry_rhs(x, u[:2], model_of(config, ns, par), ns))
            lam_a, lam_b = u[2], u[3]
            for i in range(1, 5):  # radial rate: keeps |q_A| = 1, adds no angular velocity
                d[i] = d[i] + lam_a * x[i]
            for i in range(6, 10):
                d[i] = d[i] + lam_b * x[i]
            return d

        return f

    if config.norm_mode == "none":
        return lambda x, u, t, *par: entry_rhs(x, u[:2], model_of(config, ns, par), ns)

    def f_paper(x, u, t, *par):
        d = list(entry_rhs(x, u[:2], model_of(config, ns, par), ns))
        # Section sect:Ex2-Implementation: u1..u4 replace d(eA2), d(eA3), d(eB2), d(eB3)
        d[2], d[3], d[7], d[8] = u[2], u[3], u[4], u[5]
        return d

    return f_paper


def _rate_band(config: EntryOcpConfig, ns, state_index: int, control_index: int) -> PathConstraint:
    def fn(x, u, t, *par):
        return u[control_index] - entry_rhs(x, u[:2], model_of(config, ns, par), ns)[state_index]

    name = f"band_{ENTRY_STATE_NAMES[state_index]}"
    return PathConstraint(name, fn, lower=-config.delta, upper=config.delta, scale=config.delta)


def _entry_lagrange(config: EntryOcpConfig, soft: bool, i_slack: int):
    """The running cost, Eq. Ex2-Cost, plus the exact (L1) penalty on the slacks when the path is soft."""

    def lagrange(x, u, t, *par):
        cost = config.problem.cost_integrand(x[10], u[0], u[1])
        if soft:  # exact (L1) penalty on the relative violations, per second
            cost = cost + config.soft_path_penalty * (u[i_slack] + u[i_slack + 1])
        return cost

    return lagrange


def _entry_path(config: EntryOcpConfig, ns, soft: bool, i_slack: int) -> tuple[list, list]:
    """The path constraints, Eq. Ex2-path, and the invariants of the normalization mode.

    Alpha and the rates are bounds (see `_entry_bounds`); with ``norm_mode == "paper"`` the rate
    bands join the path constraints, with ``"projection"`` the unit norms are invariants.
    """
    if soft:
        # relative, with slacks: n / n_max - excess <= 1 and q / q_min + shortfall >= 1
        path = [
            PathConstraint("aero_accel",
                           lambda x, u, t, *par: entry_forces(x, model_of(config, ns, par), ns).aero_accel
                           / config.a_max - u[i_slack], upper=1.0),
            PathConstraint("dynamic_pressure",
                           lambda x, u, t, *par: entry_forces(x, model_of(config, ns, par), ns).dynamic_pressure
                           / max(config.problem.q_min, 1.0) + u[i_slack + 1], lower=1.0),
        ]  # fmt: skip
    else:
        path = [
            PathConstraint("aero_accel",
                           lambda x, u, t, *par: entry_forces(x, model_of(config, ns, par), ns).aero_accel,
                           upper=config.a_max, scale=config.a_max),
            PathConstraint("dynamic_pressure",
                           lambda x, u, t, *par: entry_forces(x, model_of(config, ns, par), ns).dynamic_pressure,
                           lower=config.problem.q_min, scale=1e5),
        ]  # fmt: skip
    invariants = []
    if config.norm_mode == "projection":
        invariants = [
            Invariant("unit_q_A", lambda x: x[1] * x[1] + x[2] * x[2] + x[3] * x[3] + x[4] * x[4] - 1.0),
            Invariant("unit_q_B", lambda x: x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9] - 1.0),
        ]
    elif config.norm_mode == "paper":
        path += [_rate_band(config, ns, s, c) for s, c in ((2, 2), (3, 3), (7, 4), (8, 5))]
    return path, invariants


def _entry_endpoint(config: EntryOcpConfig) -> list:
    """The endpoint constraints, Eq. Ex2-endpoint: two independent equations plus the sign.

    With ``norm_mode == "none"`` the three printed equations on a1 instead; a final
    flight-path-angle limit is appended when the configuration sets one.
    """
    target, east, north = config.target_frame()

    def along(vec):
        def fn(x0, xf, t0, tf):
            a1 = position_direction(xf[1:5])
            return a1[0] * vec[0] + a1[1] * vec[1] + a1[2] * vec[2]

        return fn

    endpoint = [
        EndpointConstraint("target_east", along(east), lower=0.0, upper=0.0),
        EndpointConstraint("target_north", along(north), lower=0.0, upper=0.0),
        EndpointConstraint("target_side", along(target), lower=0.5),
    ]
    if config.norm_mode == "none":  # Eq. Ex2-endpoint verbatim: three equations on the printed a1
        endpoint = [
            EndpointConstraint(f"endpoint_{i + 1}", _printed_a1_component(i),
                               lower=float(target[i]), upper=float(target[i]))
            for i in range(3)
        ]  # fmt: skip
    if config.final_gamma_max_deg is not None:
        limit = math.sin(config.final_gamma_max_deg * DEG)
        endpoint.append(
            EndpointConstraint("final_gamma", lambda x0, xf, t0, tf: sin_flight_path(xf[6:10]), upper=limit,
                               lower=limit if config.final_gamma_equality else -math.inf)
        )  # fmt: skip
    return endpoint


def _entry_bounds(config: EntryOcpConfig, names, soft: bool) -> dict:
    """The state, boundary and control bounds, Table tab:Ex2-BCs, and the controls' scales.

    Returned as the keyword arguments of `OptimalControlProblem` they fill.
    """
    re = config.model.planet.radius
    nan_free = math.inf
    uam, usm = config.u_alpha_max, config.u_sigma_max
    q_lo, q_hi = -1.5, 1.5  # never active: the norms are 1
    state_lower = [re - 1.0, *[q_lo] * 4, 50.0, *[q_lo] * 4, 0.0, -8 * math.pi]
    state_upper = [re + 150e3, *[q_hi] * 4, 8000.0, *[q_hi] * 4, config.alpha_max, 8 * math.pi]
    x0 = config.initial_state(0.0, 0.0)
    initial_lower = x0.copy()
    initial_upper = x0.copy()
    initial_lower[IDX.angles] = (0.0, -8 * math.pi)  # alpha(0), sigma(0) free
    initial_upper[IDX.angles] = (config.alpha_max, 8 * math.pi)
    final_lower = np.full(12, -nan_free)
    final_upper = np.full(12, nan_free)
    final_lower[0] = final_upper[0] = re + config.problem.final_altitude
    final_lower[5] = final_upper[5] = config.problem.final_speed
    final_lower[10] = final_upper[10] = config.problem.final_alpha
    if config.final_gamma_max_deg is None:
        final_lower[6] = final_upper[6] = 0.0  # eB1(tf) = 0 } vertical impact, exact
        final_lower[9] = final_upper[9] = 0.0  # etaB(tf) = 0 }
    n_extra = len(names) - 2 - (len(SLACK_NAMES) if soft else 0)
    extra_bound = 10.0 if config.norm_mode == "projection" else 1.0  # 1/s: far from any value reached
    control_lower = [-uam, -usm] + [-extra_bound] * n_extra + [0.0] * (len(names) - 2 - n_extra)
    control_upper = [uam, usm] + [extra_bound] * n_extra + [1.0] * (len(names) - 2 - n_extra)
    extra_scale = 1e-3 if config.norm_mode == "projection" else 1e-2
    slack_scale = [1e-2] * (len(names) - 2 - n_extra)
    return {
        "state_lower": state_lower,
        "state_upper": state_upper,
        "control_lower": control_lower,
        "control_upper": control_upper,
        "initial_lower": initial_lower,
        "initial_upper": initial_upper,
        "final_lower": final_lower,
        "final_upper": final_upper,
        "control_scale": [uam, usm] + [extra_scale] * n_extra + slack_scale,
    }


def entry_ocp(config: EntryOcpConfig | None = None) -> OptimalControlProblem:
    """The Example 2 optimal-control problem (see the module docstring)."""
    config = config or EntryOcpConfig()
    ns = casadi_ns()
    re = config.model.planet.radius
    names = control_names(config)
    soft = config.soft_path_penalty is not None
    i_slack = len(names) - len(SLACK_NAMES)  # where the slacks sit among the controls, when soft
    lagrange = _entry_lagrange(config, soft, i_slack)
    path, invariants = _entry_path(config, ns, soft, i_slack)
    endpoint = _entry_endpoint(config)
    bounds = _entry_bounds(config, names, soft)
    return OptimalControlProblem(
        name=f"rv-euler-entry-{config.norm_mode}",
        state_names=ENTRY_STATE_NAMES,
        control_names=names,
        dynamics=entry_dynamics(config, ns),
        t0=0.0,
        tf_lower=config.tf_bounds[0],
        tf_upper=config.tf_bounds[1],
        lagrange=lagrange,
        path_constraints=path,
        endpoint_constraints=endpoint,
        invariants=invariants,
        state_scale=[1e5, 1, 1, 1, 1, 1e4, 1, 1, 1, 1, 0.5, math.pi],
        state_shift=[re, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        control_shift=[0.0] * len(names),
        time_scale=500.0,
        cost_scale=10.0,
        parameter_names=AERO_SCALE_PARAMETERS if config.aero_scale_parameters else (),
        **bounds,
    )


__all__ = [
    "NORM_MODES",
    "EntryOcpConfig",
    "position_direction",
    "sin_flight_path",
    "control_names",
    "entry_dynamics",
    "model_of",
    "AERO_SCALE_PARAMETERS",
    "entry_ocp",
]
