"""``RvEntry-v0``'s vector entry point: the NumPy vector env or, with ``backend="jax"``, the JAX one.

It sits apart from both envs so that neither imports the other's module back: the JAX env builds
on the NumPy one, and this module alone knows both.
"""

from __future__ import annotations

from rventry_env.envs.vector import RvEntryVectorEnv


def make_vector_env(num_envs: int = 1, backend: str = "numpy", dtype: str = "float64", **kwargs) -> RvEntryVectorEnv:
    """``RvEntry-v0``'s vector entry point: ``backend="numpy"`` (default) or ``"jax"`` (the ``[jax]`` extra).

    ``dtype`` (``"float64"`` or ``"float32"``) applies to the JAX backend; NumPy computes in float64.
    """
    if backend == "numpy":
        if dtype != "float64":
            raise ValueError(f"backend='numpy' computes in float64; dtype={dtype!r} needs backend='jax'")
        return RvEntryVectorEnv(num_envs, **kwargs)
    if backend == "jax":
        from rventry_env.envs.jax_vector import RvEntryJaxVectorEnv

        return RvEntryJaxVectorEnv(num_envs, dtype=dtype, **kwargs)
    raise ValueError(f"backend must be 'numpy' or 'jax', got {backend!r}")


__all__ = ["make_vector_env"]
