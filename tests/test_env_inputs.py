"""Inputs that reach the physics are checked where they enter, naming the field and its bound.

Seeds (Gymnasium's rules, NumPy integers included), reward weights, the control step and the
substeps: each bad value refused at construction or reset with a message that names it; each
good value in another type (``np.int64(3)``, ``2.0``) taken as the number it is.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401  (registers RvEntry-v0)
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.task import EntryTask


def _vec(n=2, **kw):
    return gym.make_vec("RvEntry-v0", num_envs=n, vectorization_mode="vector_entry_point", **kw)


# ----------------------------------------------------------------------------- seeds
def test_a_numpy_integer_seed_seeds_as_the_python_integer_in_every_face():
    ref, _ = _vec().reset(seed=7)
    for seed in (np.int64(7), np.int32(7), np.uint8(7)):
        obs, _ = _vec().reset(seed=seed)
        np.testing.assert_array_equal(obs, ref)
    np.testing.assert_array_equal(_vec().reset(seed=np.arange(7, 9))[0], ref)  # one seed per copy, as an array
    np.testing.assert_array_equal(_vec().reset(seed=[7, 8])[0], ref)
    single = gym.make("RvEntry-v0", dispersion="standard")
    np.testing.assert_array_equal(single.reset(seed=np.int64(8))[0], single.reset(seed=8)[0])


def test_a_seed_list_may_leave_a_copy_unseeded_as_gymnasium_allows():
    a, _ = _vec(dispersion="standard").reset(seed=[3, None])
    b, _ = _vec(dispersion="standard").reset(seed=[3, None])
    np.testing.assert_array_equal(a[0], b[0])


@pytest.mark.parametrize("seed, message", [
    (1.5, r"reset\(seed=...\) must be an integer >= 0, one seed per copy \(2\) or None, got 1.5 \(float\)"),
    (-1, r"must be an integer >= 0 or None, got -1"),
    (True, r"got True \(bool\)"),
    ("7", r"got '7' \(str\)"),
    ([1.5, 2], r"the seed of copy 0 must be an integer >= 0 or None, got 1.5"),
    ([1, 2, 3], r"needs one seed per copy \(2\), got 3"),
    (np.array([[1, 2]]), r"one seed per copy \(2\)"),
])  # fmt: skip
def test_a_bad_vector_seed_is_refused_naming_the_seed(seed, message):
    with pytest.raises(ValueError, match=message):
        _vec().reset(seed=seed)


@pytest.mark.parametrize("seed", [1.5, -3, True, "7"])
def test_a_bad_single_seed_is_refused_naming_the_seed(seed):
    with pytest.raises(ValueError, match=r"reset\(seed=...\) must be an integer >= 0 or None"):
        RvEntryEnv().reset(seed=seed)


def test_the_jax_face_takes_seeds_by_the_same_rules():
    pytest.importorskip("jax")
    env = _vec(backend="jax")
    a, _ = env.reset(seed=np.int64(7))
    np.testing.assert_array_equal(a, _vec().reset(seed=7)[0])
    with pytest.raises(ValueError, match=r"got 1.5 \(float\)"):
        env.reset(seed=1.5)


# ----------------------------------------------------------------------------- reward weights
@pytest.mark.parametrize("field", ["miss_per_km", "failure", "success_bonus", "load_violation"])
@pytest.mark.parametrize("value, message", [
    (math.nan, "must be finite, got nan"), (math.inf, "must be finite, got inf"), (-math.inf, "must be finite"),
    (-1.0, "must be >= 0 and <= 1e\\+06, got -1"), (1e300, "must be >= 0 and <= 1e\\+06, got 1e\\+300"),
    ("1", "must be a number"), (True, "must be a number"),
])  # fmt: skip
def test_a_reward_weight_that_is_not_a_finite_number_in_range_is_refused_naming_it(field, value, message):
    with pytest.raises(ValueError, match=f"RewardWeights.{field} {message}"):
        RewardWeights(**{field: value})


def test_accepted_reward_weights_give_finite_rewards_to_the_end():
    """The largest weights accepted, on an episode that fails (the failure penalty paid): finite."""
    big = RewardWeights(**{f: 1e6 for f in ("miss_per_km", "vertical_per_deg", "speed_per_mps", "alpha_per_deg",
                                            "load_violation", "q_violation", "failure")},
                        success_bonus=np.float32(2.0))  # fmt: skip
    assert isinstance(big.success_bonus, float) and big.success_bonus == 2.0
    env = RvEntryVectorEnv(3, reward=big, max_episode_steps=60)
    env.reset(seed=0)
    rewards = []
    for _ in range(60):
        _, r, term, trunc, _ = env.step(np.ones((3, 2)))
        rewards.append(r)
    assert trunc.all() or term.any()
    assert np.all(np.isfinite(rewards)) and np.all(np.asarray(rewards, np.float32) > -np.inf)


# ----------------------------------------------------------------------------- dt and substeps
@pytest.mark.parametrize("kwargs, message", [
    ({"substeps": 2**40}, r"substeps must be a positive integer <= 1000 \(RK4 substeps per control step\), "
                          r"got 1099511627776"),
    ({"substeps": 1001}, "substeps must be a positive integer <= 1000"),
    ({"substeps": 0}, "substeps must be a positive integer"),
    ({"substeps": 1.5}, "substeps must be a positive integer"),
    ({"substeps": np.float64(2.5)}, "substeps must be a positive integer"),
    ({"substeps": True}, "substeps must be a positive integer"),
    ({"substeps": math.inf}, "substeps must be a positive integer"),
    ({"dt": "abc"}, r"dt must be a positive number of seconds in \[0.001, 600\], got 'abc'"),
    ({"dt": 1e300}, r"dt must be a positive number of seconds in \[0.001, 600\], got 1e\+300"),
    ({"dt": 1e-9}, r"dt must be a positive number of seconds in \[0.001, 600\]"),
    ({"dt": -1.0}, "dt must be a positive number"),
    ({"dt": np.nan}, "dt must be a positive number"),
    ({"dt": [1.0]}, "dt must be a positive number"),
])  # fmt: skip
@pytest.mark.parametrize("make", [lambda **kw: gym.make("RvEntry-v0", **kw), lambda **kw: _vec(**kw),
                                  lambda **kw: EntryTask(**kw)], ids=["single", "vector", "task"])  # fmt: skip
def test_dt_and_substeps_out_of_their_bounds_are_refused_naming_them(make, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


@pytest.mark.parametrize("substeps", [np.int64(3), np.int32(3), 3.0, np.float64(3.0), 3])
def test_an_integer_number_of_substeps_in_any_type_is_that_integer(substeps):
    env = gym.make("RvEntry-v0", substeps=substeps)
    assert env.unwrapped.task.substeps == 3 and type(env.unwrapped.task.substeps) is int
    ref = gym.make("RvEntry-v0", substeps=3)
    np.testing.assert_array_equal(env.reset(seed=1)[0], ref.reset(seed=1)[0])
    np.testing.assert_array_equal(env.step(np.ones(2))[0], ref.step(np.ones(2))[0])


def test_dt_in_any_real_type_is_that_float_and_the_bounds_are_inclusive():
    assert RvEntryEnv(dt=np.float32(0.5)).dt == 0.5
    assert RvEntryEnv(dt=np.int64(2)).dt == 2.0
    assert EntryTask(dt=1e-3, substeps=1000).substeps == 1000
    assert EntryTask(dt=600).dt == 600.0
