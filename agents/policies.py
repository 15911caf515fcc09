"""Policies :func:`rventry_env.evaluation.rollout` can fly: saved SB3 PPO models and the reference replay."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np

import rventry_env
from rventry_env.envs.task import EntryTask
from rventry_env.evaluation.policies import ReferencePolicy

SHIPPED_PPO = Path(rventry_env.__file__).resolve().parent / "data" / "ppo"


def make_policy(predict, mode: str, authority=None, task: EntryTask | None = None):
    """A rollout policy from ``predict(observations) -> actions``: direct, or residual on the reference.

    :param authority: residual mode: (alpha, sigma) offsets in rad at a residual of 1.
    """
    if mode == "direct":
        return lambda obs, time_s, state: predict(obs)
    from agents.residual import ResidualGuidance, ResidualPolicy

    return ResidualPolicy(predict, ResidualGuidance(authority, task))


def _load_sb3(path: Path):
    """Load a saved model of any stable-baselines3 algorithm with a continuous-action policy."""
    from stable_baselines3 import A2C, DDPG, PPO, SAC, TD3

    errors = []
    for algo in (PPO, SAC, TD3, A2C, DDPG):
        try:
            return algo.load(path, device="cpu")
        except Exception as exc:  # the zip names its policy class; a mismatch fails here
            errors.append(f"{algo.__name__}: {type(exc).__name__}")
    raise ValueError(f"{path} is not a saved stable-baselines3 model ({'; '.join(errors)})")


class SB3Policy:
    """A saved stable-baselines3 model (zip) with optional VecNormalize statistics, acting deterministically.

    :param model_path: the ``.zip`` written by ``model.save``; or a directory holding
        ``model.zip`` and optionally ``vecnormalize.pkl``.
    :param normalize_path: the ``VecNormalize`` pickle (observation statistics), if any.
    """

    def __init__(self, model_path: str | Path, normalize_path: str | Path | None = None):
        from stable_baselines3.common.base_class import BaseAlgorithm

        path = Path(model_path)
        if path.is_dir():
            if normalize_path is None and (path / "vecnormalize.pkl").exists():
                normalize_path = path / "vecnormalize.pkl"
            path = path / "model.zip"
        if not path.exists():
            raise FileNotFoundError(f"no saved policy at {path}")
        self.model: BaseAlgorithm = _load_sb3(path)
        self.obs_mean = self.obs_var = None
        self.clip_obs, self.epsilon = 10.0, 1e-8
        if normalize_path is not None:
            with open(normalize_path, "rb") as f:
                vn = pickle.load(f)
            if vn.norm_obs:  # statistics exist even when they were not used
                self.obs_mean, self.obs_var = vn.obs_rms.mean.copy(), vn.obs_rms.var.copy()
                self.clip_obs, self.epsilon = vn.clip_obs, vn.epsilon
        meta = path.with_name("metadata.json")
        self.metadata = json.loads(meta.read_text()) if meta.exists() else {}
        # policy.json sits beside the model (or one level up, for checkpoints/)
        spec = next((d / "policy.json" for d in (path.parent, path.parent.parent) if (d / "policy.json").exists()), None)
        self.spec = json.loads(spec.read_text()) if spec is not None else {"mode": "direct"}
        self._act = make_policy(self._predict, self.spec["mode"], self.spec.get("authority_rad"))

    def _predict(self, obs):
        return self.model.predict(self.normalize(obs), deterministic=True)[0]

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_mean is None:
            return obs
        z = (obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def __call__(self, obs, time_s, state):
        return self._act(obs, time_s, state)


def load_policy(agent: str, task: EntryTask | None = None):
    """``"ppo"`` (the shipped policy), ``"reference"`` (open-loop optimum), ``"lqr"`` (TV-LQR
    around the guidance reference), or a path to any saved SB3 PPO policy."""
    if agent == "reference":
        return ReferencePolicy(task)
    if agent == "lqr":
        from rventry_env.evaluation.tvlqr import NeighboringOptimalGuidance

        return NeighboringOptimalGuidance(task=task)
    if agent == "ppo":
        if not (SHIPPED_PPO / "model.zip").exists():
            raise FileNotFoundError(f"the shipped PPO policy is missing from {SHIPPED_PPO}")
        return SB3Policy(SHIPPED_PPO)
    return SB3Policy(agent)
