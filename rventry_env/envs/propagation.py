"""One control step of the entry dynamics, for one vehicle or a batch.

The same code steps a single vehicle on Python floats (``MATH`` namespace, used by
:class:`~rventry_env.envs.rv_entry.RvEntryEnv`) and a batch on NumPy arrays
(``NUMPY``, used by :class:`~rventry_env.envs.vector.RvEntryVectorEnv`), so the two
environments cannot drift apart. The physics is :func:`rventry_env.physics.entry_rhs`.

Integration (see DESIGN notes in the env docstring):

* the action is held over the control step ``dt``; ``substeps`` classical RK4
  steps of ``h = dt / substeps`` integrate it; both Euler-parameter sets are
  renormalized after every substep;
* alpha saturates at [0, alpha_max]: within a substep where alpha + u h would leave
  the interval, the applied rate is reduced so that alpha lands exactly on the
  bound at the substep's end, and held there afterwards. The *commanded* rate is
  what the cost charges;
* the running cost of Eq. ``Ex2-Cost`` is integrated exactly (alpha is linear in
  time within a substep; :meth:`~rventry_env.task.problem.EntryProblem.cost_over_hold`);
* impact (r = R_e) is located inside the substep by root-finding on the RK4 map
  tau -> r(RK4(x, tau)) (Newton from a cubic Hermite start, safeguarded by Illinois regula
  falsi, to 1e-6 m), and the state returned
  is the state at impact;
* path constraints (load factor, dynamic pressure) are sampled at every RK4 node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass, replace
from typing import Any, NamedTuple

import numpy as np

from rventry_env.core.eom import radial_rate
from rventry_env.core.integrate import rk4_step
from rventry_env.physics.entry import EntryForces, entry_forces, entry_rhs
from rventry_env.physics.model import EntryModel
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import EntryTask

IMPACT_TOLERANCE_M = 1e-6
MAX_IMPACT_ITERATIONS = 60

# termination codes (0 = still flying; IDLE = not stepped this time, e.g. awaiting its reset)
FLYING, IMPACT, SKIP_OUT, NON_FINITE, STALL, IDLE = 0, 1, 2, 3, 4, 5
FAILURE_NAMES = {SKIP_OUT: "skip-out", NON_FINITE: "non-finite state", STALL: "stall"}


def take_model(model: Any, idx) -> Any:
    """The model restricted to vehicles ``idx``: every per-vehicle array parameter is indexed."""
    if idx is None:
        return model
    if isinstance(model, np.ndarray) and model.ndim >= 1:
        return model[idx]
    if is_dataclass(model) and not isinstance(model, type):
        changes = {}
        for f in fields(model):
            if not f.init:
                continue
            old = getattr(model, f.name)
            new = take_model(old, idx)
            if new is not old:
                changes[f.name] = new
        return replace(model, **changes) if changes else model
    return model


def _take(x: tuple, idx) -> tuple:
    return x if idx is None else tuple(c[idx] for c in x)


def path_violation(forces: EntryForces, task: EntryTask, model: EntryModel, ns):
    """(load-factor excess, dynamic-pressure deficit) beyond the success margin, relative and >= 0.

    The margin (``task.success.constraint_tolerance``, 1 %) is the one that decides
    success, so the reward charges exactly what counts as a violation: the optimal
    reference, which touches both bounds within 0.9 % between its nodes, pays nothing.
    """
    tol = task.success.constraint_tolerance
    load = forces.aero_accel / (model.planet.g0 * task.problem.a_max_g)
    q_short = 1.0 - forces.dynamic_pressure / task.problem.q_min
    return ns.fmax(load - 1.0 - tol, 0.0), ns.fmax(q_short - tol, 0.0)


class StepOutcome(NamedTuple):
    x: tuple  # state components at the end of the step (or at the event)
    forces: EntryForces  # forces at ``x``
    elapsed: Any  # time advanced (s): dt, or less if the episode ended inside the step
    status: Any  # FLYING / IMPACT / SKIP_OUT / NON_FINITE / STALL
    cost: Any  # running cost accrued over the step
    path_penalty: Any  # integral of weighted path-constraint violations over the step
    max_load_g: Any
    min_q: Any
    alpha_saturated: Any


@dataclass
class Propagator:
    """Steps vehicles through one control step. ``ns`` picks floats (MATH) or arrays (NUMPY);
    ``weights`` price the path-bound violations in :attr:`StepOutcome.path_penalty`."""

    task: EntryTask
    ns: Any
    weights: RewardWeights = RewardWeights()

    def forces(self, x: tuple, model: EntryModel) -> EntryForces:
        return entry_forces(x, model, self.ns)

    def step(self, x: tuple, forces: EntryForces, u_alpha, u_sigma, model: EntryModel, active=None) -> StepOutcome:
        """Advance ``x`` (with ``forces`` evaluated at ``x``) by one control step.

        :param u_alpha: commanded angle-of-attack rate (rad/s), already within bounds.
        :param u_sigma: commanded bank-angle rate (rad/s), already within bounds.
        :param active: arrays only: vehicles to step; the others stay as they are
            (status IDLE).
        """
        ns, task = self.ns, self.task
        p = task.problem
        radius = model.planet.radius
        g0 = model.planet.g0
        h = task.dt / task.substeps
        w = self.weights
        arrays = ns.array

        if arrays:
            status = ns.zeros_int8(x[0])
            if active is not None:
                status = ns.int8(ns.where(active, FLYING, IDLE))
            saturated = status != status  # all False, in the namespace's array type
        else:
            status, saturated = FLYING, False
        cost = 0.0 * x[0]
        path = 0.0 * x[0]
        elapsed = 0.0 * x[0]
        max_load = forces.aero_accel / g0
        min_q = forces.dynamic_pressure

        for _ in range(task.substeps):
            alpha0 = x[10]
            alpha_end = ns.fmin(ns.fmax(alpha0 + u_alpha * h, 0.0), p.alpha_max)
            ua = (alpha_end - alpha0) / h
            saturated = saturated | (ns.fabs(ua - u_alpha) > 1e-12)
            u = (ua, u_sigma)

            if arrays:
                # overflow and NaN are the env's to report (status NON_FINITE), not NumPy's warnings
                with np.errstate(all="ignore"):
                    x_new, tau, f_new, new_status = self._advance(x, forces, u, h, model, status, radius)
            else:
                try:
                    x_new, tau, f_new, new_status = self._advance(x, forces, u, h, model, status, radius)
                except (OverflowError, ZeroDivisionError, ValueError):
                    # Python floats raise where NumPy returns inf/NaN: the same ending, "non-finite state"
                    x_new, tau, f_new, new_status = x, 0.0, forces, NON_FINITE
            flying = status == FLYING
            step_cost = p.cost_over_hold(alpha0, ua, u_alpha, u_sigma, tau)
            if arrays and ns.known(ns.all(flying) & ns.logical_not(ns.any(new_status != FLYING))):
                x, forces = x_new, f_new  # the common case, seen by NumPy: every vehicle flies on
            elif arrays:
                # vehicles that already ended stay frozen; a non-finite step keeps the last finite state
                keep = ns.logical_not(flying) | (new_status == NON_FINITE)
                x = tuple(ns.where(keep, a, b) for a, b in zip(x, x_new))
                forces = _where_forces(keep, forces, f_new, ns)
                tau = ns.where(keep, 0.0, tau)
                step_cost = ns.where(keep, 0.0, step_cost)
                status = ns.int8(ns.where(flying, new_status, status))
            else:
                if new_status == NON_FINITE:
                    tau, step_cost = 0.0, 0.0
                else:
                    x, forces = x_new, f_new
                status = new_status
            cost = cost + step_cost
            elapsed = elapsed + tau
            load_x, q_x = path_violation(forces, task, model, ns)
            path = path + tau * (w.load_violation * load_x + w.q_violation * q_x)
            max_load = ns.fmax(max_load, forces.aero_accel / g0)
            min_q = ns.fmin(min_q, forces.dynamic_pressure)
            if ns.known(ns.logical_not(ns.any(status == FLYING))):
                break  # nobody flies on (never known while JAX traces: its ended vehicles stay frozen)
        return StepOutcome(x, forces, elapsed, status, cost, path, max_load, min_q, saturated)

    def _advance(self, x: tuple, forces: EntryForces, u: tuple, h: float, model: EntryModel, status, radius: float):
        """One RK4 substep with the rates ``u`` held, the impact located inside it; the new status."""
        ns, task = self.ns, self.task

        def rhs(_t, y):
            return entry_rhs(y, u, model, ns)

        k1 = entry_rhs(x, u, model, ns, forces=forces)
        x_new = _renormalize(rk4_step(rhs, 0.0, x, h, k1=k1), ns)
        tau = h + 0.0 * x[0]
        hit = x_new[0] < radius
        if ns.array:
            hit = hit & (status == FLYING)
        if ns.array and ns.concrete:
            if hit.any():  # root-find only for the vehicles that hit, on their sub-arrays
                idx = np.nonzero(hit)[0]
                x_hit, tau_hit = self._locate_impact(
                    _take(x, idx), _take(k1, idx), (u[0][idx], u[1][idx]), h, take_model(model, idx), radius,
                    _take(x_new, idx),
                )  # fmt: skip
                x_new = tuple(np.where(hit, _scatter(c, idx, ch), c) for c, ch in zip(x_new, x_hit))
                tau = np.where(hit, _scatter(tau, idx, tau_hit), tau)
        elif ns.array:  # traced: every vehicle goes in, those that did not hit are done from the start
            x_hit, tau_hit = self._locate_impact(x, k1, u, h, model, radius, x_new, todo=hit)
            x_new = tuple(ns.where(hit, ch, c) for c, ch in zip(x_new, x_hit))
            tau = ns.where(hit, tau_hit, tau)
        elif hit:
            x_new, tau = self._locate_impact(x, k1, u, h, model, radius, x_new)
        f_new = entry_forces(x_new, model, ns)
        return x_new, tau, f_new, _classify(x_new, f_new, hit, task, radius, ns)

    def _locate_impact(self, x0: tuple, k1: tuple, u: tuple, h: float, model: EntryModel, radius: float, xb: tuple,
                       todo=None):  # fmt: skip
        """tau in (0, h] with r(RK4(x0, tau)) = radius, and the state there.

        A safeguarded Newton iteration on g(tau) = r(RK4(x0, tau)) - radius, to within the
        namespace's impact tolerance (:func:`impact_tolerance`). The first iterate is the root
        of the cubic Hermite interpolant of r over the substep (r and its rate at both ends:
        the rate at the end is the kinematic r-dot of ``xb``); each later one a Newton step with
        the kinematic r-dot of the last iterate for g' (they differ by the RK4 truncation
        error), kept only strictly inside the bracket, else Illinois regula falsi on the
        bracket. Each iterate costs one RK4 substep. Under ``vmap`` every lane runs while any
        lane is unconverged, so the iterations, not the lanes, set the cost: this takes three
        where the regula falsi alone took six.

        :param xb: the RK4 state at ``h`` (the substep's end, below the surface).
        :param todo: arrays: the vehicles to locate (the others keep ``xb`` and ``h``); None: all.
        """
        ns = self.ns
        tol = impact_tolerance(x0[0], radius, ns)

        def rhs(_t, y):
            return entry_rhs(y, u, model, ns)

        def state_at(tau):
            return _renormalize(rk4_step(rhs, 0.0, x0, tau, k1=k1), ns)

        def finished(fc):
            done = ns.fabs(fc) <= tol
            return done if todo is None else done | ns.logical_not(todo)

        def going(carry):
            return (carry[0] < MAX_IMPACT_ITERATIONS) & ns.logical_not(ns.all(finished(carry[7])))

        def iterate(carry):
            it, lo, flo, hi, fhi, side, c, fc, xc = carry
            done = finished(fc)
            # Newton from the last iterate; else Illinois regula falsi on the bracket
            rd = radial_rate(xc[5], xc[6:10])
            rd_ok = ns.fabs(rd) > 0.0
            newton = c - fc / ns.where(rd_ok, rd, 1.0)
            inside = rd_ok & (newton > lo) & (newton < hi)
            span = fhi - flo
            span_ok = span < 0.0  # flo > 0 > fhi, unless both are exhausted
            falsi = lo - flo * (hi - lo) / ns.where(span_ok, span, -1.0)
            falsi = ns.where(span_ok, falsi, 0.5 * (lo + hi))
            cand = ns.where(inside, newton, falsi)
            cand = ns.where(it == 0, first, cand)
            cand = ns.where(done, c, cand)
            x_new = state_at(cand)
            xc = tuple(ns.where(done, old, new) for old, new in zip(xc, x_new))
            fcand = ns.where(done, fc, xc[0] - radius)
            above = fcand > 0.0
            # Illinois: a side kept twice in a row has its value halved in the regula falsi
            fhi = ns.where(above & (side > 0.0), 0.5 * fhi, fhi)
            flo = ns.where(ns.logical_not(above) & (side < 0.0), 0.5 * flo, flo)
            lo, flo = ns.where(above, cand, lo), ns.where(above, fcand, flo)
            hi, fhi = ns.where(above, hi, cand), ns.where(above, fhi, fcand)
            side = ns.where(above, one, -one)
            return it + 1, lo, flo, hi, fhi, side, cand, fcand, xc

        g0 = x0[0] - radius
        g1 = xb[0] - radius
        first = _hermite_root(g0, k1[0] * h, g1, radial_rate(xb[5], xb[6:10]) * h, ns) * h
        zero = 0.0 * x0[0]
        one = 1.0 + zero
        b = h + zero
        carry = (0, zero, g0, b, g1, zero, b, g1, xb)
        carry = ns.while_loop(going, iterate, carry)
        return carry[8], carry[6]


def impact_tolerance(r, radius, ns=None):
    """How close to the surface ``radius`` a located impact is (m): 1e-6 m, or two units in the last
    place of the surface's radius in ``r``'s float type where that type cannot resolve 1e-6 m
    (float32: about 1.5 m at the Earth's radius). ``radius`` may be traced (JAX params): then pass
    the namespace, whose ``fmax`` takes it."""
    dtype = getattr(r, "dtype", None)
    if dtype is None:
        return IMPACT_TOLERANCE_M
    fmax = max if ns is None else ns.fmax
    return fmax(IMPACT_TOLERANCE_M, 2.0 * float(np.finfo(dtype).eps) * radius)


def _hermite_root(g0, d0, g1, d1, ns):
    """s in (0, 1) where the cubic Hermite interpolant of g (values g0 > 0 > g1 at s = 0, 1, slopes
    d0, d1 in units of the interval) crosses zero: Newton on the cubic from the chord's root, each
    step kept inside the bracket; the chord's root where that fails."""
    span = g0 - g1
    s = g0 / ns.where(span > 0.0, span, 1.0)
    chord = s
    for _ in range(3):
        s2 = s * s
        s3 = s2 * s
        p = g0 * (2 * s3 - 3 * s2 + 1) + d0 * (s3 - 2 * s2 + s) + g1 * (3 * s2 - 2 * s3) + d1 * (s3 - s2)
        dp = g0 * (6 * s2 - 6 * s) + d0 * (3 * s2 - 4 * s + 1) + g1 * (6 * s - 6 * s2) + d1 * (3 * s2 - 2 * s)
        ok = ns.fabs(dp) > 0.0
        step = s - p / ns.where(ok, dp, 1.0)
        s = ns.where(ok & (step > 0.0) & (step < 1.0), step, s)
    good = (s > 0.0) & (s < 1.0)
    return ns.where(good, s, chord)


def _scatter(full, idx, values):
    out = np.array(full, dtype=float, copy=True)
    out[idx] = values
    return out


def _renormalize(x: tuple, ns) -> tuple:
    na = ns.sqrt(x[1] * x[1] + x[2] * x[2] + x[3] * x[3] + x[4] * x[4])
    nb = ns.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9])
    return (x[0], x[1] / na, x[2] / na, x[3] / na, x[4] / na, x[5],
            x[6] / nb, x[7] / nb, x[8] / nb, x[9] / nb, x[10], x[11])  # fmt: skip


def _classify(x, forces, hit, task: EntryTask, radius, ns):
    """Status after a substep: impact, skip-out above the ceiling, non-finite, stall, or flying."""
    h = x[0] - radius
    if ns.array:
        # one NaN or inf anywhere makes the sum non-finite: cheaper than testing 12 arrays
        finite = ns.isfinite(sum(x[1:], x[0]) + forces.aero_accel)
        status = ns.where(x[5] < task.min_speed, STALL, FLYING)
        status = ns.where(h > task.ceiling_altitude, SKIP_OUT, status)
        status = ns.where(hit, IMPACT, status)
        return ns.int8(ns.where(finite, status, NON_FINITE))
    if not (all(math.isfinite(c) for c in x) and math.isfinite(forces.aero_accel)):
        return NON_FINITE
    if hit:
        return IMPACT
    if h > task.ceiling_altitude:
        return SKIP_OUT
    if x[5] < task.min_speed:
        return STALL
    return FLYING


def _where_forces(keep, old: EntryForces, new: EntryForces, ns) -> EntryForces:
    def pick(a, b):
        if isinstance(a, tuple):
            return tuple(pick(ai, bi) for ai, bi in zip(a, b))
        return ns.where(keep, a, b)

    return EntryForces(*(pick(a, b) for a, b in zip(old, new)))


__all__ = [
    "Propagator",
    "StepOutcome",
    "path_violation",
    "take_model",
    "FLYING",
    "IMPACT",
    "SKIP_OUT",
    "NON_FINITE",
    "STALL",
    "IDLE",
    "FAILURE_NAMES",
]
