"""stable-baselines3 plumbing for the numpy-batched :class:`RvEntryVectorEnv`.

* :class:`RvEntrySB3VecEnv`: an SB3 ``VecEnv`` over the batched env. SB3 expects
  same-step autoreset, a list of per-copy info dicts with ``terminal_observation``
  and ``TimeLimit.truncated``, and float32 rewards; this gives it that without one
  Python env object per copy, building info dicts only for finished copies.
* :class:`RangePotentialShaping`: potential-based reward shaping on the range to
  go, a training aid that leaves the optimal policy unchanged (Ng et al. 1999).

Training-only choice: with ``time_limit_is_failure=True`` an episode cut by the
time limit is charged like a failed one (failure + terminal penalty) and is not
bootstrapped. Without it PPO learns that gliding until the limit is free: the
environment, true to Gymnasium semantics, charges nothing at truncation, and the
value function never sees the impact that would follow.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from stable_baselines3.common.vec_env import VecEnvWrapper

from rventry_env.envs.observation import RANGE_SCALE, feature_index
from rventry_env.envs.vector import TERMINAL_KEYS, RvEntryVectorEnv

EPISODE_KEYS = TERMINAL_KEYS + ("cost", "time_s")


class RvEntrySB3VecEnv(VecEnv):
    """SB3 view of ``num_envs`` batched RvEntry-v0 copies.

    :param num_envs: number of copies.
    :param time_limit_is_failure: charge a time-limit cut like a failure and do not
        bootstrap it (see the module docstring).
    :param env_kwargs: passed to :class:`RvEntryVectorEnv` (model, task, dispersion, max_episode_steps ...).
    """

    def __init__(self, num_envs: int, time_limit_is_failure: bool = False, **env_kwargs: Any):
        env_kwargs = {k: v for k, v in env_kwargs.items() if k != "autoreset_mode"}
        self.time_limit_is_failure = time_limit_is_failure
        self.venv = RvEntryVectorEnv(num_envs=num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self.render_mode = self.venv.render_mode
        self._actions: np.ndarray | None = None
        self.last_infos: dict = {}  # the batched env's info of the latest reset or step (the reset copies' own)

    def reset(self):
        seeds = None if all(s is None for s in self._seeds) else [0 if s is None else s for s in self._seeds]
        options = self._options[0] if self._options and self._options[0] else None
        obs, self.last_infos = self.venv.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    @property
    def navigation_state(self) -> np.ndarray:
        """(N, 12): where each vehicle's navigation puts it after the latest reset or step (the truth
        on sets without navigation errors): the state a guidance law is handed, as in evaluation."""
        return self.last_infos["navigation_state"]

    @property
    def true_state(self) -> np.ndarray:
        """(N, 12): every vehicle's true state after the latest reset or step (for training-time
        critics; the guidance law is handed :attr:`navigation_state`)."""
        return self.venv.state

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        self.last_infos = infos  # the batched env's own, for wrappers that read its sensors
        dones = terminated | truncated
        out: list[dict] = [{} for _ in range(self.num_envs)]
        if np.any(dones):
            final = infos["final_info"]
            if self.time_limit_is_failure and np.any(truncated):
                reward = reward - np.where(truncated, self._time_limit_penalty(final), 0.0)
            for i in np.nonzero(dones)[0]:
                d = {k: _item(final[k][i]) for k in EPISODE_KEYS}
                d["terminal_observation"] = infos["final_obs"][i]
                d["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i] and not self.time_limit_is_failure)
                out[i] = d
        return obs, reward.astype(np.float32), dones, out

    def _time_limit_penalty(self, final: dict) -> np.ndarray:
        from rventry_env.core.backend import NUMPY
        from rventry_env.envs.outcome import TerminalMetrics, time_limit_penalty

        m = TerminalMetrics(*(np.asarray(final[k], float) for k in TerminalMetrics._fields))
        return time_limit_penalty(m, self.venv.reward, NUMPY)

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        if indices is not None and list(self._get_indices(indices)) != list(range(self.num_envs)):
            raise NotImplementedError("the batched env shares attributes across copies; set them for all")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.venv.render()
        return list(frames) if frames is not None else [None]


class RangePotentialShaping(VecEnvWrapper):
    """Adds gamma * Phi(s') - Phi(s) with Phi = -weight * range to go (km) to every reward.

    Potential-based, so the optimal policy is unchanged; over an episode the
    shaping telescopes to Phi(s_T) - Phi(s_0) (with gamma = 1): a dense signal for
    moving toward the target in place of a single terminal one. Put it *inside*
    VecNormalize: it reads the raw range-to-go feature.

    :param venv: the (unnormalized) VecEnv.
    :param weight: reward per km of range closed.
    :param gamma: the discount the learner uses.
    """

    def __init__(self, venv, weight: float = 0.2, gamma: float = 0.999):
        super().__init__(venv)
        self.index = feature_index("range_to_go")
        self.scale = weight * RANGE_SCALE / 1000.0  # reward per unit of the normalized feature
        self.gamma = gamma
        self._phi = None

    def reset(self):
        obs = self.venv.reset()
        self._phi = -self.scale * obs[:, self.index]
        return obs

    def step_wait(self):
        obs, reward, dones, infos = self.venv.step_wait()
        phi_next = -self.scale * obs[:, self.index]
        for i in np.nonzero(dones)[0]:  # the transition ends at the terminal state, not the reset one
            phi_next[i] = -self.scale * infos[i]["terminal_observation"][self.index]
        shaped = reward + self.gamma * phi_next - self._phi
        self._phi = -self.scale * obs[:, self.index]  # next transition starts from the returned (reset) obs
        return obs, shaped.astype(np.float32), dones, infos


def _item(v):
    return v.item() if isinstance(v, np.generic) else v
