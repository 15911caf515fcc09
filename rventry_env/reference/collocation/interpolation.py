"""The collocation polynomials as an interpolant (NumPy only).

On interval k the state is the Lagrange polynomial of degree N_k through its
N_k LGR points and the interval's end; the control is the polynomial of degree
N_k - 1 through the N_k LGR points (extrapolated to the interval's end, which is
how the control at tf is defined). Both are exactly what the transcription
collocated, so this interpolant *is* the solution, not an approximation of it.
"""

from __future__ import annotations

import numpy as np

from rventry_env.reference.collocation.lgr import lagrange_matrix, lgr_points, support_points
from rventry_env.reference.collocation.mesh import Mesh


class PiecewiseLGR:
    """Evaluate state and control polynomials of a collocation solution.

    :param mesh: the mesh the values belong to.
    :param t0: initial time.
    :param tf: final time.
    :param x: states at the ``mesh.n_nodes`` state nodes, shape ``(n_nodes, n_x)``.
    :param u: controls at the collocation points, shape ``(n_collocation, n_u)``
        (a row for the final node, if present, is ignored: the last interval's
        polynomial defines the control at tf).
    """

    def __init__(self, mesh: Mesh, t0: float, tf: float, x: np.ndarray, u: np.ndarray):
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        if x.ndim != 2 or x.shape[0] != mesh.n_nodes:
            raise ValueError(f"x must have shape ({mesh.n_nodes}, n_x), got {x.shape}")
        if u.ndim != 2 or u.shape[0] not in (mesh.n_collocation, mesh.n_nodes):
            raise ValueError(f"u must have {mesh.n_collocation} (or {mesh.n_nodes}) rows, got {u.shape}")
        if not tf > t0:
            raise ValueError(f"tf ({tf}) must exceed t0 ({t0})")
        self.mesh, self.t0, self.tf = mesh, float(t0), float(tf)
        self.x, self.u = x, u[: mesh.n_collocation]

    def _normalise(self, t) -> tuple[np.ndarray, bool]:
        t = np.asarray(t, dtype=float)
        scalar = t.ndim == 0
        if np.any(np.isnan(t)):
            raise ValueError("times must not be NaN")
        s = np.clip((np.atleast_1d(t).ravel() - self.t0) / (self.tf - self.t0), 0.0, 1.0)
        return s, scalar

    def _evaluate(self, s: np.ndarray, control: bool) -> np.ndarray:
        mesh = self.mesh
        vals = self.u if control else self.x
        out = np.empty((s.size, vals.shape[1]))
        k_of = mesh.interval_of(s)
        for k in np.unique(k_of):
            sel = k_of == k
            a, b = mesh.breaks[k], mesh.breaks[k + 1]
            tau = 2.0 * (s[sel] - a) / (b - a) - 1.0
            n, off = int(mesh.degrees[k]), int(mesh.offsets[k])
            if control:
                if n == 1:
                    out[sel] = vals[off]
                    continue
                p = lagrange_matrix(lgr_points(n), tau)
                out[sel] = p @ vals[off : off + n]
            else:
                p = lagrange_matrix(support_points(n), tau)
                out[sel] = p @ vals[off : off + n + 1]
        return out

    def state(self, t) -> np.ndarray:
        """States at times ``t`` (clamped to [t0, tf]); ``(n_x,)`` for a scalar, else ``(len(t), n_x)``."""
        s, scalar = self._normalise(t)
        out = self._evaluate(s, control=False)
        return out[0] if scalar else out

    def control(self, t) -> np.ndarray:
        """Controls at times ``t`` (clamped to [t0, tf]); ``(n_u,)`` for a scalar, else ``(len(t), n_u)``."""
        s, scalar = self._normalise(t)
        out = self._evaluate(s, control=True)
        return out[0] if scalar else out

    def node_controls(self) -> np.ndarray:
        """Controls at every state node, the last extrapolated to tf: shape ``(n_nodes, n_u)``."""
        last = self._evaluate(np.array([1.0]), control=True)
        return np.vstack([self.u, last])


__all__ = ["PiecewiseLGR"]
