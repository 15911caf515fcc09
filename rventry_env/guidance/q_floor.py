"""A predictive floor on the dynamic pressure: the coming apex of a skip, kept above q_min.

The q bound is lost at the apex of a skip, where a vehicle that climbed too fast coasts into air
thinner than its plan assumed. Unlike the load factor, which answers alpha within the control step
(:class:`~rventry_env.guidance.load_relief.LoadRelief`), the apex is tens of seconds away when it
is decided: a one-step check would act too late. :class:`QFloor` sits after any law's rates and,
for each vehicle that is climbing with a dynamic pressure within ``watch`` times its floor,
predicts the flight to the apex:

* one control step with the rates the law asks for, then the angles held, by RK4 steps of
  ``step_s`` on the model's own equations of motion
  (:func:`~rventry_env.physics.entry.entry_rhs`), until the vehicle descends or ``horizon_s``;
* calibrated by what the accelerometer senses now, as the load relief is: the predicted q is the
  model's times the ratio of the sensed aerodynamic acceleration to the model's at the current
  state (the accelerometer sees density times the coefficients; the share that is density is what
  the q bound cares about, and that is what the observation's air data assume too).

Where the least q before the apex falls below ``q_min (1 + margin)``, the rates are replaced by the
least change that keeps the floor, predicted the same way: the bank held, or rolled at half or
full rate either way (the lift away from the vertical: the climb ends lower, in denser air), the
one nearest the law's bank rate (the running cost charges the bank rate squared); where no bank
rate keeps it, alpha down at its full rate as well (less lift, and less drag to slow the vehicle
on the way up); where nothing keeps it, whatever reaches the highest apex q. The next step asks
again with the law's own rates, so the law has its angles back as soon as its own command would
keep the floor. A first version knew only the two full bank rates and flipped between them every
step at the bank that keeps the lift furthest down: holding the bank is a candidate for that
reason. It sees only what a vehicle measures: the navigation state and the sensed acceleration.
"""

from __future__ import annotations

import numpy as np

from rventry_env.core.eom import radial_rate
from rventry_env.core.integrate import rk4_step
from rventry_env.guidance.load_relief import RateLimiter
from rventry_env.physics import EntryModel
from rventry_env.physics.entry import IDX, entry_forces, entry_rhs
from rventry_env.task import EntryTask


# (alpha rate, bank rate) of each candidate tried where the law's own rates fall short, fractions of their bounds
# (None keeps the law's): its alpha rate with the bank held, or rolled at half or full rate either way; then alpha
# down at its full rate with the bank held or rolled at full rate either way
CANDIDATES = ((None, 0.0), (None, -0.5), (None, 0.5), (None, -1.0), (None, 1.0), (-1.0, 0.0), (-1.0, -1.0),
              (-1.0, 1.0))  # fmt: skip


class QFloor(RateLimiter):
    """Replaces the rates of the vehicles whose predicted apex would take q below ``q_min (1 + margin)``.

    :param margin: fraction of q_min kept free above it (>= 0).
    :param horizon_s: how far ahead the apex is looked for (s).
    :param step_s: the prediction's RK4 step (s).
    :param watch: vehicles are checked while climbing with their sensed q below ``watch`` times the floor.

    After each call, :attr:`active` (N,) says which vehicles had their rates replaced, and
    :attr:`steps` (N,) counts the replaced steps of each vehicle since :meth:`reset`.
    """

    who = "the q floor"

    def __init__(self, model: EntryModel | None = None, task: EntryTask | None = None, margin: float = 0.02,
                 horizon_s: float = 90.0, step_s: float = 10.0, watch: float = 1.5):  # fmt: skip
        for name, v, ok, need in (("margin", margin, margin >= 0, ">= 0"), ("horizon_s", horizon_s, horizon_s > 0, "> 0"),
                                  ("step_s", step_s, step_s > 0, "> 0"), ("watch", watch, watch >= 1, ">= 1")):  # fmt: skip
            if not (np.isfinite(v) and ok):
                raise ValueError(f"q floor {name} must be a finite number {need}, got {v!r}")
        super().__init__(model, task)
        self.margin, self.horizon_s, self.step_s, self.watch = float(margin), float(horizon_s), float(step_s), float(watch)
        self.floor_pa = self.task.problem.q_min * (1.0 + self.margin)

    def apex_q(self, x: np.ndarray, u_alpha: np.ndarray, u_sigma: np.ndarray) -> np.ndarray:
        """The model's least dynamic pressure (Pa) from now to the apex (N,): one control step with
        the rates (rad/s), then the angles held, until the vehicle descends or the horizon ends."""
        p, model = self.task.problem, self.model
        dt = self.task.dt

        def rhs_with(u):
            return lambda _t, y: entry_rhs(y, u, model)

        y = rk4_step(rhs_with((u_alpha, u_sigma)), 0.0, tuple(x.T), dt)
        y = (*y[:10], np.clip(y[IDX.alpha], 0.0, p.alpha_max), y[11])
        q_min = np.minimum(np.asarray(entry_forces(tuple(x.T), model).dynamic_pressure),
                           np.asarray(entry_forces(y, model).dynamic_pressure))  # fmt: skip
        # on with the vehicles still climbing only: the others have passed their apex
        live = np.nonzero(np.asarray(radial_rate(y[5], y[6:10])) > 0.0)[0]
        y = tuple(np.asarray(c)[live] for c in y)
        hold = rhs_with((0.0, 0.0))
        t = dt
        while t < self.horizon_s and live.size:
            y = rk4_step(hold, 0.0, y, self.step_s)
            t += self.step_s
            q_min[live] = np.fmin(q_min[live], np.asarray(entry_forces(y, model).dynamic_pressure))
            still = np.asarray(radial_rate(y[5], y[6:10])) > 0.0
            live, y = live[still], tuple(c[still] for c in y)
        return q_min

    def __call__(self, rates, state, sensed_accel_b, count=None) -> np.ndarray:
        """The rates (N, 2), fractions of their bounds, replaced where the apex would pass under the floor.
        ``count`` (N,) bool: which vehicles' replaced steps :attr:`steps` counts (default all)."""
        rates, x, sensed = self._inputs(rates, state, sensed_accel_b)
        self.active = np.zeros(len(x), dtype=bool)
        f = entry_forces(tuple(x.T), self.model)
        calib = np.linalg.norm(sensed, axis=1) / np.maximum(np.asarray(f.aero_accel), 1e-12)
        q_now = calib * np.asarray(f.dynamic_pressure)
        climbing = np.asarray(radial_rate(x[:, IDX.v], x[:, 6:10].T)) > 0.0
        watched = np.nonzero(climbing & (q_now < self.watch * self.floor_pa) & np.isfinite(q_now))[0]
        if watched.size == 0:
            return rates
        p = self.task.problem
        with np.errstate(all="ignore"):  # first the law's own rates: most watched vehicles keep the floor with them
            own = self.apex_q(x[watched], rates[watched, 0] * p.u_alpha_max, rates[watched, 1] * p.u_sigma_max)
        own = np.where(np.isfinite(own), own * calib[watched], -np.inf)
        low = own < self.floor_pa
        if not low.any():
            return rates
        idx = watched[low]
        m = len(idx)
        law = rates[idx]
        k = len(CANDIDATES)
        ua = np.concatenate([law[:, 0] if a is None else np.full(m, a) for a, _ in CANDIDATES])
        us = np.concatenate([law[:, 1] if b is None else np.full(m, b) for _, b in CANDIDATES])
        with np.errstate(all="ignore"):
            apex = self.apex_q(np.tile(x[idx], (k, 1)), ua * p.u_alpha_max, us * p.u_sigma_max)
        apex = np.where(np.isfinite(apex), apex, -np.inf).reshape(k, m) * calib[idx]
        # the least change that keeps the floor: the bank first (the rate nearest the law's), then alpha down as
        # well; where nothing keeps it, the candidate that reaches the highest apex q
        cand_a, cand_s = ua.reshape(k, m), us.reshape(k, m)
        change = np.abs(cand_s - law[:, 1]) + 4.0 * (cand_a != law[:, 0])  # alpha's change ranks after any bank's
        change = np.where(apex >= self.floor_pa, change, np.inf)
        pick = np.where(np.isfinite(change.min(axis=0)), np.argmin(change, axis=0), np.argmax(apex, axis=0))
        cols = np.arange(m)
        rates[idx, 0] = cand_a[pick, cols]
        rates[idx, 1] = cand_s[pick, cols]
        self.active[idx] = True
        self._count(count)
        return rates


__all__ = ["QFloor"]
