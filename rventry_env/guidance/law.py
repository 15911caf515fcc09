"""The guidance-law interface: what a law is given at each decision, and what it must provide.

A law decides for N vehicles at once. At every control step it is given one
:class:`Measurement` (what the vehicles measure: never the dispersion draw or the true
model) and returns N actions, the environment's rate fractions in [-1, 1]:

    actions = law(measurement)          # (N, 2) float32

Every law implements :class:`GuidanceLaw`; :class:`Law` gives the parts most laws do not need
(no per-episode memory, no statistics, any number of episodes per evaluation task), so a
law writes only what it has.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from rventry_env.physics.entry import N_STATE


@dataclass(frozen=True)
class Measurement:
    """What N vehicles measure at one decision.

    :param observation: the environment's observation (N, 26) float32, computed from the
        navigation state and the sensors (the observation table of ``RvEntry-v0``).
    :param time_s: time since each episode's start (N,) in s.
    :param navigation_state: the navigation system's state (N, 12), state order of
        docs/conventions.md: the truth where no navigation error is modelled.
    :param sensed_accel_b: the accelerometer: the sensed aerodynamic specific force (N, 3)
        in body-frame B components, m/s^2 (``info["sensed_accel_b"]``).
    :param flying: (N,) bool: False for the frozen copies of episodes that have ended, which a
        batched evaluation still calls until every episode has ended (their actions are not
        flown).
    :param target_e: the target each vehicle is told (N, 3), unit vectors in E components
        (``info["target_e"]``); None: the task's fixed target. A task with
        ``targets="footprint"`` draws one per episode; the observation's target features follow it.
    """

    observation: np.ndarray
    time_s: np.ndarray
    navigation_state: np.ndarray
    sensed_accel_b: np.ndarray
    flying: np.ndarray
    target_e: np.ndarray | None = None

    def __post_init__(self):
        obs = np.asarray(self.observation)
        n = obs.shape[0] if obs.ndim == 2 else -1
        shapes = {
            "observation": (obs.shape, obs.ndim == 2),
            "time_s": (np.shape(self.time_s), np.shape(self.time_s) == (n,)),
            "navigation_state": (np.shape(self.navigation_state), np.shape(self.navigation_state) == (n, N_STATE)),
            "sensed_accel_b": (np.shape(self.sensed_accel_b), np.shape(self.sensed_accel_b) == (n, 3)),
            "flying": (np.shape(self.flying), np.shape(self.flying) == (n,)),
        }
        if self.target_e is not None:
            shapes["target_e"] = (np.shape(self.target_e), np.shape(self.target_e) == (n, 3))
        bad = [f"{k} {s}" for k, (s, ok) in shapes.items() if not ok]
        if bad:
            raise ValueError(
                "a Measurement of N vehicles needs observation (N, 26), time_s (N,), navigation_state "
                f"(N, {N_STATE}), sensed_accel_b (N, 3), flying (N,) and target_e (N, 3) or None; "
                f"got {', '.join(bad)}"
            )

    @property
    def n(self) -> int:
        """The number of vehicles."""
        return int(np.shape(self.observation)[0])

    @classmethod
    def of(cls, observation, time_s, navigation_state, sensed_accel_b, flying=None) -> "Measurement":
        """A measurement from arrays, as float64 (float32 for the observation); every vehicle
        flying unless ``flying`` says otherwise."""
        obs = np.asarray(observation, dtype=np.float32)
        n = obs.shape[0] if obs.ndim == 2 else 0
        return cls(
            obs,
            np.asarray(time_s, dtype=float),
            np.asarray(navigation_state, dtype=float),
            np.asarray(sensed_accel_b, dtype=float),
            np.ones(n, bool) if flying is None else np.asarray(flying, dtype=bool),
        )

    @classmethod
    def single(cls, observation, info: dict, navigation_state) -> "Measurement":
        """One vehicle's measurement from a single ``RvEntry-v0`` step: its observation, its
        ``info`` (time and accelerometer) and its navigation state (``env.unwrapped.state``)."""
        return cls.of(np.asarray(observation)[None], [info["time_s"]], np.asarray(navigation_state)[None],
                      np.asarray(info["sensed_accel_b"])[None])  # fmt: skip


@runtime_checkable
class GuidanceLaw(Protocol):
    """A guidance law: N actions from one :class:`Measurement`.

    * ``reset(n_episodes)`` is called before the first decision of a batch of episodes: a law
      with per-episode memory (estimates, plans, counts) starts them again;
    * ``episode_stats()`` returns one dict per episode since the last reset, merged into the
      evaluation's records (``replans``, solve times, ...), or an empty list;
    * ``episodes_per_task``: how many episodes one parallel evaluation task should hold (None:
      as many as it is given; a law that takes seconds per episode says 1);
    * ``provenance``: where a learned law comes from (algorithm, starting point, steps, seed), written
      into evaluation reports; None for a law that is not trained;
    * ``retargets`` (optional, default False): whether the law flies the target it is told
      (:attr:`Measurement.target_e`, or the observation's target features). A law that plans
      to the task's fixed target says False, and evaluation refuses it on a footprint task
      instead of scoring it against targets it never aimed at.
    """

    episodes_per_task: int | None
    provenance: dict | None

    def reset(self, n_episodes: int) -> None: ...

    def __call__(self, measurement: Measurement) -> np.ndarray: ...

    def episode_stats(self) -> list[dict]: ...


class Law:
    """Defaults for :class:`GuidanceLaw`: no per-episode memory, no statistics, any batch size."""

    episodes_per_task: ClassVar[int | None] = None
    provenance: dict | None = None
    retargets: bool = False

    def reset(self, n_episodes: int) -> None:
        """No per-episode memory."""

    def episode_stats(self) -> list[dict]:
        """No per-episode statistics."""
        return []

    def __call__(self, measurement: Measurement) -> np.ndarray:
        raise NotImplementedError


def check_law(law) -> GuidanceLaw:
    """``law`` itself, if it implements :class:`GuidanceLaw`; else a TypeError naming what is missing."""
    missing = [name for name in ("reset", "episode_stats", "__call__") if not callable(getattr(law, name, None))]
    missing += [name for name in ("episodes_per_task", "provenance") if not hasattr(law, name)]
    if missing:
        raise TypeError(
            f"{type(law).__name__} is not a guidance law: it lacks {', '.join(missing)} "
            "(subclass rventry_env.guidance.law.Law for the defaults)"
        )
    return law


def check_retargets(law, task) -> None:
    """Refuse a law that flies a fixed target on a task that draws one per episode, naming both."""
    if task is not None and task.targets != "fixed" and not getattr(law, "retargets", False):
        raise ValueError(
            f"{type(law).__name__} cannot re-target: it flies the task's fixed target, and this task draws "
            f"a target per episode (targets={task.targets!r}); fly it with targets='fixed'"
        )


__all__ = ["Measurement", "GuidanceLaw", "Law", "check_law", "check_retargets"]
