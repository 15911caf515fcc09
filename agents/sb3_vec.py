"""A stable-baselines3 ``VecEnv`` over the numpy-batched :class:`RvEntryVectorEnv`.

SB3 expects same-step autoreset, a list of per-copy info dicts with
``terminal_observation`` and ``TimeLimit.truncated``, and float32 rewards. This
adapter gives it that without one Python env object per copy: every step is one
batched step of all copies, and info dicts are built only for copies whose
episode ended (the rest get empty dicts).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from rventry_env.envs.vector import TERMINAL_KEYS, RvEntryVectorEnv

EPISODE_KEYS = TERMINAL_KEYS + ("cost", "time_s")


class RvEntrySB3VecEnv(VecEnv):
    """SB3 view of ``num_envs`` batched RvEntry-v0 copies.

    :param num_envs: number of copies.
    :param env_kwargs: passed to :class:`RvEntryVectorEnv` (model, task, dispersion, max_episode_steps ...).
    """

    def __init__(self, num_envs: int, **env_kwargs: Any):
        env_kwargs = {k: v for k, v in env_kwargs.items() if k != "autoreset_mode"}
        self.venv = RvEntryVectorEnv(num_envs=num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self.render_mode = self.venv.render_mode
        self._actions: np.ndarray | None = None

    def reset(self):
        seeds = None if all(s is None for s in self._seeds) else [0 if s is None else s for s in self._seeds]
        options = self._options[0] if self._options and self._options[0] else None
        obs, _ = self.venv.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out: list[dict] = [{} for _ in range(self.num_envs)]
        if np.any(dones):
            final = infos["final_info"]
            for i in np.nonzero(dones)[0]:
                d = {k: _item(final[k][i]) for k in EPISODE_KEYS}
                d["terminal_observation"] = infos["final_obs"][i]
                d["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                out[i] = d
        return obs, reward.astype(np.float32), dones, out

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


def _item(v):
    return v.item() if isinstance(v, np.generic) else v
