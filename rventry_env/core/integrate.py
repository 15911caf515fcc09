"""Fixed-step classical Runge-Kutta, the one integrator the project shares.

``f(t, x)`` returns dx/dt shaped like ``x``. ``x`` is either an array (any batch
layout, for example ``(n_state, n_vehicles)``) or a tuple of components (Python
floats or arrays), the form the physics functions work in: the single environment
steps one vehicle on plain floats, which is several times faster than NumPy on
12-element arrays.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

Rhs = Callable[[float, np.ndarray], np.ndarray]


def _axpy(x, a, k):
    """x + a k for arrays or tuples of components."""
    if isinstance(x, tuple):
        return tuple(xi + a * ki for xi, ki in zip(x, k))
    return x + a * k


def rk4_step(f: Rhs, t, x, h, k1=None):
    """One classical fourth-order Runge-Kutta step of size ``h`` (scalar or broadcastable array).

    :param f: right-hand side ``f(t, x)``.
    :param t: time at the start of the step.
    :param x: state, an array or a tuple of components.
    :param h: step size.
    :param k1: ``f(t, x)`` if the caller already evaluated it (saves one evaluation).
    """
    k1 = f(t, x) if k1 is None else k1
    k2 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k1))
    k3 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k2))
    k4 = f(t + h, _axpy(x, h, k3))
    w = h / 6.0
    if isinstance(x, tuple):
        return tuple(xi + w * (a + 2.0 * (b + c) + d) for xi, a, b, c, d in zip(x, k1, k2, k3, k4))
    return x + w * (k1 + 2.0 * (k2 + k3) + k4)


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
