"""The environments pickle, and the copy flies on exactly as the original.

RL tools ship environments to worker processes (``multiprocessing`` with ``spawn``) and
checkpoint them. Each face is pickled mid-episode, unpickled, and both are stepped with the
same actions to the end of the episode: the same observations, rewards, endings and end keys,
bit for bit.
"""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401  (registers RvEntry-v0)

END_KEYS = ("miss_km", "vertical_error_deg", "speed_error_mps", "is_success", "failure")


def _actions(seed: int, n: int | None):
    rng = np.random.default_rng(seed)
    while True:
        yield rng.uniform(-0.4, 0.4, 2 if n is None else (n, 2)).astype(np.float32)


def _fly_pair(env, copy, actions, vector: bool, limit: int = 3000) -> int:
    """Step ``env`` and ``copy`` alike until every episode ended once; return the steps flown."""
    ended = None
    for k in range(limit):
        a = next(actions)
        one, two = env.step(a), copy.step(a)
        for x, y in zip(one[:4], two[:4]):
            np.testing.assert_array_equal(x, y)
        for key in END_KEYS:
            if key in one[4]:
                np.testing.assert_array_equal(one[4][key], two[4][key])
        done = np.logical_or(one[2], one[3])
        if not vector:
            if done:
                assert one[4]["failure"] == two[4]["failure"]
                return k + 1
            continue
        ended = done if ended is None else ended | done
        if ended.all():
            return k + 1
    raise AssertionError("no episode ended")


@pytest.mark.parametrize("dispersion", ["none", "flight"])
def test_the_single_env_pickles_mid_episode_and_flies_the_same_episode(dispersion):
    env = gym.make("RvEntry-v0", dispersion=dispersion)
    env.reset(seed=11)
    actions = _actions(0, None)
    for _ in range(40):
        env.step(next(actions))
    copy = pickle.loads(pickle.dumps(env))
    assert copy.unwrapped is not env.unwrapped
    np.testing.assert_array_equal(copy.unwrapped.state, env.unwrapped.state)
    assert _fly_pair(env, copy, actions, vector=False) > 1
    # and the next episode, drawn from the pickled generator, is the same too
    o1, _ = env.reset()
    o2, _ = copy.reset()
    np.testing.assert_array_equal(o1, o2)


@pytest.mark.parametrize("num_envs, dispersion", [(2, "standard"), (5, "flight")])
def test_the_vector_env_pickles_mid_episode_and_flies_the_same_episodes(num_envs, dispersion):
    """Two copies step on Python floats, five on arrays: both paths pickle."""
    env = gym.make_vec("RvEntry-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", dispersion=dispersion)
    env.reset(seed=3)
    actions = _actions(1, num_envs)
    for _ in range(25):
        env.step(next(actions))
    copy = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(copy.unwrapped.state, env.unwrapped.state)
    # NEXT_STEP autoreset: an ended copy restarts from its pickled generator, alike in both
    _fly_pair(env, copy, actions, vector=True)
    for _ in range(3):
        a = next(actions)
        np.testing.assert_array_equal(env.step(a)[0], copy.step(a)[0])


def test_an_env_pickles_before_its_first_reset():
    copy = pickle.loads(pickle.dumps(gym.make("RvEntry-v0")))
    obs, _ = copy.reset(seed=5)
    np.testing.assert_array_equal(obs, gym.make("RvEntry-v0").reset(seed=5)[0])


def test_the_math_namespaces_unpickle_as_the_librarys_own():
    from rventry_env.core.backend import MATH, NUMPY

    assert pickle.loads(pickle.dumps(NUMPY)) is NUMPY
    assert pickle.loads(pickle.dumps(MATH)) is MATH


@pytest.mark.slow
def test_the_jax_vector_env_pickles_mid_episode_and_flies_the_same_episodes(dispersion="flight"):
    """The compiled functions are not pickled: the copy compiles its own (about a minute on a CPU)."""
    pytest.importorskip("jax")
    env = gym.make_vec("RvEntry-v0", num_envs=3, vectorization_mode="vector_entry_point", backend="jax",
                       dispersion=dispersion)  # fmt: skip
    env.reset(seed=8)
    actions = _actions(2, 3)
    for _ in range(25):
        env.step(next(actions))
    copy = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(copy.unwrapped.state, env.unwrapped.state)
    _fly_pair(env, copy, actions, vector=True)


def test_envs_with_start_states_and_shaping_pickle_and_fly_the_same_episodes():
    """A training env (start states drawn from the reference, potential shaping) ships as well."""
    from rventry_env.envs.shaping import PotentialShaping
    from rventry_env.reference.starts import reference_starts

    kw = {"starts": reference_starts((30.0, 200.0), altitude_m=400.0, probability=0.5),
          "shaping": PotentialShaping("range", 0.99), "dispersion": "standard"}  # fmt: skip
    single = gym.make("RvEntry-v0", **kw)
    single.reset(seed=21)
    _fly_pair(single, pickle.loads(pickle.dumps(single)), _actions(3, None), vector=False)
    vec = gym.make_vec("RvEntry-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    vec.reset(seed=22)
    _fly_pair(vec, pickle.loads(pickle.dumps(vec)), _actions(4, 3), vector=True)


def test_the_functional_env_its_params_and_state_pickle_and_step_alike():
    pytest.importorskip("gymnax")
    import jax

    from rventry_env.envs.functional import RvEntryFunctional

    env = RvEntryFunctional(dispersion="standard", dtype="float64")
    params = env.default_params
    _, state = env.reset(jax.random.PRNGKey(0), params)
    copy, copy_params, copy_state = pickle.loads(pickle.dumps((env, params, state)))
    step = jax.jit(env.step_env)
    copy_step = jax.jit(copy.step_env)
    actions = _actions(5, None)
    for k in range(3000):
        a = next(actions)
        key = jax.random.PRNGKey(k)
        one = step(key, state, a, params)
        two = copy_step(key, copy_state, a, copy_params)
        for x, y in zip(jax.tree.leaves(one), jax.tree.leaves(two)):
            np.testing.assert_array_equal(x, y)
        state, copy_state = one[1], two[1]
        if bool(one[3]):
            break
    assert bool(one[3]) and k > 10


def test_an_unpickled_functional_env_with_shaping_equals_its_original():
    """gymnax compiles with the env static, compared by value: a copy (or an equal shaping) reuses the program."""
    pytest.importorskip("gymnax")
    from rventry_env.envs.functional import RvEntryFunctional
    from rventry_env.envs.shaping import PotentialShaping

    energies, ranges = np.array([1e6, 2e6, 3e6]), np.array([0.0, 1e5, 4e5])
    env = RvEntryFunctional(shaping=PotentialShaping("energy", 0.999, energies=energies, ranges=ranges))
    copy = pickle.loads(pickle.dumps(env))
    assert copy == env and hash(copy) == hash(env)
    same = RvEntryFunctional(shaping=PotentialShaping("energy", 0.999, energies=energies.copy(), ranges=ranges.copy()))
    assert same == env
    other = RvEntryFunctional(shaping=PotentialShaping("energy", 0.999, energies=energies, ranges=ranges * 2))
    assert other != env
    assert RvEntryFunctional(shaping=PotentialShaping("range", 0.999)) != env
