"""Guidance laws: what a vehicle does with what it measures.

A law is a batched callable ``law(obs, time_s, state) -> actions`` (see
:mod:`rventry_env.evaluation.rollout`): the observation, the time since the
episode's start and the navigation state, never the dispersion draw or the true
model. Laws with per-episode memory also implement ``reset(n_episodes)``.

* :class:`~rventry_env.guidance.reference_replay.ReferencePolicy` - the open-loop
  replay of the collocation optimum;
* :class:`~rventry_env.guidance.tvlqr.NeighboringOptimalGuidance` - time-varying LQR
  around the margined guidance reference.
"""
