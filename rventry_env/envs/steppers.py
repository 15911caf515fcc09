"""Steppers: how :class:`~rventry_env.envs.vector.RvEntryVectorEnv` holds and steps its copies' episodes.

The vector env is one class. What it keeps itself is the Gymnasium face and the episode book-keeping
that no backend changes: the spaces, seeding and each copy's generator, the dispersion draws, the
flight-grade errors (:class:`~rventry_env.envs.uncertainty.VehicleErrors`), the targets, the action
checks, the autoreset modes, shaping, the infos and the end-of-episode keys, and the render tracks.
The episodes themselves (states, forces, clocks, accumulators) and the one control step of all copies
belong to a *stepper*, chosen by the env's ``backend``:

=========== ========================================= ===========================================
stepper      flies                                      chosen for
=========== ========================================= ===========================================
``arrays``   all copies at once on NumPy arrays         ``backend="numpy"``, more than
                                                        :data:`FLOAT_STEP_MAX_COPIES` copies
``floats``   each copy on Python floats, results        ``backend="numpy"``, up to
             stacked back into the arrays' layout       :data:`FLOAT_STEP_MAX_COPIES` copies whose
             (the same bits as ``arrays``)              model evaluates on floats
``jax``      all copies in one ``jax.jit`` call         ``backend="jax"``
             (:mod:`rventry_env.envs.jax_vector`)
=========== ========================================= ===========================================

Every stepper runs the same :func:`~rventry_env.envs.transition.advance` and sensing code, so each
flies the same episodes for the same seed. A feature a stepper cannot give is refused by the stepper,
with its name, when the env is built (``check_features``) or when the feature is asked for.

The interface (:class:`Stepper`), called by the env in this order:

* ``check_features(render_mode, targets)`` at construction: refuse what this stepper cannot fly;
* ``begin()`` at every ``reset``: forget the episodes (every copy is restarted next);
* ``restart(idx, x0, t0, started, errors, scales, target)``: new episodes for copies ``idx``;
* ``view(errors)`` after a restart: the observation and the flight info of the current episodes;
* ``advance(a, active, errors)``: one control step of the active copies, a :class:`Stepped`;
* ``state``, ``true_forces``, ``steps``, ``nav``, ``sensed`` and ``track()``, read between calls.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from rventry_env.core.backend import MATH, NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import common
from rventry_env.envs.observation import observe
from rventry_env.envs.propagation import IDLE, Propagator, StepOutcome
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.transition import EpisodeState, Transition, advance
from rventry_env.physics.entry import entry_forces
from rventry_env.physics.model import EntryModel, scaled_model
from rventry_env.task import EntryTask

# up to this many copies, each is stepped on Python floats: faster than arrays this short (1.6-2.3x for
# one copy, about even at 4 on the flight set), and the same bits
FLOAT_STEP_MAX_COPIES = 3


class StepSetup(NamedTuple):
    """What every stepper is built from: the env's configuration, fixed for its life."""

    num_envs: int
    task: EntryTask
    model: EntryModel  # the nominal model; each copy's draw scales or replaces it
    reward: RewardWeights
    max_episode_steps: int
    obs_low: np.ndarray
    obs_high: np.ndarray

    @property
    def radius(self) -> float:
        return self.model.planet.radius

    @property
    def g0(self) -> float:
        return self.model.planet.g0


class Stepped(NamedTuple):
    """What a stepper's step of all copies returns to :meth:`RvEntryVectorEnv.step` (NumPy arrays)."""

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    alpha_saturated: np.ndarray
    obs: np.ndarray
    obs_clipped: np.ndarray
    info: dict  # common.flight_info's values
    outcome: Any  # outcome.Outcome, or None where no episode ended
    info_max_load: np.ndarray
    info_min_q: np.ndarray


class Unsupported(ValueError, NotImplementedError):
    """A feature the env's stepper cannot give, refused with the stepper's name (a ``ValueError`` for a
    constructor's argument, a ``NotImplementedError`` for a property: either ``except`` catches it)."""


class Stepper:
    """The episodes of a vector env's copies and their step (see the module docstring).

    Between calls a stepper answers ``nav`` (the navigation states (N, 12), None where no copy's set
    has navigation errors) and ``sensed`` (the sensed specific force (N, 3), None likewise).
    """

    name = "stepper"

    def __init__(self, setup: StepSetup):
        self.setup = setup
        self.nav: np.ndarray | None = None
        self.sensed: np.ndarray | None = None

    def refuse(self, feature: str, hint: str = "") -> Unsupported:
        """The error for a feature this stepper cannot give (raise it)."""
        return Unsupported(f"the {self.name!r} stepper does not support {feature}" + (f": {hint}" if hint else ""))

    def check_features(self, render_mode: str | None, targets: str) -> None:
        """Refuse, at construction, what this stepper cannot fly (default: everything is flown)."""

    def begin(self) -> None:
        """A reset: every copy is restarted next."""

    def restart(self, idx: np.ndarray, x0: np.ndarray, t0: np.ndarray, started: np.ndarray, errors, scales: tuple,
                target: tuple) -> None:  # fmt: skip
        """Start new episodes for copies ``idx`` at states ``x0`` (len(idx), 12) and times ``t0``.

        :param started: which of them start from the start-state table (their radius is then put
            inside the path bounds with the copy's own model).
        :param errors: the copies' :class:`~rventry_env.envs.uncertainty.VehicleErrors`.
        :param scales: every copy's (density, lift, drag) factors, arrays (N,).
        :param target: the copies' target unit vectors in E (3 components, floats or arrays (N,)).
        """
        raise NotImplementedError

    def view(self, errors) -> tuple[np.ndarray, np.ndarray, dict]:
        """(observations (N, F) float32, which were clipped (N,), :func:`common.flight_info`'s values)
        of the current episodes, after a restart."""
        raise NotImplementedError

    def advance(self, a: np.ndarray, active: np.ndarray, errors) -> Stepped:
        """One control step of the ``active`` copies with actions ``a`` (N, 2), already within [-1, 1]."""
        raise NotImplementedError

    @property
    def state(self) -> np.ndarray:
        """States of all copies, float64, (N, 12) (a copy)."""
        raise NotImplementedError

    @property
    def true_forces(self):
        """The :class:`~rventry_env.physics.entry.EntryForces` at every copy's true state (arrays (N,))."""
        raise self.refuse("true_forces")

    @property
    def steps(self) -> np.ndarray:
        """Control steps each copy's episode has flown, int64 (N,)."""
        raise NotImplementedError

    def track(self) -> tuple:
        """(time (s), altitude (m), speed (m/s), latitude, longitude (rad)) of every copy, arrays (N,):
        the render's tracks."""
        raise self.refuse("render")


class ArrayStepper(Stepper):
    """All copies on NumPy arrays (12 component arrays of length N): one pass of array arithmetic per step."""

    name = "arrays"

    def __init__(self, setup: StepSetup):
        super().__init__(setup)
        self.prop = Propagator(setup.task, NUMPY, setup.reward)
        self.x = None
        self.target = None

    def begin(self) -> None:
        n = self.setup.num_envs
        self.x = tuple(np.empty(n) for _ in range(12))
        self.t = np.zeros(n)
        self._steps = np.zeros(n, dtype=np.int64)
        self.cost = np.zeros(n)
        self.max_load = np.zeros(n)
        self.min_q = np.zeros(n)

    def restart(self, idx, x0, t0, started, errors, scales, target) -> None:
        s = self.setup
        self.target = target
        density, lift, drag = scales
        if errors.any_model:
            self.model = errors.model(density, lift, drag)
        else:
            self.model = (
                s.model if np.all(density == 1) and np.all(lift == 1) and np.all(drag == 1)
                else scaled_model(s.model, density, lift, drag)
            )  # fmt: skip
        self._models_changed(errors, scales)
        for c in range(12):
            self.x[c][idx] = x0[:, c]
        if started.any():  # start states inside the path bounds, with each copy's own model
            rows = idx[started]
            self.x[0][rows] = common.within_path_bounds(self.x, self.model, s.task, NUMPY)[0][rows]
        self.forces = self.prop.forces(self.x, self.model)
        self.c_ae = dcm(*self.x[1:5])
        self.t[idx] = t0
        self._steps[idx] = 0
        self.cost[idx] = 0.0
        self.max_load[idx] = self.forces.aero_accel[idx] / s.g0  # forces/frames re-formed for all copies
        self.min_q[idx] = self.forces.dynamic_pressure[idx]

    def _models_changed(self, errors, scales) -> None:
        """Hook: the copies' models were drawn anew (``self.model``)."""

    def _measure(self, errors, elapsed=None, active=None) -> None:
        """What the vehicles' sensors and navigation make of the truth (the truth itself where
        no copy's set has sensor or navigation errors)."""
        if errors.any_sensing:
            nav, self.sensed, feats, nav_c_ae = errors.sense(self.x, self.forces, self.c_ae, self.setup.g0, elapsed,
                                                             active)  # fmt: skip
            self.nav = nav
            self._seen = (tuple(nav[:, j] for j in range(12)), feats, nav_c_ae)
        else:
            self.nav = None
            self.sensed = None
            self._seen = (self.x, self.forces, self.c_ae)

    def _observe(self):
        s = self.setup
        x, forces, c_ae = self._seen
        raw = observe(x, forces, c_ae, self.t, s.task, self.target, s.radius, s.g0, NUMPY)
        return common.observation_batch(raw, s.obs_low, s.obs_high)

    def _info_values(self) -> dict:
        s = self.setup
        return common.flight_info(self.x, self.forces, self.c_ae, self.t, self.cost, s.radius, s.g0, NUMPY)

    def view(self, errors):
        self._measure(errors)
        return (*self._observe(), self._info_values())

    def _transition(self, a: np.ndarray, active: np.ndarray) -> Transition:
        """The step of all copies as one :class:`~rventry_env.envs.transition.Transition` of arrays."""
        s = self.setup
        return advance(
            EpisodeState(self.x, self.forces, self.t, self._steps, self.cost, self.max_load, self.min_q),
            (a[:, 0], a[:, 1]), self.model, self.prop, s.max_episode_steps, self.target, active=active,
        )  # fmt: skip

    def advance(self, a, active, errors) -> Stepped:
        tr = self._transition(a, active)
        self.x, self.forces, self.t, self._steps, self.cost, self.max_load, self.min_q = tr.episode
        self.c_ae = tr.c_ae
        self._measure(errors, tr.out.elapsed, active)
        obs, obs_clipped = self._observe()
        return Stepped(tr.reward, tr.terminated, tr.truncated, tr.out.alpha_saturated, obs, obs_clipped,
                       self._info_values(), tr.outcome, self.max_load, self.min_q)  # fmt: skip

    @property
    def state(self) -> np.ndarray:
        return np.stack(self.x, axis=-1)

    @property
    def true_forces(self):
        return self.forces

    @property
    def steps(self) -> np.ndarray:
        return self._steps

    def track(self) -> tuple:
        lat, lon = common.latitude_longitude(self.c_ae[0], NUMPY)
        return self.t, self.x[0] - self.setup.radius, self.x[5], lat, lon


class FloatStepper(ArrayStepper):
    """A few copies, each stepped on Python floats (the ``MATH`` namespace), kept as the arrays' layout.

    The same code and the same floating-point operations as :class:`ArrayStepper`, so the same
    bits (``tests/envs/test_env.py`` compares the two over whole episodes of every set), without
    NumPy's per-call overhead: a few hundred operations on arrays of a few elements cost about
    1 us each, ten times their arithmetic. An evaluation flies a re-planning law's episodes one
    per task, so this is most of the environment's share of their time. A copy not stepped stays
    as it is, with what the array path reports for it. Only the propagation runs on floats;
    sensing, observation and infos are the array path's.
    """

    name = "floats"

    def __init__(self, setup: StepSetup):
        super().__init__(setup)
        self.float_prop = Propagator(setup.task, MATH, setup.reward)
        self.float_models: list[EntryModel] = []

    @staticmethod
    def flies(setup: StepSetup) -> bool:
        """Whether this stepper suits ``setup``: few copies, and a model whose every part evaluates
        on Python floats (a tabulated atmosphere, say, evaluates on arrays only)."""
        if setup.num_envs > FLOAT_STEP_MAX_COPIES:
            return False
        try:
            entry_forces(tuple(float(c) for c in setup.task.problem.initial_state(setup.radius)), setup.model, MATH)
        except TypeError:
            return False
        return True

    def _models_changed(self, errors, scales) -> None:
        self.float_models = [self._copy_model(i, errors, scales) for i in range(self.setup.num_envs)]

    def _copy_model(self, i: int, errors, scales) -> EntryModel:
        """Copy ``i``'s model as plain numbers: the batch model's row ``i``."""
        row = tuple(float(s[i]) for s in scales)
        if errors.any_model:
            return errors.model(*row, single=True, row=i)
        return self.setup.model if self.model is self.setup.model else scaled_model(self.setup.model, *row)

    def _transition(self, a: np.ndarray, active: np.ndarray) -> Transition:
        s = self.setup
        n = s.num_envs
        steps = []
        for i in range(n):
            at = lambda c: float(c[i])  # noqa: E731
            episode = EpisodeState(tuple(map(at, self.x)), _map_leaves(at, self.forces), at(self.t), int(self._steps[i]),
                            at(self.cost), at(self.max_load), at(self.min_q))  # fmt: skip
            if not active[i]:
                steps.append(_standing(episode))
                continue
            target = tuple(float(np.broadcast_to(c, (n,))[i]) for c in self.target)
            steps.append(advance(episode, (float(a[i, 0]), float(a[i, 1])), self.float_models[i], self.float_prop,
                                 s.max_episode_steps, target))  # fmt: skip
        if any(t.outcome is not None for t in steps):  # the array path's outcome holds every copy, read where one ended
            blank = _map_leaves(_blank, next(t.outcome for t in steps if t.outcome is not None))
            steps = [t if t.outcome is not None else t._replace(outcome=blank) for t in steps]
        return _map_leaves(_stack, *steps)


def numpy_stepper(setup: StepSetup) -> ArrayStepper:
    """``backend="numpy"``'s stepper for ``setup``: on floats where it suits, else on arrays."""
    return FloatStepper(setup) if FloatStepper.flies(setup) else ArrayStepper(setup)


def _map_leaves(fn, tree, *more):
    """``fn`` applied to every number of nested named tuples and tuples (leaf by leaf across
    ``tree`` and ``more`` of the same structure; None stays None)."""
    if tree is None:
        return None
    if isinstance(tree, tuple):
        items = [_map_leaves(fn, *parts) for parts in zip(tree, *more)]
        return type(tree)(*items) if hasattr(tree, "_fields") else tuple(items)
    return fn(tree, *more)


def _stack(*values) -> np.ndarray:
    """The copies' numbers of one quantity as the array path's array."""
    v = values[0]
    if isinstance(v, (bool, np.bool_)):
        return np.array(values, dtype=bool)
    if isinstance(v, str):
        return np.array(values, dtype=object)
    if isinstance(v, (int, np.integer)):
        return np.array(values, dtype=np.int64)
    return np.array(values, dtype=float)


def _blank(v):
    """The outcome's value for a copy that did not end (never read)."""
    return "" if isinstance(v, str) else type(v)(0)


def _standing(episode: EpisodeState) -> Transition:
    """A copy not stepped: as it is, no time, no reward, no ending (what the array path reports)."""
    zero = 0.0 * episode.t
    out = StepOutcome(episode.x, episode.forces, zero, IDLE, zero, zero, episode.max_load, episode.min_q, False)
    return Transition(episode, dcm(*episode.x[1:5]), out, -(zero + zero), False, False, None)


__all__ = ["FLOAT_STEP_MAX_COPIES", "ArrayStepper", "FloatStepper", "StepSetup", "Stepped", "Stepper",
           "Unsupported", "numpy_stepper"]  # fmt: skip
