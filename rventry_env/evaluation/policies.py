"""Policies that :func:`rventry_env.evaluation.rollout` can fly: a saved SB3 model, the reference replay."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rventry_env.envs.task import EntryTask

SHIPPED_PPO = Path(__file__).resolve().parent.parent / "data" / "ppo"


class SB3Policy:
    """A saved stable-baselines3 model (zip) with optional VecNormalize statistics, acting deterministically.

    :param model_path: the ``.zip`` written by ``model.save``; or a directory holding
        ``model.zip`` and optionally ``vecnormalize.pkl``.
    :param normalize_path: the ``VecNormalize`` pickle (observation statistics), if any.
    """

    def __init__(self, model_path: str | Path, normalize_path: str | Path | None = None):
        from stable_baselines3 import PPO
        from stable_baselines3.common.base_class import BaseAlgorithm

        path = Path(model_path)
        if path.is_dir():
            if normalize_path is None and (path / "vecnormalize.pkl").exists():
                normalize_path = path / "vecnormalize.pkl"
            path = path / "model.zip"
        if not path.exists():
            raise FileNotFoundError(f"no saved policy at {path}")
        try:
            self.model: BaseAlgorithm = PPO.load(path, device="cpu")
        except Exception as exc:  # an SB3 zip of another algorithm
            raise ValueError(f"{path} is not a stable-baselines3 PPO model: {exc}") from exc
        self.obs_mean = self.obs_var = None
        self.clip_obs, self.epsilon = 10.0, 1e-8
        if normalize_path is not None:
            import pickle

            with open(normalize_path, "rb") as f:
                vn = pickle.load(f)
            self.obs_mean, self.obs_var = vn.obs_rms.mean.copy(), vn.obs_rms.var.copy()
            self.clip_obs, self.epsilon = vn.clip_obs, vn.epsilon
        meta = path.with_name("metadata.json")
        self.metadata = json.loads(meta.read_text()) if meta.exists() else {}

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_mean is None:
            return obs
        z = (obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def __call__(self, obs, time_s, state):
        actions, _ = self.model.predict(self.normalize(obs), deterministic=True)
        return actions


class ReferencePolicy:
    """Open-loop replay of the collocation reference's controls.

    The action held over [t, t + dt] is the reference's *mean* rate over that
    interval, (alpha_ref(t + dt) - alpha_ref(t)) / dt and likewise for sigma, so
    alpha and sigma match the reference exactly at every step boundary.
    """

    def __init__(self, task: EntryTask | None = None, reference=None):
        from rventry_env.reference import load_reference

        self.task = EntryTask() if task is None else task
        self.reference = load_reference() if reference is None else reference

    def __call__(self, obs, time_s, state):
        p, dt = self.task.problem, self.task.dt
        ref = self.reference
        x0 = ref.state(np.minimum(time_s, ref.tf))
        x1 = ref.state(np.minimum(time_s + dt, ref.tf))
        a = np.column_stack([(x1[:, 10] - x0[:, 10]) / (dt * p.u_alpha_max), (x1[:, 11] - x0[:, 11]) / (dt * p.u_sigma_max)])
        return np.clip(a, -1.0, 1.0)


def load_policy(agent: str, task: EntryTask | None = None):
    """``"ppo"`` (the shipped policy), ``"reference"``, or a path to any saved SB3 PPO policy."""
    if agent == "reference":
        return ReferencePolicy(task)
    if agent == "ppo":
        if not (SHIPPED_PPO / "model.zip").exists():
            raise FileNotFoundError(f"the shipped PPO policy is missing from {SHIPPED_PPO}")
        return SB3Policy(SHIPPED_PPO)
    return SB3Policy(agent)
