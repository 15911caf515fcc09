"""Gymnasium environments: ``RvEntry-v0`` (single) and its numpy-batched vector version.

Importing this package registers ``RvEntry-v0`` (``gym.make("rventry_env.envs:RvEntry-v0")``
therefore works with no other import); ``import rventry_env`` registers it as soon as
Gymnasium is imported.
"""

from __future__ import annotations

ENV_ID = "RvEntry-v0"
MAX_EPISODE_STEPS = 2000


def register_envs() -> None:
    """Register ``RvEntry-v0`` with Gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    if ENV_ID in registry:
        return
    # The time limit is the environment's own (max_episode_steps, default MAX_EPISODE_STEPS): it ends
    # a truncated episode with the same info keys as any other. The spec records the same limit, so
    # Gymnasium's wrappers and the RL libraries that read env.spec.max_episode_steps know it; the
    # TimeLimit wrapper gym.make adds for it cuts at the same step as the environment, which reads it
    # at reset (common.outer_time_limit), and make_vec hands it to the vector env as its own.
    register(
        id=ENV_ID,
        entry_point="rventry_env.envs.rv_entry:RvEntryEnv",
        vector_entry_point="rventry_env.envs.vector:make_vector_env",
        max_episode_steps=MAX_EPISODE_STEPS,
    )


register_envs()
