"""The configuration of a DAgger run (``rventry train dagger``), as typed sections.

``rventry_agents/dagger.toml`` and ``dagger_flight.toml`` are read by :func:`load_config`, which
checks every key before anything is flown or written: the student's network and tracker, the
expert and its re-planning settings, the training and selection sets, the rounds, the fit, and
what follows the rounds (the ensemble refit, the distillation, and ``[deploy]``: the tracker and
load-relief scan that chooses how the student is deployed).

``[deploy]`` was called ``[flight]`` before: a config or run record with a ``[flight]`` section
is read as ``[deploy]`` (a TOML file with a FutureWarning asking to rename it); one with both is
refused.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

from rventry_agents.config import ConfigError, Section, dispersion, read_toml, setting, widths
from rventry_agents.imitation import Horizon
from rventry_agents.records import StudentNetwork, check_relief_margin

DEFAULT_CONFIG = Path(__file__).resolve().parent / "dagger.toml"
OLD_DEPLOY = "flight"  # the old name of [deploy], still read
@dataclass(frozen=True, kw_only=True)
class StudentSection(StudentNetwork):
    """``[student]``: the student's network (``members`` > 1: an ensemble, the mean of theirs), the
    labels' horizon (``lookahead_*``, which the rounds' tracker flies) and its load relief. The
    rounds fly no q floor (``q_floor_margin`` is refused: one is chosen for a trained policy)."""

    def __post_init__(self):
        super().__post_init__()
        if self.q_floor_margin is not None:
            raise ConfigError("q_floor_margin: the DAgger rounds fly no q floor; choose one for a trained policy "
                              "with studies/choose_q_floor.py")  # fmt: skip


def _replanning_fields() -> tuple[str, ...]:
    from rventry_env.guidance.replanning import ReplanningSettings

    return tuple(f.name for f in dataclasses.fields(ReplanningSettings))


@dataclass(frozen=True, kw_only=True)
class ExpertSection(Section):
    """``[expert]``: the teacher, an agent name (default ``mpc``), and for a re-planning teacher any
    :class:`~rventry_env.guidance.replanning.ReplanningSettings` field, on top of its preset."""

    agent: str = "mpc"
    settings: dict = dataclasses.field(default_factory=dict)  # ReplanningSettings fields

    def __post_init__(self):
        super().__post_init__()
        from rventry_agents.imitation import expert_options

        if self.settings:
            known = _replanning_fields()
            for key in self.settings:
                if key not in known:
                    near = difflib.get_close_matches(key, ("agent", *known), n=1)
                    raise ConfigError(f"unknown key {key!r}; " + (f"did you mean {near[0]!r}?" if near else
                                      "it takes agent and the fields of ReplanningSettings"))  # fmt: skip
        try:
            expert_options(self.agent, tuple(sorted(self.settings.items())))
        except (TypeError, ValueError) as exc:
            raise ConfigError(str(exc)) from None

    @classmethod
    def _pack(cls, data: dict) -> dict:
        return {**({"agent": data.pop("agent")} if "agent" in data else {}), "settings": data}

    def _unpack(self, data: dict) -> dict:
        return {"agent": data["agent"], **data.get("settings", {})}

    @property
    def setting_pairs(self) -> tuple:
        """The settings as sorted (name, value) pairs (:class:`~rventry_agents.imitation.CollectJob`'s)."""
        return tuple(sorted(self.settings.items()))


@dataclass(frozen=True, kw_only=True)
class DataSection(Section):
    """``[data]``: the training vehicles, from seed ``train_seed`` on."""

    dispersion: str | dict = dispersion()
    train_seed: int = setting(ge=0)


@dataclass(frozen=True, kw_only=True)
class RoundSection(Section):
    """``[[rounds]]``: a DAgger round's episodes, and beta, the probability that a step flies the
    expert's action; a round may fly its own load-relief margin (default the [student] one)."""

    episodes: int = setting(ge=1)
    beta: float = setting(ge=0, le=1)
    load_relief_margin: float | None = setting(None, check=check_relief_margin)


@dataclass(frozen=True, kw_only=True)
class FitSection(Section):
    """``[fit]``: the regression of each round's student (Adam, mean squared error)."""

    epochs: int = setting(ge=1)
    batch_size: int = setting(ge=1)
    learning_rate: float = setting(gt=0)
    weight_decay: float = setting(0.0, ge=0)
    seed: int = setting(ge=0)


@dataclass(frozen=True, kw_only=True)
class FinalSection(Section):
    """``[final]``: after the rounds, an ensemble of ``members`` refitted on all their data (1: none)."""

    members: int = setting(1, ge=1)


@dataclass(frozen=True, kw_only=True)
class DistilSection(Section):
    """``[distil]``: one network fitted to the selected network's commands on every state the
    rounds visited, those below ``emphasis_below_m`` counted ``emphasis`` times.

    :param epochs: the fit's epochs (default: [fit] epochs).
    :param keep_teacher_if_better: a teacher that is one network of the same widths keeps
        flying if it does better on the selection set.
    """

    hidden: tuple[int, ...] = widths()
    epochs: int | None = setting(None, ge=1)
    emphasis_below_m: float = setting(0.0, ge=0)
    emphasis: int = setting(1, ge=1)
    keep_teacher_if_better: bool = False


@dataclass(frozen=True, kw_only=True)
class DeploySection(Section):
    """``[deploy]``: after training, the selected network flown on the selection set with each
    tracker horizon ``tracking`` ([max_s, min_s] pairs, the altitude over ``tracking_descent_mps``
    between them), then with each load-relief margin of ``load_relief_margins``; the best is kept."""

    tracking: tuple[tuple[float, float], ...] = setting((), gt=0, what="a list of [max_s, min_s] pairs")
    tracking_descent_mps: float = setting(math.inf, gt=0, finite=False)
    load_relief_margins: tuple[float, ...] = ()

    def __post_init__(self):
        super().__post_init__()
        for m in self.load_relief_margins:
            try:
                check_relief_margin(m)
            except ValueError as exc:
                raise ConfigError(f"load_relief_margins: {exc}") from None
        try:
            self.trackers()
        except ValueError as exc:
            raise ConfigError(f"tracking: {exc}") from None

    def trackers(self) -> list[Horizon]:
        """The candidate tracker horizons."""
        return [Horizon(hi, lo, self.tracking_descent_mps) for hi, lo in self.tracking]


@dataclass(frozen=True, kw_only=True)
class SelectSection(Section):
    """``[select]``: selection after each round, the student alone on ``episodes`` vehicles of the
    ``dispersion`` set from seed ``seed`` (never the evaluation's seeds, 0...)."""

    episodes: int = setting(ge=1)
    seed: int = setting(ge=0)
    dispersion: str | dict = dispersion()


@dataclass(frozen=True, kw_only=True)
class DaggerConfig(Section):
    """A DAgger run's configuration (see the module docstring)."""

    student: StudentSection
    expert: ExpertSection = ExpertSection()
    data: DataSection
    rounds: tuple[RoundSection, ...] = setting(nonempty=True, what="a list of [[rounds]] tables")
    fit: FitSection
    final: FinalSection = FinalSection()
    distil: DistilSection | None = None
    deploy: DeploySection = DeploySection()
    select: SelectSection

    @classmethod
    def _pack(cls, data: dict) -> dict:
        if OLD_DEPLOY in data:  # the section's name before it was [deploy]
            if "deploy" in data:
                raise ConfigError(f"[{OLD_DEPLOY}] is the old name of [deploy]; give only [deploy]")
            data = {("deploy" if k == OLD_DEPLOY else k): v for k, v in data.items()}
        return data

    def __post_init__(self):
        super().__post_init__()
        if self.rounds[0].beta != 1.0:
            raise ConfigError(f"[rounds][0] beta: the first round has no student yet, so its beta must be 1, "
                              f"got {self.rounds[0].beta}")  # fmt: skip


def load_config(path: str | Path | dict | DaggerConfig | None = None, where: str | None = None) -> DaggerConfig:
    """The DAgger configuration, checked: a TOML file (default ``rventry_agents/dagger.toml``) or a
    dict as one reads (``where`` names its source).

    :raises ConfigError: naming the file, the section and the key.
    :warns FutureWarning: a TOML file with the old ``[flight]`` section (read as ``[deploy]``).
    """
    if isinstance(path, (dict, DaggerConfig)):
        return DaggerConfig.from_dict(path, where or "config")
    path = DEFAULT_CONFIG if path is None else path
    data = read_toml(path)
    if OLD_DEPLOY in data and "deploy" not in data:
        warnings.warn(f"{path}: the section [{OLD_DEPLOY}] is now called [deploy]; it is read as [deploy] "
                      "for now: rename it in the file", FutureWarning, stacklevel=2)  # fmt: skip
    return DaggerConfig.from_dict(data, str(path))


__all__ = ["DEFAULT_CONFIG", "DaggerConfig", "DataSection", "DeploySection", "DistilSection", "ExpertSection",
           "FinalSection", "FitSection", "RoundSection", "SelectSection", "StudentSection", "load_config"]  # fmt: skip
