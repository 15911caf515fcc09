"""LGR machinery: points, weights, differentiation/integration matrices, interpolation, mesh."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rventry_env.reference.collocation.interpolation import PiecewiseLGR
from rventry_env.reference.collocation.lgr import (
    differentiation_matrix,
    integration_matrix,
    lagrange_matrix,
    lgr_points,
    lgr_weights,
    support_points,
)
from rventry_env.reference.collocation.mesh import Mesh, refine_ph

DEGREES = [1, 2, 3, 4, 7, 10, 16, 25]


@pytest.mark.parametrize("n", DEGREES)
def test_points_are_radau(n):
    tau = lgr_points(n)
    assert tau[0] == -1.0 and np.all(np.diff(tau) > 0) and tau[-1] < 1.0
    if n > 1:  # interior points are the roots of (P_{n-1} + P_n) / (1 + tau)
        p = np.polynomial.legendre.Legendre.basis(n - 1) + np.polynomial.legendre.Legendre.basis(n)
        assert np.max(np.abs(p(tau))) < 1e-12


@pytest.mark.parametrize("n", DEGREES)
def test_weights_integrate_degree_2n_minus_2_exactly(n):
    tau, w = lgr_points(n), lgr_weights(n)
    for k in range(2 * n - 1):
        exact = (1 - (-1) ** (k + 1)) / (k + 1)
        assert w @ tau**k == pytest.approx(exact, abs=1e-13)
    # and not one degree more: the rule is Radau, not Gauss (the error on the
    # even power 2n is clearly non-zero; it shrinks like 4^-n, so check small n)
    if n <= 10:
        k = 2 * n
        assert abs(w @ tau**k - 2 / (k + 1)) > 1e-8


@pytest.mark.parametrize("n", DEGREES)
def test_differentiation_matrix_exact_up_to_degree_n(n):
    d = differentiation_matrix(n)
    s, tau = support_points(n), lgr_points(n)
    assert d.shape == (n, n + 1)
    for k in range(n + 1):
        expected = k * tau ** (k - 1) if k else np.zeros(n)
        assert np.max(np.abs(d @ s**k - expected)) < 1e-11 * max(1, k * k)


@pytest.mark.parametrize("n", DEGREES)
def test_integration_matrix_inverts_differentiation(n):
    a = integration_matrix(n)
    s, tau = support_points(n), lgr_points(n)
    for k in range(1, n + 1):
        assert np.max(np.abs(a @ (k * tau ** (k - 1)) - (s[1:] ** k - (-1.0) ** k))) < 1e-12 * max(1, k)


@given(st.integers(1, 12), st.lists(st.floats(-3, 3), min_size=13, max_size=13), st.floats(-1, 1))
def test_lagrange_matrix_reproduces_polynomials(n, coeffs, t):
    s = support_points(n)
    poly = np.polynomial.Polynomial(coeffs[: n + 1])
    p = lagrange_matrix(s, np.array([t]))
    assert (p @ poly(s))[0] == pytest.approx(poly(t), abs=1e-9)


@pytest.mark.parametrize("bad", [0, -1, 61])
def test_bad_number_of_points_is_rejected(bad):
    with pytest.raises(ValueError, match="LGR points"):
        lgr_points(bad)


def test_non_integer_number_of_points_is_rejected():
    with pytest.raises(TypeError, match="int"):
        lgr_points(3.0)


def test_mesh_layout_and_piecewise_interpolant_is_exact_on_polynomials():
    mesh = Mesh(np.array([0.0, 0.3, 0.5, 1.0]), np.array([3, 5, 4]))
    assert mesh.n_collocation == 12 and mesh.n_nodes == 13
    assert mesh.offsets.tolist() == [0, 3, 8]
    s = mesh.nodes()
    assert s[0] == 0 and s[-1] == 1 and np.all(np.diff(s) > 0)
    tf = 7.0
    t = tf * s
    # degree 3 fits every interval's state polynomial (degree >= 3) and control polynomial (degree >= 2)?
    x = np.column_stack([t**3 - 2 * t, np.sin(0 * t) + 1.0])
    u = np.column_stack([t**2])[:-1]
    interp = PiecewiseLGR(mesh, 0.0, tf, x, u)
    tt = np.linspace(0, tf, 97)
    assert np.max(np.abs(interp.state(tt)[:, 0] - (tt**3 - 2 * tt))) < 1e-9
    assert np.max(np.abs(interp.control(tt)[:, 0] - tt**2)) < 1e-9
    # scalars give vectors, times outside are clamped
    assert interp.state(3.0).shape == (2,)
    assert np.allclose(interp.state(-5.0), x[0]) and np.allclose(interp.state(99.0), x[-1])


@pytest.mark.parametrize(
    "breaks, degrees, match",
    [
        ([0.0, 0.5], [3], "run from 0 to 1"),
        ([0.0, 0.6, 0.4, 1.0], [3, 3, 3], "strictly increasing"),
        ([0.0, 1.0], [3, 3], "needs 1 degrees"),
        ([0.0, 1.0], [0], "degrees must be in"),
        ([0.0, 1.0], [2.5], "integers"),
    ],
)
def test_bad_mesh_is_rejected(breaks, degrees, match):
    with pytest.raises(ValueError, match=match):
        Mesh(np.array(breaks), np.array(degrees))


def test_ph_refinement_raises_degree_then_splits():
    mesh = Mesh.uniform(3, 4)
    # interval 0 fine, interval 1 slightly off (raise degree), interval 2 far off (split)
    new = refine_ph(mesh, np.array([1e-7, 1e-5, 1e2]), tol=1e-6, n_min=4, n_max=10)
    assert new.degrees[0] == 4 and new.breaks[1] == pytest.approx(1 / 3)
    # log(1e-5/1e-6)/log(4) = 1.66 -> P = 2
    assert new.degrees[1] == 6
    # log(1e8)/log(4) = 13.3 -> P = 14, N + P = 18 > 10 -> ceil(18/4) = 5 parts of 4 points
    assert new.n_intervals == 2 + 5 and np.all(new.degrees[2:] == 4)
    assert np.allclose(np.diff(new.breaks[2:]), (1 / 3) / 5)
    # nothing to do: the mesh comes back unchanged
    same = refine_ph(mesh, np.full(3, 1e-9), tol=1e-6)
    assert np.array_equal(same.breaks, mesh.breaks) and np.array_equal(same.degrees, mesh.degrees)


def test_ph_refinement_rejects_bad_input():
    mesh = Mesh.uniform(2, 4)
    with pytest.raises(ValueError, match="one error per interval"):
        refine_ph(mesh, np.ones(3), tol=1e-6)
    with pytest.raises(ValueError, match="positive"):
        refine_ph(mesh, np.ones(2), tol=0.0)


def test_end_clustered_mesh_equal_or_halving_end_block():
    from rventry_env.reference.pipeline import end_clustered_mesh

    equal = np.diff(np.asarray(end_clustered_mesh(10, 4, 0.1, 3, 5).breaks))
    np.testing.assert_allclose(equal[:10], 0.09)
    np.testing.assert_allclose(equal[10:], 0.1 / 3)
    m = end_clustered_mesh(10, 4, 0.1, 4, 5, shrink=0.5)
    widths = np.diff(np.asarray(m.breaks))
    assert m.breaks[-1] == 1.0 and len(widths) == 14
    np.testing.assert_allclose(widths[10:], 0.1 * np.array([8, 4, 2, 1]) / 15)  # each half the one before
    np.testing.assert_allclose(widths[:10], 0.09)
    with pytest.raises(ValueError, match="shrink"):
        end_clustered_mesh(10, 4, 0.1, 4, 5, shrink=0.0)
