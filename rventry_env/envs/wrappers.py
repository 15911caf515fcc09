"""Wrappers for ``RvEntry-v0``.

``RvEntry-v0`` keeps its own time limit (``max_episode_steps``, 2000 control steps by
default) and ends a truncated episode with the same info keys as any other. A shorter
Gymnasium ``TimeLimit`` around it (``gym.make("RvEntry-v0", max_episode_steps=N)``) is
read at ``reset`` and honoured the same way, with no wrapper. :class:`EndAtTimeLimit`
is for any other limit kept outside the environment (a wrapper of your own that
truncates): put outside it, it lets the environment close such an episode as it closes
any other.
"""

from __future__ import annotations

import gymnasium as gym


class EndAtTimeLimit(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Give an episode truncated by an outer time limit the same end-of-episode ``info`` as any other end.

    :param env: an environment whose unwrapped core has ``end_at_time_limit(info)``
        (:class:`~rventry_env.envs.rv_entry.RvEntryEnv`).
    """

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if truncated and not terminated and "failure" not in info:
            self.env.unwrapped.end_at_time_limit(info)
        return obs, reward, terminated, truncated, info


__all__ = ["EndAtTimeLimit"]
