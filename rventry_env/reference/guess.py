"""The initial guess of the entry problem: a simulated flight under a simple guidance law.

Nothing here is hand-typed: a batch of vehicles, one per point of a small grid of
guidance parameters, is flown through the shared RK4 and
:func:`rventry_env.physics.entry.entry_rhs` (NumPy, vectorised over the batch), and
the flight that ends closest to the terminal conditions becomes the guess.

The law (all commands reach the states through the rate controls, clipped to the
problem's rate bounds, so the guess obeys the dynamics exactly):

* glide: alpha held at alpha_bar; the vertical part of the lift tracks an altitude
  chosen so that constant-altitude drag would bleed the speed from v to ``v_dive``
  over the range left before the dive (density
  rho_req = kr 2 m ln(v / v_dive) / (S C_D (range - dive_range)), inverted through
  an exponential fit of the atmosphere); the rest of the lift goes sideways, its
  side chosen by a heading deadband (bank reversals);
* dive: inside ``dive_range`` of the target the lift is turned toward the ground
  (conventional bank 180 deg, corrected toward the target) with alpha raised to
  ``alpha_pull`` until the flight path is steep, then alpha goes to 0.

The grid spans the energy gain ``kr``, the dive range and the dive speed; the
score is miss distance / 10 km + |v - vf| / 100 m/s + |gamma + 90 deg| / 10 deg at
ground impact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.core.conversions import lift_up_angle
from rventry_env.core.euler_parameters import dcm
from rventry_env.core.integrate import rk4_step
from rventry_env.physics.entry import entry_forces, entry_rhs
from rventry_env.reference.entry_ocp import DEG, SLACK_NAMES, EntryOcpConfig

_PARAMS = ("kr", "dive_range", "v_dive")

#: the default grid: energy gain, dive range (m), dive speed (m/s)
DEFAULT_GRID = {
    "kr": (0.5, 0.7),
    "dive_range": (40e3, 70e3),
    "v_dive": (1400.0, 1700.0, 2000.0),
}


@dataclass(frozen=True)
class GuidanceGains:
    """Fixed gains of the guess law (SI).

    :param kp: altitude gain (1/s^2).
    :param kd: altitude-rate gain (1/s).
    :param deadband_deg: heading error that triggers a bank reversal.
    :param k_lateral: heading correction of the dive bank (rad/rad).
    :param alpha_pull_deg: angle of attack while pulling into the dive.
    :param rate_gain: first-order gain from command error to rate (1/s).
    :param gamma_steep_deg: flight-path angle below which alpha goes to 0.
    """

    kp: float = 0.002
    kd: float = 0.1
    deadband_deg: float = 10.0
    k_lateral: float = 1.0
    alpha_pull_deg: float = 20.0
    rate_gain: float = 0.5
    gamma_steep_deg: float = -76.0


@dataclass
class GuessFlight:
    """One simulated flight: samples up to ground impact and its terminal misses."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    params: dict
    miss_m: float
    speed_error: float
    gamma_deg: float
    score: float


def _exp_fit(config: EntryOcpConfig) -> tuple[float, float]:
    """(rho0, H) of an exponential fit of the model atmosphere between 0 and 40 km."""
    atm = config.model.atmosphere
    r0, r1 = float(atm.density(0.0, NUMPY)), float(atm.density(40e3, NUMPY))
    return r0, 40e3 / math.log(r0 / r1)


def _directions(x):
    c_ae = dcm(*x[1:5])
    c_ba = dcm(*x[6:10])
    a1 = np.array(c_ae[0])
    b1 = sum(c_ba[0][j] * np.array(c_ae[j]) for j in range(3))
    return a1, b1


def _law(x, p, state, config: EntryOcpConfig, gains: GuidanceGains, rho_fit):
    model = config.model
    re = model.planet.radius
    target = config.target_e()
    a1, b1 = _directions(x)
    r, v = x[0], x[5]
    cos_range = np.clip(target @ a1, -1.0, 1.0)
    range_left = re * np.arccos(cos_range)
    sin_g = np.sum(b1 * a1, axis=0)
    horizontal = b1 - sin_g * a1
    to_target = target[:, None] - cos_range * a1
    to_target /= np.maximum(np.linalg.norm(to_target, axis=0), 1e-12)
    right = np.cross(b1, a1, axis=0)
    right /= np.maximum(np.linalg.norm(right, axis=0), 1e-12)
    heading_error = np.arctan2(
        np.sum(to_target * right, axis=0),
        np.sum(to_target * horizontal, axis=0) / np.maximum(np.linalg.norm(horizontal, axis=0), 1e-9),
    )  # > 0: target to the right
    state["dive"] |= range_left < p["dive_range"]
    glide = ~state["dive"]
    f = entry_forces(list(x), model)
    veh = model.vehicle
    rho0, scale_h = rho_fit
    k = p["kr"] * np.log(np.maximum(v / p["v_dive"], 1.0001)) / np.maximum(range_left - p["dive_range"], 1e3)
    rho_req = k * 2.0 * veh.mass / (veh.reference_area * f.cd)
    h_ref = np.clip(scale_h * np.log(rho0 / rho_req), 15e3, 60e3)
    g = model.planet.mu / (r * r)
    # vertical lift: balance gravity less centrifugal, plus a PD pull toward h_ref
    h = r - re
    lift_up_needed = g - v * v / r * (1 - sin_g * sin_g) + gains.kp * (h_ref - h) - gains.kd * v * sin_g
    mu_glide = np.arccos(np.clip(lift_up_needed / np.maximum(f.lift_accel, 1e-3), -1.0, 1.0))
    db = gains.deadband_deg * DEG
    state["side"] = np.where(heading_error > db, 1.0, np.where(heading_error < -db, -1.0, state["side"]))
    mu = np.where(glide, state["side"] * mu_glide, math.pi - gains.k_lateral * heading_error)
    steep = sin_g < math.sin(gains.gamma_steep_deg * DEG)
    alpha_dive = np.where(steep, config.problem.final_alpha, gains.alpha_pull_deg * DEG)
    alpha_cmd = np.where(glide, config.alpha_bar, alpha_dive)
    theta_u, _ = lift_up_angle(x[6:10])
    sigma_cmd = mu + theta_u  # paper's sigma from the conventional bank (docs/conventions.md)
    sigma_cmd = x[11] + (sigma_cmd - x[11] + math.pi) % (2 * math.pi) - math.pi  # nearest turn
    u_a = np.clip(gains.rate_gain * (alpha_cmd - x[10]), -config.u_alpha_max, config.u_alpha_max)
    u_s = np.clip(gains.rate_gain * (sigma_cmd - x[11]), -config.u_sigma_max, config.u_sigma_max)
    return np.array([u_a, u_s])


def _fly_batch(config: EntryOcpConfig, p: dict, gains: GuidanceGains, dt: float, t_max: float):
    """Fly every parameter set's vehicle with RK4 steps of ``dt`` from the entry state, lift up,
    until it reaches the final altitude (crossing interpolated within the step), is lost, or ``t_max``.

    :return: ``(ts, xs, us, t_end, x_end)``: the times, states (time, 12, n) and controls of the
        steps, and each vehicle's end time and state (NaN where none ended).
    """
    n = p["kr"].size
    model = config.model
    re = model.planet.radius
    x0 = config.initial_state(config.alpha_bar, 0.0)
    theta_u, _ = lift_up_angle(x0[6:10])
    x0[11] = theta_u  # start lift up; the law banks from there
    x = np.tile(x0[:, None], (1, n))
    state = {"dive": np.zeros(n, bool), "side": np.ones(n)}
    rho_fit = _exp_fit(config)
    t = 0.0
    ts, xs, us = [0.0], [x.copy()], []
    done = np.zeros(n, bool)
    t_end = np.full(n, np.nan)
    x_end = np.full((12, n), np.nan)
    while t < t_max and not done.all():
        u = _law(x, p, state, config, gains, rho_fit)
        us.append(u)
        xn = rk4_step(lambda tt, xx, u=u: np.array(entry_rhs(list(xx), u, model)), t, x, dt)
        hit = (xn[0] < re + config.problem.final_altitude) & ~done
        if hit.any():  # linear interpolation of the ground crossing within the step
            frac = (x[0] - re - config.problem.final_altitude) / (x[0] - xn[0])
            xe = x + frac * (xn - x)
            t_end[hit] = t + frac[hit] * dt
            x_end[:, hit] = xe[:, hit]
        bad = (xn[5] < 0.25 * config.problem.final_speed) | (xn[0] > re + 150e3) | ~np.all(np.isfinite(xn), axis=0)
        lost = bad & ~done & ~hit
        t_end[lost] = t
        x_end[:, lost] = x[:, lost]
        done |= hit | lost
        x = np.where(done, x, xn)
        t += dt
        ts.append(t)
        xs.append(x.copy())
    us.append(us[-1])
    ts, xs, us = np.array(ts), np.array(xs), np.array(us)
    return ts, xs, us, t_end, x_end


def _scored_flights(config: EntryOcpConfig, p: dict, ts, xs, us, t_end, x_end) -> list[GuessFlight]:
    """Each vehicle's flight cut at its end, with its miss, final-speed error, flight-path angle and score."""
    n = p["kr"].size
    re = config.model.planet.radius
    a1, b1 = _directions(x_end)
    miss = re * np.arccos(np.clip(config.target_e() @ a1, -1.0, 1.0))
    gamma = np.degrees(np.arcsin(np.clip(np.sum(a1 * b1, axis=0), -1.0, 1.0)))
    flights = []
    for i in range(n):
        if not np.isfinite(t_end[i]):
            t_end[i], x_end[:, i] = ts[-1], xs[-1, :, i]
        k = int(np.searchsorted(ts, t_end[i]))
        t_i = np.append(ts[:k], t_end[i])
        x_i = np.vstack([xs[:k, :, i], x_end[:, i]])
        u_i = us[: k + 1, :, i]
        speed_err = abs(float(x_end[5, i]) - config.problem.final_speed)
        score = miss[i] / 10e3 + speed_err / 100.0 + abs(gamma[i] + 90.0) / 10.0
        if not np.isfinite(score):
            score = math.inf
        flights.append(
            GuessFlight(t_i, x_i, u_i, {k_: float(v[i]) for k_, v in p.items()}, float(miss[i]), speed_err,
                        float(gamma[i]), float(score))
        )  # fmt: skip
    return flights


def simulate_batch(
    config: EntryOcpConfig,
    params: dict,
    gains: GuidanceGains = GuidanceGains(),
    dt: float = 1.0,
    t_max: float = 2500.0,
) -> list[GuessFlight]:
    """Fly one vehicle per parameter set (arrays in ``params`` broadcast together).

    :param config: the entry problem (initial state, bounds, target, model).
    :param params: ``kr``, ``dive_range`` (m), ``v_dive`` (m/s), scalars or arrays.
    :param gains: the fixed gains.
    :param dt: RK4 step (s).
    :param t_max: give up after this time (s).
    :return: one :class:`GuessFlight` per parameter set, in broadcast order.
    """
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    arrays = np.broadcast_arrays(*[np.asarray(params[k], dtype=float) for k in _PARAMS])
    p = {k: a.ravel() for k, a in zip(("kr", "dive_range", "v_dive"), arrays)}
    ts, xs, us, t_end, x_end = _fly_batch(config, p, gains, dt, t_max)
    return _scored_flights(config, p, ts, xs, us, t_end, x_end)


def extra_controls(config: EntryOcpConfig, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Values of the formulation's extra controls along a simulated flight.

    ``projection``: lambda_A = lambda_B = 0 (the simulation keeps the norms);
    ``none``: no extra controls;
    ``paper``: u1..u4 = the Eq. ``Ex2-EOM`` rates of eA2, eA3, eB2, eB3.
    """
    if config.norm_mode == "projection":
        return np.zeros((x.shape[0], 2))
    if config.norm_mode == "none":
        return np.zeros((x.shape[0], 0))
    d = np.array(entry_rhs(list(x.T), list(u.T), config.model))
    return d[[2, 3, 7, 8]].T


def generate_guess(
    config: EntryOcpConfig | None = None,
    grid: dict | None = None,
    gains: GuidanceGains = GuidanceGains(),
    dt: float = 1.0,
):
    """The best simulated flight of the grid, as a collocation guess.

    :param config: the entry problem.
    :param grid: parameter values per name (default :data:`DEFAULT_GRID`); the
        full tensor grid is flown in one batch.
    :param gains: the fixed gains.
    :param dt: RK4 step (s).
    :return: ``(guess, flight)``: a :class:`~.collocation.SampledGuess`
        with the formulation's controls and the chosen :class:`GuessFlight`.
    """
    from rventry_env.reference.collocation import SampledGuess

    config = config or EntryOcpConfig()
    grid = dict(DEFAULT_GRID if grid is None else grid)
    missing = {"kr", "dive_range", "v_dive"} - set(grid)
    if missing:
        raise ValueError(f"the guess grid lacks {sorted(missing)}")
    axes = np.meshgrid(*[np.asarray(grid[k], dtype=float) for k in _PARAMS], indexing="ij")
    flights = simulate_batch(config, dict(zip(("kr", "dive_range", "v_dive"), axes)), gains, dt)
    best = min(flights, key=lambda f: f.score)
    if not math.isfinite(best.score):
        raise RuntimeError("no simulated flight of the guess grid reached the ground")
    u = np.hstack([best.u, extra_controls(config, best.x, best.u)])
    return SampledGuess(best.t, best.x, u), best


class ReferenceGuess:
    """A solved trajectory as the guess for the problem ``config`` poses: the shipped optimum
    (:func:`~rventry_env.reference.load_reference`) or a collocation solution, in any norm-keeping
    formulation.

    States and (u_alpha, u_sigma) come from the trajectory's polynomials; the formulation's extra
    controls are :func:`extra_controls` along it, the rule the generated guess follows (lambda = 0
    for ``projection``, the Eq. ``Ex2-EOM`` rates for ``paper``, none for ``none``), so the guess
    obeys every formulation's dynamics where the trajectory obeys ``entry_rhs``. Where the path
    constraints are soft (``soft_path_penalty``), their slacks start at zero: the path as the
    trajectory flew it, feasible or not under the problem's bounds.

    :param reference: anything with ``t0``, ``tf``, ``state(t)`` and ``control(t)`` whose first two
        controls are (u_alpha, u_sigma).
    :param config: the problem the guess is for (default :class:`EntryOcpConfig`).
    """

    def __init__(self, reference, config: EntryOcpConfig | None = None):
        self.config = config or EntryOcpConfig()
        self.slacks = len(SLACK_NAMES) if self.config.soft_path_penalty is not None else 0
        self.reference = reference

    @property
    def t0(self) -> float:
        return float(self.reference.t0)

    @property
    def tf(self) -> float:
        return float(self.reference.tf)

    def state(self, t) -> np.ndarray:
        return np.atleast_2d(self.reference.state(np.atleast_1d(np.asarray(t, dtype=float))))

    def control(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = self.state(t)
        u = np.atleast_2d(self.reference.control(t))[:, :2]
        return np.hstack([u, extra_controls(self.config, x, u), np.zeros((t.size, self.slacks))])


__all__ = [
    "DEFAULT_GRID",
    "ReferenceGuess",
    "GuidanceGains",
    "GuessFlight",
    "simulate_batch",
    "extra_controls",
    "generate_guess",
]
