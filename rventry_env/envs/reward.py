"""The environment's reward weights: what an RL agent is paid, not what the task asks.

The task (:mod:`rventry_env.task`) says what a flight must achieve; these weights turn
its running cost, path bounds and terminal errors into a reward. Only the environments
and training read them; guidance laws never see them.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, fields

from rventry_env.physics.checks import check_number

# the largest weight accepted: the defaults are 0.02 to 200, and at this bound the largest terminal
# penalty (a miss on the far side of the planet, 20,000 km) stays near 1e10, finite in float32
MAX_WEIGHT = 1e6


@dataclass(frozen=True)
class RewardWeights:
    """Reward weights. Each step pays -(running cost of Eq. Ex2-Cost over the step);
    the terminal step also pays -(terminal penalty); path violations are charged
    each step.

    Terminal penalty = miss_per_km * miss [km] + vertical_per_deg * vertical error [deg]
    + speed_per_mps * |v - v_f| [m/s] + alpha_per_deg * |alpha(t_f)| [deg].
    Linear, so a gradient survives far from the target and nothing explodes.
    Path penalty per second = load_violation * max(0, n/n_max - 1 - tol)
    + q_violation * max(0, 1 - q/q_min - tol), sampled at every RK4 node, with
    tol the 1 % margin of :class:`SuccessThresholds` (what counts as a violation).
    ``failure`` is added when an episode ends without impact (skip-out, non-finite
    state, stall). ``success_bonus`` (default 0) is *paid* at a successful impact
    (:class:`SuccessThresholds`): a learner's handle on the threshold-shaped task
    metric, off in the environment's own definition.

    Every weight is a finite number in [0, ``MAX_WEIGHT`` = 1e6]; anything else (NaN, infinity,
    a negative weight, a string) is refused at construction, naming the field.
    """

    miss_per_km: float = 0.2
    vertical_per_deg: float = 0.2
    speed_per_mps: float = 0.02
    alpha_per_deg: float = 0.1
    load_violation: float = 10.0
    q_violation: float = 10.0
    failure: float = 200.0
    success_bonus: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            check_number(self, f.name, low=0.0, high=MAX_WEIGHT)
            value = getattr(self, f.name)
            if isinstance(value, numbers.Real):
                object.__setattr__(self, f.name, float(value))


__all__ = ["RewardWeights", "MAX_WEIGHT"]
