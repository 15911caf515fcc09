"""The general problem definition: bad input gets a clear error; a solved textbook problem."""

import math

import numpy as np
import pytest

from rventry_env.reference.collocation import (
    EndpointConstraint,
    Invariant,
    Mesh,
    OptimalControlProblem,
    PathConstraint,
    RecordingProgress,
)
from rventry_env.reference.collocation import SampledGuess, SolverOptions, solve


def _double_integrator(**overrides):
    """min int u^2 dt, x'' = u, x(0) = v(0) = 0, x(1) = 1, v(1) = 0: u = 6 - 12 t, J = 12."""
    kw = dict(
        name="double-integrator",
        state_names=("x", "v"),
        control_names=("u",),
        dynamics=lambda x, u, t: (x[1], u[0]),
        initial_lower=[0, 0],
        initial_upper=[0, 0],
        final_lower=[1, 0],
        final_upper=[1, 0],
        tf_lower=1.0,
        tf_upper=1.0,
        lagrange=lambda x, u, t: u[0] * u[0],
    )
    kw.update(overrides)
    return OptimalControlProblem(**kw)


def test_textbook_problem_is_solved_exactly():
    prob = _double_integrator()
    t = np.linspace(0, 1, 5)
    guess = SampledGuess(t, np.column_stack([t, np.ones_like(t)]), np.zeros((5, 1)))
    rec = RecordingProgress()
    res = solve(prob, guess, Mesh.uniform(2, 4), SolverOptions(), progress=rec)
    sol = res.solution
    assert res.converged and sol.success
    assert sol.cost == pytest.approx(12.0, rel=1e-8)
    tt = np.linspace(0, 1, 11)
    assert np.max(np.abs(sol.control(tt)[:, 0] - (6 - 12 * tt))) < 1e-7
    assert np.max(np.abs(sol.state(tt)[:, 0] - (3 * tt**2 - 2 * tt**3))) < 1e-9
    assert len(rec.records) == len(res.records) >= 1
    assert rec.records[-1].max_error <= 1e-6


def test_free_final_time_problem():
    """Same dynamics, tf free, cost tf + int u^2: J(tf) = tf + 12 / tf^3, minimal at tf = 36^(1/4)."""
    prob = _double_integrator(tf_lower=0.1, tf_upper=10.0, mayer=lambda x0, xf, t0, tf: tf)
    t = np.linspace(0, 1, 5)
    guess = SampledGuess(t, np.column_stack([t, np.ones_like(t)]), np.zeros((5, 1)))
    sol = solve(prob, guess, Mesh.uniform(2, 4)).solution
    # for fixed tf the minimum energy is 12 / tf^3, so J(tf) = tf + 12 / tf^3, minimal at tf = 36^(1/4)
    assert sol.tf == pytest.approx(36 ** 0.25, rel=1e-6)
    assert sol.cost == pytest.approx(36 ** 0.25 + 12 / 36 ** 0.75, rel=1e-8)


@pytest.mark.parametrize(
    "overrides, error, match",
    [
        (dict(state_names=("x", "x")), ValueError, "unique"),
        (dict(state_names=()), ValueError, "at least one state"),
        (dict(dynamics=3), TypeError, "dynamics must be callable"),
        (dict(lagrange=None), ValueError, "needs a cost"),
        (dict(state_lower=[0, 0, 0]), ValueError, "state_lower must have 2 entries"),
        (dict(state_lower=[1, 0], state_upper=[0, 1]), ValueError, "'x' has lower 1.0 > upper 0.0"),
        (dict(initial_lower=[0, 5], initial_upper=[0, 1]), ValueError, "initial-state bounds: 'v'"),
        (dict(control_lower=[math.nan]), ValueError, "control_lower contains NaN"),
        (dict(tf_lower=0.0), ValueError, "must exceed t0"),
        (dict(tf_lower=2.0, tf_upper=1.0), ValueError, "lower bound 2.0 exceeds upper bound 1.0"),
        (dict(state_scale=[1.0, 0.0]), ValueError, "state_scale must be positive"),
        (dict(time_scale=-1.0), ValueError, "time_scale must be positive"),
        (dict(cost_scale=math.inf), ValueError, "cost_scale must be positive"),
        (dict(path_constraints=[lambda x, u, t: x[0]]), TypeError, "expected PathConstraint"),
    ],
)
def test_bad_problem_definition_is_rejected(overrides, error, match):
    with pytest.raises(error, match=match):
        _double_integrator(**overrides)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: PathConstraint("c", lambda x, u, t: x[0]), "no finite bound"),
        (lambda: PathConstraint("c", lambda x, u, t: x[0], lower=1.0, upper=0.0), "exceeds upper"),
        (lambda: PathConstraint("c", "not callable", upper=1.0), "must be callable"),
        (lambda: PathConstraint("", lambda x, u, t: x[0], upper=1.0), "non-empty name"),
        (lambda: EndpointConstraint("b", lambda x0, xf, t0, tf: xf[0], upper=1.0, scale=0.0), "scale must be"),
        (lambda: Invariant("g", lambda x: x[0], scale=-1.0), "scale must be positive"),
    ],
)
def test_bad_constraint_is_rejected(make, match):
    with pytest.raises((ValueError, TypeError), match=match):
        make()


def test_dynamics_of_wrong_length_is_reported():
    prob = _double_integrator(dynamics=lambda x, u, t: (x[1],))
    t = np.linspace(0, 1, 3)
    guess = SampledGuess(t, np.zeros((3, 2)), np.zeros((3, 1)))
    with pytest.raises(ValueError, match="dynamics returned 1 derivatives for 2 states"):
        solve(prob, guess)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(mesh_tolerance=0.0), "mesh_tolerance"),
        (dict(max_mesh_iterations=0), "max_mesh_iterations"),
        (dict(n_min=5, n_max=4), "n_min <= n_max"),
        (dict(graph="dense"), "graph"),
    ],
)
def test_bad_solver_options_are_rejected(kw, match):
    with pytest.raises(ValueError, match=match):
        SolverOptions(**kw)


def test_bad_guess_is_rejected():
    with pytest.raises(ValueError, match="strictly increasing"):
        SampledGuess(np.array([0.0, 0.0]), np.zeros((2, 2)), np.zeros((2, 1)))
    with pytest.raises(ValueError, match="NaN or inf"):
        SampledGuess(np.array([0.0, 1.0]), np.array([[0.0, np.nan], [0, 0]]), np.zeros((2, 1)))


def test_the_entry_problem_carries_the_papers_boundary_conditions_and_bounds():
    """Example 2's Table tab:Ex2-BCs and Eq. Ex2-path, as the transcription receives them: the entry
    state fixed but for alpha and sigma, the impact at the surface at 1219 m/s, vertical, alpha 0,
    and the rate and alpha bounds (an independent statement of the paper's numbers, not the config's)."""
    from rventry_env.reference.entry_ocp import EntryOcpConfig, entry_ocp

    config = EntryOcpConfig()
    p = entry_ocp(config)
    re = config.model.planet.radius
    half = math.sqrt(2.0) / 2.0
    x0 = [re + 37e3, 0, 0, 0, 1, 7138.0, 0, 0, half, half]
    assert np.allclose(np.asarray(p.initial_lower)[:10], x0, rtol=0, atol=1e-9)
    assert np.allclose(np.asarray(p.initial_upper)[:10], x0, rtol=0, atol=1e-9)
    assert p.initial_lower[10] == 0.0 and p.initial_upper[10] == pytest.approx(math.radians(25.0))  # alpha(0) free
    assert p.initial_lower[11] < -math.pi and p.initial_upper[11] > math.pi  # sigma(0) free
    lo, hi = np.asarray(p.final_lower), np.asarray(p.final_upper)
    assert lo[0] == hi[0] == pytest.approx(re)
    assert lo[5] == hi[5] == pytest.approx(1219.0)
    assert lo[10] == hi[10] == 0.0
    assert lo[6] == hi[6] == 0.0 and lo[9] == hi[9] == 0.0  # eB1 = etaB = 0: vertical impact
    free = [1, 2, 3, 4, 7, 8, 11]  # held by the path bounds alone
    assert np.array_equal(lo[free], np.asarray(p.state_lower)[free])
    assert np.array_equal(hi[free], np.asarray(p.state_upper)[free])
    assert p.state_lower[10] == 0.0 and p.state_upper[10] == pytest.approx(math.radians(25.0))
    assert p.control_upper[0] == -p.control_lower[0] == pytest.approx(math.radians(10.0))
    assert p.control_upper[1] == -p.control_lower[1] == pytest.approx(math.radians(30.0))


def test_failed_warm_pass_is_solved_again_cold():
    """A warm-started pass that IPOPT does not finish is redone with the cold options, and both
    attempts are reported; the result is the cold attempt's."""
    prob = _double_integrator()
    t = np.linspace(0, 1, 5)
    guess = SampledGuess(t, np.column_stack([t, np.ones_like(t)]), np.zeros((5, 1)))
    rec = RecordingProgress()
    opts = SolverOptions(warm_ipopt={"max_iter": 0})  # the warm attempt cannot succeed
    res = solve(prob, guess, Mesh.uniform(2, 4), opts, progress=rec, warm_start=True)
    warm, cold = rec.records[:2]
    assert not warm.success and warm.label == "" and warm.iteration == 0
    assert cold.success and cold.label == "c" and cold.iteration == 0
    assert res.converged and res.solution.cost == pytest.approx(12.0, rel=1e-8)
    # without a warm start nothing is retried
    rec2 = RecordingProgress()
    assert solve(prob, guess, Mesh.uniform(2, 4), opts, progress=rec2).converged
    assert [r.label for r in rec2.records] == [""]
