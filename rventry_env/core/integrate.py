"""Fixed-step classical Runge-Kutta, the one integrator the project shares.

``f(t, x)`` returns dx/dt as an array shaped like ``x``; ``x`` may carry any
leading batch layout the caller likes (for example ``(n_state, n_vehicles)``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

Rhs = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(f: Rhs, t, x: np.ndarray, h) -> np.ndarray:
    """One classical fourth-order Runge-Kutta step of size ``h`` (scalar or broadcastable array)."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + (0.5 * h) * k1)
    k3 = f(t + 0.5 * h, x + (0.5 * h) * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


def rk4_fixed(f: Rhs, t0: float, x0: np.ndarray, h: float, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Integrate ``n_steps`` RK4 steps of size ``h``; returns times ``(n+1,)`` and states ``(n+1, *x0.shape)``."""
    if n_steps < 1:
        raise ValueError(f"n_steps must be >= 1, got {n_steps}")
    x = np.asarray(x0, dtype=float)
    xs = np.empty((n_steps + 1,) + x.shape)
    xs[0] = x
    for k in range(n_steps):
        x = rk4_step(f, t0 + k * h, x, h)
        xs[k + 1] = x
    return t0 + h * np.arange(n_steps + 1), xs


__all__ = ["rk4_step", "rk4_fixed"]
