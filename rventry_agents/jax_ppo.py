"""Train PPO end to end in JAX: rejax's PPO on the functional ``RvEntry`` (``[jax]`` extra).

The environment (:class:`rventry_env.envs.functional.RvEntryFunctional`) and the learner are
compiled together: rollouts, advantages and updates of all vehicles are one XLA program, on
the CPU or on a GPU where JAX finds one. The run goes in chunks of ``chunk_timesteps`` (one
compiled program, called again with the training state), with an evaluation after each: the
deterministic policy flies ``eval_episodes`` vehicles of the ``eval_dispersion`` set, in JAX.
It writes into its output directory:

* ``params.npz``: the final actor's and critic's weights and the observation statistics;
* ``evaluations.json``: after each chunk, the steps, wall time, success rate, miss and return;
* ``metadata.json``: the command, config, steps reached, wall time, the first chunk's
  compilation time and the env-steps per second of the chunks after it.
"""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

import numpy as np

from rventry_env.envs.reward import RewardWeights
from rventry_env.task import Dispersion
from rventry_env.util.files import write_json

DEFAULT_CONFIG = Path(__file__).resolve().parent / "baselines" / "jax_ppo.toml"
SECTIONS = ("env", "ppo", "train")


def load_config(path=None) -> dict:
    from rventry_agents.train import read_config

    cfg, _ = read_config(path, DEFAULT_CONFIG, SECTIONS)
    return cfg


def make_env(cfg: dict):
    from rventry_env.envs.functional import RvEntryFunctional

    e = cfg["env"]
    return RvEntryFunctional(
        dt=e.get("dt"), substeps=e.get("substeps"), dispersion=Dispersion.parse(e.get("dispersion")),
        max_episode_steps=e.get("max_episode_steps", 2000), dtype=e.get("dtype", "float32"), reward=RewardWeights(),
    )  # fmt: skip


def make_algorithm(cfg: dict, env, total_timesteps: int):
    from rejax import PPO

    p = dict(cfg["ppo"])
    agent_kwargs = {"hidden_layer_sizes": tuple(p.pop("hidden_layer_sizes")), "activation": p.pop("activation")}
    return PPO.create(
        env=env, env_params=env.default_params, num_envs=cfg["env"]["num_envs"], total_timesteps=total_timesteps,
        eval_freq=total_timesteps, skip_initial_evaluation=True, agent_kwargs=agent_kwargs, **p,
    )  # fmt: skip


def deterministic_act(algo, ts):
    """The policy's mean action (clipped to the bounds), observations normalized as in training."""
    import jax.numpy as jnp

    def act(obs):
        if algo.normalize_observations:
            obs = algo.normalize_obs(ts.obs_rms_state, obs)
        mean = algo.actor.apply(ts.actor_ts.params, obs[None], method=lambda m, o: m.action_mean(m.features(o)))
        return jnp.clip(mean[0], -1.0, 1.0)

    return act


def evaluate(env, params, act, key, episodes: int) -> dict:
    """Fly ``episodes`` vehicles (one episode each, no autoreset) with ``act``; their outcomes."""
    import jax
    import jax.numpy as jnp

    def one(k):
        obs, st = env.reset(k, params)

        def going(c):
            return jnp.logical_not(c[2])

        def fly(c):
            obs, st, _, ret, info = c
            obs, st, r, done, info = env.step_env(k, st, act(obs), params)
            return obs, st, done, ret + r, info

        _, _, _, _, info0 = env.step_env(k, st, jnp.zeros(2), params)  # the info's structure
        c = jax.lax.while_loop(going, fly, (obs, st, jnp.array(False), jnp.zeros((), obs.dtype), info0))
        return c[3], c[4]["is_success"], c[4]["miss_km"], c[4]["terminated"]

    ret, success, miss, terminated = jax.jit(jax.vmap(one))(jax.random.split(key, episodes))
    return {
        "success_rate": float(np.mean(success)), "miss_km_p50": float(np.median(miss)),
        "mean_return": float(np.mean(ret)), "terminated": float(np.mean(terminated)),
    }  # fmt: skip


def train_jax_ppo(config=None, timesteps: int | None = None, seed: int | None = None, out: str | Path = "runs/jax_ppo",
                  progress=print) -> dict:  # fmt: skip
    """Train as the config says (default ``rventry_agents/baselines/jax_ppo.toml``); see the module docstring."""
    import jax

    cfg = load_config(config)
    t = cfg["train"]
    total = int(timesteps if timesteps is not None else t["total_timesteps"])
    seed = int(seed if seed is not None else t["seed"])
    chunk = min(int(t["chunk_timesteps"]), total)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = make_env(cfg)
    algo = make_algorithm(cfg, env, chunk)
    eval_params = env.make_params(dispersion=t.get("eval_dispersion", "standard"))
    train = jax.jit(algo.train)
    ts = algo.init_state(jax.random.PRNGKey(seed))
    steps, history, wall0 = 0, [], time.perf_counter()
    compile_s, chunk_rates = None, []
    while steps < total:
        t0 = time.perf_counter()
        ts, _ = train(train_state=ts)
        jax.block_until_ready(ts)
        dt = time.perf_counter() - t0
        done = int(ts.global_step)
        if compile_s is None:
            compile_s = dt - (done - steps) / _first_guess(dt, done - steps)  # refined below
        else:
            chunk_rates.append((done - steps) / dt)
        steps = done
        ev = evaluate(env, eval_params, deterministic_act(algo, ts), jax.random.PRNGKey(t["eval_seed"]),
                      int(t["eval_episodes"]))  # fmt: skip
        rec = {"timesteps": steps, "wall_s": time.perf_counter() - wall0, "chunk_s": dt, **ev}
        history.append(rec)
        progress(f"{steps:>12,d} steps  {rec['wall_s']:8.0f} s  success {ev['success_rate']:.2f}  "
                 f"miss p50 {ev['miss_km_p50']:8.1f} km  return {ev['mean_return']:9.1f}")  # fmt: skip
        write_json(out / "evaluations.json", history)
    rate = float(np.median(chunk_rates)) if chunk_rates else None
    if rate is not None:  # the first chunk's time less what its steps take at the later chunks' rate
        compile_s = history[0]["chunk_s"] - history[0]["timesteps"] / rate
    flat = {"/".join(str(getattr(k, "key", getattr(k, "idx", k))) for k in path): np.asarray(v)
            for path, v in jax.tree_util.tree_flatten_with_path(
                {"actor": ts.actor_ts.params, "critic": ts.critic_ts.params,
                 "obs_rms": getattr(ts, "obs_rms_state", None)})[0]}  # fmt: skip
    np.savez(out / "params.npz", **flat)
    meta = {
        "command": " ".join(shlex.quote(a) for a in sys.argv), "config": cfg, "seed": seed, "timesteps": steps,
        "wall_s": time.perf_counter() - wall0, "compile_s": compile_s, "env_steps_per_s": rate,
        "device": str(jax.devices()[0]), "evaluations": history,
    }  # fmt: skip
    write_json(out / "metadata.json", meta)
    return meta


def _first_guess(dt: float, steps: int) -> float:
    return max(steps / dt, 1.0)  # placeholder until a compiled chunk's rate is known


__all__ = ["train_jax_ppo", "load_config", "make_env", "evaluate", "DEFAULT_CONFIG"]
