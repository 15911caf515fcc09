"""Guidance laws: what a vehicle does with what it measures.

A law is a batched callable ``law(obs, time_s, state) -> actions`` (see
:mod:`rventry_env.evaluation.rollout`): the observation, the time since the
episode's start and the navigation state, never the dispersion draw or the true
model. Laws with per-episode memory also implement ``reset(n_episodes)``.

* :class:`~rventry_env.guidance.reference_replay.ReferencePolicy` - the open-loop
  replay of the collocation optimum;
* :class:`~rventry_env.guidance.tvlqr.NeighboringOptimalGuidance` - time-varying LQR
  around the margined guidance reference;
* :class:`~rventry_env.guidance.replanning.ReplanningGuidance` - re-solves the entry problem
  from the current state with the estimated aerodynamic scales (``mpc``).

Parts that laws share:

* :class:`~rventry_env.guidance.estimation.AeroScaleEstimator` - the aerodynamic scales from
  the accelerometer;
* :class:`~rventry_env.guidance.load_relief.LoadRelief` - a predictive cap on the alpha rate
  that keeps the load factor in bound.
"""
