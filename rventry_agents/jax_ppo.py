"""Train PPO end to end in JAX: rejax's PPO on the functional ``RvEntry`` (``[jax]`` extra).

The environment (:class:`rventry_env.envs.functional.RvEntryFunctional`) and the learner are
compiled together: rollouts, advantages and updates of all vehicles are one XLA program, on
the CPU or on a GPU where JAX finds one. The run goes in chunks of ``chunk_timesteps`` (one
compiled program, called again with the training state), with an evaluation after each: the
deterministic policy flies ``eval_episodes`` vehicles of the ``eval_dispersion`` set, in JAX.
It writes into its output directory:

* ``params.npz``: the final actor's and critic's weights and the observation statistics;
* ``evaluations.json``: after each chunk, the steps, wall time, success rate, miss and return;
* ``learning_curve.png``: those evaluations against the steps (:func:`plot_learning_curve`);
* ``metadata.json``: the command, config, steps reached, wall time, the first chunk's
  compilation time, the env-steps per second of the chunks after it, and how many training
  programs were compiled (one: every chunk after the first reuses its program).
"""

from __future__ import annotations

import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from rventry_agents.jax_ppo_config import DEFAULT_CONFIG, JaxPPOConfig, load_config
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import Dispersion
from rventry_env.util.files import write_json


def make_env(cfg: JaxPPOConfig):
    from rventry_env.envs.functional import RvEntryFunctional

    e = cfg.env
    return RvEntryFunctional(
        dt=e.dt, substeps=e.substeps, dispersion=Dispersion.parse(e.dispersion), max_episode_steps=e.max_episode_steps,
        dtype=e.dtype, reward=RewardWeights(),
    )  # fmt: skip


def make_algorithm(cfg: JaxPPOConfig, env, total_timesteps: int):
    from dataclasses import asdict

    from rejax import PPO

    p = asdict(cfg.ppo)
    agent_kwargs = {"hidden_layer_sizes": tuple(p.pop("hidden_layer_sizes")), "activation": p.pop("activation")}
    return PPO.create(
        env=env, env_params=env.default_params, num_envs=cfg.env.num_envs, total_timesteps=total_timesteps,
        eval_freq=total_timesteps, skip_initial_evaluation=True, agent_kwargs=agent_kwargs, **p,
    )  # fmt: skip


def deterministic_act(algo, ts):
    """The policy's mean action (clipped to the bounds), observations normalized as in training."""
    import jax.numpy as jnp

    from rventry_agents.jax_env import actor_inputs

    def act(obs):
        mean = algo.actor.apply(ts.actor_ts.params, actor_inputs(algo, ts, obs)[None],
                                method=lambda m, o: m.action_mean(m.features(o)))  # fmt: skip
        return jnp.clip(mean[0], -1.0, 1.0)

    return act


def make_evaluator(env, algo, episodes: int):
    """A compiled ``evaluate(ts, params, key)``: ``episodes`` vehicles, one episode each (no autoreset),
    flown by the deterministic policy of the training state ``ts``; their outcomes."""
    import jax
    import jax.numpy as jnp

    @jax.jit
    def run(ts, params, key):
        act = deterministic_act(algo, ts)

        def one(k):
            obs, st = env.reset(k, params)
            _, _, _, _, info0 = env.step_env(k, st, jnp.zeros(2), params)  # the info's structure

            def fly(c):
                obs, st, _, ret, info = c
                obs, st, r, done, info = env.step_env(k, st, act(obs), params)
                return obs, st, done, ret + r, info

            c = jax.lax.while_loop(lambda c: jnp.logical_not(c[2]), fly,
                                   (obs, st, jnp.array(False), jnp.zeros((), obs.dtype), info0))  # fmt: skip
            return c[3], c[4]["is_success"], c[4]["miss_km"], c[4]["terminated"]

        return jax.vmap(one)(jax.random.split(key, episodes))

    def evaluate(ts, params, key) -> dict:
        ret, success, miss, terminated = run(ts, params, key)
        return {
            "success_rate": float(np.mean(success)), "miss_km_p50": float(np.median(miss)),
            "mean_return": float(np.mean(ret)), "terminated": float(np.mean(terminated)),
        }  # fmt: skip

    return evaluate


def settled_state(ts):
    """The training state with the types it has after a chunk, so that the second chunk runs the
    first one's compiled program. rejax 0.1.3 starts the reward statistics' mean and variance as
    Python ints, which the first update turns into float arrays: without this every run compiled
    its training program twice (37 s of 75 on the test's small network)."""
    import jax.numpy as jnp

    rms = getattr(ts, "rew_rms_state", None)
    if rms is None:
        return ts
    dtype = jnp.asarray(rms.returns).dtype
    return ts.replace(rew_rms_state=rms.replace(mean=jnp.asarray(rms.mean, dtype), var=jnp.asarray(rms.var, dtype)))


def train_jax_ppo(config=None, timesteps: int | None = None, seed: int | None = None, out: str | Path = "runs/jax_ppo",
                  progress=print, max_wall_s: float | None = None) -> dict:  # fmt: skip
    """Train as the config says (default ``rventry_agents/baselines/jax_ppo.toml``); see the module docstring.

    :param max_wall_s: stop after the first chunk that ends past this wall time (s), with
        everything written: a run's budget ("the steps reached in two hours").
    """
    from rventry_env.core.backend import jax_x64, prefer_fused_cpu_runtime
    from rventry_env.util.files import check_writable

    if max_wall_s is not None and not (isinstance(max_wall_s, (int, float)) and 0 < max_wall_s < math.inf):
        raise ValueError(f"max_wall_s must be a finite number of seconds > 0 or None, got {max_wall_s!r}")
    check_writable(folders=(out,))  # a file in the way is named before anything runs
    prefer_fused_cpu_runtime()
    cfg = load_config(config)
    with jax_x64(cfg.env.dtype == "float64"):
        return _train(cfg, timesteps, seed, out, progress, max_wall_s)


def _train(cfg: JaxPPOConfig, timesteps, seed, out, progress, max_wall_s) -> dict:
    import jax

    t = cfg.train
    total = int(timesteps if timesteps is not None else t.total_timesteps)
    seed = int(seed if seed is not None else t.seed)
    chunk = min(t.chunk_timesteps, total)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = make_env(cfg)
    algo = make_algorithm(cfg, env, chunk)
    eval_params = env.make_params(dispersion=t.eval_dispersion)
    traces = []  # one entry per trace of the training program: each trace is a compilation

    def train_chunk(train_state):
        traces.append(1)
        return algo.train(train_state=train_state)

    train = jax.jit(train_chunk)
    evaluate = make_evaluator(env, algo, t.eval_episodes)
    ts = settled_state(algo.init_state(jax.random.PRNGKey(seed)))
    steps, history, wall0 = 0, [], time.perf_counter()
    chunk_rates = []
    while steps < total and (max_wall_s is None or time.perf_counter() - wall0 < max_wall_s):
        t0 = time.perf_counter()
        ts, _ = train(ts)
        jax.block_until_ready(ts)
        dt = time.perf_counter() - t0
        done = int(ts.global_step)
        if history:  # the first chunk includes the compilation
            chunk_rates.append((done - steps) / dt)
        steps = done
        ev = evaluate(ts, eval_params, jax.random.PRNGKey(t.eval_seed))
        rec = {"timesteps": steps, "wall_s": time.perf_counter() - wall0, "chunk_s": dt, **ev}
        history.append(rec)
        progress(f"{steps:>12,d} steps  {rec['wall_s']:8.0f} s  success {ev['success_rate']:.2f}  "
                 f"miss p50 {ev['miss_km_p50']:8.1f} km  return {ev['mean_return']:9.1f}")  # fmt: skip
        write_json(out / "evaluations.json", history)
    rate = float(np.median(chunk_rates)) if chunk_rates else None
    # the first chunk's time less what its steps take at the later chunks' rate (an upper bound without them)
    compile_s = history[0]["chunk_s"] - (history[0]["timesteps"] / rate if rate else 0.0)
    flat = {"/".join(str(getattr(k, "key", getattr(k, "idx", k))) for k in path): np.asarray(v)
            for path, v in jax.tree_util.tree_flatten_with_path(
                {"actor": ts.actor_ts.params, "critic": ts.critic_ts.params,
                 "obs_rms": getattr(ts, "obs_rms_state", None)})[0]}  # fmt: skip
    np.savez(out / "params.npz", **flat)
    meta = {
        "command": " ".join(shlex.quote(a) for a in sys.argv), "config": cfg.to_dict(), "seed": seed, "timesteps": steps,
        "wall_s": time.perf_counter() - wall0, "max_wall_s": max_wall_s, "compile_s": compile_s, "env_steps_per_s": rate,
        "device": str(jax.devices()[0]), "evaluations": history,
        # how many training programs were compiled: 1 when every chunk ran the first one's
        "train_compilations": len(traces),
    }  # fmt: skip
    write_json(out / "metadata.json", meta)
    plot_learning_curve(history, out / "learning_curve.png", f"rejax PPO on {meta['device']}")
    return meta


def plot_learning_curve(evaluations: list[dict], path: str | Path, title: str = "rejax PPO") -> Path:
    """The run's evaluations (``evaluations.json``) against environment steps: success rate, median
    miss (log axis) and mean return of the deterministic policy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rventry_env.util.files import plain_log_labels, save_figure

    steps = np.array([e["timesteps"] for e in evaluations]) / 1e6
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    ax[0].plot(steps, [e["success_rate"] for e in evaluations], "o-", ms=3)
    ax[1].semilogy(steps, [e["miss_km_p50"] for e in evaluations], "o-", ms=3)
    ax[2].plot(steps, [e["mean_return"] for e in evaluations], "o-", ms=3)
    ax[0].set(xlabel="environment steps (M)", ylabel="success rate", ylim=(-0.02, 1.02))
    ax[1].set(xlabel="environment steps (M)", ylabel="median miss (km)")
    ax[2].set(xlabel="environment steps (M)", ylabel="mean return")
    plain_log_labels(ax[1])
    for a in ax:
        a.grid(alpha=0.3)
    fig.suptitle(f"{title}: its evaluations during training (deterministic policy, {len(evaluations)} chunks)")
    return save_figure(fig, path)


__all__ = ["DEFAULT_CONFIG", "load_config", "make_env", "make_evaluator", "plot_learning_curve", "settled_state", "train_jax_ppo"]
