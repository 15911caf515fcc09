"""Guidance laws: what a vehicle does with what it measures.

A law implements :class:`~rventry_env.guidance.law.GuidanceLaw`: ``law(measurement) -> actions``,
batched, where the :class:`~rventry_env.guidance.law.Measurement` holds what a vehicle measures
(observation, time, navigation state, sensed acceleration, flying mask), never the dispersion
draw or the true model; ``reset(n_episodes)``, ``episode_stats()`` and ``episodes_per_task``
complete it (defaults in :class:`~rventry_env.guidance.law.Law`).

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
