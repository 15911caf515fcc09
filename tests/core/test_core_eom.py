"""rv-Euler equations of motion against Newton's law written directly in Cartesian vectors.

The reference here never goes through the rv-Euler algebra: positions, velocities
and forces are turned into E vectors with the DCMs, and the acceleration seen in
the rotating frame E is a = f/m - 2 w x v - alpha x r - w x (w x r) with np.cross.
"""

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rventry_env.core import cartesian, eom
from rventry_env.core import euler_parameters as ep
from rventry_env.core.backend import NUMPY, casadi_ns
from rventry_env.core.conversions import cartesian_from_spherical
from rventry_env.core.spherical import two_body_spherical_rhs

MU = 3.986004418e14


def _unit(v):
    return v / np.linalg.norm(v)


def vec3(lo, hi):
    return st.lists(st.floats(lo, hi, allow_nan=False), min_size=3, max_size=3).map(np.array)


@st.composite
def quaternions(draw):
    q = np.array([draw(st.floats(-1, 1, allow_nan=False)) for _ in range(4)])
    assume(np.linalg.norm(q) > 0.1)
    return _unit(q)


@st.composite
def rv_states(draw):
    r = draw(st.floats(6.0e6, 5.0e7))
    v = draw(st.floats(10.0, 1.2e4))
    return np.concatenate([[r], draw(quaternions()), [v], draw(quaternions())])


def _frames(x):
    c_ae = ep.dcm_from_quaternion(x[1:5])
    c_ba = ep.dcm_from_quaternion(x[6:10])
    return c_ae, c_ba, c_ba @ c_ae


def _rates(x, accel_b, omega=(0.0, 0.0, 0.0), alpha=(0.0, 0.0, 0.0)):
    return eom.rv_euler_rates(x[0], tuple(x[1:5]), x[5], tuple(x[6:10]), tuple(accel_b), tuple(omega), tuple(alpha))


def _newton(x, accel_b, omega, alpha):
    """E-relative acceleration in E from Cartesian vectors, and the size of its terms."""
    c_ae, _, c_be = _frames(x)
    r_e, v_e = x[0] * c_ae[0], x[5] * c_be[0]
    f_e = c_be.T @ accel_b
    terms = [f_e, -2 * np.cross(omega, v_e), -np.cross(alpha, r_e), -np.cross(omega, np.cross(omega, r_e))]
    return sum(terms), max(np.linalg.norm(t) for t in terms)


@given(x=rv_states(), accel=vec3(-100, 100), omega=vec3(-2e-3, 2e-3), alpha=vec3(-1e-5, 1e-5))
def test_rv_euler_acceleration_matches_newton_in_a_rotating_frame(x, accel, omega, alpha):
    assume(np.linalg.norm(omega) > 1e-6 and np.linalg.norm(alpha) > 1e-9)
    rates = _rates(x, accel, omega, alpha)
    a_rv = np.array(eom.cartesian_acceleration(x, rates))
    a_newton, scale = _newton(x, accel, omega, alpha)
    # relative to the largest term, so a cancellation in the sum cannot mask or fake an error
    assert np.linalg.norm(a_rv - a_newton) <= 1e-9 * scale


@given(x=rv_states(), accel=vec3(-100, 100), omega=vec3(-2e-3, 2e-3), alpha=vec3(-1e-5, 1e-5))
def test_velocity_derivative_from_parameter_rates_matches_newton(x, accel, omega, alpha):
    """d/dt(v b1) built from v_dot and the Euler-parameter rates alone (no omega_A, omega_B).

    C_AE and C_BA are quadratic in their parameters, so a central difference along the
    parameter rates gives their time derivatives exactly up to rounding.
    """
    assume(np.linalg.norm(omega) > 1e-6 and np.linalg.norm(alpha) > 1e-9)
    rates = _rates(x, accel, omega, alpha)
    ea, eb = x[1:5], x[6:10]
    ea_dot, eb_dot = np.array(rates.e_a_dot), np.array(rates.e_b_dot)
    c_ae, c_ba, c_be = _frames(x)

    def ddt(q, q_dot):
        h = 1e-3 / max(np.linalg.norm(q_dot), 1e-30)
        return (ep.dcm_from_quaternion(q + h * q_dot) - ep.dcm_from_quaternion(q - h * q_dot)) / (2 * h)

    dc_be = ddt(eb, eb_dot) @ c_ae + c_ba @ ddt(ea, ea_dot)
    a_alt = rates.v_dot * c_be[0] + x[5] * dc_be[0]
    a_newton, scale = _newton(x, accel, omega, alpha)
    assert np.linalg.norm(a_alt - a_newton) <= 1e-9 * scale
    # position kinematics: d/dt(r a1) = v b1 (Eq. rv with Eq. kinematics-1)
    dr = rates.r_dot * c_ae[0] + x[0] * ddt(ea, ea_dot)[0]
    np.testing.assert_allclose(dr, x[5] * c_be[0], rtol=0, atol=1e-12 * x[5])
    assert rates.r_dot == pytest.approx(x[5] * np.dot(c_ae[0], c_be[0]), rel=0, abs=1e-12 * x[5])


@given(x=rv_states(), accel=vec3(-100, 100), omega=vec3(-2e-3, 2e-3), alpha=vec3(-1e-5, 1e-5))
def test_implicit_constraints_hold(x, accel, omega, alpha):
    """Unit norms and omega_A1 = omega_B1 = 0 are implicit in the rates (Eqs. w_A1=0, w_B1=0)."""
    rates = _rates(x, accel, omega, alpha)
    for q, q_dot in ((x[1:5], rates.e_a_dot), (x[6:10], rates.e_b_dot)):
        w = ep.omega_from_quaternion_rates(q, np.array(q_dot))
        scale = np.linalg.norm(w) + 1e-30
        assert abs(w[0]) <= 1e-12 * scale
        assert abs(np.dot(q, q_dot)) <= 1e-12 * scale


def test_inertial_frame_skips_nothing_it_needs():
    """With omega_E = alpha_E = 0 the apparent force is the applied force (E = N, Example 1)."""
    x = np.array([7e6, 0.1, -0.2, 0.3, np.sqrt(1 - 0.14), 7e3, 0.5, 0.5, 0.5, 0.5])
    accel = np.array([1.0, -2.0, 3.0])
    a_rv = np.array(eom.cartesian_acceleration(x, _rates(x, accel)))
    np.testing.assert_allclose(a_rv, _frames(x)[2].T @ accel, rtol=1e-12)


@given(x=rv_states())
def test_two_body_forms_agree_with_point_mass_gravity(x):
    c_ae, _, c_be = _frames(x)
    r_e, v_e = x[0] * c_ae[0], x[5] * c_be[0]
    g = -MU * r_e / x[0] ** 3
    two_body = eom.two_body_rhs(list(x), MU)
    assert len(two_body) == 10
    acc = np.array(eom.cartesian_acceleration(x, eom.RvEulerRates(
        two_body[0], two_body[1:5], two_body[5], two_body[6:10], *_omegas(x, two_body))))  # fmt: skip
    np.testing.assert_allclose(acc, g, rtol=0, atol=1e-12 * np.linalg.norm(g))
    cart = cartesian.two_body_cartesian_rhs(tuple(np.concatenate([r_e, v_e])), MU, NUMPY)
    np.testing.assert_allclose(cart[3:], g, rtol=1e-14)
    np.testing.assert_allclose(cart[:3], v_e, rtol=1e-14)


def _omegas(x, rhs):
    """(omega_A2, omega_A3), (omega_B2, omega_B3) recovered from the parameter rates (Eq. QuatRate-2-Om)."""
    wa = ep.omega_from_quaternion_rates(x[1:5], np.array(rhs[1:5]))
    wb = ep.omega_from_quaternion_rates(x[6:10], np.array(rhs[6:10]))
    return (wa[1], wa[2]), (wb[1], wb[2])


@given(
    lon=st.floats(-3.0, 3.0), lat=st.floats(-1.4, 1.4), gamma=st.floats(-1.4, 1.4),
    psi=st.floats(-3.0, 3.0), r=st.floats(6.5e6, 4e7), v=st.floats(1e3, 1e4),
)  # fmt: skip
def test_spherical_two_body_equations_match_newton(lon, lat, gamma, psi, r, v):
    """Eq. Ex1-EOM-Geo: moving the spherical state along its rates moves (r, v) as Newton says.

    Central difference over +-h with h = 1e-3 s: truncation ~ (h v / r)^2, far below 1e-8.
    """
    s = np.array([r, lon, lat, v, gamma, psi])
    s_dot = np.array(two_body_spherical_rhs(tuple(s), MU, NUMPY))
    h = 1e-3
    (rp, vp), (rm, vm) = cartesian_from_spherical(s + h * s_dot), cartesian_from_spherical(s - h * s_dot)
    r_e, v_e = cartesian_from_spherical(s)
    np.testing.assert_allclose((rp - rm) / (2 * h), v_e, rtol=0, atol=1e-7 * v)
    np.testing.assert_allclose((vp - vm) / (2 * h), -MU * r_e / r**3, rtol=0, atol=1e-6 * MU / r**2)


@given(r=vec3(-1e7, 1e7), v=vec3(-1e4, 1e4), f=vec3(-50, 50), w=vec3(-1e-3, 1e-3), al=vec3(-1e-5, 1e-5))
def test_cartesian_relative_acceleration(r, v, f, w, al):
    got = np.array(cartesian.relative_acceleration(tuple(r), tuple(v), tuple(f), tuple(w), tuple(al)))
    want = f - 2 * np.cross(w, v) - np.cross(al, r) - np.cross(w, np.cross(w, r))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * (np.abs(want).max() + 1))


# ---------------------------------------------------------------------------------
# one implementation for NumPy and CasADi


def test_rv_euler_rates_numpy_and_casadi_agree():
    import casadi as ca

    rng = np.random.default_rng(7)
    sym = ca.SX.sym("z", 19)
    z = [sym[i] for i in range(19)]
    out = eom.rv_euler_rates(z[0], tuple(z[1:5]), z[5], tuple(z[6:10]), tuple(z[10:13]), tuple(z[13:16]),
                             tuple(z[16:19]))  # fmt: skip
    fun = ca.Function("rates", [sym], [ca.vertcat(*out.as_tuple(), *out.omega_a, *out.omega_b)])
    batch = 16
    vals = np.empty((19, batch))
    vals[0], vals[5] = rng.uniform(6.4e6, 1e7, batch), rng.uniform(100, 8e3, batch)
    vals[1:5] = ep.normalize(rng.normal(size=(batch, 4))).T
    vals[6:10] = ep.normalize(rng.normal(size=(batch, 4))).T
    vals[10:13], vals[13:16], vals[16:19] = rng.normal(size=(3, batch)) * 20, rng.normal(size=(3, batch)) * 1e-3, \
        rng.normal(size=(3, batch)) * 1e-6  # fmt: skip
    v = list(vals)  # component arrays of shape (batch,): the batched NumPy path
    np_out = eom.rv_euler_rates(v[0], tuple(v[1:5]), v[5], tuple(v[6:10]), tuple(v[10:13]), tuple(v[13:16]),
                                tuple(v[16:19]))  # fmt: skip
    np_vals = np.array([*np_out.as_tuple(), *np_out.omega_a, *np_out.omega_b])
    ca_vals = np.array(fun(vals)).reshape(np_vals.shape)  # an SX Function broadcasts over columns
    np.testing.assert_allclose(ca_vals, np_vals, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("variant", ["default", "j2 and wind"])
def test_entry_rhs_numpy_and_casadi_agree(variant):
    import casadi as ca

    from rventry_env.physics import EntryModel, HorizontalWind, J2Gravity, entry_rhs
    from rventry_env.core.conversions import rv_euler_from_cartesian

    model = EntryModel()
    if variant != "default":
        model = model.replace(gravity=J2Gravity(), wind=HorizontalWind(east=30.0, north=-10.0))
    rng = np.random.default_rng(11)
    batch = 12
    lat, lon = rng.uniform(-1.0, 1.0, batch), rng.uniform(-3, 3, batch)
    a1 = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
    d = rng.normal(size=(batch, 3))
    x10 = rv_euler_from_cartesian((6378137.0 + rng.uniform(2e4, 7e4, batch))[:, None] * a1,
                                  rng.uniform(1e3, 7e3, batch)[:, None] * (d / np.linalg.norm(d, axis=-1)[:, None]))
    x = np.concatenate([x10, rng.uniform(0.05, 0.4, (batch, 1)), rng.uniform(-3, 3, (batch, 1))], -1).T
    u = rng.normal(size=(2, batch)) * 0.1
    np_out = np.array(entry_rhs(tuple(x), tuple(u), model, NUMPY))
    xs, us = ca.SX.sym("x", 12), ca.SX.sym("u", 2)
    sym = entry_rhs([xs[i] for i in range(12)], (us[0], us[1]), model, casadi_ns())
    fun = ca.Function("entry", [xs, us], [ca.vertcat(*sym)])
    ca_out = np.array(fun(x, u))
    np.testing.assert_allclose(ca_out, np_out, rtol=1e-11, atol=1e-14)
