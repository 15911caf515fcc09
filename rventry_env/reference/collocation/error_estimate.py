"""The mesh error estimate of GPOPS-II (Patterson & Rao 2014, Sect. 4), per mesh interval."""

from __future__ import annotations

import numpy as np

from rventry_env.reference.collocation.compiled import CompiledProblem
from rventry_env.reference.collocation.lgr import integration_matrix, support_points
from rventry_env.reference.collocation.solution import CollocationSolution


def estimate_errors(cp: CompiledProblem, sol: CollocationSolution) -> np.ndarray:
    """Max relative error on each mesh interval (GPOPS-II, Patterson & Rao 2014, Sect. 4).

    On interval k with N LGR points take the N + 1 LGR points of a finer rule,
    evaluate the solution's polynomials there, integrate the dynamics with that
    rule's integration matrix from the interval's start, and compare:
    e = |X_integrated - X_polynomial| / (1 + max over the interval of |X|),
    maximised over the states and the new points.
    """
    mesh, interp = sol.mesh, sol.interpolant
    t0, tf = sol.t0, sol.tf
    all_s, owners = [], []
    for k, n in enumerate(mesh.degrees):
        m = int(n) + 1
        a, b = mesh.breaks[k], mesh.breaks[k + 1]
        all_s.append(a + (b - a) * (support_points(m) + 1.0) / 2.0)
        owners.append(k)
    # evaluate each interval's own polynomials (a point on a break belongs to the left
    # interval's support here, so do it per interval rather than through interval_of)
    xs, us = [], []
    for k, s in zip(owners, all_s):
        xs.append(interp.evaluate_in_interval(k, s, control=False))
        us.append(interp.evaluate_in_interval(k, s[:-1], control=True))
    t_col = np.concatenate([t0 + (tf - t0) * s[:-1] for s in all_s])
    fx = cp.rhs(np.vstack([x[:-1] for x in xs]), np.vstack(us), t_col, sol.parameters)
    errors = np.empty(mesh.n_intervals)
    pos = 0
    for k, (n, x) in enumerate(zip(mesh.degrees, xs)):
        m = int(n) + 1
        a, b = mesh.breaks[k], mesh.breaks[k + 1]
        fk = fx[pos : pos + m]
        pos += m
        xint = x[0] + (tf - t0) * (b - a) / 2.0 * (integration_matrix(m) @ fk)
        denom = 1.0 + np.max(np.abs(x), axis=0)
        errors[k] = np.max(np.abs(xint - x[1:]) / denom)
    return errors


__all__ = ["estimate_errors"]
