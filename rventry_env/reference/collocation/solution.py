"""The NLP solution on one mesh, with its collocation polynomials as an interpolant."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.reference.collocation.interpolation import PiecewiseLGR
from rventry_env.reference.collocation.lgr import lagrange_matrix, lgr_points, support_points
from rventry_env.reference.collocation.mesh import Mesh
from rventry_env.reference.collocation.ocp import OptimalControlProblem


class _Interp(PiecewiseLGR):
    def evaluate_in_interval(self, k: int, s: np.ndarray, control: bool) -> np.ndarray:
        mesh = self.mesh
        a, b = mesh.breaks[k], mesh.breaks[k + 1]
        tau = 2.0 * (np.asarray(s) - a) / (b - a) - 1.0
        n, off = int(mesh.degrees[k]), int(mesh.offsets[k])
        if control:
            if n == 1:
                return np.repeat(self.u[off : off + 1], tau.size, axis=0)
            return lagrange_matrix(lgr_points(n), tau) @ self.u[off : off + n]
        return lagrange_matrix(support_points(n), tau) @ self.x[off : off + n + 1]


@dataclass
class CollocationSolution:
    """The NLP solution on one mesh.

    :param mesh: the mesh.
    :param t: times of the state nodes, ``(n_nodes,)``.
    :param x: states at the nodes, ``(n_nodes, n_x)``.
    :param u: controls at the collocation points, ``(n_nodes - 1, n_u)``.
    """

    problem: OptimalControlProblem
    mesh: Mesh
    t0: float
    tf: float
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    cost: float
    status: str
    success: bool
    nlp_iterations: int
    solve_time_s: float
    build_time_s: float
    max_violation: float
    violations: dict
    errors: np.ndarray | None = None
    parameters: np.ndarray | None = None  # the problem's parameter values solved with
    z: np.ndarray | None = None  # the scaled NLP solution and its multipliers (for warm starts)
    lam_x: np.ndarray | None = None
    lam_g: np.ndarray | None = None

    @property
    def interpolant(self) -> _Interp:
        return _Interp(self.mesh, self.t0, self.tf, self.x, self.u)

    def state(self, t) -> np.ndarray:
        return self.interpolant.state(t)

    def control(self, t) -> np.ndarray:
        return self.interpolant.control(t)

    @property
    def max_error(self) -> float:
        return float(np.max(self.errors)) if self.errors is not None else math.nan


__all__ = ["CollocationSolution"]
