"""Start states: physical states of the env, the same in every backend, and never in evaluation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rventry_env.envs import common
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.evaluation.rungs import RUNGS, rung, rung_starts
from rventry_env.reference import load_reference
from rventry_env.reference.starts import reference_starts
from rventry_env.task import EntryTask
from rventry_env.task.starts import StartStates

R = 6378137.0
TASK = EntryTask()


def _late(**kw):
    return reference_starts((30.0, 200.0), altitude_m=400.0, speed_mps=20.0, flight_path_deg=0.3, heading_deg=0.3,
                            alpha_deg=2.0, sigma_deg=10.0, **kw)  # fmt: skip


def test_a_start_is_a_physical_state_inside_the_path_bounds():
    """Unit Euler parameters, alpha within its bounds, above the surface and below the ceiling, q and
    the load factor inside their bounds, and the clock at a table time in the window."""
    env = RvEntryVectorEnv(256, starts=_late(), dispersion="wide")
    _, info = env.reset(seed=0)
    x = env.state
    assert np.allclose(np.linalg.norm(x[:, 1:5], axis=1), 1.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(x[:, 6:10], axis=1), 1.0, atol=1e-12)
    assert np.all((x[:, 10] >= 0) & (x[:, 10] <= TASK.problem.alpha_max))
    h = x[:, 0] - R
    assert np.all((h > 0) & (h < TASK.ceiling_altitude))
    p = TASK.problem
    assert np.all(info["dynamic_pressure_pa"] >= p.q_min * (1 + common.START_MARGIN) * (1 - 1e-9))
    assert np.all(info["load_factor_g"] <= p.a_max_g * (1 - common.START_MARGIN) * (1 + 1e-9))
    ref = load_reference()
    before = ref.tf - info["time_s"]
    assert np.all((before >= 30.0 - 1e-9) & (before <= 200.0 + 1e-9))
    # the picked rows are the table's: time on the reference's one-second grid counted back from impact
    assert np.allclose((ref.tf - info["time_s"]) % 1.0, 0.0, atol=1e-9) or np.allclose(
        (ref.tf - info["time_s"]) % 1.0, 1.0, atol=1e-9)


def test_the_single_vector_and_jax_envs_start_the_same_episodes():
    starts = _late(probability=0.6)
    vec = RvEntryVectorEnv(6, starts=starts, dispersion="standard")
    _, vinfo = vec.reset(seed=40)
    for i in range(6):
        single = RvEntryEnv(starts=starts, dispersion="standard")
        _, info = single.reset(seed=40 + i)
        assert np.array_equal(single.unwrapped.state, vec.state[i])
        assert info["time_s"] == vinfo["time_s"][i]
    pytest.importorskip("jax")
    from rventry_env.envs.jax_vector import RvEntryJaxVectorEnv

    jx = RvEntryJaxVectorEnv(6, starts=starts, dispersion="standard", dtype="float64")
    _, jinfo = jx.reset(seed=40)
    assert np.allclose(jx.state, vec.state, rtol=1e-12, atol=1e-6)
    assert np.array_equal(jinfo["time_s"], vinfo["time_s"])


def test_episodes_not_started_from_the_table_are_the_plain_envs_episodes():
    """The start draw comes after every other draw of a reset: the episodes that start at the initial
    state are exactly those of an env without start states, seed for seed."""
    with_starts = RvEntryVectorEnv(64, starts=_late(probability=0.5), dispersion="wide")
    plain = RvEntryVectorEnv(64, dispersion="wide")
    _, a = with_starts.reset(seed=7)
    _, b = plain.reset(seed=7)
    own = a["time_s"] == 0.0
    assert 10 < own.sum() < 54  # about half, by the probability
    assert np.array_equal(with_starts.state[own], plain.state[own])
    assert np.array_equal(with_starts.dispersion_draw, plain.dispersion_draw)


def test_the_functional_env_draws_start_states_by_the_same_rule():
    jax = pytest.importorskip("jax")
    from rventry_env.envs.functional import RvEntryFunctional

    starts = _late(probability=0.7)
    env = RvEntryFunctional(starts=starts, dispersion="standard", dtype="float64")
    params = env.default_params
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.PRNGKey(3), 2000), params)
    t = np.asarray(state.episode.t)
    from_table = t > 0
    assert abs(from_table.mean() - 0.7) < 0.04  # 2000 draws: 4 standard errors is 0.041
    before = load_reference().tf - t[from_table]
    assert before.min() >= 30.0 - 1e-6 and before.max() <= 200.0 + 1e-6
    # spread over the window, not bunched: both halves of the window are drawn
    assert np.mean(before < 115.0) > 0.4 and np.mean(before > 115.0) > 0.4
    x = np.stack([np.asarray(c) for c in state.episode.x], axis=1)[from_table]
    assert np.allclose(np.linalg.norm(x[:, 6:10], axis=1), 1.0, atol=1e-12)
    q = np.asarray(state.episode.forces.dynamic_pressure)[from_table]
    assert q.min() >= TASK.problem.q_min * (1 + common.START_MARGIN) * (1 - 1e-9)


def test_start_states_are_checked_and_refused_with_their_fault_named():
    ref = load_reference()
    t = np.arange(0.0, 100.0)
    x = ref.state(t)
    with pytest.raises(ValueError, match="shape"):
        StartStates(t, x[:, :11], (0, 10))
    bad = x.copy()
    bad[5, 6] += 0.1
    with pytest.raises(ValueError, match="row 5 do not have unit norm"):
        StartStates(t, bad, (0, 10))
    with pytest.raises(ValueError, match="before_end_s"):
        StartStates(t, x, (0, 500))
    with pytest.raises(ValueError, match="probability"):
        StartStates(t, x, (0, 10), probability=0.0)
    with pytest.raises(ValueError, match="altitude_m must be a finite half-width"):
        StartStates(t, x, (0, 10), altitude_m=-1.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        StartStates(t[::-1], x, (0, 10))
    # a perturbation that can start a vehicle underground is refused by the env, before any episode
    near_impact = reference_starts((1.0, 5.0), altitude_m=5000.0)
    with pytest.raises(ValueError, match="above the surface"):
        RvEntryEnv(starts=near_impact)
    with pytest.raises(TypeError, match="StartStates"):
        RvEntryEnv(starts={"window": 3})


def test_every_rung_makes_an_env_and_the_late_rung_starts_late():
    import gymnasium as gym

    for name, r in RUNGS.items():
        env = gym.make("RvEntry-v0", **r.env_kwargs())
        _, info = env.reset(seed=1)
        if r.before_impact_s is None:
            assert info["time_s"] == 0.0 and abs(info["altitude_m"] - 37e3) < 2e3
        else:
            before = load_reference().tf - info["time_s"]
            assert r.before_impact_s[0] - 1e-9 <= before <= r.before_impact_s[1] + 1e-9
    assert rung("late").starts() is rung_starts("late")
    with pytest.raises(ValueError, match="no rung 'bogus'; the ladder: late, half"):
        rung("bogus")


def test_evaluation_flies_the_initial_state_unless_a_rung_says_otherwise():
    from rventry_env.evaluation.parallel import EvaluationJob, run_task
    from rventry_env.guidance.law import Law

    class Hold(Law):
        def __call__(self, m):
            self.first = getattr(self, "first", m.time_s.copy())
            return np.zeros((m.n, 2), np.float32)

    from rventry_env.evaluation import parallel

    law = Hold()
    parallel._LAWS[("hold-test", TASK, ())] = law
    try:
        run_task(EvaluationJob("hold-test", "standard", TASK), [0, 1])
        assert np.all(law.first == 0.0)
        law.first = None
        del law.first
        batch = run_task(EvaluationJob("hold-test", "none", TASK, rung="late"), [0, 1])
        assert np.all(load_reference().tf - law.first <= 60.0 + 1e-9)
        assert batch.miss_km.shape == (2,)
    finally:
        del parallel._LAWS[("hold-test", TASK, ())]


def test_within_path_bounds_moves_only_the_altitude_and_only_where_needed():
    from rventry_env.core.backend import NUMPY
    from rventry_env.physics.entry import entry_forces
    from rventry_env.physics.model import EntryModel

    model = EntryModel()
    ref = load_reference()
    x = ref.state(np.array([200.0, 960.0]))  # well inside the bounds; on q_min
    x[1, 0] += 300.0  # 300 m higher: below q_min
    moved = np.array(common.within_path_bounds(tuple(x.T), model, TASK, NUMPY)).T
    assert np.array_equal(moved[:, 1:], x[:, 1:])
    assert moved[0, 0] == pytest.approx(x[0, 0], abs=1e-6)  # inside: untouched
    q = entry_forces(tuple(moved.T), model, NUMPY).dynamic_pressure
    assert q[1] == pytest.approx(TASK.problem.q_min * (1 + common.START_MARGIN), rel=1e-6)
    assert moved[1, 0] < x[1, 0] and math.isclose(moved[1, 0], x[1, 0] - 300.0, abs_tol=300.0)
