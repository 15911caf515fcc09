"""The terminal angle-of-attack condition, flown: alpha reaches zero at impact.

Example 2 asks for alpha(t_f) = 0. A plan ends there, but a vehicle that arrives a little later
or earlier than planned is tracked past the plan's end, and the last control step holds one
rate for a whole ``dt`` while impact comes somewhere inside it. The environment also stops alpha
at its lower bound by lowering the applied rate so that alpha reaches 0 at the *end* of the
step: in the step that contains impact, t_last after its start, the most a law can take out is
the linear fall to zero at the step's end, which leaves alpha0 (1 - t_last / dt) at impact.
:func:`alpha_rate_bound` is the fastest alpha rate a law may command so that alpha is small
enough when that last step starts, and no smaller:

* the time to go is the altitude over the descent rate, h / (v sin(-gamma)), from the navigation
  state (infinite while the vehicle climbs or flies level); it puts the impact k whole steps
  and t_last seconds ahead;
* at the last step's start alpha may be at most ``tolerance / (1 - t_last / dt + 0.05)``: what
  leaves ``tolerance`` at impact, with 5 % of a step for the error of the time to go;
* at the next decision it may be that plus what ``rate_fraction`` of the rate bound removes in
  the k - 1 steps between them; the bound is the rate that reaches it;
* in the last step itself (k = 0) the bound is -alpha / dt: the fall to zero at the step's end,
  as cheap as any faster command (the cost charges the commanded rate).

Far from the ground the bound is far above any rate a law commands, so it changes nothing
there; near it, it takes out only what the last step could not, and leaves the plan's lift in
place until then. It lowers only the alpha rate, which lowers lift and drag: it never adds load.
A first version that counted the time to go in seconds rather than whole steps took alpha out
two steps early and cost the pull-up to vertical 5 deg of vertical-impact error. The bound
counts steps of ``dt``; with several RK4 substeps the environment stops alpha at a substep's end,
so the bound is then conservative.

**The vertical dive.** A vehicle that navigates by an inertial system knows its altitude to a
few hundred metres at impact, and the optimum is still turning its velocity toward vertical in
its last seconds, at 4-6 deg/s: a navigated altitude a kilometre high ends the flight before the
turn is done, fast and off vertical; one a kilometre low ends the plan in the air. A plan that reaches
the vertical ``height`` above the target (:func:`dive_entry_speed` gives the speed it must
have there) and a law that then dives straight, alpha at the plan's final value, end vertical
wherever within that height the ground really is.
"""

from __future__ import annotations

import numpy as np

from rventry_env.core.euler_parameters import dcm
from rventry_env.physics.entry import IDX
from rventry_env.task import EntryTask

TIME_TO_GO_MARGIN = 0.05  # of a step: what the time to go may be off by


def time_to_impact(state: np.ndarray, radius: float) -> np.ndarray:
    """Altitude over the descent rate (s) for states (N, 12); inf where the vehicle does not descend."""
    x = np.asarray(state, dtype=float)
    sin_gamma = dcm(*x[:, IDX.e_b].T)[0][0]  # C_BA(1,1) = b1 . a1: the velocity's share along the radius
    descent = -x[:, IDX.v] * sin_gamma
    h = np.maximum(x[:, IDX.r] - radius, 0.0)
    with np.errstate(divide="ignore"):
        return np.where(descent > 0, h / np.maximum(descent, 1e-12), np.inf)


def alpha_rate_bound(state: np.ndarray, task: EntryTask, radius: float, rate_fraction: float = 0.8,
                     tolerance: float = np.radians(0.2)) -> np.ndarray:  # fmt: skip
    """The highest alpha rate (rad/s, (N,)) that still leaves at most ``tolerance`` of alpha at impact.

    :param rate_fraction: the share of the rate bound kept for taking alpha out (0 < f <= 1).
    :param tolerance: the alpha (rad) the bound aims to leave at impact (> 0).
    """
    if not (0.0 < rate_fraction <= 1.0 and tolerance > 0):
        raise ValueError(f"need 0 < rate_fraction <= 1 and tolerance > 0, got {rate_fraction!r}, {tolerance!r}")
    p, dt = task.problem, task.dt
    x = np.asarray(state, dtype=float)
    t_go = time_to_impact(x, radius)
    alpha = x[:, IDX.alpha] - p.final_alpha
    finite = np.isfinite(t_go)
    k = np.floor(np.where(finite, t_go, 0.0) / dt)  # whole steps before the step of impact
    t_last = np.where(finite, t_go, 0.0) - k * dt
    at_last = tolerance / np.maximum(1.0 - t_last / dt + TIME_TO_GO_MARGIN, TIME_TO_GO_MARGIN)
    allowed_next = at_last + rate_fraction * p.u_alpha_max * dt * np.maximum(k - 1.0, 0.0)
    bound = np.where(k == 0, -alpha, allowed_next - alpha) / dt
    return np.where(finite, bound, np.inf)


def dive_entry_speed(task: EntryTask, model, height: float, step_s: float = 0.02) -> float:
    """The speed (m/s) at ``height`` (m) above the target of a straight dive that meets the task's
    final speed at the target, alpha held at its final value and the bank angle still.

    The flight is integrated backward in time by the environment's own equations of motion from
    the shipped optimum's impact (vertical, at the target), its speed and alpha replaced by the
    task's final ones.
    """
    from rventry_env.core.backend import NUMPY
    from rventry_env.core.integrate import rk4_step
    from rventry_env.physics.entry import entry_rhs
    from rventry_env.reference import load_reference

    if not (np.isfinite(height) and height >= 0):
        raise ValueError(f"the dive's height must be a finite number of metres >= 0, got {height!r}")
    p = task.problem
    ref = load_reference()
    x = np.array(ref.state(ref.tf), dtype=float).reshape(12)
    x[IDX.v], x[IDX.alpha] = p.final_speed, p.final_alpha
    radius = model.planet.radius
    top = radius + p.final_altitude + height

    def rhs(t, y):
        return np.array(entry_rhs(tuple(y), (0.0, 0.0), model, NUMPY), dtype=float)

    prev = x
    for _ in range(int(1e5)):
        if x[IDX.r] >= top:
            f = (top - prev[IDX.r]) / (x[IDX.r] - prev[IDX.r]) if x[IDX.r] > prev[IDX.r] else 1.0
            return float(prev[IDX.v] + f * (x[IDX.v] - prev[IDX.v]))
        prev, x = x, rk4_step(rhs, 0.0, x, -step_s)
        if not np.all(np.isfinite(x)) or x[IDX.r] < prev[IDX.r]:
            break
    raise RuntimeError(f"no straight dive from {height:.0f} m meets {p.final_speed:.0f} m/s at the target "
                       f"(integrated back to {x[IDX.r] - radius:.0f} m)")


__all__ = ["alpha_rate_bound", "dive_entry_speed", "time_to_impact"]
