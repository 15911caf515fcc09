"""Replay a record: fly the rv-Euler entry model with the record's controls.

The state is integrated with the classical RK4 on a grid of steps no longer than ``h_max``
whose nodes fall on sample times wherever the sampling allows (every sample of a 1 Hz record
at ``h_max`` = 1 s, every tenth of a 10 Hz record). Samples between nodes are read from the
cubic Hermite interpolant of the node states and their derivatives, which is fourth-order
like the steps themselves, so a dense record costs no more steps than a sparse one.

Two evaluations share the grid, the controls and the interpolation:

* :meth:`Replay.predict` flies any :class:`~rventry_env.physics.EntryModel` (NumPy, batched
  over a trailing axis), through :func:`~rventry_env.physics.entry_rhs` and the project's
  :func:`~rventry_env.core.integrate.rk4_step`;
* :mod:`~rventry_env.validation.replay.sensitivity` builds the same step from the same ``entry_rhs``
  in CasADi and propagates its exact derivatives, which is what the fits use.

The angle of attack and the paper's bank angle sigma are not integrated: they are set from the
record at every evaluation (sigma from the conventional mu and the current velocity frame), so
only the 10 rv-Euler parameters are states here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rventry_env.core.conversions import (
    cartesian_from_rv_euler,
    lift_up_angle,
    rv_euler_from_cartesian,
    rv_euler_from_spherical,
)
from rventry_env.core.integrate import rk4_step
from rventry_env.physics import EntryModel, entry_rhs
from rventry_env.validation.record import FlightRecord, RecordError
from rventry_env.validation.replay.controls import ControlSchedule
from rventry_env.validation.replay.replay_setup import ReplaySetup

N_RV = 10  # rv-Euler parameters integrated (alpha and sigma come from the record)
MAX_RK4_STEPS = 50_000  # a bound on the work of one replay
TIME_OFFSET = "time_offset_s"  # the parameter of a record's time-tag offset (:meth:`Replay.shifted_controls`)


@dataclass(frozen=True)
class InitialState:
    """How the fitted initial-state offsets map to rv-Euler parameters.

    ECEF records: 6 offsets (position m, velocity m/s) from the first complete
    measured sample. Reduced records: offsets of altitude (m), speed (m/s) and
    flight-path angle (rad) from the sidecar's entry state; longitude, latitude and
    azimuth stay declared (a reduced record barely observes them).
    """

    kind: str
    reference: np.ndarray  # ECEF (6,) or spherical (6,)
    names: tuple
    scales: np.ndarray  # typical size of each offset (for scaling)

    @property
    def size(self) -> int:
        return len(self.names)

    def rv_euler(self, offsets: np.ndarray) -> np.ndarray:
        """rv-Euler parameters ``(10, B)`` for offsets ``(B, size)``."""
        offsets = np.atleast_2d(offsets)
        if self.kind == "ecef":
            s = self.reference[None, :] + offsets
            x = rv_euler_from_cartesian(s[:, :3], s[:, 3:])
        else:
            s = np.repeat(self.reference[None, :], len(offsets), axis=0)
            s[:, 0] += offsets[:, 0]
            s[:, 3] += offsets[:, 1]
            s[:, 4] += offsets[:, 2]
            x = rv_euler_from_spherical(s)
        return x.T.copy()

    def jacobian(self, offsets: np.ndarray) -> np.ndarray:
        """d(rv-Euler parameters)/d(offsets) ``(10, size)`` by central differences.

        The map is a smooth closed-form conversion, so differences with steps of 1e-3 of each
        offset's scale are exact to about 1e-9 relative.
        """
        offsets = np.asarray(offsets, float)
        step = 1e-3 * self.scales
        zs = np.repeat(offsets[None, :], 2 * self.size, axis=0)
        for i in range(self.size):
            zs[2 * i, i] += step[i]
            zs[2 * i + 1, i] -= step[i]
        x = self.rv_euler(zs)
        jac = (x[:, 0::2] - x[:, 1::2]) / (2 * step[None, :])
        # the Euler parameters' sign is fixed by the conversion; guard against a flip between members
        return jac


def initial_state(record: FlightRecord, setup: ReplaySetup, t0_row: int) -> InitialState:
    """The initial-state parameterization for a record (see :class:`InitialState`)."""
    if record.kind == "ecef":
        ref = record.observations[t0_row].copy()
        return InitialState("ecef", ref, ("dx0_m", "dy0_m", "dz0_m", "dvx0_mps", "dvy0_mps", "dvz0_mps"),
                            np.array([100.0] * 3 + [1.0] * 3))  # fmt: skip
    es = setup.entry_state
    ref = np.array([setup.model.planet.radius + es.altitude, es.longitude, es.latitude, es.speed,
                    es.flight_path, es.azimuth])  # fmt: skip
    return InitialState("reduced", ref, ("dh0_m", "dv0_mps", "dgamma0_rad"), np.array([100.0, 1.0, 1e-3]))


@dataclass(frozen=True)
class Grid:
    """RK4 nodes and where every observed sample falls between them.

    :param nodes: node times ``(N + 1,)``.
    :param step: of each observed sample, the step it falls in ``(n_obs,)``.
    :param tau: its position in that step, 0 (start) to 1 (end).
    """

    nodes: np.ndarray
    step: np.ndarray
    tau: np.ndarray

    @property
    def h(self) -> np.ndarray:
        return np.diff(self.nodes)

    @property
    def n_steps(self) -> int:
        return len(self.nodes) - 1


def make_grid(t0: float, t_obs: np.ndarray, h_max: float) -> Grid:
    """Nodes from ``t0`` through the last sample: on sample times where the sampling allows, no
    step longer than ``h_max``; a longer gap between samples is divided evenly."""
    nodes = [float(t0)]
    last_in_reach = None  # latest sample time within h_max of the last node
    eps = 1e-9 * max(1.0, h_max)
    for t in np.asarray(t_obs, float):
        if t - nodes[-1] <= eps:
            continue
        while t - nodes[-1] > h_max + eps:
            if last_in_reach is not None and last_in_reach > nodes[-1] + eps:
                nodes.append(last_in_reach)
                last_in_reach = None
                continue
            n = math.ceil((t - nodes[-1]) / h_max - 1e-9)
            nodes.extend(np.linspace(nodes[-1], t, n + 1)[1:].tolist())
            last_in_reach = None
        if t - nodes[-1] > eps:
            last_in_reach = float(t)
    if last_in_reach is not None and last_in_reach > nodes[-1] + eps:
        nodes.append(last_in_reach)
    if len(nodes) < 2:
        nodes.append(nodes[0] + min(h_max, 1.0))
    g = np.array(nodes)
    step = np.clip(np.searchsorted(g, t_obs, side="right") - 1, 0, len(g) - 2)
    tau = np.clip((t_obs - g[step]) / (g[step + 1] - g[step]), 0.0, 1.0)
    return Grid(g, step, tau)


def inertial_speed(rx, ry, vx, vy, vz, omega: float, sqrt=np.sqrt):
    """|v_E + w x r| with w = (0, 0, omega): the inertial speed of an ECEF position and Earth-relative velocity.

    Plain component arithmetic, so NumPy arrays and CasADi symbols (``sqrt=casadi.sqrt``) share it:
    the replay and its exact sensitivities observe the same function.
    """
    ix, iy = vx - omega * ry, vy + omega * rx
    return sqrt(ix * ix + iy * iy + vz * vz)


def hermite_weights(tau: np.ndarray, h: np.ndarray) -> tuple:
    """Cubic Hermite weights of (x_k, f_k, x_k+1, f_k+1), derivative weights scaled by the step."""
    t2, t3 = tau * tau, tau * tau * tau
    return (2 * t3 - 3 * t2 + 1, (t3 - 2 * t2 + tau) * h, -2 * t3 + 3 * t2, (t3 - t2) * h)


class Replay:
    """Replays of one record.

    :param record: the validated record.
    :param setup: the declared vehicle and entry state.
    :param controls: the control histories.
    :param h_max: longest RK4 step (s).
    """

    def __init__(
        self, record: FlightRecord, setup: ReplaySetup, controls: ControlSchedule, h_max: float = 1.0
    ):
        if not (math.isfinite(h_max) and h_max > 0):
            raise ValueError(f"h_max must be a positive number of seconds, got {h_max!r}")
        self.record = record
        self.setup = setup
        self.controls = controls
        self.h_max = float(h_max)
        self.notes: list[str] = []
        obs = record.observations
        if record.kind == "ecef":
            full = np.flatnonzero(np.all(np.isfinite(obs), axis=1))
            if full.size == 0:
                raise RecordError(
                    "no row has the complete ECEF state (x_m .. vz_mps) to start the replay from"
                )
            t0_row = int(full[0])
            t0 = float(record.t[t0_row])
        else:
            t0 = setup.entry_state.t
            later = np.flatnonzero(record.t >= t0 - 1e-9)
            if later.size == 0:
                raise RecordError(f"sidecar: entry_state.t_s = {t0:g} is after the last row of the record")
            t0_row = int(later[0])
        self.t0 = t0
        rows = record.observed_rows
        early = rows[record.t[rows] < t0 - 1e-9]
        if early.size:
            self.notes.append(f"{early.size} observed row(s) before the start t = {t0:g} s ignored")
        self.rows = rows[record.t[rows] >= t0 - 1e-9]
        if self.rows.size < 3:
            raise RecordError("fewer than 3 observed rows after the start of the replay")
        self.init = initial_state(record, setup, t0_row)
        self.y = obs[self.rows].copy()  # (n, m) measured, NaN in gaps and rejected values
        self.t_obs = record.t[self.rows]
        span = float(self.t_obs[-1] - t0)
        if span / self.h_max > MAX_RK4_STEPS:
            raise RecordError(
                f"column t_s: {span:g} s from the start to the last observation would take "
                f"{span / self.h_max:.0f} RK4 steps of {self.h_max:g} s (at most {MAX_RK4_STEPS}); "
                "check the time unit or raise --h-max"
            )
        self.grid = make_grid(t0, self.t_obs, self.h_max)
        g = self.grid.nodes
        h = self.grid.h
        self.stage_times = np.stack([g[:-1], g[:-1] + 0.5 * h, g[1:]])  # (3, N)
        alpha, mu = controls.many(self.stage_times)
        self.stage_controls = np.concatenate([alpha, mu])  # (6, N): alpha at 3 stages, then mu
        a_end, m_end = controls.many(np.array([g[-1]]))
        self.end_controls = np.array([a_end[0], m_end[0]])
        self._shifted: dict = {}

    def shifted_controls(self, time_offset: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The controls with the record's time tags ``time_offset`` (s) early, and their time derivatives.

        A record whose state rows are tagged ``time_offset`` early (the row of time t holds the state
        flown at t + time_offset, the controls keeping their own time) is replayed on its own tags
        with the controls of t + time_offset at every RK4 stage t.

        :return: stage controls ``(6, N)`` and end controls ``(2,)`` as :attr:`stage_controls` and
            :attr:`end_controls`, then their time derivatives alike (rad/s). The last offset asked
            for is kept (a fit asks for the same point's value and Jacobian).
        """
        key = float(time_offset)
        hit = self._shifted.get(key)
        if hit is None:
            t = self.stage_times + key
            te = np.array([self.grid.nodes[-1] + key])
            alpha, mu = self.controls.many(t)
            d_alpha, d_mu = self.controls.rates(t)
            a_end, m_end = self.controls.many(te)
            da_end, dm_end = self.controls.rates(te)
            hit = (np.concatenate([alpha, mu]), np.array([a_end[0], m_end[0]]),
                   np.concatenate([d_alpha, d_mu]), np.array([da_end[0], dm_end[0]]))  # fmt: skip
            self._shifted = {key: hit}
        return hit

    # ------------------------------------------------------------------ NumPy replay of any model

    def rhs(self, model: EntryModel, time_offset: float = 0.0):
        """dx/dt for rv-Euler states ``(10, B)`` with the record's controls (read ``time_offset`` s later)."""
        ctrl = self.controls

        def f(t, x):
            theta_u, _ = lift_up_angle((x[6], x[7], x[8], x[9]))
            alpha, mu = ctrl.at(t + time_offset if time_offset else t)
            sigma = mu + theta_u  # the paper's sigma from the conventional mu, at this state
            d = entry_rhs((*x, alpha, sigma), (0.0, 0.0), model)
            out = np.empty_like(x)
            for i in range(N_RV):
                out[i] = d[i]
            return out

        return f

    def node_states(self, model: EntryModel, x0: np.ndarray, time_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """States and their derivatives at the nodes, each ``(N + 1, 10, B)`` (the controls read
        ``time_offset`` s later, :meth:`shifted_controls`)."""
        f = self.rhs(model, time_offset)
        g = self.grid.nodes
        x = np.array(x0, dtype=float)
        xs = np.empty((len(g),) + x.shape)
        fs = np.empty_like(xs)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            for k in range(len(g) - 1):
                k1 = f(g[k], x)
                xs[k], fs[k] = x, k1
                x = rk4_step(f, g[k], x, g[k + 1] - g[k], k1=k1)
                # the Euler parameters are unit by construction; RK4 lets their norms drift,
                # so project back (the dynamics assume unit norms, docs/conventions.md)
                x[1:5] /= np.sqrt(np.sum(x[1:5] ** 2, axis=0))
                x[6:10] /= np.sqrt(np.sum(x[6:10] ** 2, axis=0))
            xs[-1], fs[-1] = x, f(g[-1], x)
        return xs, fs

    @cached_property
    def hermite_matrix(self):
        """The cubic Hermite interpolation as a sparse ``(n_obs, 2 (N + 1))`` matrix on ``[xs; fs]``.

        Fixed by the grid: every observed sample is a combination of four rows (the node states and
        derivatives at both ends of its step), so interpolating node arrays of any trailing shape is
        one sparse product instead of four gathered copies per sample.
        """
        from scipy.sparse import csr_matrix

        g = self.grid
        k, n_nodes = g.step, len(g.nodes)
        w = hermite_weights(g.tau, g.h[k])
        rows = np.repeat(np.arange(len(k)), 4)
        cols = np.stack([k, n_nodes + k, k + 1, n_nodes + k + 1], axis=1).ravel()
        return csr_matrix((np.stack(w, axis=1).ravel(), (rows, cols)), shape=(len(k), 2 * n_nodes))

    def interpolate(self, xs: np.ndarray, fs: np.ndarray) -> np.ndarray:
        """States at the observed samples from node states and derivatives ``(N + 1, ...)`` (cubic Hermite)."""
        stacked = np.concatenate([xs, fs]).reshape(2 * len(xs), -1)
        return np.asarray(self.hermite_matrix @ stacked).reshape((-1,) + xs.shape[1:])

    def states(self, model: EntryModel, x0: np.ndarray, time_offset: float = 0.0) -> np.ndarray:
        """rv-Euler states at the observed samples, ``(n_obs, 10, B)``, for initial states ``x0 (10, B)``."""
        return self.interpolate(*self.node_states(model, x0, time_offset))

    def observe(self, states: np.ndarray, model: EntryModel) -> np.ndarray:
        """Predicted observations ``(n_obs, m, B)`` from :meth:`states`."""
        if self.record.kind == "ecef" or self.record.speed_frame == "inertial":
            xs = np.moveaxis(states, 1, -1).copy()  # (n, B, 10)
            xs[..., 1:5] /= np.linalg.norm(xs[..., 1:5], axis=-1, keepdims=True)
            xs[..., 6:10] /= np.linalg.norm(xs[..., 6:10], axis=-1, keepdims=True)
            r_e, v_e = cartesian_from_rv_euler(xs)
            if self.record.kind == "ecef":
                return np.moveaxis(np.concatenate([r_e, v_e], axis=-1), -1, 1)
            speed = inertial_speed(r_e[..., 0], r_e[..., 1], *np.moveaxis(v_e, -1, 0), model.planet.omega)  # (n, B)
            return np.stack([states[:, 0] - model.planet.radius, speed], axis=1)
        return np.stack([states[:, 0] - model.planet.radius, states[:, 5]], axis=1)

    def predict(self, model: EntryModel, offsets: np.ndarray, time_offset: float = 0.0) -> np.ndarray:
        """Predicted observations ``(n_obs, m, B)`` for initial-state offsets ``(B, n_init)``, the record's
        time tags ``time_offset`` s early (:meth:`shifted_controls`)."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return self.observe(self.states(model, self.init.rv_euler(offsets), time_offset), model)


__all__ = ["MAX_RK4_STEPS", "TIME_OFFSET", "Grid", "InitialState", "Replay", "hermite_weights", "inertial_speed", "initial_state",
           "make_grid"]
