"""The functional ``RvEntry`` as a JAX learner sees it: its actions, its evaluation and its export.

:class:`TrainingEnv` is a gymnax environment around
:class:`~rventry_env.envs.functional.RvEntryFunctional` that takes the policy's actions, the
environment's rates or attitude commands (:mod:`rventry_agents.commands`, flown from the
observation the policy saw, which the state carries). It also flies a learner's deterministic
policy on a batch of episodes (:meth:`TrainingEnv.evaluator`) and exports its actor for
:class:`~rventry_agents.jax_policy.JaxPolicy` (:meth:`TrainingEnv.export`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rventry_agents.commands import check_actions, output_bounds, policy_actions

OUTCOME_KEYS = ("is_success", "miss_km", "vertical_error_deg", "speed_error_mps", "constraint_violation", "status")


def make_training_env(cfg, task, starts, shaping):
    """The training environment of a :class:`~rventry_agents.scratch_config.ScratchConfig`."""
    from rventry_env.envs.functional import RvEntryFunctional

    base = RvEntryFunctional(
        task=task, dispersion=structure_dispersion(cfg.env), max_episode_steps=cfg.env.max_episode_steps,
        dtype=cfg.env.dtype, reward=cfg.reward, starts=starts, shaping=shaping,
        time_limit_is_failure=cfg.env.time_limit_is_failure,
    )  # fmt: skip
    return TrainingEnv(base, cfg.env.actions, cfg.env.command_time_s)


def training_draws(env):
    """The vehicle draws of an ``[env]`` section's training episodes: its ``draws``, else its rung's."""
    from rventry_env.evaluation.rungs import rung

    return rung(env.rung).dispersion if env.draws is None else env.draws


def structure_dispersion(env):
    """The dispersion the training environment is compiled for: the rung's, unless only the
    training draws carry flight-grade errors (profiles, sensors, navigation), which are compiled
    structure; a flight-grade environment flies plain draws with those errors off."""
    from rventry_env.envs.functional import _flight_grade
    from rventry_env.evaluation.rungs import rung
    from rventry_env.task import Dispersion

    def flight_grade(d) -> bool:
        return _flight_grade(Dispersion.parse(d))

    own = rung(env.rung).dispersion
    return env.draws if env.draws is not None and flight_grade(env.draws) and not flight_grade(own) else own


def _environment_base():
    from gymnax.environments import environment

    return environment.Environment


class TrainingEnv(_environment_base()):
    """The functional environment with the policy's actions (see the module docstring).

    Its state is the environment's and the observation of it (what attitude commands are
    flown from); gymnax's autoreset keeps the two together.
    """

    def __init__(self, base, actions: str = "rates", command_time_s: float | None = None):
        super().__init__()
        self.base = base
        self.actions = check_actions(actions)
        self.command_time_s = base.task.dt if command_time_s is None else float(command_time_s)

    def _key(self):
        return (type(self), self.base, self.actions, self.command_time_s)

    def __hash__(self):  # gymnax jits step and reset with ``self`` static
        return hash(self._key())

    def __eq__(self, other):
        return isinstance(other, TrainingEnv) and self._key() == other._key()

    @property
    def default_params(self):
        return self.base.default_params

    def env_action(self, obs, action):
        """The environment's action for the policy's ``action`` taken on ``obs``."""
        import jax.numpy as jnp

        return policy_actions(obs, action, self.actions, self.base.task, jnp, self.command_time_s)

    def reset_env(self, key, params):
        obs, state = self.base.reset_env(key, params)
        return obs, (state, obs)

    def step_env(self, key, state, action, params):
        inner, obs = state
        obs, inner, reward, done, info = self.base.step_env(key, inner, self.env_action(obs, action), params)
        return obs, (inner, obs), reward, done, info

    def observation_space(self, params=None):
        return self.base.observation_space(params)

    def action_space(self, params=None):
        """The policy's outputs: within the environment's bounds, or unbounded for circular
        commands (a learner clips its samples to these before they are flown)."""
        import jax.numpy as jnp
        from gymnax.environments import spaces

        return spaces.Box(*output_bounds(self.actions), (2,), jnp.float32)

    @property
    def name(self) -> str:
        return f"{self.base.name} ({self.actions})"

    @property
    def num_actions(self) -> int:
        return 2

    # ------------------------------------------------------------------ evaluation and export
    def raw_action(self, algo, ts, obs):
        """The actor's mean for one observation, normalized as in training, before any clip."""
        z = actor_inputs(algo, ts, obs)
        return algo.actor.apply(ts.actor_ts.params, z[None], method=lambda m, o: m.action_mean(m.features(o)))[0]

    def mean_action(self, algo, ts, obs):
        """The deterministic policy's action for one observation: :meth:`raw_action`, clipped where
        the action map's outputs are bounded."""
        import jax.numpy as jnp

        return jnp.clip(self.raw_action(algo, ts, obs), *output_bounds(self.actions))

    def evaluator(self, algo, episodes: int):
        """A compiled ``evaluate(ts, params, key) -> dict``: ``episodes`` episodes (one each, no
        autoreset) of ``params`` flown by the deterministic policy of the training state ``ts``."""
        import jax
        import jax.numpy as jnp

        @jax.jit
        def run(ts, params, key):
            def one(k):
                obs, state = self.reset(k, params)
                _, _, _, _, info0 = self.step_env(k, state, jnp.zeros(2), params)  # the info's structure

                def fly(c):
                    obs, state, _, ret, info = c
                    obs, state, r, done, info = self.step_env(k, state, self.mean_action(algo, ts, obs), params)
                    return obs, state, done, ret + r, info

                c = jax.lax.while_loop(lambda c: jnp.logical_not(c[2]), fly,
                                       (obs, state, jnp.array(False), jnp.zeros((), obs.dtype), info0))  # fmt: skip
                return c[3], {k: c[4][k] for k in OUTCOME_KEYS}

            return jax.vmap(one)(jax.random.split(key, episodes))

        def evaluate(ts, params, key) -> dict:
            ret, o = jax.device_get(run(ts, params, key))
            return summarize_outcomes(o, ret, self.base.task)

        return evaluate

    def export(self, path: str | Path, algo, ts) -> Path:
        """Write the actor of ``ts`` for :class:`~rventry_agents.jax_policy.JaxPolicy`."""
        from rventry_agents.jax_policy import NORM_EPS, export_actor

        activation = algo.actor.activation.__name__
        if algo.normalize_observations:
            mean, var = ts.obs_rms_state.mean, ts.obs_rms_state.var
        else:  # the features as they are: a scale of exactly sqrt(var + eps) = 1
            n = self.observation_space().shape[0]
            mean, var = np.zeros(n), np.full(n, 1.0 - NORM_EPS)
        return export_actor(path, ts.actor_ts.params, mean, var, activation, self.actions, self.command_time_s)


def actor_inputs(algo, ts, obs):
    """What the actor of the training state ``ts`` reads for ``obs``: the observation in standard
    deviations of the run's observation statistics where ``algo`` normalizes them (as in training),
    the features as they are where not."""
    return algo.normalize_obs(ts.obs_rms_state, obs) if algo.normalize_observations else obs


def summarize_outcomes(o: dict, ret, task) -> dict:
    """The task metrics of a batch of episodes' outcomes (arrays by :data:`OUTCOME_KEYS`): the
    success rate, the median miss, vertical error and impact-speed error (signed, the speed less the
    task's final speed), and how often each success condition held."""
    from rventry_env.envs.propagation import IMPACT

    s = task.success
    miss, vertical = np.asarray(o["miss_km"], float), np.asarray(o["vertical_error_deg"], float)
    return {
        "success_rate": float(np.mean(o["is_success"])), "miss_km_p50": float(np.median(miss)),
        "vertical_error_deg_p50": float(np.median(vertical)), "impact_rate": float(np.mean(o["status"] == IMPACT)),
        "miss_within_rate": float(np.mean(miss <= s.miss_km)),
        "vertical_within_rate": float(np.mean(vertical <= s.vertical_error_deg)),
        "speed_within_rate": float(np.mean(np.abs(o["speed_error_mps"]) <= s.speed_error_mps)),
        "speed_error_mps_p50": float(np.median(np.asarray(o["speed_error_mps"], float))),  # signed: < 0 too slow
        "violation_rate": float(np.mean(o["constraint_violation"])), "mean_return": float(np.mean(ret)),
        "episodes": int(miss.size),
    }  # fmt: skip


__all__ = ["OUTCOME_KEYS", "TrainingEnv", "actor_inputs", "make_training_env", "summarize_outcomes"]
