"""Entry dynamics: the rv-Euler equations with lift, drag, gravity and a rotating planet.

This is the paper's Example 2 system (Eqs. ``Ex2-EOM`` to ``Ex2-EOM-Ftot``) in
general form: E is the planet-fixed frame rotating at ``planet.omega`` about e3,
N is inertial, and the force-model parts come from an
:class:`~rventry_env.physics.model.EntryModel`. The state has 12 components in
the order of docs/conventions.md (:data:`ENTRY_STATE_NAMES`); the controls are the angle-of-attack
and bank-angle rates.

The bank angle sigma is the paper's: a rotation about b1 from b2 to the lift
direction, so lift = L (cos sigma b2 + sin sigma b3). Use
:func:`rventry_env.core.conversions.conventional_bank` for the conventional one.

With a wind, lift and drag follow the air-relative velocity v_air = v - w: drag
is along -v_air, and lift along the part of (cos sigma b2 + sin sigma b3) normal
to v_air. Without wind this is exactly Eq. ``Ex2-EOM-Ftot``.

One copy of this physics serves the environments (NumPy, batched), the
collocation transcription (CasADi) and the identification tool.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

from rventry_env.core.backend import NUMPY, dot3, sparse, sparse_dot
from rventry_env.core.eom import STATE_NAMES, rv_euler_rates
from rventry_env.core.euler_parameters import dcm, dcm_column
from rventry_env.physics.model import EntryModel

ENTRY_STATE_NAMES = STATE_NAMES + ("alpha", "sigma")
CONTROL_NAMES = ("u_alpha", "u_sigma")
N_STATE = len(ENTRY_STATE_NAMES)


class StateLayout(NamedTuple):
    """Where each quantity sits in the entry state (the order of :data:`ENTRY_STATE_NAMES`):
    ``x[..., IDX.alpha]``, ``x[..., IDX.angles]``. Written once, here; code that slices a state
    names the slice."""

    r: int = ENTRY_STATE_NAMES.index("r")
    e_a: slice = slice(ENTRY_STATE_NAMES.index("eA1"), ENTRY_STATE_NAMES.index("etaA") + 1)
    v: int = ENTRY_STATE_NAMES.index("v")
    e_b: slice = slice(ENTRY_STATE_NAMES.index("eB1"), ENTRY_STATE_NAMES.index("etaB") + 1)
    alpha: int = ENTRY_STATE_NAMES.index("alpha")
    sigma: int = ENTRY_STATE_NAMES.index("sigma")
    angles: slice = slice(ENTRY_STATE_NAMES.index("alpha"), ENTRY_STATE_NAMES.index("sigma") + 1)
    translation: slice = slice(0, ENTRY_STATE_NAMES.index("etaB") + 1)


IDX = StateLayout()


class EntryForces(NamedTuple):
    """Forces and flow quantities at one state (all SI)."""

    altitude: object
    density: object
    dynamic_pressure: object  # q = rho |v_air|^2 / 2 (Pa)
    mach: object
    cl: object
    cd: object
    lift_accel: object  # L / m (m/s^2)
    drag_accel: object  # D / m (m/s^2)
    accel_b: tuple  # applied specific force (aero + gravity), B components
    e3_a: tuple  # the planet's spin axis in A, C_AE(:, 3); (sin latitude, ., .)
    c_ba: tuple
    aero_b: tuple  # aerodynamic specific force, B components: what an accelerometer senses
    # sqrt(L^2 + D^2) / m, the quantity bounded by a_max in Eq. Ex2-path (m/s^2). With ns.sqrt, not
    # ** 0.5: XLA keeps a float power as pow(), which in float64 on a GPU costs a log and an exp
    aero_accel: object


def entry_forces(x: Sequence, model: EntryModel, ns=NUMPY) -> EntryForces:
    """Aerodynamic and gravitational forces for the 12 state components ``x``."""
    r, v, alpha, sigma = x[0], x[5], x[10], x[11]
    # the dynamics need only C_AE's third column (the spin axis in A), not all of C_AE
    e3_a = dcm_column(*x[1:5], 2)
    c_ba = dcm(*x[6:10])
    h = r - model.planet.radius
    atm = model.atmosphere
    rho = atm.density(h, ns)
    veh = model.vehicle
    k = veh.reference_area / veh.mass
    if model.wind is None:
        v_air = v
    else:
        w_a = model.wind.velocity_a(h, e3_a, ns)
        w_b = tuple(dot3(c_ba[i], w_a) for i in range(3))
        va = (v - w_b[0], -w_b[1], -w_b[2])
        v_air = ns.sqrt(va[0] * va[0] + va[1] * va[1] + va[2] * va[2])
    q = 0.5 * rho * v_air * v_air
    mach = v_air / atm.speed_of_sound(h, ns)
    cl, cd = veh.aerodynamics.coefficients(alpha, mach, ns)
    lift = q * k * cl
    drag = q * k * cd
    cs, sn = ns.cos(sigma), ns.sin(sigma)
    if model.wind is None:
        aero = (-drag, lift * cs, lift * sn)  # Eq. Ex2-EOM-Ftot
    else:
        u = tuple(c / v_air for c in va)  # unit air-relative velocity, B components
        l0 = (0.0, cs, sn)
        d = dot3(l0, u)
        lv = tuple(l0[i] - d * u[i] for i in range(3))
        ln = ns.sqrt(dot3(lv, lv))
        aero = tuple(-drag * u[i] + lift * lv[i] / ln for i in range(3))
    g_nz = sparse(model.gravity.acceleration_a(r, e3_a, ns))  # point mass: (g, 0, 0)
    accel_b = tuple(aero[i] + sparse_dot(c_ba[i], g_nz) for i in range(3))
    return EntryForces(h, rho, q, mach, cl, cd, lift, drag, accel_b, e3_a, c_ba, aero, ns.sqrt(lift * lift + drag * drag))


def entry_rhs(x: Sequence, u: Sequence, model: EntryModel, ns=NUMPY, forces: EntryForces | None = None):
    """Time derivatives of the 12 entry state components.

    :param x: the 12 components (NumPy arrays of one shape, or CasADi expressions).
    :param u: (u_alpha, u_sigma) in rad/s.
    :param model: the force-model parts.
    :param ns: math namespace (:data:`~rventry_env.core.backend.NUMPY` or
        :func:`~rventry_env.core.backend.casadi_ns`).
    :param forces: precomputed :func:`entry_forces` at ``x`` (saves work).
    :return: tuple of 12 derivatives.
    """
    f = entry_forces(x, model, ns) if forces is None else forces
    w = model.planet.omega  # E spins about e3: omega_E in A is w C_AE(:, 3)
    rates = rv_euler_rates(
        x[0], tuple(x[1:5]), x[5], tuple(x[6:10]), f.accel_b, c_ba=f.c_ba,
        omega_e_a=(w * f.e3_a[0], w * f.e3_a[1], w * f.e3_a[2]), alpha_e_a=None,
    )  # fmt: skip
    return (*rates.as_tuple(), u[0], u[1])


__all__ = ["ENTRY_STATE_NAMES", "CONTROL_NAMES", "N_STATE", "IDX", "StateLayout", "EntryForces", "entry_forces", "entry_rhs"]
