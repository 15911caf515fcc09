"""Sensor and navigation errors: what a vehicle measures of its own flight.

* :func:`accelerometer` - the sensed specific force, B components, from the true one with a
  bias, a scale-factor error and a misalignment per axis plus white noise;
* :func:`white_noise` - reproducible standard normals for N vehicles at one step, from each
  vehicle's key (a draw from its episode generator) and the step count: a counter-based
  stream, so a batch draws every vehicle's noise in one array operation and the single
  environment draws the same numbers;
* :func:`propagate_navigation_error` - the position and velocity error of an inertial
  navigation system, integrated from the entry fix through the accelerometer's error.

Component arithmetic on tuples of components (the ``ns`` style of the force models: NumPy and
JAX share it), with parameters per vehicle; the noise stream is NumPy's (the JAX Gymnasium
environment evaluates it on the host and sends it in). Magnitudes and their sources: docs/uncertainty.md.
"""

from __future__ import annotations

import numpy as np

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)


def _mix(z: np.ndarray) -> np.ndarray:
    """The SplitMix64 output function (Steele, Lea & Flood 2014): a bijective 64-bit mixer."""
    z = (z ^ (z >> np.uint64(30))) * _M2
    z = (z ^ (z >> np.uint64(27))) * _M3
    return z ^ (z >> np.uint64(31))


def white_noise(key, step, k: int = 3) -> np.ndarray:
    """(N, k) standard normals for vehicles with keys ``key`` (N,) uint64 at step ``step`` (N,).

    Sample j of a vehicle at a step is SplitMix64 of (key + (step k + j) golden-ratio
    increments), two of which make one normal by the Box-Muller transform: the same numbers
    whichever vehicles are evaluated together.
    """
    key = np.asarray(key, dtype=np.uint64).reshape(-1)
    step = np.asarray(step, dtype=np.uint64).reshape(-1)
    j = np.arange(2 * k, dtype=np.uint64)
    with np.errstate(over="ignore"):
        counter = (step[:, None] * np.uint64(2 * k) + j[None, :] + np.uint64(1)) * _M1
        bits = _mix(key[:, None] + counter)
    u = ((bits >> np.uint64(11)).astype(np.float64) + 0.5) * (1.0 / 9007199254740992.0)  # (0, 1)
    u1, u2 = u[:, :k], u[:, k:]
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def accelerometer(aero_b: tuple, bias: tuple, scale: tuple, misalignment: tuple, noise: tuple) -> tuple:
    """The sensed specific force (B components): (1 + s_i) a_i + (theta x a)_i + b_i + n_i.

    Component arithmetic (NumPy or JAX arrays, floats): every argument is 3 components.

    :param aero_b: the true aerodynamic specific force (m/s^2).
    :param bias, scale, misalignment, noise: per axis: bias (m/s^2), scale-factor error,
        small rotation of the sensor axes (rad), this sample's noise (m/s^2).
    """
    a, t = aero_b, misalignment
    cross = (t[1] * a[2] - t[2] * a[1], t[2] * a[0] - t[0] * a[2], t[0] * a[1] - t[1] * a[0])
    return tuple((1.0 + scale[i]) * a[i] + cross[i] + bias[i] + noise[i] for i in range(3))


def propagate_navigation_error(dr: tuple, dv: tuple, accel_error: tuple, dt) -> tuple[tuple, tuple]:
    """Position and velocity errors after ``dt`` with the acceleration error held over it.

    An inertial system integrates its accelerometer: its velocity error grows by the sensed
    acceleration's error, its position error by the velocity error (exact for a constant error
    over the step). Gravity's feedback on a position error (Schuler and vertical-channel terms,
    of order (g/r) dr dt^2) and the frame's rotation are left out: over a 10-minute flight with
    errors of hundreds of metres they are below a millimetre per second.

    :param dr, dv, accel_error: 3 components each, the same axes (Earth-fixed E components).
    :param dt: s (a number or one per vehicle).
    """
    new_dr = tuple(dr[i] + dv[i] * dt + 0.5 * accel_error[i] * dt * dt for i in range(3))
    return new_dr, tuple(dv[i] + accel_error[i] * dt for i in range(3))


__all__ = ["white_noise", "accelerometer", "propagate_navigation_error"]
