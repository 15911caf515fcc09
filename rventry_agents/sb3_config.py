"""The configuration of a stable-baselines3 training run (``rventry train ppo-residual``,
``ppo-finetune``, ``ppo-plain``, ``recurrent-ppo-plain``, ``sac-plain``), as typed sections.

A config file has the sections ``[env]``, ``[reward]`` (optional), ``[shaping]`` (optional),
``[normalize]``, one named after the algorithm (``[ppo]``, ``[recurrent_ppo]`` or ``[sac]``: its
keyword arguments), ``[policy]`` and ``[train]``; :func:`load_config` reads one and checks every
key before anything runs. The algorithm's defaults are stable-baselines3's own (a test holds them
to its signatures); the ``[policy]`` section has one variant per ``mode``
(:class:`DirectPolicy`, :class:`ResidualPolicy`, :class:`StudentPolicy`), each of which builds its
:class:`~rventry_agents.modes.PolicyMode`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, ClassVar, Literal

from rventry_agents.config import (
    ALGORITHMS,
    ConfigError,
    Section,
    check_algorithm,
    dispersion,
    setting,
    widths,
)
from rventry_agents.records import check_floor_margin
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import EntryTask

HERE = Path(__file__).resolve().parent
@dataclass(frozen=True, kw_only=True)
class EnvSection(Section):
    """``[env]``: the batched training environment.

    :param time_limit_is_failure: charge a time-limit cut like a failure and do not bootstrap it
        (:mod:`rventry_agents.sb3_vec`).
    :param dispersion: the training vehicles' draws: a named set or a table of
        :class:`~rventry_env.task.Dispersion` fields.
    """

    num_envs: int = setting(ge=1)
    dt: float = setting(gt=0)
    substeps: int = setting(ge=1)
    max_episode_steps: int = setting(ge=1)
    time_limit_is_failure: bool
    dispersion: str | dict = dispersion("none")

    def task(self, base: EntryTask | None = None) -> EntryTask:
        """The training task: ``base`` (default :class:`EntryTask`) with this dt and substeps."""
        from dataclasses import replace

        return replace(EntryTask() if base is None else base, dt=self.dt, substeps=self.substeps)


@dataclass(frozen=True, kw_only=True)
class ShapingSection(Section):
    """``[shaping]``: potential-based reward shaping on the range to go (0: none;
    :class:`~rventry_agents.sb3_vec.RangePotentialShaping`), reward per km closed."""

    range_weight: float = setting(0.0, ge=0)


@dataclass(frozen=True, kw_only=True)
class NormalizeSection(Section):
    """``[normalize]``: stable-baselines3's ``VecNormalize`` (its defaults)."""

    norm_obs: bool = True
    norm_reward: bool = True
    clip_obs: float = setting(10.0, gt=0)
    clip_reward: float = setting(10.0, gt=0)


@dataclass(frozen=True, kw_only=True)
class PPOSection(Section):
    """``[ppo]``: stable-baselines3 PPO's keyword arguments (its defaults)."""

    learning_rate: float = setting(3e-4, gt=0)
    n_steps: int = setting(2048, ge=1)
    batch_size: int = setting(64, ge=1)
    n_epochs: int = setting(10, ge=1)
    gamma: float = setting(0.99, gt=0, le=1)
    gae_lambda: float = setting(0.95, ge=0, le=1)
    clip_range: float = setting(0.2, gt=0)
    clip_range_vf: float | None = setting(None, gt=0)
    normalize_advantage: bool = True
    ent_coef: float = setting(0.0, ge=0)
    vf_coef: float = setting(0.5, ge=0)
    max_grad_norm: float = setting(0.5, gt=0)
    use_sde: bool = False
    sde_sample_freq: int = setting(-1, ge=-1)
    target_kl: float | None = setting(None, gt=0)

    def kwargs(self) -> dict[str, Any]:
        """The algorithm's keyword arguments."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True, kw_only=True)
class RecurrentPPOSection(PPOSection):
    """``[recurrent_ppo]``: sb3-contrib RecurrentPPO's keyword arguments (its defaults)."""

    n_steps: int = setting(128, ge=1)
    batch_size: int = setting(128, ge=1)


@dataclass(frozen=True, kw_only=True)
class SACSection(Section):
    """``[sac]``: stable-baselines3 SAC's keyword arguments (its defaults)."""

    learning_rate: float = setting(3e-4, gt=0)
    buffer_size: int = setting(1_000_000, ge=1)
    learning_starts: int = setting(100, ge=0)
    batch_size: int = setting(256, ge=1)
    tau: float = setting(0.005, gt=0, le=1)
    gamma: float = setting(0.99, gt=0, le=1)
    train_freq: int = setting(1, ge=1)
    gradient_steps: int = setting(1, ge=-1)
    ent_coef: float | str = setting("auto", check=lambda v: _check_auto(v, "ent_coef"))
    target_update_interval: int = setting(1, ge=1)
    target_entropy: float | str = setting("auto", check=lambda v: _check_auto(v, "target_entropy"))
    use_sde: bool = False
    sde_sample_freq: int = setting(-1, ge=-1)
    use_sde_at_warmup: bool = False

    def kwargs(self) -> dict[str, Any]:
        """The algorithm's keyword arguments."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _check_auto(value, name: str) -> None:
    if isinstance(value, str) and not value.startswith("auto"):
        raise ValueError(f"a string {name} is 'auto' or 'auto_<initial value>', got {value!r}")


LSTM_KEYS = ("lstm_hidden_size", "n_lstm_layers", "shared_lstm", "enable_critic_lstm")


def _heads(algorithm: str) -> tuple[str, str]:
    """The networks of ``algorithm``'s policy: the actor and the critic (SAC's is a Q-function)."""
    return ("pi", "qf") if algorithm == "sac" else ("pi", "vf")


@dataclass(frozen=True, kw_only=True)
class PolicySection(Section):
    """``[policy]``: the mode (one variant each) and the networks. A network key left out takes
    the algorithm's own default; the LSTM keys are RecurrentPPO's."""

    mode: str
    net_arch_pi: tuple[int, ...] | None = widths(None)
    net_arch_vf: tuple[int, ...] | None = widths(None)
    net_arch_qf: tuple[int, ...] | None = widths(None)
    activation: Literal["tanh", "relu", "elu"] | None = None
    log_std_init: float | None = None
    lstm_hidden_size: int | None = setting(None, ge=1)
    n_lstm_layers: int | None = setting(None, ge=1)
    shared_lstm: bool | None = None
    enable_critic_lstm: bool | None = None

    @classmethod
    def _variant(cls, data: dict) -> type:
        if cls is not PolicySection:
            return cls
        mode = data.get("mode", DirectPolicy.MODE)
        variants = {v.MODE: v for v in (DirectPolicy, ResidualPolicy, StudentPolicy)}
        if mode not in variants:
            raise ConfigError(f"mode must be one of {', '.join(map(repr, variants))}, got {mode!r}")
        return variants[mode]

    @classmethod
    def _unknown_hint(cls, key: str) -> str:
        owners = [v.MODE for v in (DirectPolicy, ResidualPolicy, StudentPolicy) if key in v.__dataclass_fields__]
        return f"; it belongs to mode = {' or '.join(map(repr, owners))}, not {cls.MODE!r}" if owners else ""

    def check_algorithm(self, algorithm: str) -> None:
        """Refuse what does not apply to ``algorithm``, naming it."""
        if algorithm not in self.ALGORITHMS:
            raise ConfigError(f"[policy] mode = {self.mode!r} is built for {', '.join(self.ALGORITHMS)}, not "
                              f"{algorithm}; use mode = 'direct'")  # fmt: skip
        heads = _heads(algorithm)
        for head in ("vf", "qf"):
            if head not in heads and getattr(self, f"net_arch_{head}") is not None:
                raise ConfigError(f"[policy] net_arch_{head} is not a network of {algorithm} "
                                  f"(its networks are {' and '.join(f'net_arch_{h}' for h in heads)})")  # fmt: skip
        given = [k for k in LSTM_KEYS if getattr(self, k) is not None]
        if given and algorithm != "recurrent_ppo":
            raise ConfigError(f"[policy] {', '.join(given)} configure RecurrentPPO's LSTM, not {algorithm}")
        self._check_widths(heads)

    def _check_widths(self, heads: tuple[str, str]) -> None:
        if sum(getattr(self, f"net_arch_{h}") is not None for h in heads) == 1:
            raise ConfigError(f"[policy] give both {' and '.join(f'net_arch_{h}' for h in heads)}, or neither")

    def policy_kwargs(self, algorithm: str) -> dict[str, Any]:
        """The policy network's keyword arguments for ``algorithm``."""
        import torch

        heads = _heads(algorithm)
        kwargs: dict[str, Any] = {}
        if getattr(self, f"net_arch_{heads[0]}") is not None:
            kwargs["net_arch"] = {h: list(getattr(self, f"net_arch_{h}")) for h in heads}
        if self.activation is not None:
            kwargs["activation_fn"] = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "elu": torch.nn.ELU}[self.activation]
        if self.log_std_init is not None:
            kwargs["log_std_init"] = self.log_std_init
        return kwargs | {k: getattr(self, k) for k in LSTM_KEYS if getattr(self, k) is not None}

    def build(self, task: EntryTask):
        """The :class:`~rventry_agents.modes.PolicyMode` this section describes; a student is
        loaded (and checked) here."""
        raise NotImplementedError


@dataclass(frozen=True, kw_only=True)
class DirectPolicy(PolicySection):
    """``mode = "direct"``: the model's action is the environment's (the rates)."""

    MODE: ClassVar[str] = "direct"
    ALGORITHMS: ClassVar[tuple[str, ...]] = ALGORITHMS
    mode: Literal["direct"] = "direct"

    def build(self, task: EntryTask):
        from rventry_agents.modes import DirectMode

        return DirectMode()


@dataclass(frozen=True, kw_only=True)
class ResidualPolicy(PolicySection):
    """``mode = "residual"``: pi in [-1, 1]^2 offsets TV-LQR's alpha and sigma by up to the
    authorities (deg) in one step (:mod:`rventry_agents.residual`).

    :param zero_init_residual: start the action head at zero: the untrained policy flies TV-LQR.
    """

    MODE: ClassVar[str] = "residual"
    ALGORITHMS: ClassVar[tuple[str, ...]] = ("ppo",)
    mode: Literal["residual"] = "residual"
    alpha_authority_deg: float = setting(gt=0)
    sigma_authority_deg: float = setting(gt=0)
    zero_init_residual: bool = False

    def build(self, task: EntryTask):
        from rventry_agents.modes import ResidualMode

        authority = (math.radians(self.alpha_authority_deg), math.radians(self.sigma_authority_deg))
        return ResidualMode(authority_rad=authority, zero_init=self.zero_init_residual)


@dataclass(frozen=True, kw_only=True)
class StudentPolicy(PolicySection):
    """``mode = "student"``: PPO fine-tuning of an imitation student (:mod:`rventry_agents.finetune`).

    :param start: the student: an agent name (``dagger-flight``) or a DAgger run's directory.
    :param q_floor_margin: a q floor flown in training, and by the trained policy (none: none).
    :param privileged_critic: the critic also sees the draw; the actor the student's inputs alone.
    :param critic_warmup_steps: the steps the critic learns alone first, the actor frozen.
    :param net_arch_pi: the actor's widths are the student's; when given, it must say so.
    :param net_arch_vf: the critic's widths (none: the student's).
    """

    MODE: ClassVar[str] = "student"
    ALGORITHMS: ClassVar[tuple[str, ...]] = ("ppo",)
    mode: Literal["student"] = "student"
    start: str
    q_floor_margin: float | None = setting(None, check=check_floor_margin)
    privileged_critic: bool = False
    critic_warmup_steps: int = setting(0, ge=0)
    activation: Literal["tanh"] | None = setting(None, what="'tanh' (the student's)")

    def _check_widths(self, heads: tuple[str, str]) -> None:
        pass  # the actor's are the student's (checked when it is loaded), the critic's may be given alone

    def build(self, task: EntryTask):
        from rventry_agents.finetune import StudentScales, load_start, student_spec
        from rventry_agents.modes import StudentMode

        law = load_start(self.start, task, self.q_floor_margin)
        hidden = tuple(law.network.hidden)
        if self.net_arch_pi is not None and tuple(self.net_arch_pi) != hidden:
            raise ConfigError(f"[policy] net_arch_pi = {list(self.net_arch_pi)}: the actor is the student's, of "
                              f"widths {list(hidden)}")  # fmt: skip
        spec = student_spec(law, StudentScales.of(law.network), self.start)
        return StudentMode(spec=spec, student=law, privileged=self.privileged_critic,
                           warmup_steps=self.critic_warmup_steps, critic_widths=self.net_arch_vf)  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class TrainSection(Section):
    """``[train]``: the run's length and seed, and the selection on the task metric: every
    ``eval_every`` steps the deterministic policy flies ``eval_episodes`` vehicles of the
    ``eval_dispersion`` set from seed ``eval_seed`` (never the evaluation's seeds, 0...)."""

    total_timesteps: int = setting(ge=1)
    seed: int = setting(ge=0)
    torch_threads: int = setting(1, ge=1)
    checkpoint_every: int = setting(ge=1)
    eval_every: int = setting(ge=1)
    eval_episodes: int = setting(ge=1)
    eval_seed: int = setting(ge=0)
    eval_dispersion: str | dict = dispersion()


@dataclass(frozen=True, kw_only=True)
class SB3Config(Section):
    """A stable-baselines3 training configuration; one subclass per algorithm, whose own section
    is named after it."""

    ALGORITHM: ClassVar[str]
    env: EnvSection
    reward: RewardWeights = RewardWeights()  # the training reward: the environment's weights, overridden
    shaping: ShapingSection = ShapingSection()
    normalize: NormalizeSection
    policy: PolicySection
    train: TrainSection

    def __post_init__(self):
        super().__post_init__()
        self.policy.check_algorithm(self.ALGORITHM)

    @property
    def algorithm(self) -> str:
        return self.ALGORITHM

    @property
    def hyperparameters(self) -> PPOSection | SACSection:
        """The algorithm's own section."""
        return getattr(self, self.ALGORITHM)

    @property
    def discount(self) -> float:
        """The algorithm's discount factor (also the reward normalization's and the shaping's)."""
        return self.hyperparameters.gamma


@dataclass(frozen=True, kw_only=True)
class PPOConfig(SB3Config):
    ALGORITHM: ClassVar[str] = "ppo"
    ppo: PPOSection


@dataclass(frozen=True, kw_only=True)
class RecurrentPPOConfig(SB3Config):
    ALGORITHM: ClassVar[str] = "recurrent_ppo"
    recurrent_ppo: RecurrentPPOSection


@dataclass(frozen=True, kw_only=True)
class SACConfig(SB3Config):
    ALGORITHM: ClassVar[str] = "sac"
    sac: SACSection


CONFIG_CLASSES: dict[str, type[SB3Config]] = {c.ALGORITHM: c for c in (PPOConfig, RecurrentPPOConfig, SACConfig)}
assert tuple(CONFIG_CLASSES) == ALGORITHMS

DEFAULT_CONFIG = HERE / "ppo.toml"  # the PPO residual on TV-LQR
BASELINES = HERE / "baselines"
FINETUNE_CONFIG = HERE / "ppo_finetune.toml"  # PPO from the imitation student
# the config each algorithm's trainer reads when none is given
DEFAULT_CONFIGS = {"ppo": DEFAULT_CONFIG, "recurrent_ppo": BASELINES / "recurrent_ppo.toml", "sac": BASELINES / "sac.toml"}


def load_config(config: str | Path | dict | SB3Config | None = None, algorithm: str = "ppo",
                where: str | None = None) -> SB3Config:  # fmt: skip
    """The training configuration of ``algorithm``, checked: a TOML file (default: the
    algorithm's, :data:`DEFAULT_CONFIGS`), a dict as one reads (a run's ``config.json``, say) or a
    config of another algorithm (refused, naming the sections); ``where`` names a dict's source.

    :raises ConfigError: naming the file, the section and the key.
    """
    cls = CONFIG_CLASSES[check_algorithm(algorithm)]
    if isinstance(config, SB3Config):
        return config if isinstance(config, cls) else cls.from_dict(config.to_dict(), where or "config")
    if isinstance(config, dict):
        return cls.from_dict(config, where or "config")
    return cls.load(DEFAULT_CONFIGS[algorithm] if config is None else config)


__all__ = ["BASELINES", "CONFIG_CLASSES", "DEFAULT_CONFIG", "DEFAULT_CONFIGS", "FINETUNE_CONFIG", "DirectPolicy",
           "EnvSection", "NormalizeSection", "PPOConfig", "PPOSection", "PolicySection", "RecurrentPPOConfig",
           "RecurrentPPOSection", "ResidualPolicy", "SACConfig", "SACSection", "SB3Config", "ShapingSection",
           "StudentPolicy", "TrainSection", "load_config"]  # fmt: skip
