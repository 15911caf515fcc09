"""The records a training run writes beside its policy, read back through their schemas.

A loader reads ``student.json`` (a DAgger student), ``policy.json`` (how to fly a
stable-baselines3 model) and ``metadata.json`` (a run's command, config and provenance) through
the classes here, so that a malformed or truncated file is refused naming the file and the key,
never failing deep inside a loader. :class:`StudentDeploy` is also the part of a DAgger
``[student]`` section that says how a student flies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from rventry_agents.config import ConfigError, Section, setting, widths
from rventry_agents.imitation import Horizon
from rventry_env.task import EntryTask


def check_relief_margin(margin: float) -> None:
    """A load-relief margin: a fraction in [0, 1) of the load bound (the law's own check)."""
    from rventry_env.guidance.load_relief import LoadRelief

    LoadRelief(task=EntryTask(), margin=float(margin))


def check_floor_margin(margin: float) -> None:
    """A q-floor margin (the law's own check)."""
    from rventry_env.guidance.q_floor import QFloor

    QFloor(task=EntryTask(), margin=float(margin))


HORIZON_KEYS = {"s": "max_s", "min_s": "min_s", "descent_mps": "descent_mps"}


@dataclass(frozen=True, kw_only=True)
class StudentDeploy(Section):
    """How a student network is deployed (how it flies): its tracker's horizon and its limiters.

    The horizon is ``tracking_*`` where a tracker was chosen after training, else the labels'
    ``lookahead_*``, which the rounds fly; one control step where neither is given (students
    trained before the horizon existed). A horizon is the altitude over ``*_descent_mps`` between
    ``*_min_s`` (default: ``*_s``) and ``*_s``; a descent rate absent is unbounded.
    """

    lookahead_s: float | None = setting(None, gt=0)
    lookahead_min_s: float | None = setting(None, gt=0)
    lookahead_descent_mps: float | None = setting(None, gt=0, finite=False)
    tracking_s: float | None = setting(None, gt=0)
    tracking_min_s: float | None = setting(None, gt=0)
    tracking_descent_mps: float | None = setting(None, gt=0, finite=False)
    load_relief_margin: float | None = setting(None, check=check_relief_margin)  # none: no load relief
    q_floor_margin: float | None = setting(None, check=check_floor_margin)  # none: no q floor

    def __post_init__(self):
        super().__post_init__()
        for prefix in ("lookahead", "tracking"):
            try:
                self.horizon(prefix)
            except ValueError as exc:
                raise ConfigError(f"{prefix}_*: {exc}") from None

    def horizon(self, prefix: str) -> Horizon | None:
        """The ``lookahead`` or ``tracking`` horizon, None where it is not given."""
        given = {name: float(getattr(self, f"{prefix}_{key}")) for key, name in HORIZON_KEYS.items()
                 if getattr(self, f"{prefix}_{key}") is not None}  # fmt: skip
        if not given:
            return None
        if "max_s" not in given:
            raise ValueError(f"{prefix}_s is missing beside {', '.join(f'{prefix}_{k}' for k in HORIZON_KEYS if k != 's')}")
        given.setdefault("min_s", given["max_s"])
        return Horizon(**given)

    def law(self, task: EntryTask) -> dict:
        """The :class:`~rventry_agents.imitation.LearnedGuidance` keywords: ``horizon`` (for one
        control step of ``task`` where none is given), ``load_relief_margin``, ``q_floor_margin``."""
        horizon = self.horizon("tracking") or self.horizon("lookahead") or Horizon(task.dt, task.dt)
        return {"horizon": horizon, "load_relief_margin": self.load_relief_margin, "q_floor_margin": self.q_floor_margin}


def horizon_keys(h: Horizon, prefix: str) -> dict:
    """A horizon as :class:`StudentDeploy` keys (an unbounded descent rate as None)."""
    return {f"{prefix}_s": h.max_s, f"{prefix}_min_s": h.min_s,
            f"{prefix}_descent_mps": h.descent_mps if math.isfinite(h.descent_mps) else None}  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class StudentNetwork(StudentDeploy):
    """A student's network (``members`` > 1: an ensemble, the mean of theirs) and how it flies."""

    hidden: tuple[int, ...] = widths()
    members: int = setting(1, ge=1)


@dataclass(frozen=True, kw_only=True)
class StudentRecord(StudentNetwork):
    """``student.json``: a DAgger student's shape, the task it was trained on and how it flies."""
    inputs: str | None = None
    input_features: tuple[str, ...] | None = None
    task: dict | None = None  # EntryTask.record() of the training task; none: the default task
    outputs: str | None = None
    selected_round: int | str | None = None
    distilled_from: int | str | None = None
    trained_load_relief_margin: float | None = setting(None, check=check_relief_margin)


@dataclass(frozen=True, kw_only=True)
class Scales(Section):
    """A student's standardization: its inputs' mean and spread, its commands' mean and spread."""

    mean: tuple[float, ...] = setting(nonempty=True)
    std: tuple[float, ...] = setting(gt=0, nonempty=True)
    out_mean: tuple[float, ...] = setting(nonempty=True)
    out_scale: tuple[float, ...] = setting(gt=0, nonempty=True)

    def __post_init__(self):
        super().__post_init__()
        if len(self.std) != len(self.mean) or len(self.out_scale) != len(self.out_mean):
            raise ConfigError(f"the spreads must match the means: {len(self.mean)} inputs and {len(self.std)} spreads, "
                              f"{len(self.out_mean)} commands and {len(self.out_scale)} spreads")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class FineTunedSpec(StudentDeploy):
    """``policy.json``'s ``student``: the student a fine-tuning started from (its name and the
    SHA-256 of its weights), its standardization, and how the fine-tuned actor flies."""

    start: str
    start_sha256: str | None = None
    scales: Scales
    q_floor_selection: dict | None = None  # how the q floor was chosen after training, where it was


@dataclass(frozen=True, kw_only=True)
class PolicyRecord(Section):
    """``policy.json``: how to fly the models a stable-baselines3 run saved.

    :param algorithm: the run's algorithm (none: any stable-baselines3 algorithm that loads).
    :param mode: ``direct`` (the model's action is the environment's), ``residual`` (an angle
        offset on TV-LQR of ``authority_rad``) or ``student`` (fine-tuned from a student, ``student``).
    :param normalized: whether the model was trained on normalized observations (its
        ``vecnormalize.pkl`` is then required).
    """

    algorithm: str | None = None
    mode: Literal["direct", "residual", "student"] = "direct"
    authority_rad: tuple[float, float] | None = setting(None, ge=0)
    normalized: bool = True
    student: FineTunedSpec | None = None

    def __post_init__(self):
        super().__post_init__()
        if self.mode == "residual" and not (self.authority_rad and all(a > 0 for a in self.authority_rad)):
            raise ConfigError(f"mode 'residual' needs authority_rad, two angles > 0, got {self.authority_rad}")
        if self.mode == "student" and self.student is None:
            raise ConfigError("mode 'student' needs the student it was fine-tuned from (student)")


@dataclass(frozen=True, kw_only=True)
class RunRecord(Section):
    """The keys of a run's ``metadata.json`` that loaders read (the rest is written for people)."""

    IGNORE_UNKNOWN = True

    algorithm: str | None = None
    seed: int | None = None
    timesteps: int | None = None
    provenance: dict | None = None
    config: dict | None = None
    selected: dict | None = None


__all__ = [
    "FineTunedSpec",
    "PolicyRecord",
    "RunRecord",
    "Scales",
    "StudentDeploy",
    "StudentNetwork",
    "StudentRecord",
    "check_floor_margin",
    "check_relief_margin",
    "horizon_keys",
]  # fmt: skip
