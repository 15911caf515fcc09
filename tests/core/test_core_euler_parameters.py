"""Euler parameters (Section sect:Review): DCM, rates, normalization, DCM -> parameters."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rventry_env.core import euler_parameters as ep

finite = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def unit_quaternions(draw):
    q = np.array([draw(finite) for _ in range(4)])
    n = np.linalg.norm(q)
    if n < 0.1:  # too close to zero for a well-conditioned direction
        q = np.array([0.0, 0.0, 0.0, 1.0]) if n == 0 else q / n
    return q / np.linalg.norm(q)


omegas = st.lists(st.floats(-10.0, 10.0, allow_nan=False), min_size=3, max_size=3).map(np.array)


@given(unit_quaternions())
def test_dcm_is_a_proper_rotation(q):
    c = ep.dcm_from_quaternion(q)
    np.testing.assert_allclose(c @ c.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(c) == pytest.approx(1.0, abs=1e-14)


def test_dcm_matches_axis_angle_form():
    """Eq. C_BA-Quat equals the axis-angle form Eq. C_BA-AxisAngle for a known rotation."""
    q_axis = np.array([1.0, 2.0, -2.0]) / 3.0
    phi = 0.7
    e = np.append(q_axis * np.sin(phi / 2), np.cos(phi / 2))
    c, s = np.cos(phi), np.sin(phi)
    skew = np.array([[0, -q_axis[2], q_axis[1]], [q_axis[2], 0, -q_axis[0]], [-q_axis[1], q_axis[0], 0]])
    expected = (1 - c) * np.outer(q_axis, q_axis) + c * np.eye(3) - s * skew
    np.testing.assert_allclose(ep.dcm_from_quaternion(e), expected, atol=1e-15)


def test_dcm_maps_a_components_to_b_components():
    """A rotation of +90 deg about a3: b1 = a2, so C_BA [0, 1, 0] = [1, 0, 0]."""
    q = np.array([0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)])
    np.testing.assert_allclose(ep.dcm_from_quaternion(q) @ [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], atol=1e-15)


@given(unit_quaternions(), omegas)
def test_quatrate_and_its_inverse(q, w):
    """Eq. QuatRate followed by Eq. QuatRate-2-Om gives back omega, and the rate keeps the norm."""
    q_dot = ep.quaternion_rates(q, w)
    np.testing.assert_allclose(ep.omega_from_quaternion_rates(q, q_dot), w, atol=1e-12)
    assert abs(np.dot(q, q_dot)) < 1e-12  # d|q|^2/dt = 0


@given(unit_quaternions(), omegas)
def test_quatrate_is_the_derivative_of_the_dcm(q, w):
    """dC_BA/dt = -[w]x C_BA (w = omega of B relative to A, in B), by a central difference.

    C_BA is quadratic in q, so the central difference along q_dot is exact up to rounding.
    """
    q_dot = ep.quaternion_rates(q, w)
    h = 1e-3
    c_dot = (ep.dcm_from_quaternion(q + h * q_dot) - ep.dcm_from_quaternion(q - h * q_dot)) / (2 * h)
    skew = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    np.testing.assert_allclose(c_dot, -skew @ ep.dcm_from_quaternion(q), atol=1e-9 * (1 + np.abs(w).max()))


@given(unit_quaternions())
def test_quaternion_from_dcm_round_trip(q):
    back = ep.quaternion_from_dcm(ep.dcm_from_quaternion(q))
    # q and -q are the same rotation; the convention is eta >= 0
    assert back[3] >= 0
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12


@pytest.mark.parametrize(
    "q",
    [[0, 0, 0, 1], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.5, 0.5, 0.5, 0.5], [0, np.sqrt(0.5), 0, np.sqrt(0.5)]],
)
def test_quaternion_from_dcm_on_half_turns_and_identity(q):
    """Half turns (eta = 0) are where a trace-only method fails; Shepperd's method must not."""
    q = np.array(q, dtype=float)
    back = ep.quaternion_from_dcm(ep.dcm_from_quaternion(q))
    np.testing.assert_allclose(ep.dcm_from_quaternion(back), ep.dcm_from_quaternion(q), atol=1e-15)


def test_batched_layers_agree_with_single_evaluations():
    rng = np.random.default_rng(1)
    q = ep.normalize(rng.normal(size=(4, 5, 4)))
    w = rng.normal(size=(4, 5, 3))
    c = ep.dcm_from_quaternion(q)
    assert c.shape == (4, 5, 3, 3)
    assert ep.quaternion_rates(q, w).shape == (4, 5, 4)
    np.testing.assert_allclose(c[2, 3], ep.dcm_from_quaternion(q[2, 3]))
    np.testing.assert_allclose(ep.quaternion_from_dcm(c)[1, 4], ep.quaternion_from_dcm(c[1, 4]))


@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 1e-6))  # fmt: skip
def test_normalize_gives_unit_norm_and_keeps_direction(v):
    v = np.array(v)
    q = ep.normalize(v)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(q * np.linalg.norm(v), v, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros(4), "zero or non-finite norm"),
        (np.array([[0.0, 0, 0, 1], [0, 0, 0, 0]]), r"zero or non-finite norm \(at index \[1\]\)"),
        (np.array([np.nan, 0, 0, 1]), "zero or non-finite norm"),
        (np.array([np.inf, 0, 0, 1]), "zero or non-finite norm"),
        (np.zeros(3), r"q must have 4 components on its last axis, got shape \(3,\)"),
    ],
)
def test_normalize_rejects_bad_input(bad, match):
    with pytest.raises(ValueError, match=match):
        ep.normalize(bad)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: ep.dcm_from_quaternion(np.zeros(3)), "q must have 4 components"),
        (lambda: ep.quaternion_rates(np.zeros(4), np.zeros(4)), "omega must have 3 components"),
        (lambda: ep.omega_from_quaternion_rates(np.zeros(4), np.zeros(3)), "q_dot must have 4 components"),
        (lambda: ep.quaternion_from_dcm(np.eye(4)), r"a DCM must have shape \(\.\.\., 3, 3\)"),
        (lambda: ep.dcm_from_quaternion(1.0), "q must have 4 components"),
    ],
)
def test_wrong_shapes_are_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()
