"""Open-loop replay of the reference controls through any dynamics.

The reference controls u(t) (the collocation control polynomials) are fed open
loop to a right-hand side ``rhs(x, u) -> dx/dt`` from the reference's initial
state, with a tight-tolerance integrator (DOP853). The control polynomials have
kinks at the mesh breakpoints, so the integration restarts at every breakpoint
instead of letting the step control stumble over them.

The result compares the replayed and reference *positions* (Cartesian, E
frame): at the reference impact time tf, and at the largest difference along the
flight. Any rhs fits: :func:`rventry_env.physics.entry.entry_rhs` here, or the
environment's dynamics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

from rventry_env.core.conversions import cartesian_from_rv_euler

Rhs = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass
class ReplayResult:
    """A replayed trajectory and its distance to the reference.

    :param t: output times (s).
    :param x: replayed states ``(len(t), 12)``.
    :param x_reference: reference states at ``t``.
    :param position_error_at_impact_m: |r_replay(tf) - r_ref(tf)| (m).
    :param max_position_error_m: largest position difference at the output times (m).
    :param altitude_at_tf_m: replayed altitude above the reference's final radius at tf (m).
    :param nfev: right-hand-side evaluations.
    """

    t: np.ndarray
    x: np.ndarray
    x_reference: np.ndarray
    position_error_at_impact_m: float
    max_position_error_m: float
    altitude_at_tf_m: float
    nfev: int

    @property
    def position_errors_m(self) -> np.ndarray:
        """Position difference at every output time (m)."""
        return _position_error(self.x, self.x_reference)


def _position_error(x, x_ref) -> np.ndarray:
    r1, _ = cartesian_from_rv_euler(x)
    r2, _ = cartesian_from_rv_euler(x_ref)
    return np.linalg.norm(r1 - r2, axis=-1)


def replay_controls(
    rhs: Rhs,
    reference,
    rtol: float = 1e-11,
    atol: float | np.ndarray | None = None,
    n_out: int = 2001,
    method: str = "DOP853",
) -> ReplayResult:
    """Integrate ``rhs`` under the reference controls, open loop, and compare positions.

    :param rhs: ``rhs(x, u) -> dx/dt`` on NumPy arrays (12 states, 2 controls).
    :param reference: anything with ``t``, ``x``, ``tf``, ``state(t)``, ``control(t)``
        and (optionally) ``mesh`` (a :class:`~rventry_env.reference.Reference`).
    :param rtol: relative tolerance.
    :param atol: absolute tolerance per state (default: 1e-11 of each state's
        typical size: 1e-4 m on r, 1e-11 on the Euler parameters, 1e-7 m/s on v).
    :param n_out: output times (uniform) for the comparison along the flight.
    :param method: a :func:`scipy.integrate.solve_ivp` method.
    """
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol}")
    x0 = np.asarray(reference.x[0], dtype=float)
    tf = float(reference.tf)
    t0 = float(reference.t[0])
    if atol is None:
        scale = np.array([1e7, 1, 1, 1, 1, 1e4, 1, 1, 1, 1, 1, 1])
        atol = 1e-11 * scale
    mesh = getattr(reference, "mesh", None)
    breaks = t0 + (tf - t0) * mesh.breaks if mesh is not None else np.array([t0, tf])
    t_out = np.linspace(t0, tf, n_out)

    def f(t, x):
        return np.asarray(rhs(x, reference.control(t)), dtype=float)

    xs = np.empty((n_out, x0.size))
    x = x0.copy()
    nfev = 0
    for a, b in zip(breaks[:-1], breaks[1:]):
        sel = (t_out >= a) & ((t_out < b) | (b == tf))
        sol = solve_ivp(f, (a, b), x, method=method, rtol=rtol, atol=atol, t_eval=t_out[sel])
        if not sol.success:
            raise RuntimeError(f"replay integration failed on [{a:.3f}, {b:.3f}] s: {sol.message}")
        xs[sel] = sol.y.T
        x = sol.y[:, -1] if sol.t.size and sol.t[-1] == b else _end_state(f, a, b, x, method, rtol, atol)
        nfev += sol.nfev
    x_ref = reference.state(t_out)
    errors = _position_error(xs, x_ref)
    return ReplayResult(
        t=t_out, x=xs, x_reference=x_ref,
        position_error_at_impact_m=float(errors[-1]), max_position_error_m=float(errors.max()),
        altitude_at_tf_m=float(xs[-1, 0] - reference.x[-1, 0]), nfev=nfev,
    )  # fmt: skip


REPLAY_RTOL = 1e-11  # the records' open-loop replay tolerance (DOP853)


def replay_record(reference, rhs: Rhs | None = None, rtol: float = REPLAY_RTOL, method: str = "DOP853") -> dict:
    """A reference's controls replayed open loop through ``rhs`` (default: the NumPy entry
    dynamics, :func:`entry_rhs_numpy`), as a benchmark record's entry: the tolerance, the method
    and the position errors (m). Raises as :func:`replay_controls` does."""
    res = replay_controls(entry_rhs_numpy() if rhs is None else rhs, reference, rtol=rtol, method=method)
    return {"rtol": rtol, "method": method, "position_error_at_impact_m": res.position_error_at_impact_m,
            "max_position_error_m": res.max_position_error_m, "altitude_at_tf_m": res.altitude_at_tf_m}  # fmt: skip


def _end_state(f, a, b, x, method, rtol, atol):
    sol = solve_ivp(f, (a, b), x, method=method, rtol=rtol, atol=atol)
    return sol.y[:, -1]


def entry_rhs_numpy(model=None) -> Rhs:
    """``rhs(x, u)`` of :func:`rventry_env.physics.entry.entry_rhs` for ``model`` (default: the defaults)."""
    from rventry_env.physics.entry import entry_rhs
    from rventry_env.physics.model import EntryModel

    model = model or EntryModel()
    return lambda x, u: np.array(entry_rhs(list(x), list(u), model))


__all__ = ["ReplayResult", "replay_controls", "entry_rhs_numpy"]
