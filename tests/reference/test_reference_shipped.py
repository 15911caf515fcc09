"""The shipped reference: accuracy, boundary conditions, vertical impact, norms, loader API."""

import math

import numpy as np
import pytest

from rventry_env.core.conversions import spherical_from_rv_euler
from rventry_env.physics.entry import entry_forces, entry_rhs
from rventry_env.physics.model import EntryModel
from rventry_env.reference import Reference, load_reference
from rventry_env.reference.collocation.interpolation import PiecewiseLGR
from rventry_env.reference.collocation.lgr import integration_matrix, lgr_weights, support_points

MODEL = EntryModel()
RE = MODEL.planet.radius
DEG = math.pi / 180


@pytest.fixture(scope="module")
def ref() -> Reference:
    return load_reference()


def test_summary_reports_a_converged_accurate_solution(ref):
    s = ref.summary()
    for key in ("tf_s", "cost", "mesh_error", "max_constraint_violation", "solve_time_s"):
        assert key in s and np.isfinite(s[key]), key
    assert s["converged"] is True
    assert s["mesh_error"] <= 1e-6
    assert s["max_constraint_violation"] <= 1e-7
    assert s["tf_s"] == pytest.approx(ref.tf, rel=1e-12)
    assert s["cost"] == pytest.approx(ref.cost, rel=1e-12)
    assert s["norm_mode"] == "projection"


def test_mesh_error_reestimated_independently(ref):
    """GPOPS-II's estimate redone here with NumPy entry_rhs and the file's own polynomials."""
    mesh = ref.mesh
    xs = PiecewiseLGR(mesh, ref.t0, ref.tf, ref.x, ref.u)
    lam = PiecewiseLGR(mesh, ref.t0, ref.tf, ref.x, ref.u_extra)  # lambda_A, lambda_B of the formulation
    worst = 0.0
    for k, n in enumerate(mesh.degrees):
        m = int(n) + 1
        a, b = mesh.breaks[k], mesh.breaks[k + 1]
        s = a + (b - a) * (support_points(m) + 1) / 2
        t = ref.t0 + (ref.tf - ref.t0) * s
        # strictly inside the interval so that every polynomial is this interval's own
        eps = 1e-13 * (ref.tf - ref.t0)
        t_in = np.clip(t, t[0] + eps, t[-1] - eps)
        x = xs.state(t_in)
        u = xs.control(t_in[:-1])
        la = lam.control(t_in[:-1])
        f = np.array(entry_rhs(list(x[:-1].T), list(u.T), MODEL)).T
        f[:, 1:5] += la[:, :1] * x[:-1, 1:5]
        f[:, 6:10] += la[:, 1:2] * x[:-1, 6:10]
        integrated = x[0] + (ref.tf - ref.t0) * (b - a) / 2 * (integration_matrix(m) @ f)
        err = np.abs(integrated - x[1:]) / (1 + np.max(np.abs(x), axis=0))
        worst = max(worst, float(err.max()))
    assert worst <= 1e-6 * 1.05
    assert worst == pytest.approx(ref.summary()["mesh_error"], rel=0.05)


def test_initial_state_is_table_tab_ex2_bcs(ref):
    x0 = ref.x[0]
    s2 = math.sqrt(2) / 2
    expected = [RE + 37e3, 0, 0, 0, 1, 7138.0, 0, 0, s2, s2]
    assert np.max(np.abs(x0[:10] - expected) / np.maximum(np.abs(expected), 1)) < 1e-12
    assert 0 <= x0[10] <= 25 * DEG  # alpha(0), sigma(0) free


def test_the_problem_defaults_are_the_shipped_optimum_initial_angles(ref):
    """EntryProblem carries alpha(0) and sigma(0) as numbers; they must stay those of the shipped optimum."""
    from rventry_env.task.problem import EntryProblem

    p = EntryProblem()
    assert p.initial_alpha == ref.x[0, 10] and p.initial_sigma == ref.x[0, 11]
    np.testing.assert_array_equal(p.initial_state(RE), ref.x[0])


def test_final_conditions_and_exact_vertical_impact(ref):
    xf = ref.x[-1]
    assert xf[0] == pytest.approx(RE, abs=1e-6)
    assert xf[5] == pytest.approx(1219.0, abs=1e-9)
    assert abs(xf[10]) < 1e-12
    # Eq. Ex2-endpoint: a1(tf) = (cos 25.15 deg, sin 25.15 deg, 0)
    lon = 25.15 * DEG
    e1, e2, e3, eta = xf[1:5]
    a1 = np.array([1 - 2 * (e2**2 + e3**2), 2 * (e1 * e2 + e3 * eta), 2 * (e1 * e3 - e2 * eta)])
    assert np.max(np.abs(a1 - [math.cos(lon), math.sin(lon), 0.0])) < 1e-9
    # vertical impact, exactly (bounds of the NLP): eB1 = etaB = 0
    assert xf[6] == 0.0 and xf[9] == 0.0
    sph = spherical_from_rv_euler(xf[None, :10], on_singular="nan")[0]
    assert sph[4] == pytest.approx(-math.pi / 2, abs=1e-12)


def test_unit_norms_are_kept(ref):
    na = np.linalg.norm(ref.x[:, 1:5], axis=1)
    nb = np.linalg.norm(ref.x[:, 6:10], axis=1)
    assert np.max(np.abs(na - 1)) < 1e-9 and np.max(np.abs(nb - 1)) < 1e-9
    xd = ref.state(np.linspace(0, ref.tf, 5001))
    assert np.max(np.abs(np.linalg.norm(xd[:, 1:5], axis=1) - 1)) < 1e-5
    assert np.max(np.abs(np.linalg.norm(xd[:, 6:10], axis=1) - 1)) < 1e-5
    # the norm-keeping controls are what the discretisation asked for: tiny
    assert np.max(np.abs(ref.u_extra)) < 1e-4


def test_path_constraints_hold_at_the_collocation_points(ref):
    x, u = ref.x[:-1], ref.u[:-1]
    f = entry_forces(list(x.T), MODEL)
    g0 = MODEL.planet.g0
    assert np.max(f.aero_accel) <= 12 * g0 * (1 + 1e-7)
    assert np.min(f.dynamic_pressure) >= 12e3 * (1 - 1e-7)
    assert np.min(ref.x[:, 10]) >= -1e-9 and np.max(ref.x[:, 10]) <= 25 * DEG + 1e-9
    assert np.max(np.abs(u[:, 0])) <= 10 * DEG * (1 + 1e-7)
    assert np.max(np.abs(u[:, 1])) <= 30 * DEG * (1 + 1e-7)


def test_cost_is_the_quadrature_of_eq_ex2_cost(ref):
    mesh = ref.mesh
    x, u = ref.x[:-1], ref.u[:-1]
    run = ((x[:, 10] - 11.86 * DEG) / (25 * DEG)) ** 2 + (u[:, 0] / (10 * DEG)) ** 2 + (u[:, 1] / (30 * DEG)) ** 2
    h = np.diff(mesh.breaks)
    w = np.concatenate([lgr_weights(int(n)) * h[k] for k, n in enumerate(mesh.degrees)])
    j = (ref.tf - ref.t0) / 2 * np.sum(w * run)
    assert j == pytest.approx(ref.cost, rel=1e-9)
    assert 0 < ref.cost < 10


def test_loader_api(ref):
    assert load_reference() is ref  # cached
    assert ref.x.shape == (ref.t.size, 12) and ref.u.shape == (ref.t.size, 2)
    assert ref.t[0] == 0.0 and ref.t[-1] == ref.tf and np.all(np.diff(ref.t) > 0)
    assert ref.state(0.0).shape == (12,) and ref.control(1.0).shape == (2,)
    assert ref.state(np.array([0.0, 1.0, 2.0])).shape == (3, 12)
    np.testing.assert_allclose(ref.state(ref.t), ref.x, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ref.state(-10.0), ref.x[0])
    np.testing.assert_allclose(ref.state(ref.tf + 10.0), ref.x[-1])
    u = ref.control(np.linspace(0, ref.tf, 20001))
    assert np.max(np.abs(u[:, 0])) <= 10 * DEG + 1e-15 and np.max(np.abs(u[:, 1])) <= 30 * DEG + 1e-15
    with pytest.raises(ValueError):
        ref.x[0, 0] = 1.0  # shared cached arrays are read-only
    s = ref.summary()
    s["cost"] = -1
    assert ref.summary()["cost"] == ref.cost  # summary() hands out a copy
    with pytest.raises(ValueError, match="NaN"):
        ref.state(np.nan)


def test_missing_file_gives_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="rventry reference solve"):
        load_reference(tmp_path / "nope.npz")
