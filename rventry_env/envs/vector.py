"""``RvEntryVectorEnv``: N copies of ``RvEntry-v0`` stepped in one array operation."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from rventry_env.core.backend import NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import MAX_EPISODE_STEPS, common
from rventry_env.envs.render import Track, render_tracks
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.shaping import PotentialShaping
from rventry_env.envs.steppers import FLOAT_STEP_MAX_COPIES, Stepped, Stepper, StepSetup, numpy_stepper
from rventry_env.envs.uncertainty import VehicleErrors
from rventry_env.task import Dispersion, EntryTask, apply_state_dispersion, draw_dispersion, draw_extras
from rventry_env.task.starts import StartStates
from rventry_env.physics.model import EntryModel

TERMINAL_KEYS = (
    "miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg", "max_load_factor_g",
    "min_dynamic_pressure_pa", "constraint_violation", "terminal_penalty", "failure", "is_success",
)  # fmt: skip
RENDER_COPIES = 16
BACKENDS = ("numpy", "jax")


class RvEntryVectorEnv(common.EntryEnvSetup, VectorEnv):
    """N independent copies of :class:`~rventry_env.envs.rv_entry.RvEntryEnv`, batched.

    The copies' flights and their step belong to a stepper (:mod:`rventry_env.envs.steppers`)
    chosen by ``backend``. With ``"numpy"``, every copy runs the single environment's
    propagation code on arrays (state layout: 12 component arrays of length N), so a step
    of all copies is one pass of array arithmetic with no Python loop over copies; up to
    ``FLOAT_STEP_MAX_COPIES`` copies are each propagated on Python floats instead, with
    the same bits and less overhead. With ``"jax"`` (the ``[jax]`` extra), the same step
    runs under ``jax.jit`` (:mod:`rventry_env.envs.jax_stepper`). The spaces, rewards,
    episode ends and info keys are those of the single environment, whatever the stepper.

    Seeding follows :class:`gymnasium.vector.SyncVectorEnv`: ``reset(seed=s)``
    (an integer >= 0, a NumPy integer too) seeds copy i with ``s + i``, a sequence of
    N seeds (integers or None) seeds each copy with its own, and each copy draws its
    dispersions from its own generator, so copy i reproduces a single ``RvEntry-v0``
    reset with seed ``s + i`` draw for draw. Anything else is refused naming the seed.

    Infos are dicts of arrays; the terminal keys (``miss_km`` ... ``is_success``)
    come with the usual ``_key`` masks marking the copies whose episode ended.

    :param num_envs: number of copies N.
    :param max_episode_steps: time limit in control steps (truncation).
    :param model: an :class:`~rventry_env.physics.EntryModel`.
    :param task: an :class:`~rventry_env.task.EntryTask`.
    :param dt: control step (s). :param substeps: RK4 substeps per control step.
    :param dispersion: see the single environment.
    :param render_mode: ``"rgb_array"``: one picture with the tracks of the first 16 copies.
    :param backend: ``"numpy"`` (default) or ``"jax"``: which stepper flies the copies.
    :param dtype: ``"float64"`` (default) or, with ``backend="jax"``, ``"float32"``.
    :param autoreset_mode: ``AutoresetMode.NEXT_STEP`` (Gymnasium's default: the step
        after an episode ends returns the reset observation, zero reward, and ignores
        the action) or ``AutoresetMode.SAME_STEP`` (the ending step already returns
        the reset observation; the final one is in ``infos["final_obs"]`` and the
        final info in ``infos["final_info"]``) or ``AutoresetMode.DISABLED`` (a copy whose
        episode ended stays frozen at its final state, is not stepped again and reports
        neither reward nor ending until the next ``reset``: what an evaluation of one
        episode per copy wants).

    A feature a stepper cannot give is refused by it, with its name: the ``jax`` stepper
    does not render, flies the fixed target only and keeps ``true_forces`` on the device.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int = MAX_EPISODE_STEPS,
        model: EntryModel | None = None,
        task: EntryTask | None = None,
        reward: RewardWeights | None = None,
        dt: float | None = None,
        substeps: int | None = None,
        dispersion: Dispersion | dict | str | None = None,
        render_mode: str | None = None,
        targets: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        starts: StartStates | None = None,
        shaping: PotentialShaping | None = None,
        backend: str = "numpy",
        dtype: str = "float64",
    ):
        if int(num_envs) != num_envs or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs}")
        autoreset_mode = AutoresetMode(autoreset_mode)
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED):
            raise ValueError(f"autoreset_mode must be NEXT_STEP, SAME_STEP or DISABLED, got {autoreset_mode}")
        self.metadata = {**self.metadata, "autoreset_mode": autoreset_mode}
        self.num_envs = int(num_envs)
        self.max_episode_steps = common.check_max_steps(max_episode_steps)
        self.single_observation_space, self.single_action_space = self._configure(
            model, task, reward, dt, substeps, dispersion, render_mode, NUMPY, targets, starts, shaping
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._rngs: list[np.random.Generator] | None = None
        setup = StepSetup(self.num_envs, self.task, self.model, self.reward, self.max_episode_steps, self._obs_low,
                          self._obs_high)  # fmt: skip
        self.stepper = _stepper(backend, dtype, setup)
        self.stepper.check_features(render_mode, self.task.targets)
        self.backend = backend
        self._started = False

    # ------------------------------------------------------------------ state
    @property
    def state(self) -> np.ndarray:
        """States of all copies, float64, shape (N, 12), state order of docs/conventions.md (a copy)."""
        if not self._started:
            raise RuntimeError("the environment has no state before reset()")
        return self.stepper.state

    @property
    def episode_steps(self) -> np.ndarray:
        """Control steps each copy's current episode has flown, int64 (N,)."""
        if not self._started:
            raise RuntimeError("the environment has no state before reset()")
        return self.stepper.steps

    @property
    def true_forces(self):
        """The :class:`~rventry_env.physics.entry.EntryForces` at every copy's true state, with the
        copy's own draw (its atmosphere, winds, aerodynamics and mass), after the latest reset or
        step: arrays (N,). For training-time critics and diagnostics: a guidance law never sees them.
        """
        if not self._started:
            raise RuntimeError("the environment has no state before reset()")
        return self.stepper.true_forces

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        n = self.num_envs
        seeds = common.copy_seeds(seed, n)
        if seed is None:
            if self._rngs is None:
                self._rngs = [seeding.np_random(None)[0] for _ in range(n)]
        else:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        super().reset(seed=seeds[0] if isinstance(seed, (int, np.integer)) else None)
        options = common.reset_options(options)
        # one-off, as in the single env: the episodes started by this reset draw from it,
        # later autoresets from the constructor's dispersion again
        dispersion = Dispersion.parse(options["dispersion"]) if "dispersion" in options else self.dispersion
        self.task.check_dispersion(dispersion)
        if "state" in options:
            try:
                states = np.asarray(options["state"], dtype=float)
            except (TypeError, ValueError):
                states = np.empty(0)
            if not (states.ndim == 1 or (states.ndim == 2 and states.shape[0] == n)):
                raise ValueError(
                    f"options['state'] must be one state (12,) or one per copy ({n}, 12), "
                    f"got {options['state'] if states.size == 0 else states.shape!r}"
                )
            states = np.broadcast_to(states, (n, states.shape[-1])) if states.ndim == 1 else states
            self._initial = np.stack([common.check_state(s, self._radius, self.task) for s in states])
            self._explicit = True
        else:
            self._explicit = False
            self._initial = np.broadcast_to(self._nominal, (n, self._nominal.size))
        self._density = np.ones(n)
        self._lift = np.ones(n)
        self._drag = np.ones(n)
        self._started = True  # the stepper holds the flights
        self.stepper.begin()
        self._prev_done = np.zeros(n, dtype=bool)
        self._frozen = np.zeros(n, dtype=bool)  # DISABLED: copies whose episode ended
        self._phi = np.zeros(n)  # with shaping: each copy's potential
        self.dispersion_draw = np.zeros((n, 9))
        self._targets = np.tile(self._nominal_target, (n, 1))  # each copy's target, unit vector in E
        self._errors = VehicleErrors(n, self.model)
        self._tracks = [Track() for _ in range(min(n, RENDER_COPIES))] if self.render_mode else None
        extras = self._reset_copies(np.arange(n), dispersion)
        obs, clipped, values = self.stepper.view(self._errors)
        if self.shaping is not None:
            self._phi = self._potential_now()
        info = self._info_dict(values, np.zeros(n, bool), np.zeros(n, bool), clipped)
        # the draws, for evaluation only: a guidance law is never given them
        info["dispersion_draw"] = self._errors.draw_info(self.dispersion_draw, extras)
        return obs, info

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = common.real_actions(actions, (self.num_envs, 2), "actions")
        mode = self.metadata["autoreset_mode"]
        next_step = mode == AutoresetMode.NEXT_STEP
        restart = self._prev_done if next_step else np.zeros(self.num_envs, bool)
        ignored = restart | self._frozen  # their actions are not flown, so not checked either
        finite = np.isfinite(a).all(axis=1)
        if not np.all(finite | ignored):
            bad = np.nonzero(~finite & ~ignored)[0]
            raise ValueError(f"actions contain NaN or inf (copies {bad[:10].tolist()})")
        a = np.where(finite[:, None], a, 0.0)
        action_clipped = np.any((a < -1.0) | (a > 1.0), axis=1)
        a = np.clip(a, -1.0, 1.0)
        if np.any(restart):  # NEXT_STEP: these copies start over and ignore their action
            self._reset_copies(np.nonzero(restart)[0])
        restart = restart | self._frozen  # copies not stepped this time
        st: Stepped = self.stepper.advance(a, ~restart, self._errors)
        terminated, truncated, obs = st.terminated, st.truncated, st.obs
        ended = terminated | truncated
        infos = self._info_dict(st.info, action_clipped & ~restart, st.alpha_saturated & ~restart, st.obs_clipped)
        reward = st.reward
        if self.shaping is not None:
            phi = self._potential_now()
            stepped = ~restart
            reward = reward + np.where(stepped, self.shaping.reward(self._phi, phi, terminated, NUMPY), 0.0)
            self._phi = phi  # a copy restarted this step is at its new start
        if st.outcome is not None:
            self._finish(infos, st.outcome, ended, st.info_max_load, st.info_min_q)
        self._record()
        if next_step:
            self._prev_done = ended
        elif mode == AutoresetMode.DISABLED:
            self._frozen |= ended
        elif np.any(ended):  # SAME_STEP: report the final step, then start over at once
            idx = np.nonzero(ended)[0]
            infos["final_obs"] = obs.copy()
            infos["_final_obs"] = ended.copy()
            infos["final_info"] = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in infos.items()}
            infos["_final_info"] = ended.copy()
            self._reset_copies(idx)
            obs_r, _, _ = self.stepper.view(self._errors)
            if self.shaping is not None:
                self._phi[idx] = self._potential_now()[idx]
            obs[idx] = obs_r[idx]
        return obs, reward.astype(np.float64), terminated, truncated, infos

    def render(self):
        if self.render_mode is None:
            return None
        if not self._started:
            raise RuntimeError("call reset() before render()")
        p = self.task.problem
        return (render_tracks(self._tracks, p.target_latitude, p.target_longitude, "RvEntry-v0 (vector)"),)

    # ------------------------------------------------------------------ helpers
    def _reset_copies(self, idx: np.ndarray, dispersion: Dispersion | None = None) -> list:
        """Draw and apply the start of a new episode for copies ``idx`` (each from its own generator);
        return their flight-grade draws (None each for a set without them).

        :param dispersion: this reset's dispersion (default: the constructor's).
        """
        x0, t0, started, extras = self._draw(idx, dispersion)
        self.stepper.restart(idx, x0, t0, started, self._errors, (self._density, self._lift, self._drag), self._target)
        if self._tracks is not None:
            for i in idx:
                if i < len(self._tracks):
                    self._tracks[i] = Track()
            self._record(only=[i for i in idx if i < len(self._tracks)])
        return extras

    def _potential_now(self) -> np.ndarray:
        """Every copy's shaping potential at its true state now."""
        x = tuple(self.state.T)
        return np.broadcast_to(self._potential(x, dcm(*x[1:5]), NUMPY), (self.num_envs,))

    def _draw(self, idx: np.ndarray, dispersion: Dispersion | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
        """Draw new episodes for copies ``idx`` from their generators: their initial states (len(idx), 12),
        start times (len(idx),), which started from the start states (len(idx),) and flight-grade draws
        (None each for a set without them); the density, lift and drag factors go to ``_density``,
        ``_lift``, ``_drag``, the flight-grade parts to ``_errors``."""
        dispersion = self.dispersion if dispersion is None else dispersion
        d = np.empty((len(idx), 9))
        extras, starts = [], []
        draw_start = self.starts is not None and not self._explicit
        for j, i in enumerate(idx):  # each copy's draws in the single env's order
            d[j] = draw_dispersion(self._rngs[i], dispersion)
            extras.append(draw_extras(self._rngs[i], dispersion, self.task.problem))
            target = self.task.draw_target(self._rngs[i], self._radius)
            if target is not None:
                self._targets[i] = target
            starts.append(self.starts.draw(self._rngs[i], self.task.problem.alpha_max) if draw_start else None)
            self._errors.assign(i, dispersion, extras[-1])
        if self.task.targets != "fixed":
            self._target = tuple(self._targets[:, k].copy() for k in range(3))
        x0 = self._initial[idx]
        if not dispersion.is_zero:
            x0 = apply_state_dispersion(x0, d)
        t0 = np.zeros(len(idx))
        started = np.array([s is not None for s in starts], dtype=bool)
        if started.any():  # a start state: the table's perturbation replaces the initial state's
            x0 = np.array(x0, dtype=float)
            for j in np.nonzero(started)[0]:
                t0[j], x0[j] = starts[j]
        self.dispersion_draw[idx] = d
        self._density[idx] = 1 + d[:, 0]
        self._lift[idx] = 1 + d[:, 1]
        self._drag[idx] = 1 + d[:, 2]
        return x0, t0, started, extras

    def _info_dict(self, values: dict, action_clipped, alpha_saturated, obs_clipped) -> dict:
        """The step's info from :func:`common.flight_info`'s values (3-vectors as 3 component arrays)."""
        n = self.num_envs
        infos = {
            k: (common.stack_columns(np.broadcast_arrays(*v), float) if isinstance(v, tuple) else np.array(v, dtype=float))
            for k, v in values.items()
        }  # fmt: skip
        infos["action_clipped"] = np.asarray(action_clipped, bool)
        infos["alpha_saturated"] = np.broadcast_to(np.asarray(alpha_saturated, bool), (n,)).copy()
        infos["observation_clipped"] = np.asarray(obs_clipped, bool)
        sensed, nav = self.stepper.sensed, self.stepper.nav
        if sensed is not None:
            infos["sensed_accel_b"] = sensed.copy()
        infos["navigation_state"] = self.state if nav is None else nav.copy()
        infos["target_e"] = self._targets.copy()
        for k in TERMINAL_KEYS:
            infos[k] = np.full(n, "", dtype=object) if k == "failure" else np.zeros(n, dtype=float)
            infos["_" + k] = np.zeros(n, dtype=bool)
        infos["constraint_violation"] = np.zeros(n, dtype=bool)
        infos["is_success"] = np.zeros(n, dtype=bool)
        return infos

    def _finish(self, infos: dict, o, ended, max_load, min_q) -> None:
        """Fill the end-of-episode keys for copies whose episode ended, from their outcome ``o``."""
        values = {
            **o.metrics._asdict(), "max_load_factor_g": max_load, "min_dynamic_pressure_pa": min_q,
            "constraint_violation": o.constraint_violation, "terminal_penalty": o.terminal_penalty,
            "failure": o.failure, "is_success": o.is_success,
        }  # fmt: skip
        for k, v in values.items():
            infos[k] = np.where(ended, v, infos[k])
            infos["_" + k] = ended.copy()

    def _record(self, only=None):
        if self._tracks is None:
            return
        t, altitude, speed, lat, lon = self.stepper.track()
        for i in range(len(self._tracks)) if only is None else only:
            self._tracks[i].append(t[i], altitude[i], speed[i], lat[i], lon[i])


def _stepper(backend: str, dtype: str, setup: StepSetup) -> Stepper:
    """The stepper ``backend`` flies ``setup``'s copies with."""
    if backend == "numpy":
        if dtype != "float64":
            raise ValueError(f"backend='numpy' computes in float64; dtype={dtype!r} needs backend='jax'")
        return numpy_stepper(setup)
    if backend == "jax":
        from rventry_env.envs.jax_stepper import JaxStepper

        return JaxStepper(setup, dtype)
    raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")


def RvEntryJaxVectorEnv(num_envs: int = 1, dtype: str = "float64", **kwargs) -> RvEntryVectorEnv:
    """The vector env with the JAX stepper: ``RvEntryVectorEnv(num_envs, backend="jax", dtype=dtype, ...)``."""
    return RvEntryVectorEnv(num_envs, backend="jax", dtype=dtype, **kwargs)


__all__ = ["RvEntryVectorEnv", "RvEntryJaxVectorEnv", "Stepped", "TERMINAL_KEYS", "FLOAT_STEP_MAX_COPIES"]
