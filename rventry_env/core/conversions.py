"""Conversions between rv-Euler parameters, Cartesian and spherical coordinates.

All arrays are batched over leading axes; the last axis holds the components.
An rv-Euler state array has at least 10 components in the order of
:data:`rventry_env.core.eom.STATE_NAMES`; extra trailing components (the entry
problem's alpha and sigma) are ignored where only the first 10 matter.

The free rotations
------------------
r and v fix a1 and b1 only. The rotation of (a2, a3) about r and of (b2, b3)
about v is free (the paper then keeps it fixed with omega_A1 = omega_B1 = 0). The
conversion from Cartesian picks it by one of these rules, or takes a2 and b2
explicitly:

``"east-down"`` (default)
    a2 points east (along e3 x a1), a3 = a1 x a2 points north. b2 is the unit
    vector normal to b1 in the vertical plane of the velocity, pointing down
    (along the part of -a1 normal to b1); b3 = b1 x b2. For horizontal flight
    toward the east this gives C_BA of the paper's Table ``tab:Ex2-BCs``, where
    the bank angle sigma = 180 deg means lift up. Where a rule is undefined it
    falls back: at the poles (a1 = +-e3) a2 is along e1 x a1; in vertical flight
    (b1 = +-a1) b2 is the part of a2 normal to b1.
``"orbital"``
    a3 and b3 along the angular momentum r x v (Example 1: "the initial
    conditions align a3 and b3 with the specific angular momentum"), so
    a2 = a3 x a1 and b2 = b3 x b1. Undefined when r and v are parallel.

Spherical coordinates
---------------------
(r, longitude, geocentric latitude, v, flight-path angle, azimuth), angles in
radians, azimuth measured from north toward east (the paper's psi). Longitude
and azimuth are undefined at the poles, azimuth is undefined in vertical flight:
the conversion raises :class:`SingularConversionError` there (or returns NaN in
the undefined entries with ``on_singular="nan"``).
"""

from __future__ import annotations

import numpy as np

from rventry_env.core import euler_parameters as ep

_E1 = np.array([1.0, 0.0, 0.0])
_E3 = np.array([0.0, 0.0, 1.0])
FRAME_RULES = ("east-down", "orbital")


class SingularConversionError(ValueError):
    """A conversion was asked for a quantity that is undefined at this state."""


def _unit(x, what: str, tol: float = 1e-12):
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    if np.any(~np.isfinite(n)):
        raise ValueError(f"{what} has non-finite components")
    if np.any(n <= tol):
        idx = np.argwhere(n[..., 0] <= tol)[0].tolist()
        raise ValueError(f"{what} has zero length (at index {idx})")
    return x / n


def _normal_part(x, axis):
    """The part of x normal to the unit vector ``axis``.

    Computed as (axis x x) x axis, which equals x - (x . axis) axis but stays
    orthogonal to ``axis`` to rounding even when x is nearly parallel to it. The
    subtraction form loses that near vertical flight: with v within 1e-8 rad of r,
    b2 came out 1e-9 off normal to b1 and the Cartesian round trip moved v by 1e-9.
    """
    return np.cross(np.cross(axis, x), axis)


def _pick(primary, fallback, tol: float = 1e-9):
    """Unit vector along ``primary`` where it is well defined, else along ``fallback``."""
    n = np.linalg.norm(primary, axis=-1, keepdims=True)
    m = np.linalg.norm(fallback, axis=-1, keepdims=True)
    if np.any((n <= tol) & (m <= tol)):
        raise ValueError("both the rule's axis and its fallback are degenerate")
    return np.where(n > tol, primary / np.where(n > tol, n, 1.0), fallback / np.where(m > tol, m, 1.0))


def _check_vec3(x, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"{name} must have 3 components on its last axis, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")
    return x


def rv_euler_from_cartesian(r_e, v_e, *, rule: str = "east-down", a2=None, b2=None) -> np.ndarray:
    """rv-Euler parameters ``(..., 10)`` from position and E-relative velocity in E.

    :param r_e: position in E components, shape ``(..., 3)`` (m).
    :param v_e: velocity relative to E, in E components, shape ``(..., 3)`` (m/s).
    :param rule: how to fix the free rotations: ``"east-down"`` or ``"orbital"``
        (see the module docstring).
    :param a2: optional explicit a2 direction in E (its part normal to r is used).
    :param b2: optional explicit b2 direction in E (its part normal to v is used).
    """
    if rule not in FRAME_RULES:
        raise ValueError(f"unknown frame rule {rule!r}; choose one of {FRAME_RULES}")
    r_e = _check_vec3(r_e, "r_e")
    v_e = _check_vec3(v_e, "v_e")
    r_e, v_e = np.broadcast_arrays(r_e, v_e)
    a1 = _unit(r_e, "position r_e")
    b1 = _unit(v_e, "velocity v_e (rv-Euler parameters need v > 0)")
    if rule == "orbital" and (a2 is None or b2 is None):
        h = _unit(np.cross(a1, b1), "angular momentum r x v (the orbital rule needs r not parallel to v)")
    if a2 is not None:
        a2 = _unit(_normal_part(_check_vec3(a2, "a2"), a1), "a2 normal to r")
    elif rule == "orbital":
        a2 = np.cross(h, a1)
    else:
        a2 = _pick(np.cross(_E3, a1), np.cross(_E1, a1))
    a3 = np.cross(a1, a2)
    if b2 is not None:
        b2 = _unit(_normal_part(_check_vec3(b2, "b2"), b1), "b2 normal to v")
    elif rule == "orbital":
        b2 = np.cross(h, b1)
    else:
        b2 = _pick(_normal_part(-a1, b1), _normal_part(a2, b1))
    b3 = np.cross(b1, b2)
    c_ae = np.stack([a1, a2, a3], axis=-2)  # rows: a_i in E
    c_be = np.stack([b1, b2, b3], axis=-2)
    c_ba = c_be @ np.swapaxes(c_ae, -1, -2)
    r = np.linalg.norm(r_e, axis=-1, keepdims=True)
    v = np.linalg.norm(v_e, axis=-1, keepdims=True)
    return np.concatenate([r, ep.quaternion_from_dcm(c_ae), v, ep.quaternion_from_dcm(c_ba)], axis=-1)


def _check_state(x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] < 10:
        raise ValueError(f"an rv-Euler state needs at least 10 components on its last axis, got shape {x.shape}")
    return x


def position_velocity_directions(x):
    """(a1, b1) in E components for rv-Euler states ``x (..., >=10)``."""
    x = _check_state(x)
    c_ae = ep.dcm_from_quaternion(x[..., 1:5])
    c_ba = ep.dcm_from_quaternion(x[..., 6:10])
    a1 = c_ae[..., 0, :]
    b1 = np.einsum("...j,...jk->...k", c_ba[..., 0, :], c_ae)
    return a1, b1


def cartesian_from_rv_euler(x):
    """Position and E-relative velocity ``(r_e, v_e)`` in E components, each ``(..., 3)``.

    ``r_e = r C_AE(1, :)`` and ``v_e = v (C_BA C_AE)(1, :)`` (docs/conventions.md).
    """
    x = _check_state(x)
    a1, b1 = position_velocity_directions(x)
    return x[..., 0:1] * a1, x[..., 5:6] * b1


def _singular(mask, message: str, on_singular: str):
    if on_singular == "raise" and np.any(mask):
        idx = np.argwhere(np.atleast_1d(mask))[0].tolist()
        n = int(np.count_nonzero(mask))
        raise SingularConversionError(f"{message} ({n} state(s), first at index {idx})")


def spherical_from_rv_euler(x, *, on_singular: str = "raise", tol: float = 1e-9) -> np.ndarray:
    """Spherical coordinates ``(..., 6)``: r, longitude, latitude, v, flight-path angle, azimuth.

    :param on_singular: ``"raise"`` (default) raises :class:`SingularConversionError`
        at the poles (longitude, azimuth undefined) and in vertical flight (azimuth
        undefined); ``"nan"`` puts NaN in the undefined entries instead.
    :param tol: a pole or vertical flight is where cos(latitude) or cos(flight-path
        angle) is below ``tol``.
    """
    if on_singular not in ("raise", "nan"):
        raise ValueError("on_singular must be 'raise' or 'nan'")
    x = _check_state(x)
    a1, b1 = position_velocity_directions(x)
    return _spherical_from_directions(x[..., 0], x[..., 5], a1, b1, on_singular, tol)


def spherical_from_cartesian(r_e, v_e, *, on_singular: str = "raise", tol: float = 1e-9) -> np.ndarray:
    """Spherical coordinates ``(..., 6)`` from Cartesian position and E-relative velocity."""
    r_e = _check_vec3(r_e, "r_e")
    v_e = _check_vec3(v_e, "v_e")
    r = np.linalg.norm(r_e, axis=-1)
    v = np.linalg.norm(v_e, axis=-1)
    return _spherical_from_directions(r, v, _unit(r_e, "r_e"), _unit(v_e, "v_e"), on_singular, tol)


def _spherical_from_directions(r, v, a1, b1, on_singular, tol):
    if on_singular not in ("raise", "nan"):  # checked here so every public entry point checks it
        raise ValueError(f"on_singular must be 'raise' or 'nan', got {on_singular!r}")
    cos_lat = np.hypot(a1[..., 0], a1[..., 1])
    lat = np.arctan2(a1[..., 2], cos_lat)
    pole = cos_lat < tol
    _singular(pole, "longitude and azimuth are undefined at the poles (latitude = +-90 deg)", on_singular)
    lon = np.arctan2(a1[..., 1], a1[..., 0])
    up = np.sum(b1 * a1, axis=-1)
    horizontal = b1 - up[..., None] * a1
    cos_gamma = np.linalg.norm(horizontal, axis=-1)
    gamma = np.arctan2(up, cos_gamma)
    vertical = cos_gamma < tol
    _singular(vertical, "azimuth is undefined in vertical flight (flight-path angle = +-90 deg)", on_singular)
    east = np.stack([-a1[..., 1], a1[..., 0], np.zeros_like(cos_lat)], axis=-1)  # cos(lat) * east
    north = np.cross(a1, east)  # cos(lat) * north
    psi = np.arctan2(np.sum(horizontal * east, -1), np.sum(horizontal * north, -1))
    lon = np.where(pole, np.nan, lon)
    psi = np.where(pole | vertical, np.nan, psi)
    return np.stack([r, lon, lat, v, gamma, psi], axis=-1)


def cartesian_from_spherical(s):
    """Position and E-relative velocity in E from spherical coordinates ``(..., 6)``."""
    s = np.asarray(s, dtype=float)
    if s.ndim == 0 or s.shape[-1] != 6:
        raise ValueError(f"spherical coordinates need 6 components on the last axis, got shape {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("spherical coordinates contain NaN or inf")
    r, lon, lat, v, gamma, psi = np.moveaxis(s, -1, 0)
    if np.any(r <= 0) or np.any(v <= 0):
        raise ValueError("r and v must be positive")
    cl, sl, co, so = np.cos(lat), np.sin(lat), np.cos(lon), np.sin(lon)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    east = np.stack([-so, co, np.zeros_like(co)], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    cg, sg = np.cos(gamma), np.sin(gamma)
    vdir = sg[..., None] * up + cg[..., None] * (np.cos(psi)[..., None] * north + np.sin(psi)[..., None] * east)
    return r[..., None] * up, v[..., None] * vdir


def rv_euler_from_spherical(s, *, rule: str = "east-down") -> np.ndarray:
    """rv-Euler parameters ``(..., 10)`` from spherical coordinates ``(..., 6)``."""
    r_e, v_e = cartesian_from_spherical(s)
    return rv_euler_from_cartesian(r_e, v_e, rule=rule)


# ---------------------------------------------------------------------------------
# bank angle


def lift_up_angle(e_b, ns=None):
    """Angle theta_u of 'lift up' measured like the paper's sigma (about b1 from b2).

    The local vertical a1 has B components C_BA(:, 1); its part normal to b1 is
    (0, C_BA(2,1), C_BA(3,1)), so lift up is sigma = atan2(C_BA(3,1), C_BA(2,1)).
    Component function: works on NumPy arrays (``ns=None``) or with a namespace.
    """
    eb1, eb2, eb3, etab = e_b
    u2 = 2 * (eb2 * eb1 - eb3 * etab)
    u3 = 2 * (eb3 * eb1 + eb2 * etab)
    atan2 = np.arctan2 if ns is None else ns.arctan2
    return atan2(u3, u2), u2 * u2 + u3 * u3


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _bank_inputs(x, angle, name):
    x = _check_state(x)
    angle = np.asarray(angle, dtype=float)
    if not np.all(np.isfinite(angle)):
        raise ValueError(f"{name} contains NaN or inf")
    theta_u, n2 = lift_up_angle(np.moveaxis(x[..., 6:10], -1, 0))
    _singular(n2 < 1e-18, "the conventional bank angle is undefined in vertical flight", "raise")
    return theta_u


def conventional_bank(x, sigma) -> np.ndarray:
    """Conventional bank angle mu from the paper's sigma (both rad).

    mu = 0 is lift up, positive toward b1 x up (right of the flight direction);
    sigma is the rotation about b1 from b2 to the lift (Eq. ``Ex2-EOM-Ftot``).
    Then mu = sigma - theta_u, wrapped to [-pi, pi). Undefined in vertical flight.
    """
    return wrap_angle(np.asarray(sigma, dtype=float) - _bank_inputs(x, sigma, "sigma"))


def paper_bank(x, mu) -> np.ndarray:
    """The paper's bank angle sigma from the conventional mu (inverse of :func:`conventional_bank`)."""
    return wrap_angle(np.asarray(mu, dtype=float) + _bank_inputs(x, mu, "mu"))


__all__ = [
    "FRAME_RULES",
    "SingularConversionError",
    "rv_euler_from_cartesian",
    "cartesian_from_rv_euler",
    "position_velocity_directions",
    "spherical_from_rv_euler",
    "spherical_from_cartesian",
    "cartesian_from_spherical",
    "rv_euler_from_spherical",
    "lift_up_angle",
    "wrap_angle",
    "conventional_bank",
    "paper_bank",
]
