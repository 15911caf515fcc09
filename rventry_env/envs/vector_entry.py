"""``RvEntry-v0``'s vector entry point: the vector env, its stepper chosen by ``backend``."""

from __future__ import annotations

from rventry_env.envs.vector import RvEntryVectorEnv


def make_vector_env(num_envs: int = 1, backend: str = "numpy", dtype: str = "float64", **kwargs) -> RvEntryVectorEnv:
    """``RvEntry-v0``'s vector entry point: ``backend="numpy"`` (default) or ``"jax"`` (the ``[jax]`` extra).

    ``dtype`` (``"float64"`` or ``"float32"``) applies to the JAX backend; NumPy computes in float64.
    """
    return RvEntryVectorEnv(num_envs, backend=backend, dtype=dtype, **kwargs)


__all__ = ["make_vector_env"]
