"""Cartesian / spherical <-> rv-Euler conversions, frame rules, singular cases, bank angles."""

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rventry_env.core import conversions as cv
from rventry_env.core import euler_parameters as ep

E1, E2, E3 = np.eye(3)
R_E = 6378137.0


def _unit(v):
    return v / np.linalg.norm(v)


@st.composite
def directions(draw):
    v = np.array([draw(st.floats(-1, 1, allow_nan=False)) for _ in range(3)])
    assume(np.linalg.norm(v) > 0.05)
    return _unit(v)


@st.composite
def cartesian_states(draw):
    """Position and velocity, including exactly the poles and exactly vertical flight."""
    tiny = st.sampled_from([1e-11, 1e-9, 1e-7, 1e-5])
    kind_r = draw(st.sampled_from(["random", "north pole", "south pole", "near a pole"]))
    a1 = {"random": None, "north pole": E3, "south pole": -E3, "near a pole": None}[kind_r]
    a1 = draw(directions()) if a1 is None else a1
    if kind_r == "near a pole":
        a1 = _unit(np.sign(a1[2] or 1.0) * E3 + draw(tiny) * a1)
    kind_v = draw(st.sampled_from(["random", "up", "down", "nearly vertical", "horizontal"]))
    if kind_v == "up":
        b1 = a1
    elif kind_v == "down":
        b1 = -a1
    elif kind_v == "nearly vertical":  # where the east-down rule once lost 1e-9 of v
        b1 = _unit(draw(st.sampled_from([1.0, -1.0])) * a1 + draw(tiny) * draw(directions()))
    else:
        b1 = draw(directions())
        if kind_v == "horizontal":
            b1 = b1 - np.dot(b1, a1) * a1
            assume(np.linalg.norm(b1) > 0.05)
            b1 = _unit(b1)
    r = draw(st.floats(6.0e6, 5.0e7))
    v = draw(st.floats(1.0, 1.2e4))
    return r * a1, v * b1


@st.composite
def rv_states(draw):
    """rv-Euler states with arbitrary (unit) Euler parameters."""
    qs = []
    for _ in range(2):
        q = np.array([draw(st.floats(-1, 1, allow_nan=False)) for _ in range(4)])
        assume(np.linalg.norm(q) > 0.1)
        qs.append(_unit(q))
    r = draw(st.floats(6.0e6, 5.0e7))
    v = draw(st.floats(1.0, 1.2e4))
    return np.concatenate([[r], qs[0], [v], qs[1]])


def _frames(x):
    c_ae = ep.dcm_from_quaternion(x[..., 1:5])
    c_ba = ep.dcm_from_quaternion(x[..., 6:10])
    return c_ae, c_ba @ c_ae  # rows: a_i and b_i in E


# ---------------------------------------------------------------------------------
# Cartesian <-> rv-Euler


@pytest.mark.parametrize("rule", cv.FRAME_RULES)
@given(state=cartesian_states())
def test_cartesian_round_trip_including_poles_and_vertical_flight(rule, state):
    r_e, v_e = state
    a1, b1 = _unit(r_e), _unit(v_e)
    sin_rv = np.linalg.norm(np.cross(a1, b1))  # 0 in vertical flight
    cos_lat = np.hypot(a1[0], a1[1])  # 0 at the poles
    if rule == "orbital":
        assume(not 0.5e-12 < sin_rv < 2e-12)  # the rule's own threshold is 1e-12
        if sin_rv <= 0.5e-12:
            with pytest.raises(ValueError, match="the orbital rule needs r not parallel to v"):
                cv.rv_euler_from_cartesian(r_e, v_e, rule=rule)
            return
    x = cv.rv_euler_from_cartesian(r_e, v_e, rule=rule)
    assert x.shape == (10,)
    assert np.linalg.norm(x[1:5]) == pytest.approx(1.0, abs=1e-14)
    assert np.linalg.norm(x[6:10]) == pytest.approx(1.0, abs=1e-14)
    r2, v2 = cv.cartesian_from_rv_euler(x)
    np.testing.assert_allclose(r2, r_e, rtol=0, atol=1e-14 * np.linalg.norm(r_e))
    np.testing.assert_allclose(v2, v_e, rtol=0, atol=1e-14 * np.linalg.norm(v_e))
    # converting the result again reproduces the same frames (the rule is a function of r, v),
    # except within 1e-6 rad of a singular direction, where the frames are ill-conditioned by nature
    if any(0 < c < 1e-6 for c in (sin_rv, cos_lat)):
        return
    c_ae, c_be = _frames(x)
    c_ae2, c_be2 = _frames(cv.rv_euler_from_cartesian(r2, v2, rule=rule))
    np.testing.assert_allclose(c_ae2, c_ae, atol=1e-9)
    np.testing.assert_allclose(c_be2, c_be, atol=1e-9)


@given(state=cartesian_states())
def test_east_down_rule_directions(state):
    r_e, v_e = state
    (_, a2, a3), (b1, b2, _) = _frames(cv.rv_euler_from_cartesian(r_e, v_e))
    # expectations from the input directions: near the poles and vertical flight the
    # rule is ill-conditioned, so directions re-derived from the output would not do
    a1_in, b1_in = _unit(r_e), _unit(v_e)
    cos_lat, sin_rv = np.hypot(a1_in[0], a1_in[1]), np.linalg.norm(np.cross(a1_in, b1_in))
    assume(not (0.5e-9 < cos_lat < 2e-9 or 0.5e-9 < sin_rv < 2e-9))  # the rule switches at 1e-9
    if cos_lat >= 1e-9:
        np.testing.assert_allclose(a2, _unit(np.cross(E3, a1_in)), atol=1e-12)  # east
        assert a3[2] > 0  # north has a positive e3 component off the poles
    else:
        np.testing.assert_allclose(a2, _unit(np.cross(E1, a1_in)), atol=1e-12)  # documented fallback

    def normal_to_b1(d):  # (b1 x d) x b1: the part of d normal to b1, stable when d ~ b1
        return _unit(np.cross(np.cross(b1_in, d), b1_in))

    if sin_rv >= 1e-9:
        np.testing.assert_allclose(b2, normal_to_b1(-a1_in), atol=1e-12)  # down
    else:
        np.testing.assert_allclose(b2, normal_to_b1(a2), atol=1e-12)  # documented fallback
    assert abs(np.dot(b1, b2)) < 1e-15  # orthogonal to rounding, also in nearly vertical flight


@given(state=cartesian_states())
def test_orbital_rule_aligns_a3_and_b3_with_angular_momentum(state):
    r_e, v_e = state
    h = np.cross(r_e, v_e)
    assume(np.linalg.norm(h) > 1e-6 * np.linalg.norm(r_e) * np.linalg.norm(v_e))
    (_, _, a3), (_, _, b3) = _frames(cv.rv_euler_from_cartesian(r_e, v_e, rule="orbital"))
    np.testing.assert_allclose(a3, _unit(h), atol=1e-9)
    np.testing.assert_allclose(b3, _unit(h), atol=1e-9)


@given(x=rv_states())
def test_rv_euler_round_trip_with_explicit_a2_b2(x):
    """rv -> Cartesian -> rv recovers every frame when the free rotations are passed explicitly."""
    (_, a2, _), (_, b2, _) = _frames(x)
    r_e, v_e = cv.cartesian_from_rv_euler(x)
    back = cv.rv_euler_from_cartesian(r_e, v_e, a2=a2, b2=b2)
    assert back[0] == pytest.approx(x[0], rel=1e-14)
    assert back[5] == pytest.approx(x[5], rel=1e-14)
    for sl in (slice(1, 5), slice(6, 10)):  # same parameters up to the sign of the quaternion
        assert min(np.abs(back[sl] - x[sl]).max(), np.abs(back[sl] + x[sl]).max()) < 1e-9


def test_batched_conversion_matches_single_states():
    rng = np.random.default_rng(3)
    r_e = rng.normal(size=(5, 2, 3)) * 7e6
    v_e = rng.normal(size=(5, 2, 3)) * 7e3
    x = cv.rv_euler_from_cartesian(r_e, v_e)
    assert x.shape == (5, 2, 10)
    np.testing.assert_allclose(x[3, 1], cv.rv_euler_from_cartesian(r_e[3, 1], v_e[3, 1]))


def test_east_down_rule_reproduces_table_ex2_bcs():
    """Horizontal eastward flight at longitude 0, latitude 0: eA = 0, etaA = 1, eB = (0, 0, 1/sqrt2), etaB = 1/sqrt2."""
    x = cv.rv_euler_from_cartesian((R_E + 37e3) * E1, 7138.0 * E2)
    s = np.sqrt(0.5)
    np.testing.assert_allclose(x, [R_E + 37e3, 0, 0, 0, 1, 7138.0, 0, 0, s, s], atol=1e-15, rtol=1e-15)


def test_orbital_rule_reproduces_table_ex1_ic():
    """Table tab:Ex1-IC to its printed rounding, at the inclination its azimuth implies.

    psi = -172.223 deg at the equator with gamma = 0 means i = 97.777 deg; the table's
    Euler parameters (-0.753, 0, 0, 0.658) and (0, 0, 0.707, 0.707) belong to that orbit.
    """
    s = np.array([6971e3, 0.0, 0.0, 7562.0, 0.0, math.radians(-172.223)])
    x = cv.rv_euler_from_spherical(s, rule="orbital")
    table = [6971e3, -0.753, 0.0, 0.0, 0.658, 7562.0, 0.0, 0.0, 0.707, 0.707]
    np.testing.assert_allclose(x[[0, 5]], [6971e3, 7562.0], rtol=1e-14)
    assert np.abs(x[[1, 2, 3, 4, 6, 7, 8, 9]] - np.take(table, [1, 2, 3, 4, 6, 7, 8, 9])).max() <= 0.0005
    # and the table's value is not met by a nearby wrong rule: the east-down rule gives other parameters
    other = cv.rv_euler_from_spherical(s, rule="east-down")
    assert np.abs(other[6:10] - np.take(table, [6, 7, 8, 9])).max() > 0.1


# ---------------------------------------------------------------------------------
# spherical


@given(
    lon=st.floats(-3.14, 3.14), lat=st.floats(-1.55, 1.55), gamma=st.floats(-1.55, 1.55),
    psi=st.floats(-3.14, 3.14), r=st.floats(6e6, 5e7), v=st.floats(1.0, 1.2e4),
)  # fmt: skip
def test_spherical_round_trips_where_defined(lon, lat, gamma, psi, r, v):
    s = np.array([r, lon, lat, v, gamma, psi])
    r_e, v_e = cv.cartesian_from_spherical(s)
    back = cv.spherical_from_cartesian(r_e, v_e)
    np.testing.assert_allclose(back[[0, 3]], s[[0, 3]], rtol=1e-13)
    np.testing.assert_allclose(cv.wrap_angle(back[[1, 2, 4, 5]] - s[[1, 2, 4, 5]]), 0.0, atol=1e-9)
    via_rv = cv.spherical_from_rv_euler(cv.rv_euler_from_spherical(s))
    np.testing.assert_allclose(cv.wrap_angle(via_rv[[1, 2, 4, 5]] - s[[1, 2, 4, 5]]), 0.0, atol=1e-9)


def test_spherical_conventions_on_known_states():
    """Azimuth from north toward east; flight-path angle positive up; geocentric latitude."""
    r_e = 7e6 * np.array([0.0, np.cos(0.3), np.sin(0.3)])  # longitude 90 deg, latitude 0.3 rad
    east, north, up = -E1, np.array([0, -np.sin(0.3), np.cos(0.3)]), r_e / 7e6
    v_e = 100.0 * (np.cos(0.2) * (np.cos(0.4) * north + np.sin(0.4) * east) + np.sin(0.2) * up)
    np.testing.assert_allclose(cv.spherical_from_cartesian(r_e, v_e), [7e6, np.pi / 2, 0.3, 100.0, 0.2, 0.4])


@pytest.mark.parametrize("pole", [E3, -E3])
def test_spherical_raises_at_the_poles(pole):
    r_e, v_e = 7e6 * pole, 7e3 * E1
    with pytest.raises(cv.SingularConversionError, match=r"longitude and azimuth are undefined at the poles"):
        cv.spherical_from_cartesian(r_e, v_e)
    x = cv.rv_euler_from_cartesian(r_e, v_e)
    with pytest.raises(cv.SingularConversionError, match=r"undefined at the poles \(latitude = \+-90 deg\)"):
        cv.spherical_from_rv_euler(x)
    s = cv.spherical_from_rv_euler(x, on_singular="nan")
    assert np.isnan(s[1]) and np.isnan(s[5])
    assert s[2] == pytest.approx(pole[2] * np.pi / 2)
    assert s[0] == pytest.approx(7e6) and s[3] == pytest.approx(7e3) and s[4] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_spherical_raises_in_vertical_flight(sign):
    a1 = _unit(np.array([1.0, 2.0, 0.5]))
    with pytest.raises(cv.SingularConversionError, match=r"azimuth is undefined in vertical flight"):
        cv.spherical_from_cartesian(7e6 * a1, sign * 500.0 * a1)
    s = cv.spherical_from_cartesian(7e6 * a1, sign * 500.0 * a1, on_singular="nan")
    assert np.isnan(s[5]) and np.all(np.isfinite(s[:5]))
    assert s[4] == pytest.approx(sign * np.pi / 2)


def test_singular_error_counts_and_locates_states():
    r_e = np.array([7e6 * E1, 7e6 * E3, 7e6 * E2])
    with pytest.raises(cv.SingularConversionError, match=r"\(1 state\(s\), first at index \[1\]\)"):
        cv.spherical_from_cartesian(r_e, 7e3 * np.array([E2, E1, E1]))


# ---------------------------------------------------------------------------------
# bank angle


def _paper_initial_state():
    return cv.rv_euler_from_cartesian((R_E + 37e3) * E1, 7138.0 * E2)


def test_sigma_180_is_lift_up_at_the_paper_initial_state():
    x = _paper_initial_state()
    assert abs(cv.conventional_bank(x, np.pi)) < 1e-12
    assert abs(cv.wrap_angle(cv.conventional_bank(x, 0.0) - np.pi)) < 1e-12  # sigma = 0: lift along b2, down
    assert abs(cv.wrap_angle(cv.paper_bank(x, 0.0) - np.pi)) < 1e-12


@given(x=rv_states(), mu=st.floats(-3.1, 3.1))
def test_conventional_bank_geometry(x, mu):
    """Lift at sigma = paper_bank(x, mu) is cos(mu) up + sin(mu) right (right = b1 x up)."""
    (a1, _, _), (b1, b2, b3) = _frames(x)
    up = a1 - np.dot(a1, b1) * b1
    assume(np.linalg.norm(up) > 1e-3)  # not vertical flight
    up = _unit(up)
    right = np.cross(b1, up)
    sigma = cv.paper_bank(x, mu)
    lift = np.cos(sigma) * b2 + np.sin(sigma) * b3  # Eq. Ex2-EOM-Ftot
    assert np.dot(lift, up) == pytest.approx(np.cos(mu), abs=1e-9)
    assert np.dot(lift, right) == pytest.approx(np.sin(mu), abs=1e-9)
    assert abs(cv.wrap_angle(cv.conventional_bank(x, sigma) - mu)) < 1e-9


def test_positive_bank_turns_right_in_eastward_flight():
    """Flying east at the equator, right is south (-e3): mu > 0 puts lift toward -e3."""
    x = _paper_initial_state()
    sigma = cv.paper_bank(x, math.radians(30))
    _, (_, b2, b3) = _frames(x)
    lift = np.cos(sigma) * b2 + np.sin(sigma) * b3
    np.testing.assert_allclose(lift, [np.cos(math.radians(30)), 0, -0.5], atol=1e-12)


def test_bank_is_undefined_in_vertical_flight():
    x = cv.rv_euler_from_cartesian(7e6 * E1, -300.0 * E1)
    with pytest.raises(cv.SingularConversionError, match="conventional bank angle is undefined in vertical flight"):
        cv.conventional_bank(x, 0.3)


# ---------------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: cv.rv_euler_from_cartesian([1.0, 2.0], [1.0, 0, 0]), r"r_e must have 3 components .* shape \(2,\)"),
        (lambda: cv.rv_euler_from_cartesian([7e6, 0, 0], [np.nan, 1, 0]), "v_e contains NaN or inf"),
        (lambda: cv.rv_euler_from_cartesian([0.0, 0, 0], [1.0, 0, 0]), r"position r_e has zero length"),
        (lambda: cv.rv_euler_from_cartesian([7e6, 0, 0], [0.0, 0, 0]), r"velocity v_e .* has zero length"),
        (lambda: cv.rv_euler_from_cartesian([7e6, 0, 0], [0, 1.0, 0], rule="up"), "unknown frame rule 'up'"),
        (lambda: cv.rv_euler_from_cartesian([7e6, 0, 0], [0, 1.0, 0], a2=[1.0, 0, 0]), "a2 normal to r has zero length"),
        (lambda: cv.cartesian_from_rv_euler(np.zeros(9)), r"at least 10 components .* shape \(9,\)"),
        (lambda: cv.cartesian_from_spherical(np.zeros(5)), "spherical coordinates need 6 components"),
        (lambda: cv.cartesian_from_spherical([7e6, 0, 0, np.nan, 0, 0]), "spherical coordinates contain NaN"),
        (lambda: cv.cartesian_from_spherical([-7e6, 0, 0, 1.0, 0, 0]), "r and v must be positive"),
        (lambda: cv.spherical_from_cartesian([7e6, 0, 0], [0, 1.0, 0], on_singular="zero"), "on_singular must be 'raise' or 'nan', got 'zero'"),
        (lambda: cv.conventional_bank(_paper_initial_state(), np.nan), "sigma contains NaN or inf"),
        (lambda: cv.paper_bank(_paper_initial_state(), np.inf), "mu contains NaN or inf"),
    ],
)  # fmt: skip
def test_bad_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()
