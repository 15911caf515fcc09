"""Translational motion in Cartesian coordinates of the observation frame E.

The third parameterization beside rv-Euler (:mod:`rventry_env.core.eom`) and
spherical coordinates (:mod:`rventry_env.core.spherical`): position and
E-relative velocity in E components, state order :data:`CARTESIAN_STATE_NAMES`.
It has no singularity and no trigonometry, but gravity needs the sqrt of
|r|^2. Used as the baseline of the right-hand-side benchmark and op counts.

Pure component arithmetic, with ``sqrt`` from the namespace ``ns``.
"""

from __future__ import annotations

from typing import Sequence

from rventry_env.core.backend import NUMPY, is_zero

CARTESIAN_STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz")
ZERO3 = (0.0, 0.0, 0.0)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def relative_acceleration(r_e: Sequence, v_e: Sequence, accel_e: Sequence, omega_e=ZERO3, alpha_e=ZERO3) -> tuple:
    """Acceleration seen in a rotating frame E (Newton's law in E, cf. Eq. ``F-apparent-1``).

    a = f/m - 2 w x v - alpha x r - w x (w x r), all vectors in E components.

    :param r_e: position (m).
    :param v_e: velocity relative to E (m/s).
    :param accel_e: applied force per unit mass (m/s^2).
    :param omega_e: angular velocity of E relative to N (rad/s).
    :param alpha_e: angular acceleration of E relative to N (rad/s^2).
    :return: the 3 components of the E-relative acceleration.
    """
    a = tuple(accel_e)
    if not all(is_zero(w) for w in omega_e):
        cor = _cross(omega_e, v_e)
        cen = _cross(omega_e, _cross(omega_e, r_e))
        a = tuple(a[i] - 2 * cor[i] - cen[i] for i in range(3))
    if not all(is_zero(w) for w in alpha_e):
        eul = _cross(alpha_e, r_e)
        a = tuple(a[i] - eul[i] for i in range(3))
    return a


def two_body_cartesian_rhs(x: Sequence, mu: float, ns=NUMPY) -> tuple:
    """Time derivatives of (x, y, z, vx, vy, vz) under point-mass gravity, Eq. ``Ex1-EOM``.

    :param x: the 6 components (scalars, NumPy arrays of one shape, or CasADi expressions).
    :param mu: gravitational parameter (m^3/s^2).
    :param ns: math namespace supplying sqrt.
    :return: tuple of the 6 derivatives.
    """
    px, py, pz, vx, vy, vz = x
    r2 = px * px + py * py + pz * pz
    k = -mu / (r2 * ns.sqrt(r2))  # -mu / r^3
    return (vx, vy, vz, k * px, k * py, k * pz)


__all__ = ["CARTESIAN_STATE_NAMES", "relative_acceleration", "two_body_cartesian_rhs"]
