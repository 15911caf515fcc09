"""The collocation mesh and its hp (raise-degree-or-split) refinement.

A mesh divides the normalised time s = (t - t0) / (tf - t0) in [0, 1] into K
intervals with breakpoints ``breaks`` and gives interval k ``degrees[k]`` LGR
points. Node layout (shared by the transcription, the interpolant and the data
file): the state lives at every interval's LGR points plus s = 1, so
``n_nodes = sum(degrees) + 1``; the first ``n_nodes - 1`` nodes are the
collocation points, where the controls live; interval k owns collocation points
``offsets[k] : offsets[k] + degrees[k]`` and its state polynomial uses nodes
``offsets[k] : offsets[k] + degrees[k] + 1`` (the next interval's first point, or
s = 1, closes it).

Refinement follows the ph method of Patterson, Hager & Rao (2015) used by
GPOPS-II: on an interval whose relative error e exceeds the tolerance eps, raise
the degree N by P = ceil(log(e / eps) / log(N)); if N + P exceeds ``n_max``,
split instead into B = max(ceil((N + P) / n_min), 2) equal subintervals of
``n_min`` points each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.reference.collocation.lgr import MAX_DEGREE, lgr_points


@dataclass(frozen=True)
class Mesh:
    """Breakpoints in normalised time and the number of LGR points per interval.

    :param breaks: ``K + 1`` strictly increasing values from 0 to 1.
    :param degrees: ``K`` numbers of LGR points (each >= 1).
    """

    breaks: np.ndarray
    degrees: np.ndarray

    def __post_init__(self):
        b = np.asarray(self.breaks, dtype=float)
        d = np.asarray(self.degrees)
        if b.ndim != 1 or b.size < 2:
            raise ValueError("mesh breaks must be 1-D with at least two values")
        if abs(b[0]) > 1e-14 or abs(b[-1] - 1.0) > 1e-14:
            raise ValueError(f"mesh breaks must run from 0 to 1, got {b[0]} .. {b[-1]}")
        if np.any(np.diff(b) <= 0):
            raise ValueError("mesh breaks must be strictly increasing")
        if d.ndim != 1 or d.size != b.size - 1:
            raise ValueError(f"a mesh with {b.size - 1} intervals needs {b.size - 1} degrees, got {d.size}")
        if not np.issubdtype(d.dtype, np.integer):
            if np.any(d != np.round(d)):
                raise ValueError("mesh degrees must be integers")
        d = d.astype(int)
        if np.any(d < 1) or np.any(d > MAX_DEGREE):
            raise ValueError(f"mesh degrees must be in [1, {MAX_DEGREE}], got {d.tolist()}")
        b = b.copy()
        b[0], b[-1] = 0.0, 1.0
        object.__setattr__(self, "breaks", b)
        object.__setattr__(self, "degrees", d)

    @classmethod
    def uniform(cls, n_intervals: int, degree: int) -> "Mesh":
        """``n_intervals`` equal intervals of ``degree`` LGR points each."""
        if n_intervals < 1:
            raise ValueError(f"n_intervals must be >= 1, got {n_intervals}")
        return cls(np.linspace(0.0, 1.0, n_intervals + 1), np.full(n_intervals, degree, dtype=int))

    @property
    def n_intervals(self) -> int:
        return int(self.degrees.size)

    @property
    def n_collocation(self) -> int:
        """Number of collocation points (where the controls live)."""
        return int(self.degrees.sum())

    @property
    def n_nodes(self) -> int:
        """Number of state nodes (the collocation points and s = 1)."""
        return self.n_collocation + 1

    @property
    def offsets(self) -> np.ndarray:
        """Index of each interval's first node."""
        return np.concatenate([[0], np.cumsum(self.degrees)[:-1]]).astype(int)

    def nodes(self) -> np.ndarray:
        """Normalised times of the state nodes, shape ``(n_nodes,)``."""
        parts = [
            self.breaks[k] + (self.breaks[k + 1] - self.breaks[k]) * (lgr_points(int(n)) + 1.0) / 2.0
            for k, n in enumerate(self.degrees)
        ]
        return np.concatenate(parts + [[1.0]])

    def interval_of(self, s: np.ndarray) -> np.ndarray:
        """Index of the interval holding each normalised time (the last one holds s = 1)."""
        s = np.asarray(s, dtype=float)
        return np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, self.n_intervals - 1)


def refine_ph(mesh: Mesh, errors: np.ndarray, tol: float, n_min: int = 3, n_max: int = 12) -> Mesh:
    """One ph refinement step (Patterson, Hager & Rao 2015).

    :param mesh: the current mesh.
    :param errors: max relative error per interval, shape ``(K,)``.
    :param tol: target relative error.
    :param n_min: LGR points in a new subinterval.
    :param n_max: largest number of LGR points before an interval is split.
    :return: the refined mesh (the same mesh if every error is within ``tol``).
    """
    errors = np.asarray(errors, dtype=float)
    if errors.shape != (mesh.n_intervals,):
        raise ValueError(f"need one error per interval ({mesh.n_intervals}), got shape {errors.shape}")
    if not tol > 0:
        raise ValueError(f"the mesh tolerance must be positive, got {tol}")
    if not 1 <= n_min <= n_max <= MAX_DEGREE:
        raise ValueError(f"need 1 <= n_min <= n_max <= {MAX_DEGREE}, got n_min={n_min}, n_max={n_max}")
    breaks = [0.0]
    degrees: list[int] = []
    for k, (n, e) in enumerate(zip(mesh.degrees, errors)):
        a, b = mesh.breaks[k], mesh.breaks[k + 1]
        if not np.isfinite(e):
            e = 1e3 * tol  # a NaN error (failed evaluation) is treated as large
        if e <= tol:
            breaks.append(b)
            degrees.append(int(n))
            continue
        # the error of a spectral approximation falls roughly like N^-P
        p = max(1, math.ceil(math.log(e / tol) / math.log(max(int(n), 2))))
        if n + p <= n_max:
            breaks.append(b)
            degrees.append(int(n + p))
        else:
            parts = max(math.ceil((n + p) / n_min), 2)
            for j in range(1, parts + 1):
                breaks.append(a + (b - a) * j / parts)
                degrees.append(int(n_min))
    return Mesh(np.array(breaks), np.array(degrees, dtype=int))


__all__ = ["Mesh", "refine_ph"]
