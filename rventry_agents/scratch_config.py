"""The configuration of ``rventry train ppo-scratch``: reinforcement learning from scratch, as typed sections.

A config file has the sections ``[env]`` (the rung trained on and how the policy acts),
``[reward]`` (optional overrides of :class:`~rventry_env.envs.reward.RewardWeights`),
``[curriculum]`` (start states along the shipped reference), ``[shaping]`` (a potential-based
shaping of the reward), ``[ppo]`` (rejax PPO's settings and the network) and ``[train]`` (budget,
chunks, seed, selection), and optionally ``[[stages]]``: from a given step on, the run goes on
with some of those settings changed (:class:`StageSection`), so that a recipe that changes its
learning rate or its curriculum as it trains is one file. :meth:`ScratchConfig.load` reads one
and checks every key, every stage's included, before anything runs;
``rventry_agents/ppo_scratch.toml`` is the shipped policy's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from rventry_agents.config import ConfigError, Section, dispersion, merge_tables, setting, widths
from rventry_agents.jax_ppo_config import RejaxPPOSection
from rventry_env.envs.reward import RewardWeights
from rventry_env.reference.starts import STEP_S

DEFAULT_CONFIG = Path(__file__).resolve().parent / "ppo_scratch.toml"


def _rung(name: str) -> None:
    from rventry_env.evaluation.rungs import rung

    rung(name)


@dataclass(frozen=True, kw_only=True)
class EnvSection(Section):
    """``[env]``: the task the policy learns and how it acts.

    :param rung: the ladder rung trained and selected on (:mod:`rventry_env.evaluation.rungs`);
        the JAX learner flies the fixed target, so not ``footprint``.
    :param actions: ``"rates"``: the environment's own action; ``"commands"``: attitude commands
        flown by a tracker with time constant ``command_time_s`` (:mod:`rventry_agents.commands`);
        ``"circular-commands"``: the same with the bank command read on the circle, not clipped.
    :param time_limit_is_failure: charge a time-limit cut like a failure (training only).
    :param draws: the vehicle draws of the training episodes, where they differ from the rung's: a
        named set or a table of :class:`~rventry_env.task.Dispersion` fields (e.g. the rung's
        entry state with wider aerodynamic draws). Selection always flies the rung's own draws.
    :param resets: fresh starts drawn per step for the episodes that end (an optimistic autoreset,
        :func:`~rventry_env.envs.functional.step_batch`); 0: gymnax's autoreset, a full reset per
        episode per step.
    """

    rung: str = setting("standard", check=_rung)
    actions: Literal["rates", "commands", "circular-commands"] = "commands"
    command_time_s: float = setting(1.0, gt=0, le=60)
    num_envs: int = setting(512, ge=1)
    max_episode_steps: int = setting(2000, ge=1)
    dtype: Literal["float32", "float64"] = "float32"
    time_limit_is_failure: bool = True
    draws: str | dict | None = dispersion(None)
    resets: int = setting(32, ge=0)

    def __post_init__(self):
        super().__post_init__()
        if self.resets > self.num_envs:
            raise ConfigError(f"[env] resets ({self.resets}) cannot exceed num_envs ({self.num_envs})")
        if self.rung == "footprint":
            raise ConfigError("[env] rung = 'footprint' draws a target per episode, which the JAX environment does "
                              "not fly; train on a fixed-target rung")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class CurriculumSection(Section):
    """``[curriculum]``: episodes started on the shipped reference (reference-state initialisation).

    ``kind = "reverse"`` starts them within ``latest_s`` .. W seconds before the reference's impact,
    W growing by ``growth`` (up to the rung's own earliest start) whenever the deterministic policy
    lands ``advance_at`` of ``frontier_episodes`` started near W (a reverse curriculum, Florensa et
    al. 2017), and by at most ``max_step_s`` seconds at a time where that is given (the steps of a
    constant ratio grow with W: 1.25 takes a window at 873 s to the whole flight at 1,033 s in
    one); ``"uniform"`` starts them anywhere up to the rung's earliest start at once (DeepMimic's
    reference-state initialisation); ``"none"``: only the rung's own starts. ``probability`` is the
    share of training episodes started this way; the others start as the rung does. ``far_weight``
    k makes the start density grow as (s - latest_s)^k toward the window's far end, where the
    frontier is; ``step_weighted`` instead draws the start with density 1/s, s seconds before
    impact, so that the window's parts get about equal shares of the steps flown rather than of the
    episodes (a start s seconds out flies about s steps, so uniform starts fill a rollout mostly
    from the far end) (:class:`~rventry_env.task.starts.StartStates`). Selection and evaluation
    always fly the rung's own starts.
    """

    kind: Literal["none", "reverse", "uniform"] = "reverse"
    probability: float = setting(0.9, gt=0, le=1)
    first_window_s: float = setting(60.0, gt=0)
    latest_s: float = setting(20.0, ge=1)
    growth: float = setting(1.25, gt=1)
    max_step_s: float | None = setting(None, gt=0)
    advance_at: float = setting(0.5, gt=0, le=1)
    frontier_episodes: int = setting(128, ge=1)
    far_weight: float = setting(0.0, ge=0)
    step_weighted: bool = False
    altitude_m: float = setting(300.0, ge=0)
    speed_mps: float = setting(20.0, ge=0)
    flight_path_deg: float = setting(0.2, ge=0)
    heading_deg: float = setting(0.2, ge=0)
    alpha_deg: float = setting(1.0, ge=0)
    sigma_deg: float = setting(5.0, ge=0)

    def __post_init__(self):
        super().__post_init__()
        if self.latest_s > self.first_window_s:
            raise ConfigError(f"[curriculum] latest_s ({self.latest_s:g}) must not exceed first_window_s "
                              f"({self.first_window_s:g})")  # fmt: skip
        if self.step_weighted and self.far_weight:
            raise ConfigError("[curriculum] step_weighted and far_weight both shape where in the window episodes "
                              "start; give one of them")  # fmt: skip
        if self.step_weighted and self.latest_s <= STEP_S:
            raise ConfigError(f"[curriculum] step_weighted draws starts with density 1/s, so latest_s must exceed the "
                              f"start table's {STEP_S:g} s step, got {self.latest_s:g}")  # fmt: skip

    def perturbations(self) -> dict:
        return {k: getattr(self, k) for k in ("altitude_m", "speed_mps", "flight_path_deg", "heading_deg", "alpha_deg",
                                              "sigma_deg")}  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class ShapingSection(Section):
    """``[shaping]``: potential-based shaping (:mod:`rventry_env.envs.shaping`), ``"none"`` to leave the
    reward as it is; ``weight`` is the reward per km of the potential. ``fade_s``: the potential fades
    out linearly in specific energy over the shipped reference's last ``fade_s`` seconds, from its
    whole weight at the reference's energy then to none at its impact energy (0: no fade).
    ``terminal``: the terminal terms (``"miss"``, ``"vertical"``, ``"speed"``, ``"alpha"``) that the
    potential takes on over the reference's last ``terminal_s`` seconds, rising linearly in energy from
    none to the ``[reward]`` section's weight at its impact energy, read on the current state as if
    the flight ended there (none by default)."""

    potential: Literal["none", "range", "energy"] = "none"
    weight: float = setting(0.2, gt=0)
    fade_s: float = setting(0.0, ge=0)
    terminal: tuple[Literal["miss", "vertical", "speed", "alpha"], ...] = ()
    terminal_s: float = setting(0.0, ge=0)

    def __post_init__(self):
        super().__post_init__()
        if self.fade_s and self.potential == "none":
            raise ConfigError(f"[shaping] fade_s ({self.fade_s:g}) fades a potential, and potential = 'none' has none")
        if bool(self.terminal) != bool(self.terminal_s):
            raise ConfigError(f"[shaping] terminal ({list(self.terminal)}) and terminal_s ({self.terminal_s:g}) go "
                              "together: the terms and the seconds over which the potential takes them on")  # fmt: skip
        if self.terminal and self.potential == "none":
            raise ConfigError("[shaping] terminal adds the terminal terms to a potential, and potential = 'none' has none")
        if len(set(self.terminal)) != len(self.terminal):
            raise ConfigError(f"[shaping] terminal names a term twice: {list(self.terminal)}")


@dataclass(frozen=True, kw_only=True)
class PPOSection(RejaxPPOSection):
    """``[ppo]``: rejax PPO's settings and the networks, with this learner's defaults, and the
    exploration noise's starting log standard deviation; the rewards are always normalized.
    ``hidden_layer_sizes`` sizes the actor, and the critic too unless ``critic_hidden_layer_sizes``
    gives the critic its own (a small policy, cheap to fly and to update, beside a wider value
    function). ``restart_exploration``: a run started from another run's checkpoint
    (``init_from``) sets the noise's log standard deviation back to ``log_std_init`` (the learned
    one has often shrunk by then to where the policy barely explores the curriculum's new starts);
    a fresh run starts there anyway, and a resumed run goes on with its own. ``train_actor =
    false`` holds the policy as it is (the actor and its observation statistics) while the critic
    and the reward statistics learn: the critic's warm-up of a run started from a policy alone (a
    ``policy.npz`` without its critic), whose new critic would otherwise steer the policy's first
    updates with values it has not learned yet. ``learning_rate_end``: the learning rate (actor's
    and critic's) falls linearly, update by update, from ``learning_rate`` where the stage it is set
    in starts to this at ``[train] total_timesteps`` (the first stage starts at the run's first step,
    or at the step of the checkpoint the run starts from); not given: constant. A later stage that
    gives ``learning_rate`` or ``learning_rate_end`` starts the fall afresh from its own first step,
    and a later stage that gives neither goes on with it from where it stands."""

    num_minibatches: int = setting(8, ge=1)
    num_epochs: int = setting(4, ge=1)
    hidden_layer_sizes: tuple[int, ...] = widths((64, 64))
    critic_hidden_layer_sizes: tuple[int, ...] | None = widths(None)
    log_std_init: float = setting(-1.0, lt=2)
    restart_exploration: bool = False
    train_actor: bool = True
    learning_rate_end: float | None = setting(None, ge=0)


@dataclass(frozen=True, kw_only=True)
class TrainSection(Section):
    """``[train]``: the budget, its chunks (one compiled program, called again), the seed and the
    selection set: after each chunk the deterministic policy flies ``select_episodes`` of the rung's
    own episodes (keys from ``select_seed``, never the evaluation's seeds) and the best by the task
    metric (success rate, then median miss) is kept. A run started from another run's checkpoint
    (``init_from``) under another ``seed`` folds it into the checkpoint's random key; under the
    same seed it draws what the other run would have drawn next.

    ``policy_average`` b > 0: the run also keeps the exponential average of the actor's parameters
    over its chunks (after each chunk, b times the average before plus 1 - b times the chunk's
    actor), flies that average on the selection set too, and keeps whichever of the two policies
    ranks better (weight averaging: where the chunks' policies swing about a landing, their average
    may land steadier than any one of them). Training goes on from the chunk's own networks. The
    average goes on through the stages, a resume and a run started from another's checkpoint, and
    starts afresh where the rung changes (another selection set) or a stage turns it on. Not given:
    no average."""

    total_timesteps: int = setting(200_000_000, ge=1)
    chunk_timesteps: int = setting(4_194_304, ge=1)
    seed: int = setting(0, ge=0)
    select_episodes: int = setting(256, ge=1)
    select_seed: int = setting(100_000, ge=0)
    max_wall_s: float | None = setting(None, gt=0)
    policy_average: float | None = setting(None, gt=0, lt=1)


# what a stage may not change: what sizes the training state (the network, the environments, the
# actions), the compiled chunk, the budget and the selection set every chunk is ranked on
STAGE_FIXED = {"env": ("actions", "num_envs", "dtype", "resets"),
               "ppo": ("hidden_layer_sizes", "critic_hidden_layer_sizes", "activation", "normalize_observations",
                       "num_steps", "num_minibatches"),
               "train": ("total_timesteps", "chunk_timesteps", "max_wall_s", "select_episodes", "select_seed")}  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class StageSection(Section):
    """``[[stages]]``: from where it starts, the run goes on with the stage's keys changed, on top of
    the stages before it. A stage starts after the first chunk (of the stage before it) at which
    everything it names holds:

    - ``from_timesteps``: the run has trained this many steps (a whole number of chunks);
    - ``when_stalled_chunks``: the curriculum's window has not moved back for this many chunks of the
      stage before;
    - ``when_window_s``: the window has reached this far back (s before impact);
    - ``when_window_complete``: the window holds the whole flight (the rung's own earliest start);
    - ``when_select_success``: a chunk of the stage before has landed this share of the selection set.

    A recipe written on steps alone replays one run's schedule; one written on the curriculum's
    progress fits runs of other seeds, whose windows move back at other steps. The keys are tables
    of the sections above (``ppo = {learning_rate = 1e-4}``, ``curriculum = {growth = 1.06}``),
    checked as the sections check them; what sizes the training state, the chunk, the budget and the
    selection stay (:data:`STAGE_FIXED`). Entering a stage is what starting a new run from the
    checkpoint at that step with ``init_from`` does: ``[ppo] restart_exploration`` sets the
    exploration noise back to ``log_std_init``, and another ``[train] seed`` is folded into the
    random key; the curriculum's window, the history and the selected policy go on. Where a stage
    changes the rung or the shaping, every vehicle in flight starts afresh (its state's form, its
    draws or its potential are the stage before's)."""

    from_timesteps: int | None = setting(None, ge=1)
    when_stalled_chunks: int | None = setting(None, ge=1)
    when_window_s: float | None = setting(None, gt=0.0)
    when_window_complete: bool | None = setting(None)
    when_select_success: float | None = setting(None, gt=0.0, le=1.0)
    changes: dict = field(default_factory=dict)

    def __post_init__(self):
        super().__post_init__()
        if self.when_window_complete is False:
            raise ConfigError("when_window_complete = false names nothing to wait for: leave it out")
        if all(getattr(self, k) is None for k in TRIGGERS):
            raise ConfigError(f"a stage names where it starts: one or more of {', '.join(TRIGGERS)}")
        for name, table in self.changes.items():
            if name == "stages" or not isinstance(table, dict):
                raise ConfigError(f"{name!r}: a stage changes keys of the sections (env, reward, curriculum, shaping, "
                                  "ppo, train), each given as a table")  # fmt: skip
            for key in STAGE_FIXED.get(name, ()):
                if key in table:
                    raise ConfigError(f"{name}.{key} cannot change in a stage: the run's training state, chunk, "
                                      "budget and selection stay as the config's first sections set them")  # fmt: skip

    @property
    def on_progress(self) -> bool:
        """Whether the stage waits on the training's progress, not on its steps alone."""
        return any(getattr(self, k) is not None for k in TRIGGERS[1:])

    def waits(self) -> str:
        """What the stage waited on, in words, where it waits on the training's progress ("" otherwise)."""
        said = []
        if (n := self.when_stalled_chunks) is not None:
            said.append(f"the window stood for {n} chunk{'s' if n != 1 else ''}")
        if self.when_window_s is not None:
            said.append(f"the window at {self.when_window_s:.0f} s or further back")
        if self.when_window_complete:
            said.append("the window holds the whole flight")
        if self.when_select_success is not None:
            said.append(f"{self.when_select_success:g} of the selection set landed")
        return ", ".join(said)

    def due(self, timesteps: int, records: list[dict], window_s: float, window_complete: bool) -> bool:
        """Whether the stage starts at ``timesteps``, after the chunks ``records`` of the stage before
        it (this run's, oldest first), with the curriculum's window at ``window_s`` (holding the whole
        flight or not)."""
        if self.from_timesteps is not None and timesteps < self.from_timesteps:
            return False
        if self.when_window_s is not None and window_s < self.when_window_s:
            return False
        if self.when_window_complete and not window_complete:
            return False
        if self.when_stalled_chunks is not None and stalled_chunks(records) < self.when_stalled_chunks:
            return False
        if self.when_select_success is not None:
            return bool(records) and records[-1]["select"]["success_rate"] >= self.when_select_success
        return True

    @classmethod
    def _pack(cls, data: dict) -> dict:
        return {**{k: data.pop(k) for k in TRIGGERS if k in data}, "changes": data}

    def _unpack(self, data: dict) -> dict:
        return {**{k: data[k] for k in TRIGGERS if k in data}, **data.get("changes", {})}


# what a stage may wait on, the steps first
TRIGGERS = ("from_timesteps", "when_stalled_chunks", "when_window_s", "when_window_complete", "when_select_success")


def stalled_chunks(records: list[dict]) -> int:
    """How many of the last chunks ``records`` (oldest first) ended with the curriculum's window where
    it stood when they began: none moved it back."""
    n = 0
    for rec in reversed(records):
        c = rec.get("curriculum")
        if not c or c["next_window_s"] > c["window_s"]:
            break
        n += 1
    return n


@dataclass(frozen=True, kw_only=True)
class ScratchConfig(Section):
    """A whole ``ppo-scratch`` config (see the module docstring)."""

    env: EnvSection = EnvSection()
    reward: RewardWeights = RewardWeights()
    curriculum: CurriculumSection = CurriculumSection()
    shaping: ShapingSection = ShapingSection()
    ppo: PPOSection = PPOSection()
    train: TrainSection = TrainSection()
    stages: tuple[StageSection, ...] = setting((), what="a list of [[stages]] tables")

    def __post_init__(self):
        super().__post_init__()
        starts = [s.from_timesteps for s in self.stages if s.from_timesteps is not None]
        if starts != sorted(set(starts)):
            raise ConfigError(f"[[stages]] from_timesteps must increase from one stage to the next, got {starts}")
        for i, s in enumerate(self.stages):
            if s.from_timesteps is not None and s.from_timesteps % self.train.chunk_timesteps:
                raise ConfigError(f"[stages][{i}] from_timesteps ({s.from_timesteps:,}) must be a whole number of "
                                  f"chunks ([train] chunk_timesteps = {self.train.chunk_timesteps:,})")  # fmt: skip
        configs = self.stage_configs()  # each stage's config is checked here, before anything runs
        for i, (s, (_, before)) in enumerate(zip(self.stages, configs)):
            if (s.when_stalled_chunks or s.when_window_s or s.when_window_complete) and before.curriculum.kind != "reverse":
                raise ConfigError(f"[stages][{i}] waits on the curriculum's window, and the stage before it has "
                                  f"[curriculum] kind = {before.curriculum.kind!r} (only a reverse curriculum has one)")  # fmt: skip
        if self.train.chunk_timesteps < self.env.num_envs * self.ppo.num_steps:
            raise ConfigError(f"[train] chunk_timesteps ({self.train.chunk_timesteps:,}) is shorter than one rollout "
                              f"(num_envs x num_steps = {self.env.num_envs * self.ppo.num_steps:,})")  # fmt: skip
        if (self.env.num_envs * self.ppo.num_steps) % self.ppo.num_minibatches:
            raise ConfigError(f"[ppo] num_minibatches ({self.ppo.num_minibatches}) must divide a rollout's "
                              f"{self.env.num_envs * self.ppo.num_steps:,} steps")  # fmt: skip

    def stage_configs(self) -> tuple[tuple[int | None, ScratchConfig], ...]:
        """(``from_timesteps``, config) of each stage, the config's own first sections from step 0;
        each config without stages of its own."""
        plain = {k: v for k, v in self.to_dict().items() if k != "stages"}
        out = [(0, self if not self.stages else ScratchConfig.from_dict(plain))]
        for i, stage in enumerate(self.stages):
            plain = merge_tables(plain, stage.changes)
            try:
                out.append((stage.from_timesteps, ScratchConfig.from_dict(plain, f"[stages][{i}]")))
            except ConfigError as exc:
                raise ConfigError(str(exc).replace(f"[stages][{i}]: [", f"[stages][{i}] [")) from None
        return tuple(out)

    def stage_at(self, timesteps: int) -> int:
        """The stage a run of this config is in at ``timesteps`` (0: the config's first sections) as
        far as the steps say: the stages up to the first one that waits on the training's progress,
        which only the run's record tells (:meth:`StageSection.due`)."""
        n = 0
        for s in self.stages:
            if s.on_progress or s.from_timesteps > timesteps:
                break
            n += 1
        return n


def load_config(path: str | Path | dict | None = None) -> ScratchConfig:
    """The config at ``path`` (default :data:`DEFAULT_CONFIG`), or from a dict, checked."""
    if isinstance(path, dict):
        return ScratchConfig.from_dict(path)
    return ScratchConfig.load(DEFAULT_CONFIG if path is None else path)


__all__ = [
    "DEFAULT_CONFIG",
    "CurriculumSection",
    "EnvSection",
    "PPOSection",
    "ScratchConfig",
    "ShapingSection",
    "StageSection",
    "TrainSection",
    "load_config",
]  # fmt: skip
