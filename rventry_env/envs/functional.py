"""``RvEntry-v0`` in JAX: a functional, gymnax-style environment (needs the ``[jax]`` extra).

The step is :func:`rventry_env.envs.transition.advance`, the very code the NumPy
vector environment runs, traced with the JAX namespace; nothing of the physics is
written twice. Following gymnax:

* ``obs, state = env.reset(key, params)``;
* ``obs, state, reward, done, info = env.step(key, state, action, params)``, which
  starts a new episode (from ``key``) where one ended, as gymnax environments do;
* every function is pure, so ``jax.jit``, ``jax.vmap`` and ``jax.lax.scan`` apply, and
  JAX RL libraries that take gymnax environments (rejax) train on it.

:class:`EnvParams` holds the data of a configuration as arrays: every number of the
:class:`~rventry_env.physics.EntryModel` (a tabulated density profile included,
:func:`~rventry_env.physics.model.numeric_leaves`), the nominal initial state, the
dispersion half-widths and the time limit. Changing them needs no recompilation; a
batch of params (``vmap`` over them) flies a batch of different models. The task
(problem, reward weights, ``dt``, ``substeps``) and the model's structure are the
environment's own, fixed at construction (a new one compiles anew).

Each reset draws the 9 dispersion variables uniformly from ``key`` (the
:class:`~rventry_env.envs.task.Dispersion` rule) and perturbs the initial state with
:func:`~rventry_env.envs.common.disperse_state`, the NumPy environments' own rule.

``info`` carries ``terminated``, ``truncated`` (gymnax's ``done`` is their union),
``status`` (the propagation's ending code), ``observation_clipped`` and, valid where
``done``, the outcome: ``miss_km``, ``vertical_error_deg``, ``speed_error_mps``,
``alpha_final_deg``, ``constraint_violation``, ``is_success`` and ``terminal_penalty``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

from rventry_env.core.backend import prefer_fused_cpu_runtime

prefer_fused_cpu_runtime()  # before JAX loads (see core/backend.py)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np
from gymnax.environments import environment, spaces

from rventry_env.core.backend import jax_ns
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import MAX_EPISODE_STEPS, common
from rventry_env.envs.observation import observation_box
from rventry_env.envs.propagation import Propagator
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import SCALAR_FIELDS, Dispersion, apply_state_dispersion, disperse_state
from rventry_env.envs.transition import Flight, advance, observe_flight, start_flight
from rventry_env.physics.model import EntryModel, numeric_leaves, scaled_model, with_numeric_leaves

DTYPES = ("float32", "float64")


class EnvParams(NamedTuple):
    """A configuration's data, as arrays (a JAX pytree)."""

    model: tuple  # the EntryModel's numbers, in numeric_leaves order
    nominal: Any  # (12,) initial state before dispersion
    dispersion: Any  # (9,) half-widths, Dispersion field order
    max_steps_in_episode: Any  # time limit in control steps


class EnvState(NamedTuple):
    """One episode's state (a JAX pytree)."""

    flight: Flight
    scales: Any  # (3,) this episode's density, C_L and C_D factors

    @property
    def time(self):
        """Control steps taken (gymnax's name)."""
        return self.flight.steps


class RvEntryFunctional(environment.Environment):
    """The entry benchmark as pure JAX functions (see the module docstring).

    :param model: an :class:`~rventry_env.physics.EntryModel` (default: the benchmark's).
    :param task: an :class:`~rventry_env.envs.task.EntryTask`.
    :param dt: control step (s). :param substeps: RK4 substeps per control step.
    :param dispersion: the default params' dispersion: ``"none"``, ``"standard"``, ``"wide"``,
        a :class:`Dispersion` or a dict of its fields.
    :param max_episode_steps: the default params' time limit (control steps).
    :param dtype: ``"float32"`` (default: what RL wants, and GPUs) or ``"float64"``.
    :param reward: the :class:`~rventry_env.envs.reward.RewardWeights` (default: the benchmark's).
    """

    def __init__(self, model=None, task=None, dt=None, substeps=None, dispersion=None,
                 max_episode_steps: int = MAX_EPISODE_STEPS, dtype: str = "float32",
                 reward: RewardWeights | None = None):  # fmt: skip
        super().__init__()
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
        if common.check_max_steps(max_episode_steps) is None:
            raise ValueError("the functional environment needs a time limit (max_episode_steps)")
        self.ns = jax_ns(dtype)
        self.dtype = dtype
        self.model = common.make_model(model)
        self.task = common.make_task(task, dt, substeps)
        if self.task.targets != "fixed":
            raise ValueError(f"the functional environment flies the fixed target; targets={self.task.targets!r} "
                             "needs the NumPy environments")  # fmt: skip
        self.reward = common.make_reward(reward)
        self.dispersion = Dispersion.parse(dispersion)
        self.task.check_dispersion(self.dispersion)
        self.max_episode_steps = int(max_episode_steps)
        self.prop = Propagator(self.task, self.ns, self.reward)
        self.target = tuple(float(c) for c in self.task.problem.target_unit_vector())
        radius = self.model.planet.radius
        self.obs_low, self.obs_high = observation_box(self.task, radius)
        self._nominal = self.task.problem.initial_state(radius)

    # gymnax's step/reset are jitted with ``self`` static: hash and compare by configuration
    def _key(self):
        return (type(self), self.model, self.task, self.reward, self.dtype)

    def __hash__(self):
        return hash(self._key())

    def __eq__(self, other):
        return isinstance(other, RvEntryFunctional) and self._key() == other._key()

    # ------------------------------------------------------------------ params
    @property
    def default_params(self) -> EnvParams:
        return self.make_params()

    def make_params(self, model: EntryModel | None = None, dispersion=None, max_episode_steps: int | None = None,
                    nominal=None) -> EnvParams:  # fmt: skip
        """Params for a model with this environment's structure (its parts' types and tuples).

        :param model: default: the environment's. Another model must have the same structure
            (e.g. the same parts with other numbers, or per-vehicle arrays in their place).
        :param nominal: an initial state (12,), checked like ``reset(options={"state": ...})``.
        """
        model = self.model if model is None else common.make_model(model)
        leaves = numeric_leaves(model)
        if len(leaves) != len(numeric_leaves(self.model)) or _structure(model) != _structure(self.model):
            raise ValueError("the model's structure differs from the environment's: make a new environment for it")
        dispersion = self.dispersion if dispersion is None else Dispersion.parse(dispersion)
        self.task.check_dispersion(dispersion)
        steps = self.max_episode_steps if max_episode_steps is None else max_episode_steps
        if common.check_max_steps(steps) is None:
            raise ValueError("the functional environment needs a time limit (max_episode_steps)")
        x0 = self._nominal if nominal is None else common.check_state(nominal, model.planet.radius, self.task)
        if dispersion.shape != "uniform" or dispersion.mass or dispersion.flight is not None:
            raise ValueError(f"the functional environment flies the uniform scalar dispersion sets (none, standard, "
                             f"wide, custom half-widths); the {dispersion.name!r} set needs the NumPy vector env")  # fmt: skip
        half = [getattr(dispersion, f) for f in SCALAR_FIELDS]
        apply_state_dispersion(x0, np.asarray(half))  # refuses angles that are undefined at this start
        f = self.ns.float_dtype
        return EnvParams(tuple(jnp.asarray(v, dtype=f) for v in leaves), jnp.asarray(x0, f), jnp.asarray(half, f),
                         jnp.asarray(steps, jnp.int32))  # fmt: skip

    # ------------------------------------------------------------------ gymnax API
    def reset_env(self, key, params: EnvParams):
        ns = self.ns
        d = jax.random.uniform(key, (9,), dtype=ns.float_dtype, minval=-1.0, maxval=1.0) * params.dispersion
        x0 = disperse_state(tuple(params.nominal), tuple(d), ns)
        scales = 1.0 + d[:3]
        model = self._model(params, scales)
        flight = start_flight(x0, model, self.prop)
        obs, _ = self._observe(flight, dcm(*x0[1:5]), model)
        return obs, EnvState(flight, scales)

    def step_env(self, key, state: EnvState, action, params: EnvParams):
        a = jnp.clip(jnp.asarray(action, dtype=self.ns.float_dtype), -1.0, 1.0)
        model = self._model(params, state.scales)
        tr = advance(state.flight, (a[0], a[1]), model, self.prop, params.max_steps_in_episode, self.target)
        obs, clipped = self._observe(tr.flight, tr.c_ae, model)
        done = tr.terminated | tr.truncated
        o = tr.outcome
        info = {
            "terminated": tr.terminated, "truncated": tr.truncated, "status": tr.out.status,
            "observation_clipped": clipped, "time_s": tr.flight.t, "discount": jnp.where(tr.terminated, 0.0, 1.0),
            **o.metrics._asdict(), "constraint_violation": o.constraint_violation, "is_success": o.is_success,
            "terminal_penalty": o.terminal_penalty,
        }  # fmt: skip
        return obs, EnvState(tr.flight, state.scales), tr.reward, done, info

    def observation_space(self, params: EnvParams | None = None):
        return spaces.Box(jnp.asarray(self.obs_low), jnp.asarray(self.obs_high), self.obs_low.shape, jnp.float32)

    def action_space(self, params: EnvParams | None = None):
        return spaces.Box(-1.0, 1.0, (2,), jnp.float32)

    @property
    def name(self) -> str:
        return "RvEntry-v0"

    @property
    def num_actions(self) -> int:
        return 2

    # ------------------------------------------------------------------ helpers
    def _model(self, params: EnvParams, scales) -> EntryModel:
        model = with_numeric_leaves(self.model, iter(params.model))
        return scaled_model(model, scales[0], scales[1], scales[2])

    def _observe(self, flight: Flight, c_ae, model):
        raw = jnp.stack(observe_flight(flight, c_ae, model, self.prop, self.target)).astype(jnp.float32)
        clipped = jnp.any((raw < self.obs_low) | (raw > self.obs_high))
        return jnp.clip(raw, self.obs_low, self.obs_high), clipped


def _structure(obj):
    """What must match for params to fit a compiled environment: the parts' types, their
    non-numeric fields (tuples such as knots are compiled in) and the shapes of their numbers.
    A part's ``TABLE_FIELDS`` are carried as arrays (their numbers are leaves) and skipped."""
    if isinstance(obj, np.ndarray) or (isinstance(obj, (int, float)) and not isinstance(obj, bool)):
        return np.shape(obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        skip = getattr(type(obj), "TABLE_FIELDS", ())
        return (type(obj),) + tuple(_structure(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.name not in skip)
    return obj


__all__ = ["RvEntryFunctional", "EnvParams", "EnvState", "DTYPES"]
