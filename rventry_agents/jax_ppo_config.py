"""The configuration of ``rventry train jax-ppo``: the plain-RL baseline in JAX, as typed sections.

A config file has the sections ``[env]`` (the functional environment's vehicles, step and
training draws), ``[ppo]`` (rejax PPO's settings and the network) and ``[train]`` (budget, chunks,
seed and the evaluation between chunks). :func:`load_config` reads one and checks every key
before anything runs; ``rventry_agents/baselines/jax_ppo.toml`` is the shipped baseline's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from rventry_agents.config import ConfigError, Section, dispersion, setting, widths

DEFAULT_CONFIG = Path(__file__).resolve().parent / "baselines" / "jax_ppo.toml"


@dataclass(frozen=True, kw_only=True)
class EnvSection(Section):
    """``[env]``: the functional environment trained on.

    :param dispersion: the training vehicles' draws: a named set or a table of
        :class:`~rventry_env.task.Dispersion` fields.
    """

    num_envs: int = setting(256, ge=1)
    dt: float = setting(1.0, gt=0)
    substeps: int = setting(1, ge=1)
    max_episode_steps: int = setting(2000, ge=1)
    dtype: Literal["float32", "float64"] = "float32"
    dispersion: str | dict = dispersion("none")


@dataclass(frozen=True, kw_only=True)
class RejaxPPOSection(Section):
    """rejax PPO's settings and the networks (actor and critic alike), as both JAX learners read them
    (the baseline's defaults; :class:`~rventry_agents.scratch_config.PPOSection` sets its own)."""

    num_steps: int = setting(64, ge=1)
    num_minibatches: int = setting(4, ge=1)
    num_epochs: int = setting(5, ge=1)
    learning_rate: float = setting(3e-4, gt=0)
    gamma: float = setting(0.999, gt=0, le=1)
    gae_lambda: float = setting(0.95, ge=0, le=1)
    clip_eps: float = setting(0.2, gt=0)
    ent_coef: float = setting(0.0, ge=0)
    vf_coef: float = setting(0.5, ge=0)
    max_grad_norm: float = setting(0.5, gt=0)
    normalize_observations: bool = True
    hidden_layer_sizes: tuple[int, ...] = widths((256, 256))
    activation: Literal["tanh", "relu"] = "tanh"


@dataclass(frozen=True, kw_only=True)
class PPOSection(RejaxPPOSection):
    """``[ppo]``: rejax PPO's settings, and whether the rewards are normalized."""

    normalize_rewards: bool = True


@dataclass(frozen=True, kw_only=True)
class TrainSection(Section):
    """``[train]``: the budget, its chunks (one compiled program, called again), the seed, and the
    evaluation after each chunk: the deterministic policy on ``eval_episodes`` vehicles of
    ``eval_dispersion`` drawn from the key ``eval_seed``."""

    total_timesteps: int = setting(10_000_000, ge=1)
    chunk_timesteps: int = setting(1_048_576, ge=1)
    seed: int = setting(0, ge=0)
    eval_episodes: int = setting(128, ge=1)
    eval_seed: int = setting(100_000, ge=0)
    eval_dispersion: str | dict = dispersion("standard")


@dataclass(frozen=True, kw_only=True)
class JaxPPOConfig(Section):
    """A whole ``jax-ppo`` config (see the module docstring)."""

    env: EnvSection = EnvSection()
    ppo: PPOSection = PPOSection()
    train: TrainSection = TrainSection()

    def __post_init__(self):
        super().__post_init__()
        rollout = self.env.num_envs * self.ppo.num_steps
        if rollout % self.ppo.num_minibatches:
            raise ConfigError(f"[ppo] num_minibatches ({self.ppo.num_minibatches}) must divide a rollout's "
                              f"{rollout:,} steps")  # fmt: skip


def load_config(path: str | Path | dict | JaxPPOConfig | None = None) -> JaxPPOConfig:
    """The config at ``path`` (default :data:`DEFAULT_CONFIG`), from a dict, or as given; checked."""
    if isinstance(path, JaxPPOConfig):
        return path
    if isinstance(path, dict):
        return JaxPPOConfig.from_dict(path)
    return JaxPPOConfig.load(DEFAULT_CONFIG if path is None else path)


__all__ = ["DEFAULT_CONFIG", "EnvSection", "JaxPPOConfig", "PPOSection", "RejaxPPOSection", "TrainSection", "load_config"]
