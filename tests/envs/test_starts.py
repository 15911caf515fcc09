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


def _seconds_before_impact(starts, n=20000, seed=0):
    _, t = starts.pick(np.random.default_rng(seed).uniform(size=n))
    return load_reference().tf - t


LO, HI = 20.0, 600.0  # a window in seconds before impact; the table ends 1 s before impact
SHAPES = {
    "uniform": ({}, lambda v: (v - LO) / (HI - LO)),
    "far_weight": ({"far_weight": 2.0}, lambda v: ((v - LO) / (HI - LO)) ** 3),  # density (s - LO)^2
    "step_weighted": ({"step_weighted": True}, lambda v: np.log((v - 1) / (LO - 1)) / np.log((HI - 1) / (LO - 1))),
}  # fmt: skip


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_the_start_time_has_the_density_its_table_states(shape):
    """The Kolmogorov-Smirnov distance to the density's own distribution function (in seconds s before
    impact; step_weighted's density is 1/(s - 1), the seconds before the table's end) is at the
    level of sampling noise, and far from the other two densities. The table is on a 1 s grid and a
    draw takes the first row at or after its time, so a drawn s stands for the draws in [s, s + 1)."""
    kw, cdf = SHAPES[shape]
    s = _seconds_before_impact(reference_starts((LO, HI), **kw))
    grid = np.arange(LO, HI)
    ecdf = np.searchsorted(np.sort(s), grid, side="right") / s.size

    def distance(f):
        return np.max(np.abs(ecdf - f(np.minimum(grid + 1.0, HI))))

    assert distance(cdf) < 0.012  # 20,000 draws: 1.36 / sqrt(20,000) = 0.0096 at 95 %
    for other in set(SHAPES) - {shape}:
        assert distance(SHAPES[other][1]) > 0.1


def test_step_weighted_starts_spread_the_steps_flown_evenly_over_the_window():
    """What the weighting is for: a start s seconds before impact flies about s steps, so with
    density 1/s each tenth of the window holds about a tenth of the steps flown; uniform starts give
    the far tenth 18 % of them and the near tenth 1.6 % ((b^2 - a^2) / (HI^2 - LO^2) for a tenth a..b)."""
    edges = np.linspace(LO, HI, 11)
    for kw, near, far in (({"step_weighted": True}, 0.1, 0.1), ({}, 0.0158, 0.184)):
        s = _seconds_before_impact(reference_starts((LO, HI), **kw), n=200000)
        share = np.histogram(s, bins=edges, weights=s)[0] / s.sum()
        assert share[0] == pytest.approx(near, rel=0.1) and share[-1] == pytest.approx(far, rel=0.1)


def test_the_jax_env_draws_step_weighted_starts_as_the_numpy_envs_do():
    pytest.importorskip("jax")
    from rventry_env.envs.jax_vector import RvEntryJaxVectorEnv

    starts = reference_starts((LO, HI), step_weighted=True)
    vec = RvEntryVectorEnv(64, starts=starts, dispersion="standard")
    jx = RvEntryJaxVectorEnv(64, starts=starts, dispersion="standard", dtype="float64")
    _, vinfo = vec.reset(seed=11)
    _, jinfo = jx.reset(seed=11)
    assert np.array_equal(jinfo["time_s"], vinfo["time_s"])
    assert np.median(load_reference().tf - vinfo["time_s"]) < 150.0  # uniform: 310 s


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
    with pytest.raises(ValueError, match="give one of them"):
        StartStates(t, x, (1, 10), far_weight=1.0, step_weighted=True)
    with pytest.raises(ValueError, match="window must end before it"):
        StartStates(t, x, (0, 10), step_weighted=True)
    with pytest.raises(ValueError, match="step_weighted must be True or False"):
        StartStates(t, x, (1, 10), step_weighted="yes")
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
