"""The two-body problem in spherical coordinates (the paper's Eq. ``Ex1-EOM-Geo``).

This is the *comparison* parameterization of Example 1, kept beside the rv-Euler
equations so the two can be integrated, benchmarked and op-counted side by side.
E is inertial here (omega_E = alpha_E = 0), as in the paper's Example 1.

State (6 components), :data:`SPHERICAL_STATE_NAMES`: geocentric radius r (m),
longitude phi, geocentric latitude theta, speed v (m/s), flight-path angle gamma
and azimuth psi (measured from north toward east), angles in radians. The same
order as :func:`rventry_env.core.conversions.spherical_from_cartesian`.

The equations divide by cos(theta) and so are singular at the poles; that
singularity is the point of the example. Pure component arithmetic with the
trigonometric functions taken from ``ns`` (see :mod:`rventry_env.core.backend`).
"""

from __future__ import annotations

from typing import Sequence

from rventry_env.core.backend import NUMPY

SPHERICAL_STATE_NAMES = ("r", "lon", "lat", "v", "gamma", "psi")


def two_body_spherical_rhs(s: Sequence, mu: float, ns=NUMPY) -> tuple:
    """Time derivatives of the 6 spherical coordinates under point-mass gravity, Eq. ``Ex1-EOM-Geo``.

    :param s: (r, lon, lat, v, gamma, psi) as scalars, NumPy arrays of one shape, or CasADi
        expressions.
    :param mu: gravitational parameter (m^3/s^2).
    :param ns: math namespace supplying sin and cos.
    :return: tuple of the 6 derivatives.
    """
    r, _lon, lat, v, gamma, psi = s
    sg, cg = ns.sin(gamma), ns.cos(gamma)
    sp, cp = ns.sin(psi), ns.cos(psi)
    st, ct = ns.sin(lat), ns.cos(lat)
    v_r = v / r
    g = mu / (r * r)
    # v cos(gamma) sin(psi) / (r cos(theta)) appears in both phi_dot and psi_dot
    lon_dot = v_r * cg * sp / ct
    return (
        v * sg,  # r_dot
        lon_dot,  # phi_dot
        v_r * cg * cp,  # theta_dot
        -g * sg,  # v_dot
        cg * (v_r - g / v),  # gamma_dot
        lon_dot * st,  # psi_dot
    )


__all__ = ["SPHERICAL_STATE_NAMES", "two_body_spherical_rhs"]
