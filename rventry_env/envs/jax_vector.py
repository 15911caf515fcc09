"""``RvEntryJaxVectorEnv``: the vector env with the JAX stepper.

There is one vector env class, :class:`~rventry_env.envs.vector.RvEntryVectorEnv`; ``backend="jax"``
hands its flights to :class:`~rventry_env.envs.jax_stepper.JaxStepper`. This name builds it, as
``gym.make_vec("RvEntry-v0", num_envs=N, vectorization_mode="vector_entry_point", backend="jax")`` does.
"""

from __future__ import annotations

from rventry_env.envs.vector import RvEntryJaxVectorEnv

__all__ = ["RvEntryJaxVectorEnv"]
