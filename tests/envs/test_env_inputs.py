"""Inputs that reach the physics are checked where they enter, naming the field and its bound.

Seeds (Gymnasium's rules, NumPy integers included), reward weights, the control step and the
substeps: each bad value refused at construction or reset with a message that names it; each
good value in another type (``np.int64(3)``, ``2.0``) taken as the number it is.
"""

from __future__ import annotations

import math
import re

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


# ----------------------------------------------------------------------------- time limits
@pytest.mark.parametrize("steps", [2**31, 2**40, 10**30])
@pytest.mark.parametrize("make", [lambda **kw: RvEntryEnv(**kw), lambda **kw: RvEntryVectorEnv(2, **kw)],
                         ids=["single", "vector"])  # fmt: skip
def test_a_time_limit_beyond_the_step_counter_is_refused_naming_it_and_its_bound(make, steps):
    with pytest.raises(ValueError, match=r"max_episode_steps must be a positive integer <= 2147483647 \(what the step "
                                         rf"counter, int32, holds\) or None, got {steps}"):  # fmt: skip
        make(max_episode_steps=steps)


def test_the_largest_time_limit_is_accepted():
    assert RvEntryVectorEnv(1, max_episode_steps=np.int64(2**31 - 1)).max_episode_steps == 2**31 - 1


# ----------------------------------------------------------------------------- the functional env
def _functional(**kw):
    pytest.importorskip("gymnax")
    from rventry_env.envs.functional import RvEntryFunctional

    return RvEntryFunctional(dtype="float64", **kw)


@pytest.mark.parametrize("shape", [(1,), (3,), (), (2, 2), (1, 2)])
def test_a_functional_action_of_another_shape_is_refused_when_traced_naming_the_shape(shape):
    import jax
    import jax.numpy as jnp

    env = _functional()
    params = env.default_params
    key = jax.random.PRNGKey(0)
    _, state = env.reset(key, params)
    with pytest.raises(ValueError, match=rf"the action must have shape \(2,\) \(\[alpha rate, bank rate\], each in "
                                         rf"\[-1, 1\]\), got shape {re.escape(str(shape))}"):  # fmt: skip
        env.step(key, state, jnp.zeros(shape), params)  # gymnax's step: jit
    with pytest.raises(ValueError, match="must be real numbers, got dtype complex"):
        env.step(key, state, jnp.zeros(2, jnp.complex64), params)
    with pytest.raises(ValueError, match=r"step_batch takes actions of shape \(N, 2\)"):
        from rventry_env.envs.functional import step_batch

        keys = jax.random.split(key, 3)
        states = jax.vmap(env.reset_env, in_axes=(0, None))(keys, params)[1]
        step_batch(env, keys, states, jnp.zeros((3, 3)), params, 1)


def test_a_functional_action_out_of_range_is_clipped_and_reported_and_a_nan_one_ends_the_episode():
    import jax
    import jax.numpy as jnp

    from rventry_env.envs.propagation import NON_FINITE

    env = _functional()
    params = env.default_params
    key = jax.random.PRNGKey(1)
    _, state = env.reset(key, params)
    step = jax.jit(env.step_env)
    o_in, _, r_in, _, info = step(key, state, jnp.array([0.5, -1.0]), params)
    assert not bool(info["action_clipped"])
    o_big, _, r_big, _, info_big = step(key, state, jnp.array([3.0, -1e300]), params)
    o_one, _, r_one, _, _ = step(key, state, jnp.array([1.0, -1.0]), params)
    assert bool(info_big["action_clipped"])
    np.testing.assert_array_equal(o_big, o_one)  # clipped to the bounds, and flown as them
    assert float(r_big) == float(r_one)
    _, _, r_nan, done, info_nan = step(key, state, jnp.array([math.nan, 0.0]), params)
    assert bool(done) and bool(info_nan["terminated"]) and int(info_nan["status"]) == NON_FINITE
    assert math.isfinite(float(r_nan)) and not bool(info_nan["is_success"])


@pytest.mark.parametrize("kwargs, message", [
    ({"max_episode_steps": 2**40}, r"max_episode_steps must be a positive integer <= 2147483647 .*needs a time limit"),
    ({"max_episode_steps": None}, r"max_episode_steps must be a positive integer .*needs a time limit\), got None"),
    ({"max_episode_steps": 0}, "max_episode_steps must be a positive integer"),
    ({"dtype": "float16"}, r"dtype must be one of \('float32', 'float64'\)"),
    ({"dtype": ["float32"]}, r"dtype must be one of"),
    ({"pool_size": 0}, "pool_size must be a positive integer"),
    ({"substeps": 2**40}, r"substeps must be a positive integer <= 1000"),
    ({"dt": "abc"}, r"dt must be a positive number of seconds"),
])  # fmt: skip
def test_a_functional_env_with_a_bad_argument_is_refused_naming_it(kwargs, message):
    pytest.importorskip("gymnax")
    from rventry_env.envs.functional import RvEntryFunctional

    with pytest.raises(ValueError, match=message):
        RvEntryFunctional(**kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"max_episode_steps": 2**40}, r"max_episode_steps must be a positive integer <= 2147483647"),
    ({"max_episode_steps": 2.5}, r"max_episode_steps must be a positive integer"),
    ({"seed": -1}, r"seed must be an integer >= 0"),
    ({"seed": 1.5}, r"seed must be an integer >= 0"),
    ({"nominal": np.full(12, np.nan)}, "the initial state contains NaN"),
    ({"dispersion": {"density": -0.1}}, "dispersion density must be a finite half-width >= 0"),
])  # fmt: skip
def test_make_params_refuses_bad_values_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _functional().make_params(**kwargs)


def _bad_params(params):
    import jax.numpy as jnp

    nan_model = tuple(jnp.full_like(v, jnp.nan) for v in params.model)
    return [
        ("dispersion", params.dispersion.at[0].set(jnp.nan), r"EnvParams.dispersion / clip_sigmas: dispersion density "
                                                            r"must be a finite half-width >= 0, got nan"),
        ("dispersion", params.dispersion.at[9].set(-0.1), "dispersion mass must be a finite"),
        ("dispersion", params.dispersion.at[1].set(2.0), r"dispersion lift = 2 is relative"),
        ("clip_sigmas", jnp.asarray(0.0, params.clip_sigmas.dtype), "clip_sigmas must be a positive number, got 0"),
        ("nominal", params.nominal * 0, r"EnvParams.nominal: the initial radius 0.0 m is not above the surface"),
        ("nominal", params.nominal.at[5].set(jnp.nan), "EnvParams.nominal: the initial state contains NaN"),
        ("nominal", params.nominal[:3], r"EnvParams.nominal must have shape \(12,\) \(real numbers\), got shape \(3,\)"),
        ("model", nan_model, r"EnvParams.model: \w+\.\w+ must"),
        ("model", tuple(v * 0 for v in params.model), r"EnvParams.model: \w+\.\w+ must"),
        ("model", tuple(-v for v in params.model), r"EnvParams.model: \w+\.\w+ must"),
        ("model", params.model[:-1], r"EnvParams.model must be a tuple of \d+ arrays"),
        ("max_steps_in_episode", jnp.asarray(0, jnp.int32), "EnvParams.max_steps_in_episode must be a positive integer"),
        ("max_steps_in_episode", jnp.asarray(10.0), r"EnvParams.max_steps_in_episode must have shape \(\) \(integers\)"),
        ("gaussian", jnp.asarray(1.0), r"EnvParams.gaussian must have shape \(\) \(booleans\)"),
        ("pool", params, "EnvParams.pool must be None for this environment"),
    ]  # fmt: skip


def test_hand_made_functional_params_are_refused_at_reset_naming_the_field():
    """NaN, zero or negative numbers put into the params by hand would give NaN observations:
    ``reset`` outside ``jit`` checks them, and ``check_params`` does on demand."""
    import jax

    env = _functional()
    params = env.default_params
    key = jax.random.PRNGKey(0)
    for field, value, message in _bad_params(params):
        bad = params._replace(**{field: value})
        with pytest.raises(ValueError, match=message):
            env.reset(key, bad)
        with pytest.raises(ValueError, match=message):
            env.check_params(bad)
    assert env.check_params(params) is params


def test_checked_functional_params_fly_as_before_and_traced_ones_are_not_checked():
    """Checking changes no number: the checked reset is the jitted, unchecked one bit for bit."""
    import jax

    env = _functional(dispersion="standard")
    params = env.make_params(dispersion="wide", max_episode_steps=500)
    keys = jax.random.split(jax.random.PRNGKey(4), 3)
    checked = [env.reset(k, params) for k in keys]
    traced = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    for i, (obs, state) in enumerate(checked):
        np.testing.assert_array_equal(obs, traced[0][i])
        np.testing.assert_array_equal(np.stack(state.episode.x), np.stack(traced[1].episode.x)[:, i])


def test_flight_grade_params_and_start_params_are_checked_too():
    import jax
    import jax.numpy as jnp

    from rventry_env.reference.starts import reference_starts

    env = _functional(dispersion="flight", pool_size=3)
    params = env.default_params
    bad = params._replace(pool=params.pool._replace(dr=params.pool.dr.at[0, 0].set(jnp.inf)))
    with pytest.raises(ValueError, match="EnvParams.pool.dr contains NaN or inf"):
        env.reset(jax.random.PRNGKey(0), bad)
    plain = _functional()
    starts = plain.start_params(reference_starts((30.0, 200.0), altitude_m=400.0))
    good = plain.default_params._replace(starts=starts)
    assert plain.check_params(good) is good
    for field, value, message in [
        ("probability", jnp.asarray(1.5, starts.probability.dtype), r"EnvParams.starts: start states: probability must "
                                                                    r"lie in \(0, 1\], got 1.5"),
        ("half_widths", starts.half_widths.at[0].set(-1.0), "start states: altitude_m must be a finite half-width >= 0"),
        ("states", starts.states.at[:, 0].set(1.0), "EnvParams.starts: start states .*must lie above the surface"),
        ("times", starts.times[::-1], "EnvParams.starts: start states: times must be one or more strictly increasing"),
    ]:  # fmt: skip
        with pytest.raises(ValueError, match=message):
            plain.check_params(good._replace(starts=starts._replace(**{field: value})))
