"""Neighboring-optimal guidance: time-varying LQR tracking of a reference trajectory.

The classical answer to dispersions about an optimal trajectory: linearize the
dynamics along it and feed back the deviation,

    u_k = u_ref,k - K_k (x - x_ref(t_k)),

with K_k from the backward Riccati recursion of a discrete LQR problem. Here the
"dynamics" are exactly the environment's control step: ``task.substeps`` RK4
substeps of :func:`rventry_env.physics.entry_rhs` with the rates held over ``dt``.
Its Jacobians come from CasADi's automatic differentiation of that same code (one
copy of the physics), evaluated along the reference sampled at the control steps.
They are the Jacobians of the unconstrained RK4 map: the environment also
renormalizes both quaternions after every substep and stops alpha at its bounds,
and neither is in the linearization. Along the reference the renormalization
changes nothing to first order (the RK4 map keeps unit norms to O(h^5)); the
saturation matters only where alpha reaches 0 or 25 deg, which the reference
touches at its end.

Costs, with deviations measured in engineering units (km of position, 10 m/s of
speed, degrees of the velocity direction and of alpha, sigma):

* stage: ``q_weight`` (1e-5) on every scaled deviation (a light regularization:
  the guidance goal is the terminal state);
* control: ``r_weight`` (100) ``* (du_alpha / u_alpha_max)^2 + (du_sigma / u_sigma_max)^2``;
* terminal: 1/(5 km)^2 on position, 1/(5 deg)^2 on the velocity direction (the
  vertical impact), 1/(10 m/s)^2 on speed, 1/(5 deg)^2 on alpha: the success
  thresholds, roughly, as quadratic weights.

The law knows only the nominal model: it cannot see a density or aerodynamic
error except through the state it causes, and it knows nothing of the path
constraints, which is why it tracks a reference solved with margins on them
(:func:`rventry_env.reference.load_guidance_reference`).

**With estimation** (``estimate=True``, the agent ``lqr-est``): the law also reads the
accelerometer, estimates the drag-acceleration and lift-to-drag scale factors online
(:class:`~rventry_env.guidance.estimation.AeroScaleEstimator`), and answers their
logarithms theta like a known, constant disturbance. The linearization gets their
Jacobian G (the same AD of the same step), the LQR state is augmented with theta
(theta_{k+1} = theta_k, no cost on it), and the gain splits into feedback on the state
and feedforward on the estimate:

    u_k = u_ref,k - K_k (x - x_ref(t_k)) - K^theta_k theta_hat.

Nothing else changes, so the difference between ``lqr`` and ``lqr-est`` is what the
estimate alone is worth.

The defaults come from a scan on 100 dispersed episodes (seed 100000): stage
weights 1e-5 to 1e-4 and control weights 30 to 300 give 66-77 % success around the
30 % / 6 % guidance reference; 1e-5 / 100 gives 75 % there and the best median
miss (2.3 km). Around the optimum itself (no margins) every setting violated a
path bound in nearly every episode.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.guidance.law import Law, Measurement
from rventry_env.physics.entry import IDX
from rventry_env.task import EntryTask
from rventry_env.physics.model import EntryModel

# deviation scales: km of radius, km of horizontal position (R_e x Euler parameter),
# 10 m/s of speed, degrees of velocity direction (Euler parameter -> rad -> deg), alpha, sigma
_RE_KM = 6378.137
_SCALE = np.array([1e-3, _RE_KM, _RE_KM, _RE_KM, _RE_KM, 0.1, *([math.degrees(1.0)] * 4), math.degrees(1.0), math.degrees(1.0)])
# terminal weights on the scaled deviations: 5 km, 5 deg, 10 m/s, 5 deg; sigma(t_f) is free
_TERMINAL = np.array([1 / 5**2] * 5 + [1 / 10**2] + [1 / 5**2] * 4 + [1 / 5**2, 0.0])


class StepLinearization:
    """Jacobians of the environment's control step, for any trajectory and aerodynamic scales.

    One CasADi function, built once: ``task.substeps`` RK4 substeps of
    :func:`~rventry_env.physics.entry_rhs` with the rates held over ``task.dt``, on the
    model with the drag-acceleration and lift-to-drag factors exp(theta)
    (:func:`~rventry_env.physics.model.with_aero_scales`); returns A = dx+/dx,
    B = dx+/du and G = dx+/dtheta.

    :param task: dt and substeps.
    :param model: the nominal model.
    """

    def __init__(self, task: EntryTask | None = None, model: EntryModel | None = None):
        import casadi as ca

        from rventry_env.core.backend import casadi_ns
        from rventry_env.core.integrate import rk4_step
        from rventry_env.physics.entry import entry_rhs
        from rventry_env.physics.model import with_aero_scales

        self.task = EntryTask() if task is None else task
        self.model = EntryModel() if model is None else model
        x, u, th = ca.SX.sym("x", 12), ca.SX.sym("u", 2), ca.SX.sym("theta", 2)
        ns = casadi_ns()
        model_th = with_aero_scales(self.model, ca.exp(th[0]), ca.exp(th[1]))
        h = self.task.dt / self.task.substeps

        def f(_t, y):
            return ca.vertcat(*entry_rhs([y[i] for i in range(12)], [u[0], u[1]], model_th, ns))

        y = x
        for _ in range(self.task.substeps):  # the env's step: RK4 substeps with the rates held
            y = rk4_step(f, 0.0, y, h)
        self._jac = ca.Function("step_jacobians", [x, u, th], [ca.jacobian(y, x), ca.jacobian(y, u), ca.jacobian(y, th)])
        self._maps: dict[int, object] = {}

    def along(self, xs: np.ndarray, us: np.ndarray, theta=(0.0, 0.0)):
        """(A (n, 12, 12), B (n, 12, 2), G (n, 12, 2)) at states ``xs (n, 12)`` and rates ``us (n, 2)``."""
        n = xs.shape[0]
        size = 64 * math.ceil(n / 64)  # a few mapped functions serve every length, padded at most 63
        fn = self._maps.get(size)
        if fn is None:
            fn = self._maps[size] = self._jac.map(size)
        pad = size - n
        xp = np.vstack([xs, np.repeat(xs[-1:], pad, axis=0)]) if pad else xs
        up = np.vstack([us, np.repeat(us[-1:], pad, axis=0)]) if pad else us
        th = np.repeat(np.asarray(theta, dtype=float).reshape(2, 1), size, axis=1)
        a, b, g = fn(xp.T, up.T, th)
        a = np.array(a).reshape(12, size, 12).transpose(1, 0, 2)[:n]
        b = np.array(b).reshape(12, size, 2).transpose(1, 0, 2)[:n]
        g = np.array(g).reshape(12, size, 2).transpose(1, 0, 2)[:n]
        return a, b, g


def lqr_gains(a, b, q, r, p_terminal, g=None):
    """Backward Riccati recursion of a discrete, time-varying LQR problem.

    :param a: (n, nx, nx) state Jacobians; ``b`` (n, nx, nu) control Jacobians.
    :param q: stage weight (nx, nx); ``r`` (nu, nu); ``p_terminal`` (nx, nx).
    :param g: optional (n, nx, np) Jacobians on constant disturbances theta; the state is
        then augmented with theta (unweighted, theta_{k+1} = theta_k).
    :return: gains (n, nu, nx), and with ``g`` also the disturbance gains (n, nu, np).
    """
    n, nx, nu = b.shape
    n_th = 0 if g is None else g.shape[2]
    m = nx + n_th
    qa = np.zeros((m, m))
    qa[:nx, :nx] = q
    p = np.zeros((m, m))
    p[:nx, :nx] = p_terminal
    aa = np.eye(m)
    ba = np.zeros((m, nu))
    gains = np.zeros((n, nu, m))
    for k in range(n - 1, -1, -1):
        aa[:nx, :nx] = a[k]
        if n_th:
            aa[:nx, nx:] = g[k]
        ba[:nx] = b[k]
        pb = p @ ba
        gains[k] = np.linalg.solve(r + ba.T @ pb, pb.T @ aa)
        p = qa + aa.T @ p @ (aa - ba @ gains[k])
        p = 0.5 * (p + p.T)
    return (gains[:, :, :nx], gains[:, :, nx:]) if n_th else gains


def tracking_weights(task: EntryTask, q_weight: float, r_weight: float):
    """(Q, R, P_terminal) of the module docstring, in SI units."""
    p = task.problem
    s = np.diag(_SCALE)
    u_max = np.array([p.u_alpha_max, p.u_sigma_max])
    return s @ (q_weight * np.eye(12)) @ s, r_weight * np.diag(1.0 / u_max**2), s @ np.diag(_TERMINAL) @ s


def sample_plan(plan, dt: float):
    """A trajectory sampled at the control steps: states (n+1, 12) and step-mean rates (n, 2).

    ``plan`` has ``tf`` and ``state(t)`` from t = 0; the rates are those that carry alpha
    and sigma exactly from one sample to the next.
    """
    n = max(int(math.floor(plan.tf / dt)), 1)
    t = np.arange(n + 1) * dt
    x = np.atleast_2d(plan.state(np.minimum(t, plan.tf)))
    return x, np.diff(x[:, IDX.angles], axis=0) / dt


class NeighboringOptimalGuidance(Law):
    """TV-LQR tracking of a reference with the environment's own step map; optionally with estimation.

    :param reference: the trajectory to track (default: the guidance reference).
    :param task: the task (dt, substeps, rate limits).
    :param model: the nominal force model the gains are computed with.
    :param q_weight: stage weight on the scaled deviations.
    :param r_weight: weight on the scaled rate corrections.
    :param estimate: also estimate the aerodynamic scale factors from the accelerometer and
        feed them forward (the agent ``lqr-est``).
    :param estimator_settings: the filter's :class:`~rventry_env.guidance.estimation.EstimatorSettings`.
    """

    def __init__(self, reference=None, task: EntryTask | None = None, model: EntryModel | None = None,
                 q_weight: float = 1e-5, r_weight: float = 100.0, estimate: bool = False,
                 estimator_settings=None):  # fmt: skip
        if reference is None:
            from rventry_env.reference import load_guidance_reference

            reference = load_guidance_reference()
        if not (q_weight >= 0 and r_weight > 0):
            raise ValueError(f"need q_weight >= 0 and r_weight > 0, got {q_weight}, {r_weight}")
        self.reference = reference
        self.task = EntryTask() if task is None else task
        self.model = EntryModel() if model is None else model
        p, dt = self.task.problem, self.task.dt
        self.u_max = np.array([p.u_alpha_max, p.u_sigma_max])
        self.x_ref, self.u_ref = sample_plan(reference, dt)
        self.n_steps = self.u_ref.shape[0]
        self.linearization = StepLinearization(self.task, self.model)
        a, b, g = self.linearization.along(self.x_ref[:-1], self.u_ref)
        weights = tracking_weights(self.task, q_weight, r_weight)
        self.estimate = bool(estimate)
        if self.estimate:
            from rventry_env.guidance.estimation import AeroScaleEstimator

            self.gains, self.theta_gains = lqr_gains(a, b, *weights, g=g)
            self.estimator = AeroScaleEstimator(self.model, 1, estimator_settings)
        else:
            self.gains, self.theta_gains, self.estimator = lqr_gains(a, b, *weights), None, None

    def reset(self, n_episodes: int) -> None:
        """New episodes: the estimates start again from their prior."""
        if self.estimator is not None:
            self.estimator.reset(n_episodes)

    def episode_stats(self) -> list[dict]:
        """With estimation: per episode, the estimator updates refused by its scale bounds."""
        if self.estimator is None:
            return []
        return [{"estimator_rejected_updates": int(c)} for c in self.estimator.rejected]

    def _jacobians(self, xs: np.ndarray, us: np.ndarray):
        """(A, B) of the step at ``xs``, ``us`` for the nominal model."""
        a, b, _ = self.linearization.along(xs, us)
        return a, b

    def rates(self, time_s: np.ndarray, state: np.ndarray, theta=None) -> np.ndarray:
        """Commanded (u_alpha, u_sigma) in rad/s, unclipped, for states (N, 12) at times (N,).

        :param theta: with estimation, the estimated log-scales (N, 2).
        """
        time_s = np.asarray(time_s, dtype=float)
        k = np.clip(np.rint(time_s / self.task.dt).astype(int), 0, self.n_steps - 1)
        u = self.u_ref[k] - np.einsum("nij,nj->ni", self.gains[k], np.asarray(state) - self.x_ref[k])
        if theta is not None and self.theta_gains is not None:
            u = u - np.einsum("nij,nj->ni", self.theta_gains[k], theta)
        return np.where((time_s < self.reference.tf)[:, None], u, 0.0)

    def __call__(self, m: Measurement) -> np.ndarray:
        theta = self.estimator.observe(m) if self.estimate else None
        return np.clip(self.rates(m.time_s, m.navigation_state, theta) / self.u_max, -1.0, 1.0).astype(np.float32)


__all__ = ["StepLinearization", "lqr_gains", "tracking_weights", "sample_plan", "NeighboringOptimalGuidance"]
