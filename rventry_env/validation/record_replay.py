"""Replay a record: fly the rv-Euler entry model with the record's controls, many models at once.

The state is integrated with the project's one RK4 (:func:`~rventry_env.core.integrate.rk4_step`)
on a grid whose nodes include every observed sample time, so predictions need
no interpolation. All arrays carry a trailing batch axis: one replay flies B
initial states and B parameter sets of the force-model parts together (the parts
accept per-member NumPy arrays), which is how a finite-difference Jacobian costs
about as much as one trajectory.

The angle of attack and the paper's bank angle sigma are not integrated: they are
set from the record at every evaluation (sigma from the conventional mu and the
current velocity frame), so only the 10 rv-Euler parameters are states here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.core.conversions import (
    cartesian_from_rv_euler,
    lift_up_angle,
    rv_euler_from_cartesian,
    rv_euler_from_spherical,
)
from rventry_env.core.integrate import rk4_step
from rventry_env.physics import EntryModel, entry_rhs
from rventry_env.validation.controls import ControlSchedule
from rventry_env.validation.record import FlightRecord, RecordError
from rventry_env.validation.replay_setup import ReplaySetup

N_RV = 10  # rv-Euler parameters integrated (alpha and sigma come from the record)


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
    scales: np.ndarray  # typical size of each offset (for scaling and finite differences)

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


class Replay:
    """Batched replays of one record.

    :param record: the validated record.
    :param setup: the declared vehicle and entry state.
    :param controls: the control histories.
    :param h_max: longest RK4 step (s); the grid also has a node at every observed sample.
    """

    def __init__(
        self, record: FlightRecord, setup: ReplaySetup, controls: ControlSchedule, h_max: float = 1.0
    ):
        self.record = record
        self.controls = controls
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
                raise RecordError(f"the entry state's t_s = {t0:g} is after the last row")
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
        self.y = obs[self.rows]  # (n, m) measured, NaN in gaps
        self.t_obs = record.t[self.rows]
        self.grid, self.node_of_row = _grid(t0, self.t_obs, h_max)

    def rhs(self, model: EntryModel):
        """dx/dt for rv-Euler states ``(10, B)`` with the record's controls."""
        ctrl = self.controls

        def f(t, x):
            theta_u, _ = lift_up_angle((x[6], x[7], x[8], x[9]))
            alpha, mu = ctrl.at(t)
            sigma = mu + theta_u  # the paper's sigma from the conventional mu, at this state
            d = entry_rhs((*x, alpha, sigma), (0.0, 0.0), model)
            out = np.empty_like(x)
            for i in range(N_RV):
                out[i] = d[i]
            return out

        return f

    def states(self, model: EntryModel, x0: np.ndarray) -> np.ndarray:
        """rv-Euler states at the observed samples, ``(n_obs, 10, B)``, for initial states ``x0 (10, B)``."""
        f = self.rhs(model)
        g = self.grid
        out = np.empty((len(self.node_of_row), N_RV) + x0.shape[1:])
        x = np.array(x0, dtype=float)
        k_out = 0
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if self.node_of_row[0] == 0:
                out[0] = x
                k_out = 1
            for k in range(len(g) - 1):
                x = rk4_step(f, g[k], x, g[k + 1] - g[k])
                # the Euler parameters are unit by construction; RK4 lets their norms drift,
                # so project back (the dynamics assume unit norms, PROBLEM.md)
                x[1:5] /= np.sqrt(np.sum(x[1:5] ** 2, axis=0))
                x[6:10] /= np.sqrt(np.sum(x[6:10] ** 2, axis=0))
                while k_out < len(self.node_of_row) and self.node_of_row[k_out] == k + 1:
                    out[k_out] = x
                    k_out += 1
        return out

    def observe(self, states: np.ndarray, model: EntryModel) -> np.ndarray:
        """Predicted observations ``(n_obs, m, B)`` from :meth:`states`."""
        if self.record.kind == "ecef":
            xs = np.moveaxis(states, 1, -1)  # (n, B, 10)
            r_e, v_e = cartesian_from_rv_euler(xs)
            return np.moveaxis(np.concatenate([r_e, v_e], axis=-1), -1, 1)
        return np.stack([states[:, 0] - model.planet.radius, states[:, 5]], axis=1)

    def predict(self, model: EntryModel, offsets: np.ndarray) -> np.ndarray:
        """Predicted observations ``(n_obs, m, B)`` for initial-state offsets ``(B, n_init)``."""
        return self.observe(self.states(model, self.init.rv_euler(offsets)), model)


def _grid(t0: float, t_obs: np.ndarray, h_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Integration nodes from t0 through every observed time, no step longer than h_max."""
    nodes = [t0]
    node_of_row = np.empty(len(t_obs), dtype=int)
    for i, t in enumerate(t_obs):
        if t - nodes[-1] > 1e-9:
            n = max(1, math.ceil((t - nodes[-1]) / h_max - 1e-9))
            nodes.extend(np.linspace(nodes[-1], t, n + 1)[1:].tolist())
        node_of_row[i] = len(nodes) - 1
    return np.array(nodes), node_of_row


__all__ = ["InitialState", "initial_state", "Replay"]
