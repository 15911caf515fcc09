"""Pieces shared by the single and the vector environment: set-up, dispersion draws, info."""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np
from gymnasium import spaces

from rventry_env.envs.reward import RewardWeights
from rventry_env.task import Dispersion, EntryTask
from rventry_env.physics.entry import N_STATE
from rventry_env.physics.model import EntryModel


class EntryEnvSetup:
    """Construction shared by :class:`RvEntryEnv` and :class:`RvEntryVectorEnv`."""

    @property
    def feature_names(self) -> tuple[str, ...]:
        """The observation's feature names in index order (``obs[..., i]`` is ``feature_names[i]``;
        :func:`rventry_env.envs.observation.feature_index` gives an index by name)."""
        from rventry_env.envs.observation import feature_names

        return feature_names()

    def _configure(self, model, task, reward, dt, substeps, dispersion, render_mode, ns,
                   targets=None, starts=None, shaping=None) -> tuple[spaces.Box, spaces.Box]:  # fmt: skip
        """Validate and store the arguments; return the single-copy (observation, action) spaces."""
        from rventry_env.envs.observation import observation_box
        from rventry_env.envs.propagation import Propagator
        from rventry_env.envs.shaping import check_shaping

        self.model = make_model(model)
        self.task = make_task(task, dt, substeps, targets)
        self.reward = make_reward(reward)
        self.dispersion = Dispersion.parse(dispersion)
        self.task.check_dispersion(self.dispersion)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.dt = self.task.dt
        self._radius = self.model.planet.radius
        self._g0 = self.model.planet.g0
        # the episode's target, unit vector in E (per copy in the vector env with a footprint)
        self._nominal_target = tuple(float(c) for c in self.task.problem.target_unit_vector())
        self._target = self._nominal_target
        self._nominal = self.task.problem.initial_state(self.model.planet.radius)
        self._obs_low, self._obs_high = observation_box(self.task, self._radius)
        self._prop = Propagator(self.task, ns, self.reward)
        self.starts = check_starts(starts, self._radius, self.task)
        self.shaping = check_shaping(shaping)
        self._x = None
        return (
            spaces.Box(self._obs_low, self._obs_high, dtype=np.float32),
            spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32),
        )


    def _potential(self, x, c_ae, ns):
        """The shaping potential of the true states ``x`` (C_AE ``c_ae``); None without shaping."""
        if self.shaping is None:
            return None
        planet = self.model.planet
        return self.shaping.phi(x, c_ae, self._target, planet.mu, planet.radius, ns)


def _feature_major(columns, dtype) -> np.ndarray:
    """The arrays ``columns`` (each (n,)) as the rows of one (len(columns), n) array: contiguous writes."""
    rows = np.empty((len(columns), np.shape(columns[0])[0]), dtype=dtype)
    for i, c in enumerate(columns):
        rows[i] = c
    return rows


def stack_columns(columns, dtype=float) -> np.ndarray:
    """The arrays ``columns`` (each (n,)) as the columns of one C-ordered (n, len(columns)) array.

    Written row by row into the transposed layout, then transposed in one blocked copy:
    2.5x faster than ``np.stack(columns, axis=-1)`` at n = 8192, where the strided writes dominate.
    """
    return np.ascontiguousarray(_feature_major(columns, dtype).T)


def observation_batch(features, low: np.ndarray, high: np.ndarray):
    """A batch of observations from its feature arrays (each (n,)): (n, len(features)) float32,
    clipped into the Box, and which rows needed it (as :func:`clip_observation`).

    Bounds are checked on the feature-major layout, where each feature's test is contiguous
    (7x faster at n = 8192 than on the vehicle-major one), and transposed once at the end.
    """
    rows = _feature_major(features, np.float32)
    lo, hi = low[:, None], high[:, None]
    clipped = ((rows < lo) | (rows > hi)).any(axis=0)
    if clipped.any():
        rows = np.clip(rows, lo, hi)
    return np.ascontiguousarray(rows.T), clipped


def clip_observation(obs: np.ndarray, low: np.ndarray, high: np.ndarray):
    """Clip observations into the Box, and say which rows needed it (never silently)."""
    clipped = ((obs < low) | (obs > high)).any(axis=-1)
    if np.any(clipped):
        obs = np.clip(obs, low, high)
    return obs, clipped


def real_actions(actions, shape: tuple, what: str) -> np.ndarray:
    """Actions as float64 of ``shape``: real numbers only (a complex action is refused, not cut to its real part)."""
    raw = np.asarray(actions)
    if raw.dtype.kind not in "biuf":
        raise ValueError(f"{what} must be real numbers, got dtype {raw.dtype}: {raw.tolist()!r:.80}")
    a = raw.astype(np.float64)
    if a.shape != shape:
        layout = "[alpha rate, bank rate]" if len(shape) == 1 else "one [alpha rate, bank rate] per copy"
        raise ValueError(f"{what} must have shape {shape} ({layout}), got shape {a.shape}")
    return a


# the longest time limit: what the compiled steps' step counter (int32) holds, 2**31 - 1 control steps
MAX_STEPS_BOUND = 2**31 - 1


def check_max_steps(max_episode_steps, name: str = "max_episode_steps", optional: bool = True) -> int | None:
    """A time limit in control steps: an integer in [1, :data:`MAX_STEPS_BOUND`], or (``optional``) None for none."""
    if max_episode_steps is None and optional:
        return None
    if (isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer))
            or not 1 <= max_episode_steps <= MAX_STEPS_BOUND):  # fmt: skip
        none = " or None" if optional else " (this environment needs a time limit)"
        raise ValueError(f"{name} must be a positive integer <= {MAX_STEPS_BOUND} (what the step counter, int32, "
                         f"holds){none}, got {max_episode_steps!r}")  # fmt: skip
    return int(max_episode_steps)


# how far up the call stack reset() looks for the wrappers that called it (Monitor, TimeLimit,
# OrderEnforcing, PassiveEnvChecker and its helper, a vector env: about 8 frames)
_CALLER_DEPTH = 24


def outer_time_limit(env, own: int | None) -> int | None:
    """The time limit an episode of ``env`` ends at: its own, or a shorter one set outside it.

    ``gym.make(id, max_episode_steps=N)`` wraps the environment in Gymnasium's ``TimeLimit``
    and records N only in that wrapper's ``spec.max_episode_steps``: the environment itself is
    given a spec without it, and Gymnasium refuses extra wrappers outside ``TimeLimit`` for an id
    with a ``vector_entry_point``. Called from ``reset``, this finds the ``TimeLimit`` wrappers of
    ``env`` among the frames that called it (each wrapper's ``reset`` calls the one inside it)
    and reads their ``spec.max_episode_steps``, so that the environment truncates at the same
    step and closes the episode with its end keys itself.
    """
    from gymnasium.wrappers import TimeLimit

    limits = [] if own is None else [own]
    frame = sys._getframe(1)
    for _ in range(_CALLER_DEPTH):
        if frame is None:
            break
        caller = frame.f_locals.get("self")
        if isinstance(caller, TimeLimit) and caller.unwrapped is env:
            spec = caller.spec
            n = spec.max_episode_steps if spec is not None else None
            if n is not None:
                limits.append(int(n))
        frame = frame.f_back
    return min(limits) if limits else None


def check_seed(seed) -> int | None:
    """``reset(seed=...)`` of one episode: None, or an integer >= 0 (a NumPy integer too) as a Python int."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"reset(seed=...) must be an integer >= 0 or None, got {seed!r} ({type(seed).__name__})")
    return int(seed)


def copy_seeds(seed, n: int) -> list[int | None]:
    """``reset(seed=...)`` of a vector env as one seed per copy, by Gymnasium's rule for vector envs
    (:class:`gymnasium.vector.SyncVectorEnv`): None seeds none; an integer ``s`` (a NumPy integer
    too) seeds copy i with ``s + i``; a sequence gives each copy its own, an integer >= 0 or None."""
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
        first = check_seed(seed)
        return [first + i for i in range(n)]
    if isinstance(seed, (str, bytes, dict)) or not hasattr(seed, "__len__") or np.ndim(seed) != 1:
        raise ValueError(f"reset(seed=...) must be an integer >= 0, one seed per copy ({n}) or None, "
                         f"got {seed!r:.80} ({type(seed).__name__})")  # fmt: skip
    if len(seed) != n:
        raise ValueError(f"reset(seed=...) needs one seed per copy ({n}), got {len(seed)}")
    out = []
    for i, s in enumerate(seed):
        try:
            out.append(check_seed(s))
        except ValueError:
            raise ValueError(f"reset(seed=...): the seed of copy {i} must be an integer >= 0 or None, "
                             f"got {s!r} ({type(s).__name__})") from None  # fmt: skip
    return out


RESET_OPTIONS = ("dispersion", "state")


def reset_options(options) -> dict:
    """``reset(options=...)`` checked: None or a dict whose keys are among :data:`RESET_OPTIONS`."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(
            f"reset(options=...) must be a dict such as {{'state': x}} or {{'dispersion': 'standard'}}, "
            f"got {type(options).__name__} {options!r:.80}"
        )
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; known: {list(RESET_OPTIONS)}")
    return dict(options)


def make_task(task: EntryTask | None, dt: float | None, substeps: int | None, targets: str | None = None) -> EntryTask:
    task = EntryTask() if task is None else task
    if not isinstance(task, EntryTask):
        raise TypeError(f"task must be an EntryTask, got {type(task).__name__}")
    changes = {}
    if dt is not None:
        changes["dt"] = dt  # checked by EntryTask, which names it
    if substeps is not None:
        changes["substeps"] = substeps
    if targets is not None:
        changes["targets"] = targets
    return replace(task, **changes) if changes else task


def make_reward(reward: RewardWeights | None) -> RewardWeights:
    reward = RewardWeights() if reward is None else reward
    if not isinstance(reward, RewardWeights):
        raise TypeError(f"reward must be RewardWeights, got {type(reward).__name__}")
    return reward


def make_model(model: EntryModel | None) -> EntryModel:
    model = EntryModel() if model is None else model
    if not isinstance(model, EntryModel):
        raise TypeError(f"model must be an EntryModel built from rventry_env.physics parts, got {type(model).__name__}")
    return model


# the fastest start accepted: well beyond any entry (Earth's escape speed is 11.2 km/s), and far
# enough below overflow that every force and reward of the first steps stays finite
MAX_INITIAL_SPEED = 1e5


def check_state(state, radius: float, task: EntryTask) -> np.ndarray:
    """Validate a user-supplied initial state (12 components, state order of docs/conventions.md).

    Refused, naming the component: not 12 finite numbers, not above the surface or above the
    skip-out ceiling, a speed not in (0, 100 km/s], Euler parameters not of unit norm, alpha
    outside [0, alpha_max] (where the environment holds it).
    """
    try:
        x = np.asarray(state, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"an initial state must be {N_STATE} numbers, got {state!r:.200}") from None
    if x.shape != (N_STATE,):
        raise ValueError(f"an initial state must have shape ({N_STATE},): r, eA1..etaA, v, eB1..etaB, alpha, sigma; got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"the initial state contains NaN or inf: {x}")
    if x[0] <= radius:
        raise ValueError(f"the initial radius {x[0]:.1f} m is not above the surface ({radius:.1f} m)")
    if x[0] - radius > task.ceiling_altitude:
        raise ValueError(f"the initial altitude {x[0] - radius:.6g} m is above the skip-out ceiling "
                         f"({task.ceiling_altitude:g} m, EntryTask.ceiling_altitude)")  # fmt: skip
    if not 0 < x[5] <= MAX_INITIAL_SPEED:
        raise ValueError(f"the initial speed must lie in (0, {MAX_INITIAL_SPEED:g}] m/s, got {x[5]:.6g}")
    for name, q in (("eA", x[1:5]), ("eB", x[6:10])):
        with np.errstate(over="ignore"):
            n = np.linalg.norm(q)
        if not abs(n - 1) <= 1e-6:
            raise ValueError(f"the initial {name} Euler parameters must have unit norm, got norm {n:.9g}")
    alpha_max = task.problem.alpha_max
    if not 0 <= x[10] <= alpha_max:
        raise ValueError(f"the initial alpha must lie in [0, {math.degrees(alpha_max):g}] deg (alpha_max), "
                         f"got {x[10]:.6g} rad")  # fmt: skip
    return x


def check_starts(starts, radius: float, task: EntryTask):
    """A :class:`~rventry_env.task.StartStates` (or None) checked against the planet and the task: every
    state its window can pick, at the extremes of its perturbations, lies above the surface and below
    the skip-out ceiling, with alpha in [0, alpha_max] (the perturbation holds alpha there)."""
    from rventry_env.task.starts import StartStates

    if starts is None:
        return None
    if not isinstance(starts, StartStates):
        raise TypeError(f"starts must be a StartStates (rventry_env.task.starts) or None, got {type(starts).__name__}")
    lo, hi = starts.window_times()
    rows = starts.states[(starts.times >= lo - 1e-9) & (starts.times <= hi + 1e-9)]
    if rows.size == 0:
        raise ValueError(f"start states ({starts.label}): no table state lies in the window {starts.before_end_s} s before its end")
    h = rows[:, 0] - radius
    if h.min() - starts.altitude_m <= 0 or h.max() + starts.altitude_m > task.ceiling_altitude:
        raise ValueError(
            f"start states ({starts.label}): altitudes {h.min():.0f}-{h.max():.0f} m with the +/-{starts.altitude_m:g} m "
            f"perturbation must lie above the surface and below the skip-out ceiling ({task.ceiling_altitude:g} m)"
        )
    alpha = rows[:, 10]
    if alpha.min() < 0 or alpha.max() > task.problem.alpha_max:
        raise ValueError(f"start states ({starts.label}): alpha must lie in [0, alpha_max] in every state of the window")
    if rows[:, 5].min() - starts.speed_mps <= 0 or rows[:, 5].max() + starts.speed_mps > MAX_INITIAL_SPEED:
        raise ValueError(f"start states ({starts.label}): speeds with the +/-{starts.speed_mps:g} m/s perturbation must "
                         f"lie in (0, {MAX_INITIAL_SPEED:g}] m/s")  # fmt: skip
    return starts


# a start state lies this far inside each path bound (relative): the success test allows 1 % outside
START_MARGIN = 0.005
_SLOPE_STEP_M = 10.0


def within_path_bounds(x: tuple, model: EntryModel, task: EntryTask, ns, iterations: int = 2) -> tuple:
    """The start state components ``x`` moved in altitude where needed, so that the dynamic pressure lies
    :data:`START_MARGIN` inside q >= q_min and the load factor inside n <= n_max.

    A state taken from a trajectory that rides a path bound (the optimum rides q_min) and then
    perturbed can start outside it, and an episode that starts outside a bound has failed before
    its first decision. At a fixed speed and alpha both q and n scale with the density, so the
    altitude alone moves them: ``iterations`` Newton steps on ln q(h), its slope from a
    10 m difference of the model's own forces (any atmosphere, wind and aerodynamics). Floats,
    NumPy arrays or JAX values alike.
    """
    from rventry_env.physics.entry import entry_forces

    p, g0 = task.problem, model.planet.g0
    x = list(x)
    for _ in range(iterations):
        f = entry_forces(x, model, ns)
        q, n = f.dynamic_pressure, f.aero_accel / g0
        q_hi = q * p.a_max_g * (1.0 - START_MARGIN) / ns.fmax(n, 1e-12)  # where n meets its bound
        want = ns.fmax(ns.fmin(q, q_hi), p.q_min * (1.0 + START_MARGIN))  # q_min first where both bind
        up = entry_forces([x[0] + _SLOPE_STEP_M, *x[1:]], model, ns).dynamic_pressure
        slope = (ns.log(up) - ns.log(q)) / _SLOPE_STEP_M  # d ln q / dh < 0
        x[0] = x[0] + ns.log(want / q) / slope
    return tuple(x)


def position_velocity_e(c_ae, c_ba, r, v):
    """(r_E, v_E) components from cached DCMs: r a1 and v b1 in E (docs/conventions.md)."""
    a1 = c_ae[0]
    b1 = tuple(c_ba[0][0] * c_ae[0][j] + c_ba[0][1] * c_ae[1][j] + c_ba[0][2] * c_ae[2][j] for j in range(3))
    return tuple(r * a for a in a1), tuple(v * b for b in b1), a1


def flight_info(x, forces, c_ae, t, cost, radius: float, g0: float, ns) -> dict:
    """The per-step info values of the vector environments (3-vectors as tuples of components)."""
    r_e, v_e, a1 = position_velocity_e(c_ae, forces.c_ba, x[0], x[5])
    lat, lon = latitude_longitude(a1, ns)
    return {
        "r_ecef_m": r_e,
        "v_ecef_mps": v_e,
        "latitude_deg": lat * RAD2DEG,
        "longitude_deg": lon * RAD2DEG,
        "altitude_m": x[0] - radius,
        "speed_mps": x[5],
        "dynamic_pressure_pa": forces.dynamic_pressure,
        "load_factor_g": forces.aero_accel / g0,
        "sensed_accel_b": tuple(forces.aero_b),
        "cost": cost,
        "time_s": t,
    }


def latitude_longitude(a1, ns):
    """Geocentric latitude and longitude (rad) of the unit position a1 (E components)."""
    lat = ns.arctan2(a1[2], ns.sqrt(a1[0] * a1[0] + a1[1] * a1[1]))
    lon = ns.arctan2(a1[1], a1[0])
    return lat, lon


RAD2DEG = 180.0 / math.pi
