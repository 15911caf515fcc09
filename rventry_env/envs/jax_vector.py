"""``RvEntryJaxVectorEnv``: the Gymnasium vector environment with its step compiled by JAX.

``gym.make_vec("RvEntry-v0", num_envs=N, vectorization_mode="vector_entry_point",
backend="jax", dtype="float64")`` (or ``"float32"``). Everything a user sees is the
NumPy vector environment's (:class:`~rventry_env.envs.vector.RvEntryVectorEnv`, its
subclass): spaces, seeding, autoreset modes, infos, errors. Episodes are drawn on the
host with the same per-copy ``np_random`` generators, so the same seed flies the same
episodes as ``backend="numpy"``. The step of all copies
(:func:`~rventry_env.envs.transition.advance`, the NumPy environment's own code) runs
under ``jax.jit`` on the default JAX device (CPU, or a GPU where JAX finds one);
observations, rewards and infos come back as NumPy arrays.
"""

from __future__ import annotations

from rventry_env.core.backend import prefer_fused_cpu_runtime

prefer_fused_cpu_runtime()  # before JAX loads (see core/backend.py)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np
from gymnasium.vector import AutoresetMode

from rventry_env.core.backend import NUMPY, jax_ns
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import common
from rventry_env.envs.functional import DTYPES
from rventry_env.envs.outcome import Outcome, TerminalMetrics, failure_name
from rventry_env.envs.propagation import Propagator
from rventry_env.envs.transition import Flight, advance, observe_flight, start_flight
from rventry_env.envs.vector import RvEntryVectorEnv, Stepped
from rventry_env.physics.model import numeric_leaves, scaled_model, with_numeric_leaves


class RvEntryJaxVectorEnv(RvEntryVectorEnv):
    """:class:`RvEntryVectorEnv` with its step compiled by JAX (see the module docstring).

    :param dtype: ``"float64"`` (default: agrees with NumPy to rounding) or ``"float32"``
        (faster; see the README for its error at impact).
    Other arguments as :class:`RvEntryVectorEnv`; ``render_mode`` is not supported.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, dtype: str = "float64", render_mode=None, **kwargs):
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
        if render_mode is not None:
            raise ValueError(f"backend='jax' does not render (render_mode={render_mode!r}); use backend='numpy'")
        super().__init__(num_envs, **kwargs)
        if self.task.targets != "fixed":
            raise ValueError(f"backend='jax' flies the fixed target; targets={self.task.targets!r} needs backend='numpy'")
        self.dtype = dtype
        self._ns = jax_ns(dtype)
        self._jprop = Propagator(self.task, self._ns, self.reward)
        f = self._ns.float_dtype
        self._leaves = tuple(jnp.asarray(v, dtype=f) for v in numeric_leaves(self.model))
        self._flight = None
        self._x0 = None  # (12, N) host: initial states of the current episodes
        self._step_fn = jax.jit(self._step_all)
        self._restart_fn = jax.jit(self._restart)
        self._view_fn = jax.jit(self._view)

    @property
    def state(self) -> np.ndarray:
        """States of all copies, float64, shape (N, 12), state order of docs/conventions.md (a copy)."""
        if self._flight is None:
            raise RuntimeError("the environment has no state before reset()")
        return np.stack([np.asarray(c, dtype=np.float64) for c in self._flight.x], axis=-1)

    # ------------------------------------------------------------------ backend hooks
    def _reset_copies(self, idx: np.ndarray, dispersion=None) -> list:
        d = self.dispersion if dispersion is None else dispersion
        if d.mass or d.flight is not None:
            raise ValueError(f"backend='jax' flies the scalar dispersion sets; the {d.name!r} set's mass and "
                             "flight-grade errors (profiles, sensors) need backend='numpy'")  # fmt: skip
        x0, extras = self._draw(idx, dispersion)
        if self._x0 is None or self._flight is None or len(idx) == self.num_envs:
            self._x0 = np.empty((12, self.num_envs))
        self._x0[:, idx] = x0.T
        mask = np.zeros(self.num_envs, bool)
        mask[idx] = True
        f = self._ns.float_dtype
        scales = jnp.asarray(np.stack([self._density, self._lift, self._drag]), f)
        self._scales = scales
        self._flight = self._restart_fn(self._flight, jnp.asarray(self._x0, f), scales, jnp.asarray(mask), self._leaves)
        return extras

    def _measure(self, elapsed=None, active=None) -> None:
        """No sensor or navigation errors fly with backend='jax' (refused at reset): laws see the truth."""
        self._nav = self._sensed = None

    def _observe(self):
        obs, clipped, _ = self._view_fn(self._flight, self._scales, self._leaves)
        return np.asarray(obs), np.asarray(clipped)

    def _info(self, action_clipped, alpha_saturated, obs_clipped) -> dict:
        _, _, info = self._view_fn(self._flight, self._scales, self._leaves)
        return self._info_dict(_to_host(info), action_clipped, alpha_saturated, obs_clipped)

    def _advance_all(self, a: np.ndarray, active: np.ndarray) -> Stepped:
        f = self._ns.float_dtype
        self._flight, out = self._step_fn(
            self._flight, self._scales, jnp.asarray(a, f), jnp.asarray(active), self._leaves
        )
        out = _to_host(out)
        terminated, truncated = out["terminated"], out["truncated"]
        ended = terminated | truncated
        outcome = None
        if ended.any():
            outcome = Outcome(
                TerminalMetrics(*out["metrics"]), out["violation"], out["success"], out["penalty"],
                failure_name(out["status"], terminated, NUMPY),
            )  # fmt: skip
        return Stepped(out["reward"].astype(np.float64), terminated, truncated, out["saturated"], out["obs"],
                       out["obs_clipped"], out["info"], outcome, out["max_load"], out["min_q"])  # fmt: skip

    def _record(self, only=None):
        return None  # no rendering with backend='jax'

    # ------------------------------------------------------------------ compiled parts
    def _model(self, leaves, scales):
        return scaled_model(with_numeric_leaves(self.model, iter(leaves)), scales[0], scales[1], scales[2])

    def _restart(self, flight, x0, scales, mask, leaves):
        fresh = start_flight(tuple(x0), self._model(leaves, scales), self._jprop)
        if flight is None:
            return fresh
        return jax.tree.map(lambda new, old: jnp.where(mask, new, old), fresh, flight)

    def _view(self, flight: Flight, scales, leaves, c_ae=None):
        model = self._model(leaves, scales)
        c_ae = dcm(*flight.x[1:5]) if c_ae is None else c_ae
        raw = jnp.stack(observe_flight(flight, c_ae, model, self._jprop, self._target)).astype(jnp.float32)
        lo, hi = self._obs_low[:, None], self._obs_high[:, None]
        clipped = jnp.any((raw < lo) | (raw > hi), axis=0)
        obs = jnp.clip(raw, lo, hi).T
        info = common.flight_info(flight.x, flight.forces, c_ae, flight.t, flight.cost, self._radius, self._g0, self._ns)
        return obs, clipped, info

    def _step_all(self, flight: Flight, scales, a, active, leaves):
        model = self._model(leaves, scales)
        tr = advance(flight, (a[:, 0], a[:, 1]), model, self._jprop, self.max_episode_steps, self._target, active)
        obs, clipped, info = self._view(tr.flight, scales, leaves, tr.c_ae)
        o = tr.outcome
        return tr.flight, {
            "reward": tr.reward, "terminated": tr.terminated, "truncated": tr.truncated, "status": tr.out.status,
            "saturated": tr.out.alpha_saturated, "obs": obs, "obs_clipped": clipped, "info": info,
            "metrics": tuple(o.metrics), "violation": o.constraint_violation, "success": o.is_success,
            "penalty": o.terminal_penalty, "max_load": tr.flight.max_load, "min_q": tr.flight.min_q,
        }  # fmt: skip


def _to_host(tree):
    return jax.tree.map(np.asarray, jax.device_get(tree))


__all__ = ["RvEntryJaxVectorEnv"]
