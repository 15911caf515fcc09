"""How a stable-baselines3 policy meets the task: its mode, as an object that builds, trains,
ships and flies itself.

* :class:`DirectMode`: the model's action is the environment's (the rates); any algorithm.
* :class:`ResidualMode`: the model offsets the angles TV-LQR flies around the guidance reference,
  by up to its authority (:mod:`rventry_agents.residual`); PPO, with an actor whose mean is zero on
  the reference (:mod:`rventry_agents.zero_policy`).
* :class:`StudentMode`: the model's actor starts as an imitation student and commands angles in
  the student's terms, which the student's tracker and limiters fly (:mod:`rventry_agents.finetune`).

A training run builds its mode from the config's ``[policy]`` section
(:meth:`rventry_agents.sb3_config.PolicySection.build`) and writes :meth:`PolicyMode.record` to
``policy.json``; a saved model is flown by the mode :meth:`PolicyMode.of_record` reads back from it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from rventry_agents.config import ALGORITHMS
from rventry_agents.records import FineTunedSpec, PolicyRecord
from rventry_env.guidance.law import Law, Measurement
from rventry_env.task import EntryTask

DATA = Path(__file__).resolve().parent / "data"
SHIPPED_PPO_RESIDUAL = DATA / "ppo_residual"  # the PPO residual on TV-LQR (agent ppo-residual)
SHIPPED_PPO_FINETUNE = DATA / "ppo_finetune"  # PPO fine-tuning of the flight-set student (agent ppo)
SHIPPED_BASELINES = DATA / "baselines"  # the plain baselines, one folder per algorithm


class Predictor:
    """``predict(observations) -> actions`` of a model, deterministic, on normalized observations.

    A recurrent model (sb3-contrib ``RecurrentPPO``) carries its LSTM state from call to call,
    one per vehicle; :meth:`reset` starts new episodes.
    """

    def __init__(self, model, normalize=None):
        self.model, self.normalize = model, normalize
        self.recurrent = hasattr(model.policy, "lstm_actor")
        self.reset(0)

    def reset(self, n_episodes: int) -> None:
        self.lstm_state, self.starts = None, np.ones(int(n_episodes), bool)

    def __call__(self, obs):
        obs = obs if self.normalize is None else self.normalize(obs)
        if not self.recurrent:
            return self.model.predict(obs, deterministic=True)[0]
        if len(self.starts) != len(obs):
            self.reset(len(obs))
        actions, self.lstm_state = self.model.predict(obs, state=self.lstm_state, episode_start=self.starts,
                                                      deterministic=True)  # fmt: skip
        self.starts = np.zeros(len(obs), bool)
        return actions


class DirectLaw(Law):
    """A direct policy: the model's action is the environment's (it aims where the observation's
    target features point, so it flies any target it is told)."""

    retargets = True

    def __init__(self, predict):
        self.predict = predict

    def reset(self, n_episodes: int) -> None:
        if hasattr(self.predict, "reset"):
            self.predict.reset(n_episodes)

    def __call__(self, m: Measurement) -> np.ndarray:
        return self.predict(m.observation)


class PolicyMode:
    """A policy's mode: what the model's actions mean, and so how it is built, trained, shipped and flown."""

    name: ClassVar[str]
    origin: ClassVar[str]  # what training starts from, for a run's provenance

    # -- build
    def wrap_env(self, venv, task: EntryTask):
        """The training VecEnv as the model sees it (``venv``: an
        :class:`~rventry_agents.sb3_vec.RvEntrySB3VecEnv`)."""
        return venv

    def network(self, algorithm: str, kwargs: dict) -> tuple[object, dict]:
        """The policy class (or SB3's name of one) and its keyword arguments, from the config's."""
        return ("MlpLstmPolicy" if algorithm == "recurrent_ppo" else "MlpPolicy"), kwargs

    # -- train
    def start(self, model, timesteps: int) -> int:
        """Set a new model's starting weights; returns the steps the critic learns alone first."""
        return 0

    def provenance(self, warmup: int, timesteps: int, selected_at: int) -> dict | None:
        """What a run's metadata says the policy came from (None: the algorithm, seed and steps say it)."""
        return None

    # -- ship
    def record(self) -> dict:
        """``policy.json``'s keys for this mode (the run adds its algorithm)."""
        return {"mode": self.name, "authority_rad": [0.0, 0.0]}

    def destination(self, algorithm: str | None) -> Path:
        """Where ``rventry train ship`` puts a run of this mode unless told otherwise."""
        raise NotImplementedError

    # -- fly
    def law(self, model, normalize, task: EntryTask) -> Law:
        """The model as a guidance law; ``normalize`` maps raw observations to the model's."""
        raise NotImplementedError

    @property
    def q_floor_margin(self) -> float | None:
        """The q floor the policy flies (None: none)."""
        return None

    def with_q_floor(self, margin: float | None) -> PolicyMode:
        raise ValueError(f"a q floor belongs to a policy fine-tuned from a student, not to a {self.name!r} one")

    @classmethod
    def from_record(cls, record: PolicyRecord) -> PolicyMode:
        """This mode as a saved run's ``policy.json`` describes it."""
        return cls()

    @staticmethod
    def of_record(record: PolicyRecord) -> PolicyMode:
        """The mode a saved run's ``policy.json`` describes."""
        modes = {m.name: m for m in (DirectMode, ResidualMode, StudentMode)}
        return modes[record.mode].from_record(record)


@dataclass(frozen=True)
class DirectMode(PolicyMode):
    """The model's action is the environment's: a plain-RL policy from scratch."""

    name: ClassVar[str] = "direct"
    origin: ClassVar[str] = "scratch"

    def destination(self, algorithm: str | None) -> Path:
        if algorithm not in ALGORITHMS:  # the baselines' folders are named by algorithm
            raise ValueError(f"no shipped place for mode 'direct', algorithm {algorithm!r}; give --dest")
        return SHIPPED_BASELINES / algorithm

    def law(self, model, normalize, task: EntryTask) -> Law:
        return DirectLaw(Predictor(model, normalize))


@dataclass(frozen=True)
class ResidualMode(PolicyMode):
    """The model offsets TV-LQR's angles by up to ``authority_rad`` (alpha, sigma) per step.

    :param zero_init: start the action head at zero, so that the untrained policy flies TV-LQR.
    """

    authority_rad: tuple[float, float]
    zero_init: bool = False
    name: ClassVar[str] = "residual"
    origin: ClassVar[str] = "TV-LQR, residual"

    def wrap_env(self, venv, task: EntryTask):
        from rventry_agents.residual import ResidualGuidance, ResidualVecEnv

        return ResidualVecEnv(venv, ResidualGuidance(list(self.authority_rad), task))

    def network(self, algorithm: str, kwargs: dict) -> tuple[object, dict]:
        from rventry_agents.zero_policy import ZeroOnReferencePolicy
        from rventry_env.envs.observation import feature_index

        return ZeroOnReferencePolicy, {**kwargs, "n_raw_features": feature_index("load_factor") + 1}  # raw features first

    def start(self, model, timesteps: int) -> int:
        if self.zero_init:  # start exactly on the reference: a residual of 0.02 alone moves the impact by ~265 km
            import torch

            with torch.no_grad():
                model.policy.action_net.weight.zero_()
                model.policy.action_net.bias.zero_()
        return 0

    @classmethod
    def from_record(cls, record: PolicyRecord) -> ResidualMode:
        return cls(authority_rad=record.authority_rad)

    def record(self) -> dict:
        return {"mode": self.name, "authority_rad": list(self.authority_rad)}

    def destination(self, algorithm: str | None) -> Path:
        return SHIPPED_PPO_RESIDUAL

    def law(self, model, normalize, task: EntryTask) -> Law:
        from rventry_agents.residual import ResidualGuidance, ResidualPolicy

        return ResidualPolicy(Predictor(model, normalize), ResidualGuidance(list(self.authority_rad), task))


@dataclass(frozen=True)
class StudentMode(PolicyMode):
    """The actor starts as an imitation student and flies in its terms (:mod:`rventry_agents.finetune`).

    :param spec: the student and how the actor flies (``policy.json``'s ``student``).
    :param student: in training, the student's law (:func:`~rventry_agents.finetune.load_start`).
    :param privileged: the critic also sees the draw (:class:`~rventry_agents.finetune.PrivilegedCriticPolicy`).
    :param warmup_steps: the steps the critic learns alone, the actor frozen, before the actor moves.
    :param critic_widths: the critic's layer widths (None: the student's).
    """

    spec: FineTunedSpec
    student: object = None
    privileged: bool = False
    warmup_steps: int = 0
    critic_widths: tuple[int, ...] | None = None
    name: ClassVar[str] = "student"
    origin: ClassVar[str] = "student"

    @classmethod
    def from_record(cls, record: PolicyRecord) -> StudentMode:
        return cls(spec=record.student)

    @property
    def q_floor_margin(self) -> float | None:
        return self.spec.q_floor_margin

    def _scales(self):
        from rventry_agents.finetune import StudentScales

        return StudentScales(**self.spec.scales.to_dict())

    def _training(self):
        if self.student is None:
            raise ValueError("a student-mode policy read from a saved run flies; build one from its config to train it")
        return self.student

    def wrap_env(self, venv, task: EntryTask):
        from rventry_agents.finetune import StudentVecEnv

        return StudentVecEnv(venv, self._training(), self._scales(), privileged=self.privileged)

    def network(self, algorithm: str, kwargs: dict) -> tuple[object, dict]:
        import torch

        hidden = list(self._training().network.hidden)
        kwargs = {**kwargs, "net_arch": {"pi": hidden, "vf": list(self.critic_widths or hidden)},
                  "activation_fn": torch.nn.Tanh}  # the student's  # fmt: skip
        if not self.privileged:
            return "MlpPolicy", kwargs
        from rventry_agents.finetune import PrivilegedCriticPolicy

        # the actor sees the student's inputs, the critic the draw too
        return PrivilegedCriticPolicy, {**kwargs, "n_actor_inputs": len(self.spec.scales.mean)}

    def start(self, model, timesteps: int) -> int:
        from rventry_agents.finetune import init_actor_from_student

        init_actor_from_student(model.policy, self._training().network)  # step 0 flies exactly the student
        return min(self.warmup_steps, timesteps)

    def provenance(self, warmup: int, timesteps: int, selected_at: int) -> dict | None:
        return {"algorithm": "PPO (stable-baselines3)", "start": self.spec.start, "start_sha256": self.spec.start_sha256,
                "critic_warmup_steps": warmup, "timesteps": timesteps, "selected_at_timesteps": selected_at}  # fmt: skip

    def record(self) -> dict:
        return {**super().record(), "student": self.spec.to_dict()}

    def destination(self, algorithm: str | None) -> Path:
        return SHIPPED_PPO_FINETUNE

    def law(self, model, normalize, task: EntryTask) -> Law:
        from rventry_agents.finetune import fine_tuned_law

        return fine_tuned_law(model.policy, self.spec, task)

    def with_q_floor(self, margin: float | None) -> StudentMode:
        return replace(self, spec=self.spec.replace(q_floor_margin=margin))


__all__ = ["SHIPPED_BASELINES", "SHIPPED_PPO_RESIDUAL", "SHIPPED_PPO_FINETUNE", "DirectLaw", "DirectMode", "PolicyMode",
           "Predictor", "ResidualMode", "StudentMode"]  # fmt: skip
