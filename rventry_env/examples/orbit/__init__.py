"""Example 1 of the paper: one period of a circular polar orbit in rv-Euler and spherical coordinates.

* :mod:`.numerics` - the orbit, the RK4 propagation in both forms, the error sweep;
* :mod:`.plots` - the panels of Fig. ``fig:Ex1-res``;
* :mod:`.cli` - ``rventry orbit``.
"""

from rventry_env.examples.orbit.numerics import (
    FORMS,
    CircularOrbit,
    OrbitRun,
    default_n_values,
    pole_pass_ratio,
    positions,
    propagate,
    run_example,
    sweep,
)

__all__ = [
    "FORMS",
    "CircularOrbit",
    "OrbitRun",
    "default_n_values",
    "pole_pass_ratio",
    "positions",
    "propagate",
    "run_example",
    "sweep",
]
