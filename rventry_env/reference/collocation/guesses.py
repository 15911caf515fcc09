"""Initial guesses: anything with ``t0``, ``tf``, ``state(t)`` and ``control(t)``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class TrajectoryLike(Protocol):
    t0: float
    tf: float

    def state(self, t) -> np.ndarray: ...

    def control(self, t) -> np.ndarray: ...


@dataclass
class SampledGuess:
    """A guess given as samples, interpolated linearly (the angles are not wrapped).

    :param t: strictly increasing times, shape ``(n,)``; ``t[0]`` is t0 and ``t[-1]`` the guessed tf.
    :param x: states, shape ``(n, n_x)``.
    :param u: controls, shape ``(n, n_u)``.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float)
        self.x = np.asarray(self.x, dtype=float)
        self.u = np.asarray(self.u, dtype=float)
        if self.t.ndim != 1 or self.t.size < 2 or np.any(np.diff(self.t) <= 0):
            raise ValueError("guess times must be 1-D, at least two, strictly increasing")
        for name, arr in (("x", self.x), ("u", self.u)):
            if arr.ndim != 2 or arr.shape[0] != self.t.size:
                raise ValueError(f"guess {name} must have shape ({self.t.size}, n), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"guess {name} contains NaN or inf")

    @property
    def t0(self) -> float:
        return float(self.t[0])

    @property
    def tf(self) -> float:
        return float(self.t[-1])

    def _interp(self, t, arr):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([np.interp(t, self.t, arr[:, i]) for i in range(arr.shape[1])], axis=-1)

    def state(self, t) -> np.ndarray:
        return self._interp(t, self.x)

    def control(self, t) -> np.ndarray:
        return self._interp(t, self.u)


__all__ = ["TrajectoryLike", "SampledGuess"]
