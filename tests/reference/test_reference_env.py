"""The environment against the shipped collocation reference: the replay lands, and the reward is the cost."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401
from rventry_env.core.backend import NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs.outcome import terminal_metrics, terminal_penalty
from rventry_env.envs.propagation import path_violation
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.guidance.law import Law, Measurement
from rventry_env.task import EntryTask
from rventry_env.guidance.reference_replay import ReferencePolicy
from rventry_env.physics import EntryModel, entry_forces
from rventry_env.reference import load_reference
from rventry_env.reference.open_loop import entry_rhs_numpy, replay_controls


@pytest.fixture(scope="module")
def replay():
    # a fine output grid: the env's cost is evaluated segment by segment along it
    return replay_controls(entry_rhs_numpy(), load_reference(), n_out=200_001)


def test_default_env_starts_from_the_reference_initial_state():
    env = gym.make("RvEntry-v0")
    env.reset(seed=0)
    np.testing.assert_array_equal(env.unwrapped.state, load_reference().x[0])


@pytest.mark.slow
def test_tight_replay_of_the_reference_controls_lands_within_100_m(replay):
    assert replay.position_error_at_impact_m < 100.0
    assert abs(replay.altitude_at_tf_m) < 100.0


@pytest.mark.slow
def test_env_reward_along_the_tight_replay_is_minus_j_star_with_no_terminal_penalty(replay):
    """The environment's reward terms, evaluated on the replay, sum to -J*."""
    ref, task, model = load_reference(), EntryTask(), EntryModel()
    t, x = replay.t, replay.x
    u = ref.control(0.5 * (t[1:] + t[:-1]))  # each segment holds its midpoint rates
    tau = np.diff(t)
    u_alpha_applied = np.diff(x[:, 10]) / tau  # alpha is linear within a segment, as in the env
    cost = np.sum(task.problem.cost_over_hold(x[:-1, 10], u_alpha_applied, u[:, 0], u[:, 1], tau))
    assert cost == pytest.approx(ref.cost, rel=1e-3)
    forces = entry_forces(tuple(x.T), model, NUMPY)
    load_x, q_x = path_violation(forces, task, model, NUMPY)
    assert np.all(load_x == 0) and np.all(q_x == 0)  # the reference stays within the success margin
    xf = tuple(x[-1])
    m = terminal_metrics(xf, dcm(*xf[1:5]), task, task.problem.target_unit_vector(), model.planet.radius, NUMPY)
    assert m.miss_km < 0.1 and m.vertical_error_deg < 0.1 and abs(m.speed_error_mps) < 1.0
    assert abs(m.alpha_final_deg) < 0.05
    assert terminal_penalty(m, RewardWeights(), NUMPY) < 0.02 * ref.cost


def test_env_default_step_replays_the_reference_closely():
    """The reference's step-mean rates through the env at dt = 1 s, 2 RK4 substeps."""
    ref = load_reference()
    env = RvEntryEnv()
    policy = ReferencePolicy()
    obs, info = env.reset(seed=0)
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(policy(Measurement.single(obs, info, env.state))[0])
        total += r
        if term or trunc:
            break
    assert info["failure"] == "" and info["is_success"] and not info["constraint_violation"]
    assert info["miss_km"] < 0.5 and info["vertical_error_deg"] < 1.0 and abs(info["speed_error_mps"]) < 5.0
    assert info["time_s"] == pytest.approx(ref.tf, abs=0.5)
    # a zero-order hold averages the final alpha bang away: the step cost is a little below J*
    assert 0.85 * ref.cost < info["cost"] <= ref.cost
    assert total == pytest.approx(-(info["cost"] + info["terminal_penalty"]), rel=1e-9)
