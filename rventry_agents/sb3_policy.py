"""Saved stable-baselines3 policies as guidance laws :func:`rventry_env.evaluation.rollout` can fly.

Two loaders are registered with ``rventry evaluate`` through entry points:

* ``ppo`` and ``ppo-residual`` (group ``rventry.agents``): the PPO-trained policy shipped in
  ``rventry_agents/data/ppo``, the PPO residual on TV-LQR; ``ppo-plain``, ``recurrent-ppo-plain`` and
  ``sac-plain``: the plain-RL baselines;
* ``sb3`` (group ``rventry.agent_files``): any saved model, given as a path.

A training run of this package writes, beside ``model.zip``, ``policy.json`` (how
to fly it: direct, or residual on the classical law) and ``vecnormalize.pkl`` (the
observation statistics). A model without its normalization file is refused, never
flown on raw observations, which would be a different policy; a model that was trained
on raw observations says so in ``policy.json`` beside it: ``{"mode": "direct",
"normalized": false}``.
"""

from __future__ import annotations

import json
import pickle
import re
from pathlib import Path

import numpy as np

from rventry_env.guidance.law import Law, Measurement
from rventry_env.task import EntryTask

SHIPPED_PPO = Path(__file__).resolve().parent / "data" / "ppo"  # the PPO residual on TV-LQR
# the PPO-trained policy: PPO fine-tuning of the flight-set DAgger student (ppo_finetune.toml)
SHIPPED_PPO_FINETUNE = Path(__file__).resolve().parent / "data" / "ppo_finetune"
# agent name -> the shipped PPO-trained policy's directory
SHIPPED_PPO_AGENTS = {"ppo": SHIPPED_PPO_FINETUNE, "ppo-residual": SHIPPED_PPO}
SHIPPED_BASELINES = Path(__file__).resolve().parent / "data" / "baselines"
# agent name -> the shipped plain baseline's directory under SHIPPED_BASELINES
BASELINE_AGENTS = {"ppo-plain": "ppo", "recurrent-ppo-plain": "recurrent_ppo", "sac-plain": "sac"}


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


class _Direct(Law):
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


def make_policy(predict, mode: str, authority=None, task: EntryTask | None = None):
    """A rollout policy from ``predict(observations) -> actions``: direct, or residual on the classical law.

    :param authority: residual mode: (alpha, sigma) offsets in rad at a residual of 1.
    """
    if mode == "direct":
        return _Direct(predict)
    from rventry_agents.residual import ResidualGuidance, ResidualPolicy

    return ResidualPolicy(predict, ResidualGuidance(authority, task))


def _load_sb3(path: Path, algorithm: str | None = None):
    """Load a saved model: of ``algorithm`` when the run names it, else of any stable-baselines3
    (or sb3-contrib recurrent) algorithm with a continuous-action policy."""
    from stable_baselines3 import A2C, DDPG, PPO, SAC, TD3

    from rventry_agents.config import algorithm_class

    if algorithm is not None:
        return algorithm_class(algorithm).load(path, device="cpu")
    errors = []
    for algo in (PPO, SAC, TD3, A2C, DDPG, algorithm_class("recurrent_ppo")):
        try:
            return algo.load(path, device="cpu")
        except Exception as exc:  # the zip names its policy class; a mismatch fails here
            errors.append(f"{algo.__name__}: {type(exc).__name__}")
    raise ValueError(f"{path} is not a saved stable-baselines3 model ({'; '.join(errors)})")


def _normalization_for(model_zip: Path) -> Path:
    """The VecNormalize file that belongs to a run's model: ``vecnormalize.pkl`` beside it, or for a
    checkpoint ``ppo_<N>_steps.zip`` the ``ppo_vecnormalize_<N>_steps.pkl`` SB3 saved with it."""
    m = re.fullmatch(r"(?P<prefix>.+)_(?P<steps>\d+)_steps", model_zip.stem)
    if m:
        return model_zip.with_name(f"{m['prefix']}_vecnormalize_{m['steps']}_steps.pkl")
    if model_zip.name == "final_model.zip":
        return model_zip.with_name("final_vecnormalize.pkl")
    return model_zip.with_name("vecnormalize.pkl")


class SB3Policy(Law):
    """A saved stable-baselines3 model (zip) with its VecNormalize statistics, acting deterministically.

    :param model_path: the ``.zip`` written by ``model.save``, or a run directory holding ``model.zip``.
    :param normalize_path: the ``VecNormalize`` pickle; default: the one that belongs to the model
        (required for a model of an rventry training run).
    :param task: the task to fly (default: the run's training task); a run's model is refused,
        with each difference named, on a task other than the one it was trained on.
    """

    def __init__(self, model_path: str | Path, normalize_path: str | Path | None = None, task: EntryTask | None = None):
        from stable_baselines3.common.base_class import BaseAlgorithm

        path = Path(model_path)
        if path.is_dir():
            path = path / "model.zip"
        if not path.is_file():
            raise FileNotFoundError(f"no saved policy at {path}")
        # policy.json sits beside the model (or one level up, for checkpoints/): an rventry run
        spec = next((d / "policy.json" for d in (path.parent, path.parent.parent) if (d / "policy.json").is_file()), None)
        self.spec = json.loads(spec.read_text()) if spec is not None else {"mode": "direct"}
        self.from_run = spec is not None
        self.model: BaseAlgorithm = _load_sb3(path, self.spec.get("algorithm"))  # first: is it a model at all
        if normalize_path is None:
            normalize_path = _normalization_for(path)
            if not normalize_path.is_file():
                if self.spec.get("normalized", True):
                    raise FileNotFoundError(
                        f"{path} has no observation statistics beside it ({normalize_path.name}): flown on raw "
                        "observations it would be a different policy, so it is refused. Put the VecNormalize file "
                        f"it was trained with there as {normalize_path.name}, or, for a model trained on raw "
                        f'observations, write {{"mode": "direct", "normalized": false}} to '
                        f"{path.parent / 'policy.json'}"
                    )
                normalize_path = None
        self.obs_mean = self.obs_var = None
        self.clip_obs, self.epsilon = 10.0, 1e-8
        self.normalize_path = None if normalize_path is None else Path(normalize_path)
        if self.normalize_path is not None:
            if not self.normalize_path.is_file():
                raise FileNotFoundError(f"no VecNormalize statistics at {self.normalize_path}")
            with open(self.normalize_path, "rb") as f:
                vn = pickle.load(f)  # SB3's own format for VecNormalize
            if vn.norm_obs:  # statistics exist even when they were not used
                self.obs_mean, self.obs_var = vn.obs_rms.mean.copy(), vn.obs_rms.var.copy()
                self.clip_obs, self.epsilon = vn.clip_obs, vn.epsilon
        meta = next((d / "metadata.json" for d in (path.parent, path.parent.parent) if (d / "metadata.json").is_file()), None)
        self.metadata = json.loads(meta.read_text()) if meta is not None else {}
        self.task = EntryTask() if task is None else task
        env = self.metadata.get("config", {}).get("env")
        if env is not None:
            self.task.check_trained(EntryTask(dt=float(env["dt"]), substeps=int(env["substeps"])).record(),
                                    f"the model {path}")  # fmt: skip
        self.provenance = self.metadata.get("provenance") or (
            {"algorithm": f"{self.metadata.get('algorithm', self.spec.get('algorithm', 'ppo'))} (stable-baselines3)",
             "start": {"residual": "TV-LQR, residual", "direct": "scratch"}.get(self.spec["mode"], self.spec["mode"]),
             "timesteps": self.metadata.get("timesteps"), "seed": self.metadata.get("seed")}
            if self.from_run else None)  # fmt: skip
        if self.spec["mode"] == "student":
            floor = self.spec["student"].get("q_floor_margin")
            self.with_q_floor(floor)
            if floor is not None and self.provenance is not None:
                self.provenance = {**self.provenance, "q_floor_margin": floor}
        else:
            self._act = make_policy(Predictor(self.model, self.normalize), self.spec["mode"],
                                    self.spec.get("authority_rad"), self.task)  # fmt: skip

    def with_q_floor(self, margin: float | None) -> "SB3Policy":
        """A student-mode policy flies with the q floor ``margin`` (None: none) in place of its own."""
        from rventry_agents.finetune import fine_tuned_law

        if self.spec["mode"] != "student":
            raise ValueError(f"a q floor belongs to a policy fine-tuned from a student, not to a {self.spec['mode']!r} one")
        self._act = fine_tuned_law(self.model.policy, {**self.spec["student"], "q_floor_margin": margin}, self.task)
        return self

    def reset(self, n_episodes: int) -> None:
        self._act.reset(n_episodes)

    def episode_stats(self) -> list[dict]:
        return self._act.episode_stats()

    @property
    def retargets(self) -> bool:
        """As the law it flies: direct and student-mode policies aim by the observation, a residual
        on TV-LQR tracks the fixed-target reference."""
        return bool(getattr(self._act, "retargets", False))

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_mean is None:
            return obs
        z = (obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def __call__(self, m: Measurement) -> np.ndarray:
        return self._act(m)


def load_shipped(name: str = "ppo", task: EntryTask | None = None) -> SB3Policy:
    """A PPO-trained policy shipped with this package: ``ppo``, PPO fine-tuning of the flight-set
    DAgger student, or ``ppo-residual``, the PPO residual on TV-LQR."""
    if name not in SHIPPED_PPO_AGENTS:
        raise ValueError(f"no shipped PPO policy named {name!r}; shipped: {', '.join(SHIPPED_PPO_AGENTS)}")
    run = SHIPPED_PPO_AGENTS[name]
    if not (run / "model.zip").is_file():
        raise FileNotFoundError(f"the shipped policy {name} is missing from {run}")
    return SB3Policy(run, task=task)


def load_baseline(name: str, task: EntryTask | None = None) -> SB3Policy:
    """A plain-RL baseline shipped with this package (entry points ``ppo-plain``, ...)."""
    if name not in BASELINE_AGENTS:
        raise ValueError(f"no baseline named {name!r}; baselines: {', '.join(BASELINE_AGENTS)}")
    run = SHIPPED_BASELINES / BASELINE_AGENTS[name]
    if not (run / "model.zip").is_file():
        raise FileNotFoundError(f"the baseline {name} is not shipped: no {run / 'model.zip'}")
    return SB3Policy(run, task=task)


def load_saved(path: str, task: EntryTask | None = None) -> SB3Policy:
    """A saved SB3 model or run directory (entry point ``rventry.agent_files``)."""
    return SB3Policy(path, task=task)


__all__ = [
    "BASELINE_AGENTS",
    "SHIPPED_BASELINES",
    "SHIPPED_PPO",
    "SHIPPED_PPO_AGENTS",
    "SHIPPED_PPO_FINETUNE",
    "Predictor",
    "SB3Policy",
    "load_baseline",
    "load_saved",
    "load_shipped",
    "make_policy",
]
