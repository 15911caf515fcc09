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

Each reset draws the 9 dispersion variables and the mass factor from ``key`` by the
:class:`~rventry_env.task.Dispersion` rule of its shape (uniform half-widths, or standard
deviations of normals clipped at ``clip_sigmas``: the shape is data in the params too) and
perturbs the initial state with :func:`~rventry_env.task.disperse_state`, the NumPy
environments' own rule. The numbers come from ``key`` through :func:`uniforms`: two words of
``jax.random.bits`` hashed with a counter. Under ``vmap`` in a scan, as RL libraries run
gymnax environments, every step also draws the reset it may need (gymnax's autoreset), and
``jax.random.uniform`` for ten numbers per vehicle cost as much as the physics of the step
(XLA CPU, N = 8192: 1.4 ms against 0.13 ms for two words); the hash keeps the draws
deterministic in ``key`` and costs a few integer operations per number.

The flight-grade errors (the ``flight`` set: NRLMSIS and Gauss-Markov density profiles, wind
profiles, Mach-varying C_L and C_D, accelerometer and navigation errors) need their structure
compiled in: an environment made with such a dispersion flies them (and any other set, as zero
errors). Drawing a vehicle's profiles takes NRLMSIS and about 330 normals, too much to repeat for
every vehicle at every step of a scan, so :meth:`RvEntryFunctional.make_params` draws a pool of
``pool_size`` vehicles' flight-grade errors on the host with the NumPy environments' own draw
(:func:`~rventry_env.task.draw_extras`, seeded by ``seed``) and each reset picks one of them with
its fresh scalar and mass draws; the accelerometer's white noise is drawn from the step's key. New
params (another seed) are a new pool, without recompiling. The observation is then built from the
navigation state and the sensed features (:func:`~rventry_env.envs.uncertainty.sense`, the NumPy
environments' code).

``info`` carries ``terminated``, ``truncated`` (gymnax's ``done`` is their union),
``status`` (the propagation's ending code), ``observation_clipped`` and, valid where
``done``, the outcome: ``miss_km``, ``vertical_error_deg``, ``speed_error_mps``,
``alpha_final_deg``, ``constraint_violation``, ``is_success`` and ``terminal_penalty``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from gymnax.environments import environment, spaces

from rventry_env.core.backend import jax_ns
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import MAX_EPISODE_STEPS, common
from rventry_env.envs.observation import observation_box
from rventry_env.envs.propagation import Propagator
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import SCALAR_FIELDS, Dispersion, apply_state_dispersion, disperse_state
from rventry_env.envs.outcome import time_limit_penalty
from rventry_env.envs.shaping import PotentialShaping, check_shaping
from rventry_env.envs.transition import EpisodeState, advance, observe_episode, start_episode
from rventry_env.task.starts import DRAWS, StartStates, perturbed, window_time
from rventry_env.physics.model import EntryModel, numeric_leaves, scaled_model, with_numeric_leaves

DTYPES = ("float32", "float64")
ENV_DEFAULT = object()  # make_params: the environment's own setting
_START_OFFSET = 96  # the start draw's counters, after the dispersion's, the pool pick's and the sensors'


class EnvParams(NamedTuple):
    """A configuration's data, as arrays (a JAX pytree)."""

    model: tuple  # the EntryModel's numbers, in numeric_leaves order
    nominal: Any  # (12,) initial state before dispersion
    dispersion: Any  # (10,) half-widths or standard deviations: the 9 of SCALAR_FIELDS, then the mass
    gaussian: Any  # True: clipped normals (the dispersion's shape "gaussian"); False: uniform
    clip_sigmas: Any  # where the normals are clipped
    max_steps_in_episode: Any  # time limit in control steps
    pool: Any = None  # flight-grade environments: the ErrorPool the resets pick from
    starts: Any = None  # environments with start states: the StartParams the resets draw from


class StartParams(NamedTuple):
    """A :class:`~rventry_env.task.starts.StartStates` as arrays (changing them needs no recompilation)."""

    times: Any  # (K,) the table's flight times
    states: Any  # (K, 12)
    window: Any  # (2,) the table times an episode may start at: earliest, latest
    probability: Any  # the share of episodes that start from the table
    half_widths: Any  # (6,) the perturbations of PERTURBATIONS
    far_weight: Any  # the start time's density grows toward the window's far end as (s - earliest)^far_weight
    step_weighted: Any  # 1: density 1/s in the seconds s before the table's end instead (0: not)


class ErrorPool(NamedTuple):
    """``pool_size`` vehicles' flight-grade errors (rows), drawn on the host by the NumPy draw."""

    log_factors: Any  # (P, K) ln(density / model density) on the altitude grid
    wind_east: Any  # (P, K) m/s
    wind_north: Any
    aero: Any  # (P, 4) lift P1, P2, drag P1, P2
    bias: Any  # (P, 3) accelerometer bias, scale factor, misalignment
    scale: Any
    misalignment: Any
    noise: Any  # (P,) white-noise rms per sample
    senses: Any  # (P,) bool
    dr: Any  # (P, 3) navigation errors at the entry fix (E components)
    dv: Any


class EpisodeErrors(NamedTuple):
    """One episode's flight-grade errors and its navigation errors so far."""

    row: ErrorPool  # one row of the pool
    dr: Any  # (3,)
    dv: Any


class EnvState(NamedTuple):
    """One episode's state (a JAX pytree)."""

    episode: EpisodeState
    scales: Any  # (4,) this episode's density, C_L, C_D and mass factors
    errors: Any = None  # flight-grade environments: this episode's EpisodeErrors
    potential: Any = None  # environments with shaping: the potential of the current state

    @property
    def time(self):
        """Control steps taken (gymnax's name)."""
        return self.episode.steps


class RvEntryFunctional(environment.Environment):
    """The entry benchmark as pure JAX functions (see the module docstring).

    :param model: an :class:`~rventry_env.physics.EntryModel` (default: the benchmark's).
    :param task: an :class:`~rventry_env.envs.task.EntryTask`.
    :param dt: control step (s). :param substeps: RK4 substeps per control step.
    :param dispersion: the default params' dispersion: ``"none"``, ``"standard"``, ``"wide"``, ``"peer"``,
        ``"peer-0.1"``,
        a :class:`Dispersion` or a dict of its fields.
    :param max_episode_steps: the default params' time limit (control steps).
    :param dtype: ``"float32"`` (default: what RL wants, and GPUs) or ``"float64"``.
    :param reward: the :class:`~rventry_env.envs.reward.RewardWeights` (default: the benchmark's).
    :param pool_size: flight-grade environments: how many vehicles' flight-grade errors the params
        hold for the resets to pick from (see the module docstring).
    """

    def __init__(self, model=None, task=None, dt=None, substeps=None, dispersion=None,
                 max_episode_steps: int = MAX_EPISODE_STEPS, dtype: str = "float32",
                 reward: RewardWeights | None = None, pool_size: int = 256, starts: StartStates | None = None,
                 shaping: PotentialShaping | None = None, time_limit_is_failure: bool = False):  # fmt: skip
        super().__init__()
        common.check_max_steps(max_episode_steps, optional=False)
        if not isinstance(dtype, str) or dtype not in DTYPES:
            raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
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
        self.flight_grade = _flight_grade(self.dispersion)
        if isinstance(pool_size, bool) or not isinstance(pool_size, (int, np.integer)) or pool_size < 1:
            raise ValueError(f"pool_size must be a positive integer, got {pool_size!r}")
        self.pool_size = int(pool_size)
        if self.flight_grade and self.model.wind is not None:
            raise ValueError("a dispersion with flight-grade errors needs a model without a wind of its own")
        self.max_episode_steps = int(max_episode_steps)
        self.prop = Propagator(self.task, self.ns, self.reward)
        self.target = tuple(float(c) for c in self.task.problem.target_unit_vector())
        radius = self.model.planet.radius
        self.obs_low, self.obs_high = observation_box(self.task, radius)
        self._nominal = self.task.problem.initial_state(radius)
        self.starts = common.check_starts(starts, radius, self.task)
        self.shaping = check_shaping(shaping)
        if not isinstance(time_limit_is_failure, bool):
            raise ValueError(f"time_limit_is_failure must be True or False, got {time_limit_is_failure!r}")
        self.time_limit_is_failure = time_limit_is_failure
        self._checked = None  # the params reset() last checked

    # gymnax's step/reset are jitted with ``self`` static: hash and compare by configuration
    def _key(self):
        return (type(self), self.model, self.task, self.reward, self.dtype, self.flight_grade, self.pool_size,
                self.shaping, self.time_limit_is_failure)  # fmt: skip

    def __hash__(self):
        return hash(self._key())

    def __eq__(self, other):
        return isinstance(other, RvEntryFunctional) and self._key() == other._key()

    # ------------------------------------------------------------------ params
    @property
    def default_params(self) -> EnvParams:
        return self.make_params()

    def make_params(self, model: EntryModel | None = None, dispersion=None, max_episode_steps: int | None = None,
                    nominal=None, seed: int = 0, starts=ENV_DEFAULT) -> EnvParams:  # fmt: skip
        """Params for a model with this environment's structure (its parts' types and tuples).

        :param model: default: the environment's. Another model must have the same structure
            (e.g. the same parts with other numbers, or per-vehicle arrays in their place).
        :param nominal: an initial state (12,), checked like ``reset(options={"state": ...})``.
        :param seed: flight-grade environments: the seed of the pool of flight-grade draws.
        :param starts: a :class:`~rventry_env.task.starts.StartStates` the resets draw from, or None for
            none (default: the environment's).
        """
        model = self.model if model is None else common.make_model(model)
        leaves = numeric_leaves(model)
        if len(leaves) != len(numeric_leaves(self.model)) or _structure(model) != _structure(self.model):
            raise ValueError("the model's structure differs from the environment's: make a new environment for it")
        dispersion = self.dispersion if dispersion is None else Dispersion.parse(dispersion)
        self.task.check_dispersion(dispersion)
        steps = self.max_episode_steps
        if max_episode_steps is not None:
            steps = common.check_max_steps(max_episode_steps, optional=False)
        seed = _check_seed(seed)
        x0 = self._nominal if nominal is None else common.check_state(nominal, model.planet.radius, self.task)
        if _flight_grade(dispersion) and not self.flight_grade:
            raise ValueError(f"the {dispersion.name!r} set's flight-grade errors (profiles, Mach-varying aerodynamics, "
                             "sensors, navigation) are compiled structure: make the environment with a flight-grade "
                             f"dispersion, e.g. RvEntryFunctional(dispersion={dispersion.name!r})")  # fmt: skip
        half = [getattr(dispersion, f) for f in SCALAR_FIELDS]
        # refuses angles that are undefined at this start
        apply_state_dispersion(x0, np.asarray([dispersion.largest(f) for f in SCALAR_FIELDS]))
        f = self.ns.float_dtype
        params = EnvParams(tuple(jnp.asarray(v, dtype=f) for v in leaves), jnp.asarray(x0, f),
                           jnp.asarray([*half, dispersion.mass], f), jnp.asarray(dispersion.shape == "gaussian"),
                           jnp.asarray(dispersion.clip_sigmas, f), jnp.asarray(steps, jnp.int32),
                           self._pool(model, dispersion, seed) if self.flight_grade else None,
                           self.start_params(self.starts if starts is ENV_DEFAULT else starts, model))  # fmt: skip
        self._checked = self.check_params(params)
        return params

    def check_params(self, params: EnvParams) -> EnvParams:
        """``params`` checked on the host, each field against this environment: its structure, shapes
        and dtypes (what the compiled functions were traced for) and its values, naming the field
        that is wrong. :meth:`make_params` checks what it makes; params built or changed by hand
        (``params._replace(...)``) can be checked here before a compiled ``reset``/``step`` takes them
        (values cannot be checked under ``jit``: a NaN parameter there gives NaN observations).

        :return: ``params``, unchanged.
        :raises ValueError: naming the field and what is wrong with it.
        """
        if not isinstance(params, EnvParams):
            raise ValueError(f"params must be an EnvParams (env.make_params(...)), got {type(params).__name__}")
        reference = self._reference_params(params)
        for name in EnvParams._fields:
            _check_like(f"EnvParams.{name}", getattr(params, name), getattr(reference, name))
        host = jax.device_get(params)
        leaves = [np.asarray(v, np.float64) for v in host.model]
        template = numeric_leaves(self.model)
        model = with_numeric_leaves(self.model, iter(_host_leaf(v, t) for v, t in zip(leaves, template)))
        try:
            rebuilt = _rebuilt(model)
        except (TypeError, ValueError) as e:
            raise ValueError(f"EnvParams.model: {e}") from None
        try:
            x0 = common.check_state(np.asarray(host.nominal, np.float64), rebuilt.planet.radius, self.task)
        except ValueError as e:
            raise ValueError(f"EnvParams.nominal: {e}") from None
        spread = [float(v) for v in np.asarray(host.dispersion, np.float64)]
        try:  # the Dispersion's own checks, and the make_params' one of the angles at this start
            d = Dispersion(shape="gaussian" if bool(host.gaussian) else "uniform", clip_sigmas=float(host.clip_sigmas),
                           mass=spread[-1], **dict(zip(SCALAR_FIELDS, spread[:-1])))  # fmt: skip
            apply_state_dispersion(x0, np.asarray([d.largest(f) for f in SCALAR_FIELDS]))
        except ValueError as e:
            raise ValueError(f"EnvParams.dispersion / clip_sigmas: {e}") from None
        common.check_max_steps(int(host.max_steps_in_episode), "EnvParams.max_steps_in_episode", optional=False)
        if host.pool is not None:
            for name, v in zip(ErrorPool._fields, host.pool):
                if np.asarray(v).dtype.kind == "f" and not np.all(np.isfinite(v)):
                    raise ValueError(f"EnvParams.pool.{name} contains NaN or inf")
        if host.starts is not None:
            _check_start_params(host.starts, rebuilt.planet.radius, self.task)
        return params

    def _reference_params(self, params: EnvParams) -> EnvParams:
        """Params of this environment's own structure, to compare a user's against (cached)."""
        ref = getattr(self, "_reference", None)
        if ref is None:
            f = self.ns.float_dtype
            z = lambda v: jax.ShapeDtypeStruct(np.shape(v), f)  # noqa: E731
            pool = None
            if self.flight_grade:
                pool = jax.eval_shape(lambda: self._pool(self.model, Dispersion.parse("none"), 0))
            ref = self._reference = EnvParams(
                tuple(z(v) for v in numeric_leaves(self.model)), jax.ShapeDtypeStruct((12,), f),
                jax.ShapeDtypeStruct((10,), f), jax.ShapeDtypeStruct((), jnp.bool_), jax.ShapeDtypeStruct((), f),
                jax.ShapeDtypeStruct((), jnp.int32), pool, None,
            )  # fmt: skip
        if params.starts is not None:  # a table of any length: the shapes of its rows and scalars are fixed
            k = np.shape(params.starts.times)[:1]
            f = self.ns.float_dtype
            s = jax.ShapeDtypeStruct
            ref = ref._replace(starts=StartParams(s(k, f), s(k + (12,), f), s((2,), f), s((), f), s((6,), f), s((), f),
                                                  s((), f)))  # fmt: skip
        return ref

    def start_params(self, starts, model: EntryModel | None = None) -> StartParams | None:
        """Start states as the params' arrays (checked against the model's planet and the task): what a
        curriculum changes between calls without recompiling (``params._replace(starts=...)``)."""
        model = self.model if model is None else model
        starts = common.check_starts(starts, model.planet.radius, self.task)
        if starts is None:
            return None
        f = self.ns.float_dtype
        return StartParams(jnp.asarray(starts.times, f), jnp.asarray(starts.states, f),
                           jnp.asarray(starts.window_times(), f), jnp.asarray(starts.probability, f),
                           jnp.asarray(starts.half_widths, f), jnp.asarray(starts.far_weight, f),
                           jnp.asarray(starts.step_weighted, f))  # fmt: skip

    def _pool(self, model: EntryModel, dispersion: Dispersion, seed: int) -> ErrorPool:
        """The pool of flight-grade draws (zeros for a set without them)."""
        from rventry_env.envs.uncertainty import VehicleErrors
        from rventry_env.task import draw_extras

        errs = VehicleErrors(self.pool_size, model)
        if _flight_grade(dispersion):
            rng = np.random.default_rng(seed)
            for i in range(self.pool_size):
                errs.assign(i, dispersion, draw_extras(rng, dispersion, self.task.problem))
        f = self.ns.float_dtype
        a = lambda v: jnp.asarray(np.ascontiguousarray(v), f)  # noqa: E731
        return ErrorPool(a(errs.log_factors), a(errs.wind_east), a(errs.wind_north), a(errs.aero), a(errs.bias),
                          a(errs.scale), a(errs.misalignment), a(errs.noise), jnp.asarray(errs.senses), a(errs.dr.T),
                          a(errs.dv.T))  # fmt: skip

    # ------------------------------------------------------------------ gymnax API
    def reset(self, key, params: EnvParams | None = None):
        """gymnax's ``reset``; params given outside ``jit`` (concrete arrays) are checked first by
        :meth:`check_params` (once for the same params object), so that a hand-made NaN or
        negative parameter is refused naming its field rather than flown into NaN observations."""
        if params is not None and params is not self._checked and not _traced(params):
            self._checked = self.check_params(params)
        return super().reset(key, params)

    def reset_env(self, key, params: EnvParams):
        ns = self.ns
        d = dispersion_draw(key, params, ns.float_dtype)
        x0 = disperse_state(tuple(params.nominal), tuple(d[:9]), ns)
        scales = 1.0 + jnp.concatenate([d[:3], d[9:]])
        errors = None
        if self.flight_grade:
            pick = uniforms(key, 1, ns.float_dtype, offset=2 * d.shape[0])[0]
            i = jnp.minimum((pick * self.pool_size).astype(jnp.int32), self.pool_size - 1)
            row = jax.tree.map(lambda v: v[i], params.pool)
            errors = EpisodeErrors(row, row.dr, row.dv)
        model = self._model(params, scales, errors)
        episode = start_episode(x0, model, self.prop)
        if params.starts is not None:
            episode = self._start_from_table(key, params.starts, episode, model)
        c_ae = dcm(*episode.x[1:5])
        obs, _, _ = self._observe(key, episode, c_ae, model, params, errors, None)
        return obs, EnvState(episode, scales, errors, self._potential(episode.x, c_ae))

    def _start_from_table(self, key, sp: StartParams, episode: EpisodeState, model: EntryModel) -> EpisodeState:
        """``episode``, or where this reset's draw says so, an episode from the start table (the NumPy
        environments' rule: :meth:`~rventry_env.task.starts.StartStates.draw`)."""
        ns = self.ns
        u = uniforms(key, DRAWS, ns.float_dtype, offset=_START_OFFSET)
        t = window_time(u[1], sp.window, sp.far_weight, jnp, sp.times[-1], sp.step_weighted > 0.5)
        k = jnp.clip(jnp.searchsorted(sp.times, t), 0, sp.times.shape[0] - 1)
        row = sp.states[k]
        x = perturbed(tuple(row[i] for i in range(12)), tuple((2.0 * u[2:] - 1.0) * sp.half_widths),
                      self.task.problem.alpha_max, ns)  # fmt: skip
        x = common.within_path_bounds(x, model, self.task, ns)
        table = start_episode(x, model, self.prop)._replace(t=sp.times[k])
        return jax.tree.map(lambda a, b: jnp.where(u[0] < sp.probability, a, b), table, episode)

    def _potential(self, x, c_ae):
        """The shaping potential of the true state (None without shaping)."""
        if self.shaping is None:
            return None
        planet = self.model.planet
        return self.shaping.phi(x, c_ae, self.target, planet.mu, planet.radius, self.ns)

    def step_env(self, key, state: EnvState, action, params: EnvParams):
        raw = jnp.asarray(check_action(action), dtype=self.ns.float_dtype)
        a = jnp.clip(raw, -1.0, 1.0)
        model = self._model(params, state.scales, state.errors)
        tr = advance(state.episode, (a[0], a[1]), model, self.prop, params.max_steps_in_episode, self.target)
        obs, clipped, errors = self._observe(key, tr.episode, tr.c_ae, model, params, state.errors, tr.out.elapsed)
        done = tr.terminated | tr.truncated
        o = tr.outcome
        reward = tr.reward
        if self.time_limit_is_failure:  # training: a cut is charged like a failure, and is final
            reward = reward - jnp.where(tr.truncated, time_limit_penalty(o.metrics, self.reward, self.ns), 0.0)
        phi = self._potential(tr.episode.x, tr.c_ae)
        if phi is not None:
            final = tr.terminated | (tr.truncated & self.time_limit_is_failure)
            reward = reward + self.shaping.reward(state.potential, phi, final, self.ns)
        info = {
            "terminated": tr.terminated, "truncated": tr.truncated, "status": tr.out.status,
            "observation_clipped": clipped, "action_clipped": jnp.any((raw < -1.0) | (raw > 1.0)), "time_s": tr.episode.t, "discount": jnp.where(tr.terminated, 0.0, 1.0),
            **o.metrics._asdict(), "constraint_violation": o.constraint_violation, "is_success": o.is_success,
            "terminal_penalty": o.terminal_penalty,
        }  # fmt: skip
        return obs, EnvState(tr.episode, state.scales, errors, phi), reward, done, info

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
    def _model(self, params: EnvParams, scales, errors=None) -> EntryModel:
        model = with_numeric_leaves(self.model, iter(params.model))
        model = scaled_model(model, scales[0], scales[1], scales[2])
        model = with_mass_factor(model, scales[3])
        if errors is None:
            return model
        from rventry_env.physics.uncertainty import MachVaryingAerodynamics, ProfileAtmosphere, ProfileWind
        from rventry_env.task.flight_grade import GRID_START_M, GRID_STEP_M

        row = errors.row
        aero = _unchecked(MachVaryingAerodynamics, base=model.vehicle.aerodynamics, lift_p1=row.aero[0],
                          lift_p2=row.aero[1], drag_p1=row.aero[2], drag_p2=row.aero[3])  # fmt: skip
        atmosphere = _unchecked(ProfileAtmosphere, base=model.atmosphere, start=GRID_START_M, step=GRID_STEP_M,
                                log_factors=row.log_factors)  # fmt: skip
        wind = _unchecked(ProfileWind, start=GRID_START_M, step=GRID_STEP_M, east=row.wind_east, north=row.wind_north)
        return _replaced(model, vehicle=_replaced(model.vehicle, aerodynamics=aero), atmosphere=atmosphere, wind=wind)

    def _observe(self, key, episode: EpisodeState, c_ae, model, params: EnvParams, errors, elapsed):
        """The observation (clipped into the Box), whether it needed clipping, and the episode's errors
        (navigation errors advanced over ``elapsed``): what the sensors and navigation make of the truth."""
        seen_x, seen_forces, seen_c_ae = episode.x, episode.forces, c_ae
        if errors is not None:
            from rventry_env.envs.uncertainty import SensorErrors, sense

            row, f = errors.row, self.ns.float_dtype
            u = uniforms(key, 6, f, offset=64)
            noise = jnp.sqrt(-2.0 * jnp.log(u[:3])) * jnp.cos(2.0 * jnp.pi * u[3:]) * row.noise
            sensor = SensorErrors(tuple(row.bias), tuple(row.scale), tuple(row.misalignment), tuple(noise), row.senses,
                                  tuple(errors.dr), tuple(errors.dv))  # fmt: skip
            base = with_numeric_leaves(self.model, iter(params.model))  # the nominal model: what air data assume
            seen = sense(episode.x, episode.forces, c_ae, sensor.dr, sensor.dv, sensor, base, elapsed, self.ns)
            seen_x, seen_forces, seen_c_ae = seen.x, seen.features, seen.c_ae
            errors = errors._replace(dr=jnp.stack(seen.dr), dv=jnp.stack(seen.dv))
        seen_episode = episode._replace(x=seen_x, forces=seen_forces)
        raw = jnp.stack(observe_episode(seen_episode, seen_c_ae, model, self.prop, self.target)).astype(jnp.float32)
        clipped = jnp.any((raw < self.obs_low) | (raw > self.obs_high))
        return jnp.clip(raw, self.obs_low, self.obs_high), clipped, errors


def step_batch(env, keys, states, actions, params, resets: int):
    """One step of a batch of episodes of a gymnax environment, with an optimistic autoreset.

    gymnax's ``step`` computes a whole reset for every episode at every step and selects it where
    the episode ended; under ``vmap`` both branches always run, and on a GPU the reset is half
    of an ``RvEntry`` step's time. This steps every episode (``vmap`` of ``step_env``), draws only
    ``resets`` new starts (keys from the first episode's), and gives the k-th episode that ended
    the start number k modulo ``resets`` (Craftax's optimistic reset). Each start is a fresh draw
    of the environment's own reset, so the distribution of starts is the plain reset's; only when
    more than ``resets`` episodes end in one step do some of them share a start.

    :param keys: (N, 2) one key per episode; ``states``, ``actions``: the batch (N leading).
    :return: as a vmapped ``step``: observations, states, rewards, dones and infos, each (N, ...).
    """
    import jax

    n = actions.shape[0] if actions.ndim else 0
    if actions.shape != (n, 2) or keys.shape[:1] != (n,):
        raise ValueError(f"step_batch takes actions of shape (N, 2), one [alpha rate, bank rate] per episode, and N keys: "
                         f"got actions of shape {actions.shape} and keys of shape {keys.shape}")  # fmt: skip
    if isinstance(resets, bool) or not isinstance(resets, (int, np.integer)) or not 1 <= resets <= n:
        raise ValueError(f"resets must lie in [1, {n}] (the batch), got {resets}")
    obs_st, state_st, reward, done, info = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))(keys, states, actions, params)
    reset_keys = jax.random.split(jax.random.fold_in(keys[0], 0x5EED), resets)
    obs_re, state_re = jax.vmap(env.reset_env, in_axes=(0, None))(reset_keys, params)
    pick = (jnp.cumsum(done) - 1) % resets

    def select(fresh, stepped):
        mask = done.reshape(done.shape + (1,) * (stepped.ndim - 1))
        return jnp.where(mask, fresh[pick], stepped)

    return select(obs_re, obs_st), jax.tree.map(select, state_re, state_st), reward, done, info


ACTION_SHAPE = (2,)


def check_action(action):
    """One vehicle's action, checked where ``step_env`` is traced (shapes and dtypes are static under
    ``jit``): shape (2,), real numbers. Its values cannot be checked there: a NaN action ends the
    episode as a "non-finite state" failure, and values outside [-1, 1] are clipped and reported
    (``info["action_clipped"]``).

    :raises ValueError: naming the shape or dtype expected and the one given.
    """
    shape, dtype = jnp.shape(action), jnp.result_type(action)
    if shape != ACTION_SHAPE:
        batch = " (a batch of actions: jax.vmap the step, or step_batch)" if len(shape) == 2 and shape[-1] == 2 else ""
        raise ValueError(f"the action must have shape {ACTION_SHAPE} ([alpha rate, bank rate], each in [-1, 1]), got "
                         f"shape {shape}{batch}")  # fmt: skip
    if np.dtype(dtype).kind not in "biuf":
        raise ValueError(f"the action must be real numbers, got dtype {dtype}")
    return action


def _traced(tree) -> bool:
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(tree))


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0 (the flight-grade pool's seed), got {seed!r}")
    return int(seed)


def _check_like(name: str, value, ref) -> None:
    """``value`` has the pytree structure, shapes and kinds of number of ``ref`` (leaves: ShapeDtypeStruct)."""
    if ref is None:
        if value is not None:
            raise ValueError(f"{name} must be None for this environment, got {type(value).__name__}")
        return
    if isinstance(ref, tuple):
        if value is None or not isinstance(value, tuple) or len(value) != len(ref):
            what = f"a {type(ref).__name__} of {len(ref)}" if hasattr(ref, "_fields") else f"a tuple of {len(ref)} arrays"
            raise ValueError(f"{name} must be {what} (as make_params makes it), got {type(value).__name__}")
        parts = ref._fields if hasattr(ref, "_fields") else [f"[{i}]" for i in range(len(ref))]
        for part, v, r in zip(parts, value, ref):
            _check_like(f"{name}.{part}" if hasattr(ref, "_fields") else f"{name}{part}", v, r)
        return
    try:
        shape, kind = jnp.shape(value), np.dtype(jnp.result_type(value)).kind
    except TypeError:
        raise ValueError(f"{name} must be an array of shape {ref.shape}, got {type(value).__name__}") from None
    want = np.dtype(ref.dtype).kind
    if shape != ref.shape or (kind != want and not (want == "f" and kind in "iu")):
        kinds = {"f": "real numbers", "i": "integers", "b": "booleans"}
        raise ValueError(f"{name} must have shape {ref.shape} ({kinds.get(want, want)}), got shape {shape} of "
                         f"{jnp.result_type(value)}")  # fmt: skip


def _host_leaf(value: np.ndarray, template):
    """A params' leaf as the number or array of the model's own leaf (an int stays an int)."""
    if np.ndim(template) > 0:
        return value
    return int(value.item()) if isinstance(template, (int, np.integer)) else float(value.item())


def _rebuilt(obj):
    """``obj`` rebuilt by its parts' constructors, so that their checks run (and name the field)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return type(obj)(**{f.name: _rebuilt(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.init})
    return obj


def _check_start_params(sp: StartParams, radius: float, task) -> None:
    """Start-state params as a :class:`~rventry_env.task.starts.StartStates` would be checked."""
    from rventry_env.task.starts import PERTURBATIONS

    times, states = np.asarray(sp.times, np.float64), np.asarray(sp.states, np.float64)
    window = np.asarray(sp.window, np.float64)
    try:
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(window))):
            raise ValueError("times and window must be finite")
        end, span = times[-1], times[-1] - times[0]
        before = tuple(float(np.clip(end - w, 0.0, span)) if -1e-3 <= end - w <= span + 1e-3 else float(end - w)
                       for w in window[::-1])  # fmt: skip
        starts = StartStates(times, states, before, probability=float(sp.probability), far_weight=float(sp.far_weight),
                             step_weighted=bool(float(sp.step_weighted) > 0.5),
                             label="EnvParams.starts", **dict(zip(PERTURBATIONS, (float(v) for v in sp.half_widths))))  # fmt: skip
        common.check_starts(starts, radius, task)
    except ValueError as e:
        raise ValueError(f"EnvParams.starts: {e}") from None


def _flight_grade(dispersion: Dispersion) -> bool:
    return dispersion.flight is not None and not dispersion.flight.is_zero


def _unchecked(cls, **fields):
    """A frozen part built around traced values, without its constructor's checks (its structure is the
    checked one of a part the host built, or a profile the pool's draws filled)."""
    new = object.__new__(cls)
    for f in dataclasses.fields(cls):
        object.__setattr__(new, f.name, fields[f.name] if f.name in fields else f.default)
    return new


def _replaced(obj, **changes):
    """``obj`` with some fields replaced, without its constructor's checks (the values may be traced)."""
    return _unchecked(type(obj), **{**{f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}, **changes})


_GOLDEN32 = 0x9E3779B9


def _mix32(z):
    """A bijective 32-bit integer mixer (the "lowbias32" constants of C. Wellons' hash-prospector)."""
    z = z ^ (z >> 16)
    z = z * jnp.uint32(0x7FEB352D)
    z = z ^ (z >> 15)
    z = z * jnp.uint32(0x846CA68B)
    return z ^ (z >> 16)


def uniforms(key, k: int, dtype, offset: int = 0):
    """``k`` numbers uniform in (0, 1) from ``key``: two words of ``jax.random.bits``, each number
    the hash of them and its counter (``offset`` + 0 .. k-1; 53 bits for float64, 24 for float32)."""
    w = jax.random.bits(key, (2,), jnp.uint32)
    j = jnp.arange(offset, offset + k, dtype=jnp.uint32)
    hi = _mix32(w[0] ^ _mix32(w[1] + j * jnp.uint32(_GOLDEN32)))
    if dtype == jnp.float32:
        return ((hi >> 8).astype(dtype) + 0.5) * (1.0 / 16777216.0)
    lo = _mix32(hi ^ w[1])
    return ((hi >> 5).astype(dtype) * 67108864.0 + (lo >> 6).astype(dtype) + 0.5) * (1.0 / 9007199254740992.0)


def dispersion_draw(key, params: EnvParams, dtype):
    """The 10 dispersion numbers of one episode (the 9 of SCALAR_FIELDS, then the mass offset): uniform
    in +/- the half-widths, or clipped normals (Box-Muller) times the standard deviations."""
    k = params.dispersion.shape[0]
    u = uniforms(key, 2 * k, dtype)
    uniform = 2.0 * u[:k] - 1.0
    normal = jnp.sqrt(-2.0 * jnp.log(u[:k])) * jnp.cos(2.0 * jnp.pi * u[k:])
    normal = jnp.clip(normal, -params.clip_sigmas, params.clip_sigmas)
    return jnp.where(params.gaussian, normal, uniform) * params.dispersion


def with_mass_factor(model: EntryModel, factor) -> EntryModel:
    """The model with its vehicle's mass times ``factor`` (a traced value: built without the checks)."""
    return _replaced(model, vehicle=_replaced(model.vehicle, mass=model.vehicle.mass * factor))


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


__all__ = ["RvEntryFunctional", "EnvParams", "check_action", "ACTION_SHAPE", "EnvState", "ErrorPool", "EpisodeErrors", "StartParams", "DTYPES", "uniforms",
           "step_batch",
           "dispersion_draw", "with_mass_factor"]  # fmt: skip
