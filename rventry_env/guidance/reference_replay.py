"""The open-loop replay of the collocation reference, as a policy :func:`rollout` can fly.

Learned policies (the PPO baseline, any saved SB3 model) live in :mod:`rventry_agents.sb3_policy`.
"""

from __future__ import annotations

import numpy as np

from rventry_env.guidance.law import Law, Measurement
from rventry_env.physics.entry import IDX
from rventry_env.task import EntryTask


class ReferencePolicy(Law):
    """Open-loop replay of the collocation reference's controls.

    The action held over [t, t + dt] is the reference's *mean* rate over that
    interval, (alpha_ref(t + dt) - alpha_ref(t)) / dt and likewise for sigma, so
    alpha and sigma match the reference exactly at every step boundary.
    """

    def __init__(self, task: EntryTask | None = None, reference=None):
        from rventry_env.reference import load_reference

        self.task = EntryTask() if task is None else task
        self.reference = load_reference() if reference is None else reference

    def __call__(self, m: Measurement) -> np.ndarray:
        p, dt = self.task.problem, self.task.dt
        time_s = m.time_s
        ref = self.reference
        x0 = ref.state(np.minimum(time_s, ref.tf))
        x1 = ref.state(np.minimum(time_s + dt, ref.tf))
        a = np.column_stack([(x1[:, IDX.alpha] - x0[:, IDX.alpha]) / (dt * p.u_alpha_max),
                             (x1[:, IDX.sigma] - x0[:, IDX.sigma]) / (dt * p.u_sigma_max)])  # fmt: skip
        return np.clip(a, -1.0, 1.0).astype(np.float32)
