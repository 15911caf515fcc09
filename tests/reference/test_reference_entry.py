"""The entry problem's formulation: one copy of the physics, the norm-keeping controls, the guess."""

import math

import numpy as np
import pytest

from rventry_env.task.problem import EntryProblem

from rventry_env.core.euler_parameters import omega_from_rates
from rventry_env.physics.entry import entry_rhs
from rventry_env.physics.model import EntryModel
from rventry_env.reference import load_reference
from rventry_env.reference.collocation import CompiledProblem
from rventry_env.reference.entry_ocp import EntryOcpConfig, entry_ocp, position_direction
from rventry_env.reference.guess import ReferenceGuess, generate_guess
from rventry_env.reference.spherical_entry import (
    spherical_from_entry_states,
    spherical_problem,
    spherical_rhs,
)

MODEL = EntryModel()


def _random_states(n, seed=0):
    rng = np.random.default_rng(seed)
    qa = rng.normal(size=(n, 4))
    qb = rng.normal(size=(n, 4))
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    qb /= np.linalg.norm(qb, axis=1, keepdims=True)
    r = MODEL.planet.radius + rng.uniform(5e3, 60e3, n)
    v = rng.uniform(800, 7000, n)
    return np.column_stack([r, qa, v, qb, rng.uniform(0, 0.4, n), rng.uniform(-6, 6, n)])


def test_dynamics_are_entry_rhs_plus_radial_norm_rates():
    cp = CompiledProblem(entry_ocp(EntryOcpConfig()))
    x = _random_states(20)
    rng = np.random.default_rng(1)
    u = np.column_stack([rng.uniform(-0.1, 0.1, (20, 2)), np.zeros((20, 2))])
    f = cp.rhs(x, u, np.zeros(20))
    ref = np.array(entry_rhs(list(x.T), list(u[:, :2].T), MODEL)).T
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-15)  # lambda = 0: exactly the physics
    u[:, 2:] = rng.uniform(-1e-3, 1e-3, (20, 2))
    f2 = cp.rhs(x, u, np.zeros(20))
    for q, dq, lam in ((x[:, 1:5], f2[:, 1:5], u[:, 2]), (x[:, 6:10], f2[:, 6:10], u[:, 3])):
        # d|q|^2/dt = 2 lambda |q|^2, and the implied twist rate omega_1 stays 0
        np.testing.assert_allclose(2 * np.sum(q * dq, axis=1), 2 * lam, rtol=1e-9, atol=1e-15)
        w1 = omega_from_rates(*q.T, *dq.T)[0]
        assert np.max(np.abs(w1)) < 1e-15


def test_paper_mode_replaces_four_rates_with_controls():
    cfg = EntryOcpConfig(norm_mode="paper")
    prob = entry_ocp(cfg)
    assert prob.control_names == ("u_alpha", "u_sigma", "u1", "u2", "u3", "u4")
    assert [c.name for c in prob.path_constraints][2:] == ["band_eA2", "band_eA3", "band_eB2", "band_eB3"]
    assert all(c.upper == 1e-6 and c.lower == -1e-6 for c in prob.path_constraints[2:])
    cp = CompiledProblem(prob)
    x = _random_states(5)
    u = np.column_stack([np.zeros((5, 2)), np.arange(20.0).reshape(5, 4)])
    f = cp.rhs(x, u, np.zeros(5))
    np.testing.assert_array_equal(f[:, [2, 3, 7, 8]], u[:, 2:])


def test_position_direction_is_homogeneous():
    q = np.array([0.1, -0.3, 0.2, 0.9])
    q /= np.linalg.norm(q)
    a1 = np.array(position_direction(q))
    assert np.linalg.norm(a1) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(np.array(position_direction(1.01 * q)), 1.01**2 * a1, rtol=1e-14)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(norm_mode="free"), "norm_mode"),
        (dict(tf_bounds=(10.0, 5.0)), "tf_bounds"),
        (dict(final_gamma_max_deg=-95.0), "final_gamma_max_deg"),
        (dict(delta=0.0), "delta"),
    ],
)
def test_bad_entry_config_is_rejected(kw, match):
    with pytest.raises(ValueError, match=match):
        EntryOcpConfig(**kw)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(alpha_bar=math.radians(30.0)), "alpha_bar"),
        (dict(initial_e_a=(0.0, 0.0, 0.0, 2.0)), "unit norm"),
        (dict(u_sigma_max=0.0), "u_sigma_max"),
        (dict(initial_altitude=-1.0), "initial_altitude"),
        (dict(q_min=float("nan")), "q_min"),
    ],
)
def test_bad_problem_constants_are_rejected(kw, match):
    with pytest.raises(ValueError, match=match):
        EntryProblem(**kw)


def test_generated_guess_reaches_the_ground_near_the_target():
    guess, flight = generate_guess(EntryOcpConfig())
    re = MODEL.planet.radius
    assert guess.x[-1, 0] == pytest.approx(re, abs=1.0)
    assert flight.miss_m < 50e3 and flight.gamma_deg < -45.0
    assert np.all(np.isfinite(guess.x)) and guess.u.shape == (guess.t.size, 4)
    # the guess obeys the rate bounds it is flown with
    assert np.max(np.abs(guess.u[:, 0])) <= math.radians(10) + 1e-15


@pytest.mark.parametrize("mode", ["projection", "paper", "none"])
def test_the_shipped_optimum_as_a_guess_obeys_each_formulations_dynamics(mode):
    """Its states and (u_alpha, u_sigma) are the optimum's; its extra controls make every formulation's
    right-hand side the physics' (lambda = 0, or u1..u4 = the rates they replace), so the guess is as
    consistent in each formulation as the optimum is with entry_rhs."""
    ref = load_reference()
    cfg = EntryOcpConfig(norm_mode=mode)
    guess = ReferenceGuess(ref, cfg)
    t = ref.t[::7]
    x, u = guess.state(t), guess.control(t)
    assert (guess.t0, guess.tf) == (ref.t0, ref.tf)
    np.testing.assert_array_equal(x, ref.state(t))
    np.testing.assert_array_equal(u[:, :2], ref.control(t))
    cp = CompiledProblem(entry_ocp(cfg))
    assert u.shape == (t.size, len(cp.problem.control_names))
    physics = np.array(entry_rhs(list(x.T), list(u[:, :2].T), MODEL)).T
    np.testing.assert_allclose(cp.rhs(x, u, np.zeros(t.size)), physics, rtol=1e-12, atol=1e-15)
    if mode == "paper":  # the band constraints |u_i - rate| <= delta hold with room: u_i is the rate
        np.testing.assert_allclose(u[:, 2:], physics[:, [2, 3, 7, 8]], rtol=1e-12, atol=1e-15)
    one = guess.control(ref.tf / 2)  # a single time: one row
    assert one.shape == (1, u.shape[1])
    # soft path constraints: the same controls, and the slacks at zero (the path as the optimum flew it)
    soft = EntryOcpConfig(norm_mode=mode, soft_path_penalty=10.0)
    padded = ReferenceGuess(ref, soft).control(t)
    assert padded.shape == (t.size, entry_ocp(soft).n_u) == (t.size, u.shape[1] + 2)
    np.testing.assert_array_equal(padded[:, : u.shape[1]], u)
    assert not padded[:, u.shape[1] :].any()


def test_a_given_guess_replaces_the_generated_one(monkeypatch):
    """``solve_reference(guess=...)`` hands that guess to the solver and flies no guidance-law batch."""
    import rventry_env.reference.guess as guess_module
    from rventry_env.reference import collocation
    from rventry_env.reference.pipeline import solve_reference

    seen = []

    class Stop(Exception):
        pass

    def solver(problem, guess, mesh, options, progress, label=""):
        seen.append(guess)
        raise Stop

    def no_flights(config):
        raise AssertionError("the guidance-law guess was flown although a guess was given")

    monkeypatch.setattr(collocation, "solve", solver)
    monkeypatch.setattr(collocation, "CompiledProblem", lambda problem: problem)
    monkeypatch.setattr(guess_module, "generate_guess", no_flights)
    given = ReferenceGuess(load_reference())
    with pytest.raises(Stop):
        solve_reference(guess=given)
    assert seen == [given]
    seen.clear()
    monkeypatch.undo()
    monkeypatch.setattr(collocation, "solve", solver)
    monkeypatch.setattr(collocation, "CompiledProblem", lambda problem: problem)
    with pytest.raises(Stop):
        solve_reference()  # without one: the generated guess, sampled from the flight
    assert type(seen[0]).__name__ == "SampledGuess"


def test_spherical_equations_agree_with_rv_euler_away_from_vertical():
    """d/dt of the spherical coordinates of an rv-Euler flight equals the spherical EOM."""
    ref = load_reference()
    x, u = ref.x[5:-20], ref.u[5:-20]
    h = 1e-3
    xd = np.array(entry_rhs(list(x.T), list(u.T), MODEL)).T
    s0 = spherical_from_entry_states(x)
    num = (spherical_from_entry_states(x + h * xd) - spherical_from_entry_states(x - h * xd)) / (2 * h)
    ana = np.array(spherical_rhs(list(s0.T), [u[:, 0], np.zeros(len(u))], MODEL)).T
    np.testing.assert_allclose(num[:, :6], ana[:, :6], rtol=1e-6, atol=1e-6)


def test_spherical_problem_rejects_bad_terminal_angle():
    with pytest.raises(ValueError, match="final_gamma_deg"):
        spherical_problem(final_gamma_deg=-91.0)
