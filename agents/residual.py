"""Residual guidance: the collocation reference as feedforward, a learned policy as feedback.

The shipped PPO baseline commands angles, not rates. Over the control step
[t, t + dt] it steers alpha and sigma to

    alpha_cmd = alpha_ref(t + dt) + alpha_authority * pi_0
    sigma_cmd = sigma_ref(t + dt) + sigma_authority * pi_1

with a deadbeat tracker, rate = clip((angle_cmd - angle) / dt, -rate limit,
+rate limit), which is the environment's action. Here

* alpha_ref, sigma_ref: the collocation reference (its states);
* pi = pi(o, o - o_ref(t)) in [-1, 1]^2: the learned policy, seeing its
  observation and its deviation from the reference's observation o_ref(t).

With pi = 0 and the vehicle on the reference this is exactly the open-loop
replay (:class:`~rventry_env.evaluation.policies.ReferencePolicy`): the rate is
the reference's step-mean rate. Why angles: a residual on the *rates* turns any
small bias of the network into an integrating drift (0.015 of the bank-rate
limit held for 1000 s is 450 deg of bank). Measured: after 1.5M PPO steps the
rate residual was still worse than no feedback at all (dispersed mean miss 275 km
vs 222 km, vertical error 64 vs 16 deg). An angle offset stays an offset.

Indexed by time, not energy: specific energy falls monotonically along the
reference and is the classical index for entry guidance, but on this skipping
trajectory an energy-indexed feedforward feeds dissipation errors back into the
bank schedule. Measured with pi = 0: nominal miss 43 km (time-indexed: 0.14 km),
dispersed mean miss 1024 km (time-indexed: 222 km).

Everything is computed from the observation alone (its time feature), so the
same code serves training (a VecEnv wrapper) and evaluation (a policy). The
final ``clip`` is part of the policy: the environment never sees an
out-of-range action from it.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnvWrapper

from rventry_env.core.backend import NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs.observation import TIME_SCALE, feature_index, observation_box, observe

_ALPHA, _SIN_SIGMA, _COS_SIGMA = feature_index("alpha"), feature_index("sin_sigma"), feature_index("cos_sigma")
# Deviations from the reference are a few hundredths of a feature's range; a fixed gain
# (not running normalization) brings them to order one and keeps "on the reference"
# at exactly zero input, which ZeroOnReferencePolicy relies on.
DEVIATION_GAIN = 10.0
from rventry_env.envs.task import EntryTask
from rventry_env.physics.entry import entry_forces
from rventry_env.physics.model import EntryModel


class ReferenceSchedule:
    """The reference's angles one step ahead and its observation features, tabulated against time.

    :param task: the task (its problem gives the rate limits and the target; its dt the step).
    :param model: the nominal model the reference was solved with.
    :param reference: a loaded reference (default :func:`rventry_env.reference.load_reference`).
    :param spacing: tabulation step (s).
    """

    def __init__(self, task: EntryTask | None = None, model: EntryModel | None = None, reference=None,
                 spacing: float = 0.05):  # fmt: skip
        if reference is None:
            from rventry_env.reference import load_reference

            reference = load_reference()
        self.task = EntryTask() if task is None else task
        self.model = EntryModel() if model is None else model
        p, dt = self.task.problem, self.task.dt
        t = np.arange(0.0, reference.tf + spacing, spacing)
        x = reference.state(np.minimum(t, reference.tf))
        x1 = reference.state(np.minimum(t + dt, reference.tf))
        planet = self.model.planet
        comps = tuple(x.T)
        forces = entry_forces(comps, self.model, NUMPY)
        target = tuple(float(c) for c in p.target_unit_vector())
        obs = observe(comps, forces, dcm(*comps[1:5]), t, self.task, target, planet.radius, planet.g0, NUMPY)
        self.t = t
        self.tf = float(reference.tf)
        self.angles_next = x1[:, 10:12].copy()  # where the reference's alpha, sigma are one step later
        self.obs = np.stack(obs, axis=-1).astype(np.float64)
        self.radius = planet.radius
        self._time_index = feature_index("time")

    def time_of(self, obs: np.ndarray) -> np.ndarray:
        """Time since the episode's start, from the observations' time feature."""
        return obs[:, self._time_index].astype(np.float64) * TIME_SCALE

    def lookup(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((alpha, sigma)_ref at t + dt (N, 2), o_ref(t) (N, 26)) at the times of ``obs``."""
        t = np.clip(self.time_of(obs), 0.0, self.t[-1])
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.t.size - 2)
        w = ((t - self.t[k]) / (self.t[k + 1] - self.t[k]))[:, None]
        target = (1 - w) * self.angles_next[k] + w * self.angles_next[k + 1]
        o = (1 - w) * self.obs[k] + w * self.obs[k + 1]
        return target, o

    def augment(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(augmented observation (N, 51) = [o, gain (o - o_ref) without time], target angles (N, 2)).

        The time deviation is zero by construction (the reference is read at the
        observation's own time); left in, normalization would blow its float32
        round-off up into a unit-variance noise input.
        """
        target, o_ref = self.lookup(obs)
        dev = DEVIATION_GAIN * np.delete(obs - o_ref, self._time_index, axis=1)
        return np.concatenate([obs, dev], axis=1).astype(np.float32), target

    def augmented_space(self) -> spaces.Box:
        low, high = observation_box(self.task, self.radius)
        dlow = DEVIATION_GAIN * np.delete(low - high, self._time_index)
        dhigh = DEVIATION_GAIN * np.delete(high - low, self._time_index)
        return spaces.Box(np.concatenate([low, dlow]), np.concatenate([high, dhigh]), dtype=np.float32)


def compose(obs: np.ndarray, target: np.ndarray, residual: np.ndarray, authority, task: EntryTask) -> np.ndarray:
    """The environment action that steers (alpha, sigma) to ``target + authority * residual`` in one step.

    :param obs: raw observations (N, 26): alpha and sigma are read from them.
    :param target: the reference's (alpha, sigma) at the end of the step (N, 2).
    :param residual: the policy's output (N, 2) in [-1, 1].
    :param authority: (alpha, sigma) offsets at residual = 1 (rad).
    :param task: rate limits and the control step.
    """
    p, dt = task.problem, task.dt
    alpha = 0.5 * (obs[:, _ALPHA].astype(np.float64) + 1.0) * p.alpha_max
    sigma = np.arctan2(obs[:, _SIN_SIGMA].astype(np.float64), obs[:, _COS_SIGMA].astype(np.float64))
    cmd = target + np.asarray(authority) * np.clip(np.asarray(residual, dtype=np.float64), -1.0, 1.0)
    d_alpha = cmd[:, 0] - alpha
    d_sigma = (cmd[:, 1] - sigma + np.pi) % (2 * np.pi) - np.pi  # the short way round
    a = np.column_stack([d_alpha / (dt * p.u_alpha_max), d_sigma / (dt * p.u_sigma_max)])
    return np.clip(a, -1.0, 1.0).astype(np.float32)


class ResidualVecEnv(VecEnvWrapper):
    """Presents the residual problem to the learner: augmented observations, residual actions.

    :param venv: a VecEnv of raw RvEntry-v0 observations (26 features).
    :param schedule: the time-indexed reference.
    :param authority: (alpha, sigma) offsets (rad) at a residual of 1.
    """

    def __init__(self, venv, schedule: ReferenceSchedule, authority):
        super().__init__(venv, observation_space=schedule.augmented_space(), action_space=venv.action_space)
        self.schedule, self.authority = schedule, np.asarray(authority, dtype=np.float64)
        self._obs = self._target = None

    def reset(self):
        self._obs = self.venv.reset()
        aug, self._target = self.schedule.augment(self._obs)
        return aug

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(compose(self._obs, self._target, actions, self.authority, self.schedule.task))

    def step_wait(self):
        obs, reward, dones, infos = self.venv.step_wait()
        self._obs = obs
        aug, self._target = self.schedule.augment(obs)
        for i in np.nonzero(dones)[0]:
            term = infos[i].get("terminal_observation")
            if term is not None:
                infos[i]["terminal_observation"] = self.schedule.augment(term[None])[0][0]
        return aug, reward, dones, infos


class ResidualPolicy:
    """A trained residual model as a :func:`rventry_env.evaluation.rollout` policy.

    :param predict: maps augmented observations to residuals (normalizing them as the model expects).
    :param schedule: the time-indexed reference.
    :param authority: (alpha, sigma) offsets (rad) at a residual of 1.
    """

    def __init__(self, predict, schedule: ReferenceSchedule, authority):
        self.predict, self.schedule = predict, schedule
        self.authority = np.asarray(authority, dtype=np.float64)

    def __call__(self, obs, time_s, state):
        obs = np.asarray(obs)
        aug, target = self.schedule.augment(obs)
        return compose(obs, target, self.predict(aug), self.authority, self.schedule.task)
