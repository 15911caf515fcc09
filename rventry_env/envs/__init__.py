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
    # The time limit is the environment's own (max_episode_steps, default MAX_EPISODE_STEPS), not
    # Gymnasium's TimeLimit wrapper, which truncates without telling the environment: this way a
    # truncated episode ends with the same info keys as any other.
    register(
        id=ENV_ID,
        entry_point="rventry_env.envs.rv_entry:RvEntryEnv",
        vector_entry_point="rventry_env.envs.vector:make_vector_env",
    )


register_envs()
