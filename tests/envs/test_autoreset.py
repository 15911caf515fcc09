"""The optimistic autoreset draws what a plain reset draws: the same distribution of starts, every named set."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
import jax.numpy as jnp  # noqa: E402
from scipy import stats  # noqa: E402

from rventry_env.envs.functional import RvEntryFunctional, step_batch  # noqa: E402
from rventry_env.evaluation.rungs import rung_starts  # noqa: E402

SETS = ("none", "standard", "wide", "flight", "peer", "peer-0.1")
N, LIMIT, STEPS = 512, 32, 96


def _draws(state):
    """What a start draws, per episode: the 12 state components, the start time and the four scale factors."""
    x = np.stack([np.asarray(c, float) for c in state.episode.x], axis=1)
    return np.concatenate([x, np.asarray(state.episode.t, float)[:, None], np.asarray(state.scales, float)], axis=1)


def _restarts(env, params, resets: int, seed: int):
    """The starts the optimistic autoreset hands to episodes that end, over STEPS steps of a batch whose
    episodes end one by one (each at its own step count under a time limit of LIMIT)."""
    keys = jax.random.split(jax.random.PRNGKey(seed), N)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    episode = states.episode._replace(steps=jnp.asarray(np.arange(N) % LIMIT, states.episode.steps.dtype))
    states = states._replace(episode=episode)
    step = jax.jit(lambda k, s: step_batch(env, k, s, jnp.zeros((N, 2)), params, resets))
    got, key = [], jax.random.PRNGKey(seed + 1)
    for _ in range(STEPS):
        key, sub = jax.random.split(key)
        _, states, _, done, _ = step(jax.random.split(sub, N), states)
        done = np.asarray(done)
        got.append(_draws(states)[done])
    return np.concatenate(got)


@pytest.mark.slow
@pytest.mark.parametrize("name", SETS)
def test_the_optimistic_autoreset_draws_the_plain_resets_distribution(name):
    starts = rung_starts("late") if name == "none" else None  # the start states' draw too, once
    env = RvEntryFunctional(dispersion=name, max_episode_steps=LIMIT, starts=starts, dtype="float64", pool_size=64)
    params = env.default_params
    fresh = _restarts(env, params, resets=N // 16, seed=1)
    assert len(fresh) >= N * STEPS // LIMIT - N  # about one episode in LIMIT ends each step
    plain_keys = jax.random.split(jax.random.PRNGKey(99), len(fresh))
    _, plain_states = jax.vmap(env.reset, in_axes=(0, None))(plain_keys, params)
    plain = _draws(plain_states)
    # no two episodes shared a start (fewer ended in any step than there were fresh starts)
    assert len(np.unique(fresh, axis=0)) == len(fresh)
    for j in range(plain.shape[1]):
        a, b = fresh[:, j], plain[:, j]
        if np.ptp(b) == 0:  # a component the set does not draw: the same constant in both
            assert np.all(a == b[0])
            continue
        se = np.sqrt(a.var() / a.size + b.var() / b.size)
        assert abs(a.mean() - b.mean()) < 5 * se, (name, j)
        assert stats.ks_2samp(a, b).pvalue > 1e-4, (name, j)


def test_the_optimistic_autoreset_steps_as_the_plain_step_does_and_shares_starts_only_when_it_must():
    env = RvEntryFunctional(dispersion="standard", max_episode_steps=1)
    params = env.default_params
    keys = jax.random.split(jax.random.PRNGKey(0), 64)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    obs, new, reward, done, info = step_batch(env, keys, states, jnp.zeros((64, 2)), params, resets=64)
    _, _, reward_plain, done_plain, info_plain = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))(
        keys, states, jnp.zeros((64, 2)), params)  # fmt: skip
    assert np.array_equal(reward, reward_plain) and np.array_equal(done, done_plain) and np.all(done)
    assert np.array_equal(info["miss_km"], info_plain["miss_km"])
    assert np.all(np.asarray(new.episode.steps) == 0) and np.all(np.asarray(new.episode.t) == 0)
    assert len(np.unique(_draws(new), axis=0)) == 64  # 64 fresh starts for 64 ends
    _, shared, *_ = step_batch(env, keys, states, jnp.zeros((64, 2)), params, resets=16)
    assert len(np.unique(_draws(shared), axis=0)) == 16  # more ends than starts: shared
    with pytest.raises(ValueError, match=r"resets must lie in \[1, 64\]"):
        step_batch(env, keys, states, jnp.zeros((64, 2)), params, resets=0)
