"""Exact sensitivities of the RK4 replay: CasADi forward-mode derivatives of every step.

For one set of effects, the replay's step is built symbolically from the one copy of the physics
(:func:`~rventry_env.physics.entry_rhs` on CasADi symbols, the force-model parts taking symbolic
parameters) and the same RK4 stages, Euler-parameter projection and control handling as
:class:`~rventry_env.validation.replay.record_replay.Replay`. Forward-mode automatic differentiation
(``jtimes``) carries the sensitivity matrix S = dx/d(theta) through every step along with the
state, so the Jacobian of the discrete replay is exact (not a finite difference of it). Its cost
grows with the number of columns of S (an 82-column trace step is about 14 times a 7-column
one), so with more than :data:`REVERSE_ABOVE` columns (entry state and free parameters) the step's own Jacobian
d(x_next)/d(x, p) is taken by reverse mode instead (one sweep per state, whatever the number of
parameters) and chained, S_next = dx_next/dx S + [0, dx_next/dp]: the same derivative, equal to
rounding (1e-14 relative), at a third to a quarter of the cost for the trace's 32- to 71-column
replays. ``mapaccum`` runs the steps in CasADi's virtual machine without a Python loop.

A record's time offset (the parameter ``time_offset_s``, :mod:`~rventry_env.validation.search.effects`)
is not a force: it moves the controls along the record's time. Each replay reads them at the fitted
offset (:meth:`~rventry_env.validation.replay.record_replay.Replay.shifted_controls`), with their time
derivatives, and the step flies ``c + (p - tau) dc/dt`` at ``p = tau``: the controls' values, and
the exact derivative in the offset.

Observed samples between nodes come from the same cubic Hermite interpolant as the NumPy
replay, applied to the states and to their sensitivities.

:meth:`SensitivityReplay.predict` flies the same step expressions without their derivatives, for
the trial points a fit rejects without needing their Jacobian: its numbers are those of
:meth:`SensitivityReplay.evaluate` bit for bit (the same operations on the same values), at about
a tenth of the cost. The observation function's identical subexpressions are merged (CasADi's
``cse``, which merges only identical operations on identical operands, so no value changes); the
step's are not, since merging them costs more at the build than it saves over a fit's replays.
"""

from __future__ import annotations

import numpy as np

from rventry_env.core.backend import casadi_ns
from rventry_env.core.conversions import lift_up_angle
from rventry_env.core.euler_parameters import dcm
from rventry_env.physics import entry_rhs
from rventry_env.validation.replay.record_replay import N_RV, TIME_OFFSET, Replay, inertial_speed


def _dense(*exprs, cse: bool = False) -> list:
    """Outputs with every entry stored: a function buffer writes only the stored (nonzero) ones.

    With ``cse``, identical subexpressions are merged first (the values are unchanged).
    """
    import casadi as ca

    out = [ca.densify(e) for e in exprs]
    return ca.cse(out) if cse else out


def _call(buffer, args, results) -> None:
    """Evaluate a CasADi function buffer on NumPy arrays, writing into ``results`` in place.

    Arguments are copied to contiguous float64, with every column a mapped function expects
    (a buffer does not repeat a single column); every result must be a C-contiguous float64 view
    laid out as CasADi's column-major output.
    """
    buf, run = buffer
    keep = [np.ascontiguousarray(a, dtype=float) for a in args]  # alive until the call returns
    for i, a in enumerate(keep):
        buf.set_arg(i, memoryview(a))
    for i, r in enumerate(results):
        buf.set_res(i, memoryview(r))
    run()


def _dcm_and_partials(e1, e2, e3, eta) -> tuple[np.ndarray, np.ndarray]:
    """C_BA of unit Euler parameters (:func:`~rventry_env.core.euler_parameters.dcm`), each ``(n,)``, as
    ``(3, 3, n)``, and its partial derivatives in (e1, e2, e3, eta), ``(3, 3, 4, n)`` (quadratic entries)."""
    z = np.zeros_like(e1)
    a, b, g, d = 2 * e1, 2 * e2, 2 * e3, 2 * eta
    c = np.array(dcm(e1, e2, e3, eta))
    dc = np.array([
        [[z, -2 * b, -2 * g, z], [b, a, d, g], [g, -d, a, -b]],
        [[b, a, -d, -g], [-2 * a, z, -2 * g, z], [d, g, b, a]],
        [[g, d, a, b], [-d, g, b, -a], [-2 * a, -2 * b, z, z]],
    ])  # fmt: skip
    return c, dc


def _through_normalization(m: np.ndarray, q: np.ndarray, norm: np.ndarray) -> np.ndarray:
    """``m`` ``(3, 4, n)``, a derivative in the unit parameters ``q`` ``(4, n)``, as one in the parameters before
    their normalization by ``norm``: m (I - q q^T) / |q|."""
    mq = np.einsum("jkn,kn->jn", m, q)
    return (m - mq[:, None, :] * q[None, :, :]) / norm


def ecef_observation_jacobian(x: np.ndarray) -> np.ndarray:
    """d(ECEF position, velocity)/d(rv-Euler state) at states ``x`` ``(n, 10)``, as ``(n, 10, 6)`` (state, observation).

    The observation is r_E = r C_AE[0] and v_E = v C_BA[0] C_AE with both Euler-parameter sets
    normalized (the sensitivity replay's ``observe``); its derivative is written out (the DCM is
    quadratic in the parameters, the normalization's derivative is (I - q q^T) / |q|) and
    evaluated on all samples at once, instead of a symbolic Jacobian per sample: the same
    derivative to rounding, at a fraction of the cost on a dense record.
    """
    xt = np.ascontiguousarray(np.asarray(x, float).T)  # (10, n): every quantity a row over the samples
    na = np.sqrt(np.sum(xt[1:5] ** 2, axis=0))
    nb = np.sqrt(np.sum(xt[6:10] ** 2, axis=0))
    qa, qb = xt[1:5] / na, xt[6:10] / nb
    c_ae, dc_ae = _dcm_and_partials(*qa)
    c_ba, dc_ba = _dcm_and_partials(*qb)
    first = c_ba[0]  # (3, n)
    r, v = xt[0], xt[5]
    out = np.zeros((x.shape[0], N_RV, 6))
    out[:, 0, :3] = c_ae[0].T
    out[:, 5, 3:] = np.einsum("in,ijn->nj", first, c_ae)
    out[:, 1:5, :3] = (r * _through_normalization(dc_ae[0], qa, na)).T
    along = first[0] * dc_ae[0] + first[1] * dc_ae[1] + first[2] * dc_ae[2]  # (3, 4, n): d(C_BA[0] C_AE)/dq_a
    out[:, 1:5, 3:] = (v * _through_normalization(along, qa, na)).T
    across = np.einsum("ikn,ijn->jkn", dc_ba[0], c_ae)  # d(C_BA[0])/dq_b C_AE
    out[:, 6:10, 3:] = (v * _through_normalization(across, qb, nb)).T
    return out


# more sensitivity columns (entry state and free parameters) than this: the step's Jacobian by reverse mode
# (one sweep per state, whatever the number of columns), chained with the sensitivities; fewer: forward mode
# along them. On a 300-step replay forward mode costs about 6 ms per column (48 ms at 8, 80 ms at 14, 101 ms
# at 18), reverse mode about 48 ms from 8 to 14 columns and 53 ms at 18: they cross at 8
REVERSE_ABOVE = 8


def _chain(e, z, nx: int, s, n_init: int):
    """d(e)/d(theta) = de/dx S + [0, de/dp], with z = (x, p) and x its first ``nx`` entries; the
    Jacobians of ``e`` by reverse mode (one sweep per entry of e)."""
    import casadi as ca

    jac = ca.jtimes(e, z, ca.SX.eye(e.shape[0]), True).T  # (n_e, n_x + n_p)
    return ca.mtimes(jac[:, :nx], s) + ca.horzcat(ca.SX.zeros(e.shape[0], n_init), jac[:, nx:])


class SensitivityReplay:
    """The replay of one record for one model structure, with its exact Jacobian.

    :param replay: the record's replay (grid, controls, initial-state map).
    :param build: ``build(values) -> EntryModel`` for a dict of parameter values (CasADi
        symbols here).
    :param names: the free model parameters, in order.
    :param forcing: an extra specific force added to the model's (the residual trace,
        :mod:`~rventry_env.validation.trace.forcing`): ``forcing.n_inputs`` known values per RK4
        stage (``forcing.stage_inputs``, ``(3 n_inputs, N)``; ``forcing.end_inputs`` at the last
        node) and ``forcing.forces(x, model, values, inputs, theta_u, ns) -> (model, forces)``.
    """

    def __init__(self, replay: Replay, build, names: tuple, forcing=None):
        import casadi as ca

        self.replay = replay
        self.names = tuple(names)
        ns = casadi_ns()
        n_init = replay.init.size
        n_p = len(self.names)
        self.n_sens = n_init + n_p
        x = ca.SX.sym("x", N_RV)
        p = ca.SX.sym("p", n_p)
        h = ca.SX.sym("h")
        self.forcing = forcing
        q = 0 if forcing is None else forcing.n_inputs
        # the record's time offset: the controls at every stage are read that much later, c(t + tau); the
        # stage inputs then hold c and dc/dt at the fitted tau and tau itself, and the step flies
        # c + (p_tau - tau) dc/dt: the same value (p_tau - tau is 0), with the exact derivative in tau
        self._i_tau = self.names.index(TIME_OFFSET) if TIME_OFFSET in self.names else None
        n_tau = 0 if self._i_tau is None else 7  # the 6 stage control rates and tau
        u = ca.SX.sym("u", 6 + 3 * q + n_tau)
        s = ca.SX.sym("S", N_RV, self.n_sens)
        values = {name: p[i] for i, name in enumerate(self.names)}
        model = build(values)

        def f(xx, alpha, mu, inputs=()):
            theta_u, _ = lift_up_angle((xx[6], xx[7], xx[8], xx[9]), ns)
            full = (*[xx[i] for i in range(N_RV)], alpha, mu + theta_u)
            if forcing is None:
                d = entry_rhs(full, (0.0, 0.0), model, ns)
            else:
                m2, forces = forcing.forces(full, model, values, inputs, theta_u, ns)
                d = entry_rhs(full, (0.0, 0.0), m2, ns, forces=forces)
            return ca.vertcat(*d[:N_RV])

        def w(stage):  # the forcing's known inputs at one RK4 stage
            return [u[6 + stage * q + i] for i in range(q)]

        def shifted(value, rate, tau):  # a control read at the fitted offset tau: its value, and d/d(tau) exact
            return value + (p[self._i_tau] - tau) * rate

        def c(i):  # control i of the stage inputs (alpha at 3 stages, then mu), at the record's time offset
            b = 6 + 3 * q
            return u[i] if self._i_tau is None else shifted(u[i], u[b + i], u[b + 6])

        k1 = f(x, c(0), c(3), w(0))
        k2 = f(x + 0.5 * h * k1, c(1), c(4), w(1))
        k3 = f(x + 0.5 * h * k2, c(1), c(4), w(1))
        k4 = f(x + h * k3, c(2), c(5), w(2))
        xn = x + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        xn = ca.vertcat(xn[0], xn[1:5] / ca.norm_2(xn[1:5]), xn[5], xn[6:10] / ca.norm_2(xn[6:10]))
        seeds = ca.vertcat(s, ca.horzcat(ca.SX.zeros(n_p, n_init), ca.SX.eye(n_p)))
        z = ca.vertcat(x, p)
        n = replay.grid.n_steps
        self.mode = "reverse" if self.n_sens > REVERSE_ABOVE else "forward"

        def d(e):  # d(e)/d(theta), by the mode chosen for this many parameters
            return ca.jtimes(e, z, seeds) if self.mode == "forward" else _chain(e, z, x.shape[0], s, n_init)

        step = ca.Function("step", [x, s, h, u, p], _dense(xn, d(xn), k1, d(k1)))
        self._steps_buffer = step.mapaccum("replay", n, [0, 1], [0, 1]).buffer()
        value_step = ca.Function("step_values", [x, h, u, p], _dense(xn, k1))  # the same expressions
        self._values_buffer = value_step.mapaccum("replay_values", n, [0], [0]).buffer()
        ue = ca.SX.sym("ue", 2 + q + (0 if self._i_tau is None else 3))
        ce = [ue[0], ue[1]]
        if self._i_tau is not None:  # the end's controls at the time offset, as the stages'
            ce = [shifted(ue[i], ue[2 + q + i], ue[2 + q + 2]) for i in range(2)]
        fe = f(x, ce[0], ce[1], [ue[2 + i] for i in range(q)])
        self._end_buffer = ca.Function("end", [x, s, ue, p], _dense(fe, d(fe))).buffer()
        self._end_values_buffer = ca.Function("end_values", [x, ue, p], _dense(fe)).buffer()
        self._build_observation(x)

    def _build_observation(self, x) -> None:
        """The observation at the samples (its values, and its Jacobian where it is taken symbolically)."""
        import casadi as ca

        replay = self.replay
        rec = replay.record
        if rec.kind == "ecef" or rec.speed_frame == "inertial":
            qa = x[1:5] / ca.norm_2(x[1:5])
            qb = x[6:10] / ca.norm_2(x[6:10])
            c_ae = dcm(qa[0], qa[1], qa[2], qa[3])
            c_ba = dcm(qb[0], qb[1], qb[2], qb[3])
            a1 = [c_ae[0][j] for j in range(3)]
            b1 = [sum(c_ba[0][i] * c_ae[i][j] for i in range(3)) for j in range(3)]
            r_e, v_e = [x[0] * a for a in a1], [x[5] * b for b in b1]
        if rec.kind == "ecef":
            y = ca.vertcat(*r_e, *v_e)
        elif rec.speed_frame == "inertial":
            y = ca.vertcat(x[0] - replay.setup.model.planet.radius,
                           inertial_speed(r_e[0], r_e[1], *v_e, replay.setup.model.planet.omega, ca.sqrt))
        else:
            y = ca.vertcat(x[0] - replay.setup.model.planet.radius, x[5])
        # an ECEF record's observation Jacobian is written out over all samples at once
        # (ecef_observation_jacobian); the others' are small and taken symbolically, per sample
        self._observe_buffer = None
        if rec.kind != "ecef":
            obs = ca.Function("observe", [x], _dense(y, ca.jacobian(y, x), cse=True))
            self._observe_buffer = obs.map(len(replay.t_obs)).buffer()
        self._observe_values_buffer = ca.Function("observe_values", [x], _dense(y)).map(len(replay.t_obs)).buffer()
        self.n_obs_channels = int(y.shape[0])

    def _inputs(self, offsets: np.ndarray, params: np.ndarray):
        """Initial state, parameters column, stage and end inputs of one replay."""
        rp = self.replay
        x0 = rp.init.rv_euler(offsets[None, :])[:, 0]
        p = np.asarray(params, float).reshape(-1, 1) if len(params) else np.zeros((0, 1))
        stage, end = rp.stage_controls, rp.end_controls
        if self._i_tau is not None:
            tau = float(p[self._i_tau, 0])
            stage, end, stage_rate, end_rate = rp.shifted_controls(tau)
        if self.forcing is not None and self.forcing.n_inputs:
            stage = np.concatenate([stage, self.forcing.stage_inputs])
            end = np.concatenate([end, self.forcing.end_inputs])
        if self._i_tau is not None:
            stage = np.concatenate([stage, stage_rate, np.full((1, stage.shape[1]), tau)])
            end = np.concatenate([end, end_rate, [tau]])
        return x0, p, stage, end

    def predict(self, offsets: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Predicted observations ``(n_obs, m)`` without the Jacobian: the same numbers as
        :meth:`evaluate`'s, bit for bit, at a fraction of its cost."""
        rp = self.replay
        x0, p, stage, end = self._inputs(offsets, params)
        n = rp.grid.n_steps
        xs, fs = np.empty((n + 1, N_RV)), np.empty((n + 1, N_RV))
        xs[0] = x0
        _call(self._values_buffer, (x0, rp.grid.h, stage.T, np.broadcast_to(p.T, (n, p.shape[0]))), (xs[1:], fs[:-1]))
        _call(self._end_values_buffer, (xs[-1], end, p), (fs[-1],))
        x_s = rp.interpolate(xs, fs)
        y = np.empty((len(x_s), self.n_obs_channels))
        _call(self._observe_values_buffer, (x_s,), (y,))
        return y

    def evaluate(self, offsets: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted observations ``(n_obs, m)`` and their Jacobian ``(n_obs, m, n_init + n_p)``.

        :param offsets: initial-state offsets ``(n_init,)``.
        :param params: the free model parameters ``(n_p,)`` in the order of :attr:`names`.
        """
        rp = self.replay
        n_init, ns_ = rp.init.size, self.n_sens
        x0, p, stage, end = self._inputs(offsets, params)
        s0 = np.zeros((N_RV, ns_))
        s0[:, :n_init] = rp.init.jacobian(offsets)
        g = rp.grid
        n, m = g.n_steps, self.n_obs_channels
        # CasADi writes straight into these arrays (column-major (r, c) is C-order (c, r)): no DM copies
        xs, fs = np.empty((n + 1, N_RV)), np.empty((n + 1, N_RV))
        ss, sf = np.empty((n + 1, ns_, N_RV)), np.empty((n + 1, ns_, N_RV))
        xs[0], ss[0] = x0, s0.T
        _call(self._steps_buffer, (x0, s0.T, g.h, stage.T, np.broadcast_to(p.T, (n, p.shape[0]))), (xs[1:], ss[1:], fs[:-1], sf[:-1]))
        _call(self._end_buffer, (xs[-1], ss[-1], end, p), (fs[-1], sf[-1]))
        x_s = rp.interpolate(xs, fs)  # (n_obs, 10)
        s_s = rp.interpolate(ss, sf)  # (n_obs, n_sens, 10)
        y = np.empty((len(x_s), m))
        if self._observe_buffer is None:
            _call(self._observe_values_buffer, (x_s,), (y,))
            dy = ecef_observation_jacobian(x_s)
        else:
            dy = np.empty((len(x_s), N_RV, m))
            _call(self._observe_buffer, (x_s,), (y, dy))
        return y, np.einsum("nji,nkj->nik", dy, s_s, optimize=True)


class ReplayCache:
    """The last replays with sensitivities, by engine and point, for the points asked for again.

    A fit starts where its screening's Gauss-Newton step was taken, ends on a point whose Jacobian
    it took when it accepted it, and a trace's covariance is taken at the point its refinement
    accepted last: each is a replay already made. A replay is deterministic (the same operations
    on the same values), so the arrays kept are those a new replay would give, bit for bit; the
    callers count their replays as before (the count bounds the search), only the work is saved.
    The arrays are shared, never written to.

    :param size: replays kept (the most recently used).
    """

    def __init__(self, size: int = 8):
        from collections import OrderedDict

        self.size = int(size)
        self._kept = OrderedDict()
        self.served = 0  # replays served from here

    @staticmethod
    def _key(engine, offsets, params) -> tuple:
        return engine, np.asarray(offsets, float).tobytes(), np.asarray(params, float).tobytes()

    def evaluate(self, engine: SensitivityReplay, offsets: np.ndarray, params: np.ndarray):
        """:meth:`SensitivityReplay.evaluate`, from a kept replay where there is one."""
        key = self._key(engine, offsets, params)
        hit = self._kept.get(key)
        if hit is None:
            hit = self._kept[key] = engine.evaluate(offsets, params)
            while len(self._kept) > self.size:
                self._kept.popitem(last=False)
        else:
            self._kept.move_to_end(key)
            self.served += 1
        return hit

    def predict(self, engine: SensitivityReplay, offsets: np.ndarray, params: np.ndarray) -> np.ndarray:
        """:meth:`SensitivityReplay.predict` (the same numbers as the evaluation's), from a kept replay where there is one."""
        hit = self._kept.get(self._key(engine, offsets, params))
        if hit is None:
            return engine.predict(offsets, params)
        self.served += 1
        return hit[0]


__all__ = ["REVERSE_ABOVE", "ReplayCache", "SensitivityReplay", "ecef_observation_jacobian"]
