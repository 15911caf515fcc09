"""Saved stable-baselines3 policies as guidance laws :func:`rventry_env.evaluation.rollout` can fly.

Two loaders are registered with ``rventry evaluate`` through entry points:

* group ``rventry.agents``: ``ppo``, PPO fine-tuning of the flight-set DAgger student
  (``rventry_agents/data/ppo_finetune``); ``ppo-residual``, the PPO residual on TV-LQR
  (``rventry_agents/data/ppo_residual``); ``ppo-plain``, ``recurrent-ppo-plain`` and ``sac-plain``, the
  plain-RL baselines (``rventry_agents/data/baselines``);
* ``sb3`` (group ``rventry.agent_files``): any saved model, given as a path.

A training run of this package writes, beside ``model.zip``, ``policy.json`` (how to fly it: its
mode, :mod:`rventry_agents.modes`) and ``vecnormalize.pkl`` (the observation statistics). A
model without its normalization file is refused, never flown on raw observations, which would
be a different policy; a model that was trained on raw observations says so in ``policy.json``
beside it: ``{"mode": "direct", "normalized": false}``. Every file beside the model is read
through its schema (:mod:`rventry_agents.records`): a corrupt one is refused naming it.
"""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import numpy as np

from rventry_agents.modes import (  # noqa: F401  (where the shipped policies live, and the predictor, by their old names)
    SHIPPED_BASELINES,
    SHIPPED_PPO_RESIDUAL,
    SHIPPED_PPO_FINETUNE,
    DirectLaw,
    PolicyMode,
    Predictor,
)
from rventry_agents.records import PolicyRecord, RunRecord
from rventry_env.guidance.law import Law, Measurement
from rventry_env.task import EntryTask

# agent name -> the shipped PPO-trained policy's directory (``ppo``: PPO fine-tuning of the flight-set
# DAgger student, ppo_finetune.toml; ``ppo-residual``: the PPO residual on TV-LQR, ppo.toml)
SHIPPED_PPO_AGENTS = {"ppo": SHIPPED_PPO_FINETUNE, "ppo-residual": SHIPPED_PPO_RESIDUAL}
# agent name -> the shipped plain baseline's directory under SHIPPED_BASELINES
BASELINE_AGENTS = {"ppo-plain": "ppo", "recurrent-ppo-plain": "recurrent_ppo", "sac-plain": "sac"}


def _load_sb3(path: Path, algorithm: str | None = None):
    """Load a saved model: of ``algorithm`` when the run names it, else of any stable-baselines3
    (or sb3-contrib recurrent) algorithm with a continuous-action policy."""
    from stable_baselines3 import A2C, DDPG, PPO, SAC, TD3

    from rventry_agents.config import algorithm_class

    if algorithm is not None:
        cls = algorithm_class(algorithm)
        try:
            return cls.load(path, device="cpu")
        except Exception as exc:  # a truncated or foreign zip
            raise ValueError(f"{path} is not a saved {cls.__name__} model ({type(exc).__name__}: {exc})") from None
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


def _normalization_path(path: Path, given, record: PolicyRecord) -> Path | None:
    """The statistics file to read: ``given``, or the one that belongs to the model; None for a
    model its ``policy.json`` declares trained on raw observations."""
    if given is not None:
        if not Path(given).is_file():
            raise FileNotFoundError(f"no VecNormalize statistics at {given}")
        return Path(given)
    found = _normalization_for(path)
    if found.is_file():
        return found
    if not record.normalized:
        return None
    raise FileNotFoundError(
        f"{path} has no observation statistics beside it ({found.name}): flown on raw "
        "observations it would be a different policy, so it is refused. Put the VecNormalize file "
        f"it was trained with there as {found.name}, or, for a model trained on raw "
        f'observations, write {{"mode": "direct", "normalized": false}} to '
        f"{path.parent / 'policy.json'}"
    )


def read_normalization(path: Path, observation_shape: tuple) -> tuple:
    """(mean, var, clip_obs, epsilon) of the observations from SB3's VecNormalize pickle at
    ``path`` (mean and var None where it did not normalize observations), checked against the
    model's ``observation_shape``; a corrupt or foreign file is refused naming it."""
    try:
        with open(path, "rb") as f:
            vn = pickle.load(f)  # SB3's own format for VecNormalize
    except Exception as exc:  # empty, truncated or foreign: EOFError, UnpicklingError, OverflowError, ...
        raise ValueError(f"{path} is not a VecNormalize file stable-baselines3 saved "
                         f"({type(exc).__name__}: {exc})") from None  # fmt: skip
    try:
        norm_obs, clip_obs, epsilon = bool(vn.norm_obs), float(vn.clip_obs), float(vn.epsilon)
        mean, var = (vn.obs_rms.mean.copy(), vn.obs_rms.var.copy()) if norm_obs else (None, None)
    except (AttributeError, TypeError, ValueError) as exc:
        raise ValueError(f"{path} holds a {type(vn).__name__}, not stable-baselines3's VecNormalize ({exc})") from None
    if norm_obs:  # statistics exist even when they were not used
        if np.shape(mean) != tuple(observation_shape) or np.shape(var) != tuple(observation_shape):
            raise ValueError(f"{path} normalizes observations of shape {np.shape(mean)}, the model reads "
                             f"{tuple(observation_shape)}")  # fmt: skip
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var)) and np.all(var >= 0)):
            raise ValueError(f"{path} holds non-finite or negative observation statistics")
    return mean, var, clip_obs, epsilon


def _beside(path: Path, name: str) -> Path | None:
    """``name`` beside the model, or one level up (for checkpoints/): an rventry run's record."""
    return next((d / name for d in (path.parent, path.parent.parent) if (d / name).is_file()), None)


def _run_record(path: Path, algorithm: str):
    """The run's metadata (checked) and its config's [env] (None without a record)."""
    from rventry_agents.sb3_config import load_config

    meta = _beside(path, "metadata.json")
    if meta is None:
        return None, None
    record = RunRecord.read_json(meta)
    if record.config is None:
        return record, None
    return record, load_config(record.config, record.algorithm or algorithm, f"{meta} [config]").env


class SB3Policy(Law):
    """A saved stable-baselines3 model (zip) with its VecNormalize statistics, acting deterministically.

    :param model_path: the ``.zip`` written by ``model.save``, or a run directory holding ``model.zip``.
    :param normalize_path: the ``VecNormalize`` pickle; default: the one that belongs to the model
        (required for a model of an rventry training run).
    :param task: the task to fly (default: the run's training task); a run's model is refused,
        with each difference named, on a task other than the one it was trained on.
    """

    def __init__(self, model_path: str | Path, normalize_path: str | Path | None = None, task: EntryTask | None = None):
        path = Path(model_path)
        if path.is_dir():
            path = path / "model.zip"
        if not path.is_file():
            raise FileNotFoundError(f"no saved policy at {path}")
        spec = _beside(path, "policy.json")
        self.from_run = spec is not None
        self.record = PolicyRecord.read_json(spec) if spec is not None else PolicyRecord()
        self.mode = PolicyMode.of_record(self.record)
        self.model = _load_sb3(path, self.record.algorithm)  # first: is it a model at all
        self.normalize_path = _normalization_path(path, normalize_path, self.record)
        self.obs_mean = self.obs_var = None
        self.clip_obs, self.epsilon = 10.0, 1e-8
        if self.normalize_path is not None:
            shape = self.model.observation_space.shape
            self.obs_mean, self.obs_var, self.clip_obs, self.epsilon = read_normalization(self.normalize_path, shape)
        self.metadata, env = _run_record(path, self.record.algorithm or "ppo")
        self.task = EntryTask() if task is None else task
        if env is not None:
            self.task.check_trained(EntryTask(dt=env.dt, substeps=env.substeps).record(), f"the model {path}")
        self.provenance = self._provenance()
        self._act = self.mode.law(self.model, self.normalize, self.task)

    @property
    def spec(self) -> dict:
        """``policy.json`` as a dict (``{"mode": "direct", ...}`` for a model without one)."""
        return self.record.to_dict()

    def _provenance(self) -> dict | None:
        meta = self.metadata
        if meta is not None and meta.provenance:
            provenance = dict(meta.provenance)
        elif self.from_run:
            algorithm = (meta and meta.algorithm) or self.record.algorithm or "ppo"
            provenance = {"algorithm": f"{algorithm} (stable-baselines3)", "start": self.mode.origin,
                          "timesteps": meta and meta.timesteps, "seed": meta and meta.seed}  # fmt: skip
        else:
            return None
        floor = self.mode.q_floor_margin
        return provenance if floor is None else {**provenance, "q_floor_margin": floor}

    def with_q_floor(self, margin: float | None) -> SB3Policy:
        """A student-mode policy flies with the q floor ``margin`` (None: none) in place of its own."""
        self.mode = self.mode.with_q_floor(margin)
        self._act = self.mode.law(self.model, self.normalize, self.task)
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
    "SHIPPED_PPO_RESIDUAL",
    "SHIPPED_PPO_AGENTS",
    "SHIPPED_PPO_FINETUNE",
    "Predictor",
    "SB3Policy",
    "load_baseline",
    "load_saved",
    "load_shipped",
    "read_normalization",
]
