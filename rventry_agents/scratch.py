"""Reinforcement learning from scratch: rejax PPO on the functional ``RvEntry``, with a reverse curriculum.

No teacher, no demonstrations, no optimizer in the loop and no reference in the observation:
the policy sees the environment's 26 features and is paid the environment's reward. What helps
it is where its training episodes start. ``[curriculum]`` starts most of them on the shipped
reference trajectory (perturbed, inside the path bounds), first in the last minute before
impact, then further back each time the policy lands from there (a reverse curriculum); the
others start as the rung does. Optional: attitude commands instead of rates
(:mod:`rventry_agents.commands`), potential-based shaping (:mod:`rventry_env.envs.shaping`).
Every setting is in one config file (:mod:`rventry_agents.scratch_config`,
``rventry_agents/ppo_scratch.toml``).

The environment and the learner are compiled together (rejax: rollouts, advantages and updates
in one XLA program). Training goes in chunks of ``chunk_timesteps``; the curriculum's window is
data, so every chunk runs the first one's program. After each chunk the run:

* moves the curriculum's window back where the policy lands from its frontier;
* flies the deterministic policy on ``select_episodes`` of the rung's own episodes (JAX, keys
  from ``select_seed``) and keeps the best by the task metric as ``policy.npz``;
* keeps the policy that has just landed the frontier, where the window moves, in
  ``milestones/window_<W>s/`` (later chunks may forget the late flight while they learn further back);
* writes ``checkpoint/`` whole (the training state, the curriculum, the history), from which
  ``resume=True`` goes on after an interruption, and from which another run may start under a
  changed config (``init_from``: a new curriculum or learning rate from where this run stood);
* where the chunk is the best so far, copies that checkpoint to ``selected/`` with the run's
  config: a later stage (another rung, a smaller step) starts from the selected policy with its
  own critic, optimizer moments and reward statistics (``init_from=RUN/selected``), which an
  export alone does not carry.

A run writes into its output directory ``policy.npz`` (the selected actor,
:class:`~rventry_agents.jax_policy.JaxPolicy` flies it), ``evaluations.json``,
``learning_curve.png``, ``config.json`` and ``metadata.json`` (provenance, the task, steps,
wall time, env-steps/s, the device, the curriculum's history, and ``runs``: the processes that
trained it, a resumed run's after those it resumes, each with its steps, command, commit, machine
and packages).
"""

from __future__ import annotations

import json
import math
import shlex
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from rventry_agents.config import ConfigError
from rventry_agents.scratch_config import ScratchConfig, load_config
from rventry_env.envs.reward import RewardWeights
from rventry_env.util.files import output_set, write_json

FRONTIER_DEPTH = 0.85  # the frontier: starts between this share of the window and all of it
UNKNOWN = object()  # a source's training draws where its record does not say them


def make_task(cfg: ScratchConfig):
    from rventry_env.task import EntryTask

    return EntryTask()


def make_shaping(cfg: ScratchConfig):
    """The shaping the config asks for (None: none)."""
    sh = cfg.shaping
    if sh.potential == "none":
        return None
    from rventry_env.envs.shaping import PotentialShaping
    from rventry_env.reference.shaping import energy_range_profile, fade_energies

    def reference_energies(key: str):  # the reference's energies over its last [shaping] `key` seconds
        try:
            return fade_energies(getattr(sh, key))
        except ValueError as exc:
            raise ConfigError(f"[shaping] {key}: {exc}") from None

    fade = reference_energies("fade_s") if sh.fade_s else None
    late = {}
    if sh.terminal:  # the reward's own weights of the terms named, none of the others
        named = {f: getattr(cfg.reward, f) if term in sh.terminal else 0.0 for term, f in TERMINAL_TERMS.items()}
        late = {"terminal": RewardWeights(**named), "terminal_energies": reference_energies("terminal_s"),
                "final_speed": make_task(cfg).problem.final_speed}  # fmt: skip
    if sh.potential == "range":
        return PotentialShaping("range", cfg.ppo.gamma, sh.weight, fade_energies=fade, **late)
    energies, ranges = energy_range_profile()
    return PotentialShaping("energy", cfg.ppo.gamma, sh.weight, energies=energies, ranges=ranges, fade_energies=fade,
                            **late)  # fmt: skip


# [shaping] terminal's terms: the RewardWeights field that weights each
TERMINAL_TERMS = {"miss": "miss_per_km", "vertical": "vertical_per_deg", "speed": "speed_per_mps", "alpha": "alpha_per_deg"}


class Curriculum:
    """Where training episodes start: the window of the reverse curriculum, as start states."""

    def __init__(self, cfg: ScratchConfig, window_s: float | None = None):
        from rventry_env.evaluation.rungs import rung
        from rventry_env.reference import load_reference

        self.cfg, self.c = cfg, cfg.curriculum
        self.rung = rung(cfg.env.rung)
        ref = load_reference()
        # how far back the window may go: the rung's own earliest start, or the reference's entry
        self.limit = float(self.rung.before_impact_s[1]) if self.rung.before_impact_s else math.floor(ref.tf - ref.t0)
        first = self.limit if self.c.kind == "uniform" else min(self.c.first_window_s, self.limit)
        self.window = first if window_s is None else float(window_s)

    @property
    def active(self) -> bool:
        return self.c.kind != "none"

    @property
    def complete(self) -> bool:
        return self.window >= self.limit

    def starts(self, window: float | None = None, probability: float | None = None):
        """Start states of the window (or another ``window``): None without a curriculum."""
        from rventry_env.reference.starts import reference_starts

        if not self.active:
            return self.rung.starts()
        w = self.window if window is None else window
        # a rung with start states of its own is all start states: its episodes come from the window
        p = 1.0 if self.rung.before_impact_s else self.c.probability
        lo = min(self.c.latest_s, w)
        return reference_starts((lo, w), p if probability is None else probability, far_weight=self.c.far_weight,
                                step_weighted=self.c.step_weighted, **self.c.perturbations())  # fmt: skip

    def frontier(self):
        """Start states near the window's far end, every episode from them."""
        return self.starts_between(FRONTIER_DEPTH * self.window, self.window)

    def starts_between(self, lo: float, hi: float):
        from rventry_env.reference.starts import reference_starts

        return reference_starts((max(lo, 1.0), hi), 1.0, **self.c.perturbations())

    def advance(self, frontier_success: float) -> bool:
        """Move the window back where the policy lands from its frontier; whether it moved."""
        if self.c.kind != "reverse" or self.complete or frontier_success < self.c.advance_at:
            return False
        grown = self.window * self.c.growth
        if self.c.max_step_s is not None:
            grown = min(grown, self.window + self.c.max_step_s)
        self.window = min(grown, self.limit)
        return True


def ppo_class(resets: int, train_actor: bool = True):
    """rejax's PPO, stepping its environments with :func:`~rventry_env.envs.functional.step_batch`'s
    optimistic autoreset (``resets`` fresh starts a step) where ``resets`` > 0, with gymnax's own else;
    with the policy held as it is (the actor's parameters, its optimizer's state and its observation
    statistics) where not ``train_actor``, while the critic and the reward statistics learn (a
    critic's warm-up, ``[ppo] train_actor``)."""
    from rejax import PPO

    base = PPO
    if resets > 0:
        from rventry_env.envs.functional import step_batch

        class OptimisticResetPPO(PPO):
            @property
            def vmap_step(self):
                return lambda keys, states, actions, params: step_batch(self.env, keys, states, actions, params, resets)

        base = OptimisticResetPPO
    if train_actor:
        return base

    class HeldActorPPO(base):
        """The policy held: the actor's parameters and its observation statistics (which the
        actor's inputs are scaled by) stay as they are."""

        def update_actor(self, ts, batch):
            return ts

        def update_and_normalize_obs(self, rms_state, x, batched=True):
            return rms_state, self.normalize_obs(rms_state, x)

    return HeldActorPPO


def _agent(cfg: ScratchConfig, env, params, chunk: int):
    """rejax PPO for ``env`` (its evaluation replaced: the run evaluates between chunks)."""
    p = cfg.ppo
    algo = ppo_class(cfg.env.resets, p.train_actor).create(
        env=env, env_params=params, num_envs=cfg.env.num_envs, num_steps=p.num_steps, num_epochs=p.num_epochs,
        num_minibatches=p.num_minibatches, learning_rate=p.learning_rate, gamma=p.gamma, gae_lambda=p.gae_lambda,
        clip_eps=p.clip_eps, ent_coef=p.ent_coef, vf_coef=p.vf_coef, max_grad_norm=p.max_grad_norm,
        normalize_observations=p.normalize_observations, normalize_rewards=True, reward_normalization_discount=p.gamma,
        total_timesteps=chunk, eval_freq=chunk, skip_initial_evaluation=True,
        agent_kwargs={"hidden_layer_sizes": tuple(p.hidden_layer_sizes), "activation": p.activation},
    )  # fmt: skip
    if p.critic_hidden_layer_sizes is not None:  # the critic of its own widths, the actor's activation
        algo = algo.replace(critic=algo.critic.clone(hidden_layer_sizes=tuple(p.critic_hidden_layer_sizes)))
    return algo.replace(eval_callback=lambda algo, ts, rng: ())


def _initial_state(algo, cfg: ScratchConfig, seed: int):
    import jax

    from rventry_agents.jax_ppo import settled_state

    return settled_state(with_log_std(algo.init_state(jax.random.PRNGKey(seed)), cfg.ppo.log_std_init))


def _reseeded(ts, seed: int):
    """The training state with ``seed`` folded into its random key: a run started from another's
    checkpoint under another seed draws its own rollouts and minibatches from there (the key is
    in the checkpoint, so without this the seed would change nothing)."""
    import jax

    return ts.replace(rng=jax.random.fold_in(ts.rng, seed))


def _entered(ts, cfg: ScratchConfig, seed_before: int | None):
    """The training state as a run under ``cfg`` starts from another's (or a stage from the stage
    before it), and what that changed, for the progress line: the exploration noise set back to
    ``log_std_init`` where ``restart_exploration``, and another seed than ``seed_before`` folded into
    the random key."""
    changes = ""
    if cfg.ppo.restart_exploration:
        ts = with_log_std(ts, cfg.ppo.log_std_init)
        changes += f", exploration std set back to {math.exp(cfg.ppo.log_std_init):.3g}"
    if cfg.train.seed != seed_before:
        ts = _reseeded(ts, cfg.train.seed)
        changes += f", seed {cfg.train.seed} folded into its random key"
    return ts, changes


def _with_optimizers(ts, algo):
    """The training state with ``algo``'s optimizers (its learning rate and gradient clip), their
    state (Adam's moments and count) as it was: a stage's new settings reach the updates (the
    optimizer is a static part of the state, which the state would otherwise keep)."""
    import jax

    fresh = algo.initialize_network_params(jax.random.PRNGKey(0))
    return ts.replace(actor_ts=ts.actor_ts.replace(tx=fresh["actor_ts"].tx),
                      critic_ts=ts.critic_ts.replace(tx=fresh["critic_ts"].tx))  # fmt: skip


def falling_adam(learning_rate: float, learning_rate_end: float, first: int, last: int, max_grad_norm: float):
    """rejax PPO's optimizer (each gradient's elements clipped to ``max_grad_norm``, then Adam) with
    its learning rate falling linearly from ``learning_rate`` at Adam's update ``first`` to
    ``learning_rate_end`` at update ``last``, and held there after. Its state has the form of
    rejax's (``optax.adam``'s: the moments and their count, then an empty state), so a checkpoint
    of either goes on under the other; with the two rates equal it is rejax's, update for update."""
    import jax
    import jax.numpy as jnp
    import optax

    adam = optax.scale_by_adam()
    span = max(last - first, 1)

    def init(params):
        return adam.init(params), optax.EmptyState()

    def update(updates, state, params=None):
        moments, empty = state
        k = jnp.clip((moments.count - first) / span, 0.0, 1.0)
        lr = learning_rate + (learning_rate_end - learning_rate) * k
        updates, moments = adam.update(updates, moments, params)
        return jax.tree_util.tree_map(lambda u: -lr * u, updates), (moments, empty)

    return optax.chain(optax.clip(max_grad_norm), optax.GradientTransformation(init, update))


def updates_between(cfg: ScratchConfig, start: int, end: int) -> int:
    """Adam's updates (of the actor's, or the critic's) in training from step ``start`` to ``end``
    under ``cfg``: an update per minibatch, ``num_minibatches`` an epoch, ``num_epochs`` a rollout
    of ``num_envs`` x ``num_steps`` steps."""
    p = cfg.ppo
    return (end - start) // (cfg.env.num_envs * p.num_steps) * p.num_epochs * p.num_minibatches


def adam_count(ts) -> int:
    """The count of Adam's updates in the training state (the actor's)."""
    import optax

    return int(optax.tree_utils.tree_get(ts.actor_ts.opt_state, "count"))


def _falling(ts, cfg: ScratchConfig, lr_from: int, steps: int, changes: str = ""):
    """The training state under ``cfg``'s falling learning rate (``[ppo] learning_rate_end``), its
    fall started at step ``lr_from`` (the run stands at ``steps``), and ``changes`` with the fall
    named (for the progress line); both as they were where the rate is constant."""
    p = cfg.ppo
    if p.learning_rate_end is None:
        return ts, changes
    first = adam_count(ts) - updates_between(cfg, lr_from, steps)
    last = first + updates_between(cfg, lr_from, cfg.train.total_timesteps)
    tx = falling_adam(p.learning_rate, p.learning_rate_end, first, last, p.max_grad_norm)
    changes += (f", learning rate {learning_rate_at(cfg, lr_from, steps):.3g} falling to {p.learning_rate_end:.3g} "
                f"by {cfg.train.total_timesteps:,d} steps")  # fmt: skip
    return ts.replace(actor_ts=ts.actor_ts.replace(tx=tx), critic_ts=ts.critic_ts.replace(tx=tx)), changes


def learning_rate_at(cfg: ScratchConfig, lr_from: int, steps: int) -> float:
    """The learning rate of the next update at ``steps`` under ``cfg``, its fall started at ``lr_from``."""
    p = cfg.ppo
    if p.learning_rate_end is None:
        return p.learning_rate
    span = max(updates_between(cfg, lr_from, cfg.train.total_timesteps), 1)
    k = min(max(updates_between(cfg, lr_from, steps) / span, 0.0), 1.0)
    return p.learning_rate + (p.learning_rate_end - p.learning_rate) * k


def _sets_learning_rate(stage) -> bool:
    """Whether a stage gives the learning rate or its fall (and so starts the fall afresh)."""
    ppo = stage.changes.get("ppo", {})
    return "learning_rate" in ppo or "learning_rate_end" in ppo


def _next_stage(trainer: Trainer, cfg: ScratchConfig) -> Trainer:
    """A trainer for the next stage's ``cfg``, where ``trainer`` stood: its curriculum's window, its
    start, the count of compilations."""
    nxt = Trainer(cfg, trainer.out, cfg.train.seed)
    nxt.curriculum.window = trainer.curriculum.window
    nxt.init_from, nxt.traces = trainer.init_from, trainer.traces
    nxt.with_window()
    return nxt


def _restored_average(point, ts, history: list[dict], rung: str):
    """The averaged actor (``[train] policy_average``) a run goes on with from ``point`` (its own
    checkpoint or another run's, with its chunks' records ``history``): the checkpoint's, unless its
    last chunk flew another rung than ``rung``, where the average starts afresh (None)."""
    if point is None or not history or history[-1].get("rung", rung) != rung:
        return None
    return point.average(ts.actor_ts.params)


def _average_flown(trainer: Trainer, ts, rec: dict, average):
    """After a chunk, under ``[train] policy_average``: the averaged actor brought up to the chunk's,
    its flight of the selection set recorded in ``rec`` (``average``); None without an average."""
    b = trainer.cfg.train.policy_average
    if not b:
        return None
    average = _averaged(average, ts.actor_ts.params, b)
    rec["average"] = {"select": trainer.select(with_actor(ts, average))}
    return average


def _averaged(average, params, b: float):
    """The exponential average of the actor's parameters after a chunk whose actor has ``params``:
    ``b`` times ``average`` (None: none yet, so the chunk's own) plus 1 - ``b`` times ``params``."""
    import jax

    return params if average is None else jax.tree_util.tree_map(lambda a, p: b * a + (1 - b) * p, average, params)


def with_actor(ts, params):
    """The training state with the actor's parameters ``params`` (all else as it was)."""
    return ts.replace(actor_ts=ts.actor_ts.replace(params=params))


def with_log_std(ts, log_std: float):
    """The training state with the exploration noise's log standard deviation set to ``log_std``
    in every action dimension (the rest of the state, the optimizer's included, as it was)."""
    import jax
    import jax.numpy as jnp

    params = jax.tree_util.tree_map(lambda v: v, ts.actor_ts.params)
    params["params"]["action_log_std"] = jnp.full_like(params["params"]["action_log_std"], log_std)
    return ts.replace(actor_ts=ts.actor_ts.replace(params=params))


class Trainer:
    """One run: the environment, the learner, the curriculum and the evaluations (see the module docstring)."""

    def __init__(self, cfg: ScratchConfig, out: Path, seed: int):
        import jax

        from rventry_agents.jax_env import make_training_env, training_draws

        self.cfg, self.out, self.seed = cfg, out, seed
        self.task = make_task(cfg)
        self.curriculum = Curriculum(cfg)
        self.env = make_training_env(cfg, self.task, self.curriculum.starts(), make_shaping(cfg))
        base = self.env.base
        self.params = base.make_params(dispersion=training_draws(cfg.env), seed=seed)
        chunk = cfg.train.chunk_timesteps
        self.algo = _agent(cfg, self.env, self.params, chunk)
        self.traces = []
        self.init_from = None  # the checkpoint this run started from (another run's), if any

        def train_chunk(algo, ts):
            self.traces.append(1)  # one entry per trace of the training program: each is a compilation
            return algo.train(train_state=ts)[0]

        self._train = jax.jit(train_chunk)
        # compiled once each: a new evaluator would be a new program to compile
        self.selection = self.env.evaluator(self.algo, cfg.train.select_episodes)
        self.frontier_eval = self.env.evaluator(self.algo, cfg.curriculum.frontier_episodes)
        # the rung's own episodes (its start states, or none), the selection pool's seed apart from training's
        self.select_params = base.make_params(dispersion=self.curriculum.rung.dispersion, seed=cfg.train.select_seed,
                                              starts=self.curriculum.rung.starts())  # fmt: skip

    def with_window(self) -> None:
        """The learner's environment params with the curriculum's current window (no recompilation)."""
        starts = self.curriculum.starts()
        params = self.params if starts is None else self.params._replace(starts=self.env.base.start_params(starts))
        self.algo = self.algo.replace(env_params=params)

    def chunk(self, ts):
        import jax

        ts = self._train(self.algo, ts)
        jax.block_until_ready(ts)
        return ts

    def frontier(self, ts, key) -> dict:
        params = self.params._replace(starts=self.env.base.start_params(self.curriculum.frontier()))
        return self.frontier_eval(ts, params, key)

    def probe(self, ts, lo: float, hi: float, key) -> dict:
        """The deterministic policy from the reference ``lo``-``hi`` s before impact (the frontier's episodes)."""
        params = self.params._replace(starts=self.env.base.start_params(self.curriculum.starts_between(lo, hi)))
        return self.frontier_eval(ts, params, key)

    def select(self, ts) -> dict:
        import jax

        return self.selection(ts, self.select_params, jax.random.PRNGKey(self.cfg.train.select_seed))


def train_scratch(config=None, out: str | Path = "runs/ppo_scratch", seed: int | None = None,
                  timesteps: int | None = None, max_wall_s: float | None = None, resume: bool = False,
                  init_from: str | Path | None = None, progress=print) -> dict:  # fmt: skip
    """Train as the config says (default ``rventry_agents/ppo_scratch.toml``); see the module docstring.

    :param timesteps: override ``[train] total_timesteps``; :param seed: ``[train] seed``;
    :param max_wall_s: stop after the chunk that ends past this wall time (s), everything written
        (``[train] max_wall_s``); a resumed run counts its earlier segments' time, a run from another
        run's checkpoint or export its own time alone (not its source's).
    :param resume: go on with the interrupted run in ``out`` from its last checkpoint.
    :param init_from: a run folder whose checkpoint this run starts from: its training state, its
        curriculum's window, its history and its steps and wall time (which the budget counts), under
        this config, in a new ``out``. The training state must fit the config (the network, the
        number of environments, the algorithm's settings that size it); the rest may change. The
        run's metadata and milestones name where it started.
    """
    from rventry_agents.scratch_state import check_out, check_source
    from rventry_env.core.backend import jax_x64, prefer_fused_cpu_runtime

    cfg = load_config(config)
    changes = {k: v for k, v in (("seed", seed), ("total_timesteps", timesteps), ("max_wall_s", max_wall_s)) if v is not None}
    if changes:
        cfg = cfg.replace(train=replace(cfg.train, **changes))
    out = Path(out)
    if resume and init_from is not None:
        raise ValueError("give resume (go on with the run in out) or init_from (a new run from another's checkpoint), "
                         "not both")  # fmt: skip
    source = None if init_from is None else check_source(Path(init_from), out)
    check_out(out, cfg, resume)
    prefer_fused_cpu_runtime()
    with jax_x64(cfg.env.dtype == "float64"):
        return _train(cfg, out, resume, progress, source)


def _train(cfg: ScratchConfig, out: Path, resume: bool, progress, source: Path | None = None) -> dict:
    from rventry_agents.scratch_state import Checkpoint, PolicyStart, Processes, plot_learning_curve, read_start
    from rventry_agents.scratch_state import record_chunk

    start = out if resume else source  # the checkpoint (or the exported policy) this run goes on from, if any
    point = None if start is None else read_start(start)
    steps = 0 if point is None else point.steps
    stages = cfg.stage_configs()
    stage = _stage_now(cfg, steps, point.history if resume else [])
    trainer = Trainer(stages[stage][1], out, stages[stage][1].train.seed)
    if isinstance(point, PolicyStart):
        point.check(trainer.cfg)
    if point is None:
        ts = _initial_state(trainer.algo, trainer.cfg, trainer.cfg.train.seed)
        history, wall_before = [], 0.0
    else:
        ts, history, wall_before, steps = _restored(point, trainer)
    first = _stage_records(history, stage) if resume else len(history)  # this stage's chunks, for what the next waits on
    average = _restored_average(point, ts, history, trainer.cfg.env.rung)
    ts, changes = _starting(ts, trainer, point, history, source, stages, stage if resume else None)
    lr_from = _fall_from(cfg, history if resume else [], stage, steps)
    ts, changes = _falling(ts, trainer.cfg, lr_from, steps, changes)
    # a resumed run keeps its own start; a run from another's checkpoint starts there
    trainer.init_from = None if point is None else point.init_from if resume else point.origin()
    runs = Processes(point.runs if resume else [], steps)  # this process, after those of the run it resumes
    if not resume:
        write_json(out / "config.json", cfg.to_dict())
    if line := _start_line(cfg, source, point, stage, steps, changes):
        progress(line)
    trainer.with_window()
    t0, rates = time.perf_counter(), []
    best = _best(history, trainer.cfg.env.rung)
    compiles = True  # the next chunk includes the compilation of its program
    while steps < cfg.train.total_timesteps:
        c = trainer.curriculum
        if stage < len(cfg.stages) and cfg.stages[stage].due(steps, history[first:], c.window, c.complete):
            stage, first = stage + 1, len(history)  # the next stage starts here
            before = stages[stage - 1][1]
            trainer = _next_stage(trainer, stages[stage][1])
            lr_from = steps if _sets_learning_rate(cfg.stages[stage - 1]) else lr_from
            ts, changes = _stage_entered(ts, trainer, before, lr_from, steps)
            best = _best(history, trainer.cfg.env.rung)
            average = average if trainer.cfg.env.rung == before.env.rung else None  # a rung's own chunks averaged
            waited = cfg.stages[stage - 1].waits()
            progress(f"stage {stage} from {steps:,d} steps{changes}" + (f" ({waited})" if waited else ""))
            compiles = True
        c0 = time.perf_counter()
        ts = trainer.chunk(ts)
        dt = time.perf_counter() - c0
        done = int(ts.global_step)
        if not compiles:
            rates.append((done - steps) / dt)
        compiles = False
        steps = done
        rec = record_chunk(trainer, ts, steps, wall_before + time.perf_counter() - t0, dt)
        if cfg.stages:
            rec["stage"] = stage
        rec["rung"] = trainer.cfg.env.rung
        _record_rate(rec, trainer.cfg, lr_from, steps)
        average = _average_flown(trainer, ts, rec, average)
        history.append(rec)
        if best is None or chunk_rank(rec) > chunk_rank(best):
            best = rec
            rec["best"] = True
            trainer.env.export(out / "policy.npz", trainer.algo, with_actor(ts, average) if _by_average(rec) else ts)
        c = rec.get("curriculum")
        if c and c["next_window_s"] > c["window_s"]:
            save_milestone(out, trainer, ts, rec)
        progress(_line(rec, trainer.cfg.curriculum.advance_at))
        write_json(out / "evaluations.json", history)
        Checkpoint.write(out, ts, trainer.curriculum.window, history, rec["wall_s"], steps, trainer.init_from, average,
                         runs.now(steps))  # fmt: skip
        if rec.get("best"):
            Checkpoint.keep_selected(out)
        if (budget := cfg.train.max_wall_s) is not None and own_wall(rec["wall_s"], trainer.init_from) >= budget:
            break
    meta = _metadata(cfg, trainer, history, best, rates, steps, runs.now(steps))
    write_json(out / "metadata.json", meta)
    plot_learning_curve(history, out / "learning_curve.png", f"PPO from scratch (rejax) on the {cfg.env.rung} rung")
    return meta


def _fall_from(cfg: ScratchConfig, history: list[dict], stage: int, steps: int) -> int:
    """The step where the learning rate's fall started: here (the run's first step, a checkpoint's, a
    stage's entered here that gives the rate), else the resumed run's record (``history`` is a resumed
    run's own, empty otherwise)."""
    last = history[-1] if history else {}
    passed = cfg.stages[last.get("stage", 0):stage]  # the stages a resumed run enters here
    fresh_fall = "learning_rate_from" not in last or any(map(_sets_learning_rate, passed))
    return steps if fresh_fall else last["learning_rate_from"]


def _stage_entered(ts, trainer: Trainer, before: ScratchConfig, lr_from: int, steps: int):
    """(state, changes) on entering the stage of ``trainer`` from the one configured by ``before``: the
    optimizers the new settings need, the rate's fall from ``lr_from``, vehicles drawn afresh where the
    rung, its draws or the shaping change."""
    ts, changes = _entered(_with_optimizers(ts, trainer.algo), trainer.cfg, before.train.seed)
    ts, changes = _falling(ts, trainer.cfg, lr_from, steps, changes)
    return _vehicles_afresh(ts, trainer, before.env.rung, changes, shaping_before=before.shaping,
                            draws_before=before.env.draws)  # fmt: skip


def _record_rate(rec: dict, cfg: ScratchConfig, lr_from: int, steps: int) -> None:
    """The learning rate at ``steps`` and where its fall started, in a falling rate's chunk record."""
    if cfg.ppo.learning_rate_end is not None:
        rec["learning_rate"] = learning_rate_at(cfg, lr_from, steps)
        rec["learning_rate_from"] = lr_from


def last_state(run: str | Path):
    """(trainer, training state, steps) of ``run``'s last checkpoint, under the stage the run was in
    (its curriculum's window as the run left it), for a study of where the run stands."""
    from rventry_agents.scratch_state import Checkpoint

    run = Path(run)
    cfg = load_config(json.loads((run / "config.json").read_text()))
    point = Checkpoint.read(run)
    stage_cfg = cfg.stage_configs()[_stage_now(cfg, point.steps, point.history)][1]
    trainer = Trainer(stage_cfg, run, stage_cfg.train.seed)
    ts = point.restore(_initial_state(trainer.algo, stage_cfg, stage_cfg.train.seed))[0]
    trainer.curriculum.window = point.window
    return trainer, ts, point.steps


def own_wall(wall_s: float, init_from: dict | None) -> float:
    """The run's own wall time: a run's records count on from its source's (a run from another run's
    checkpoint or export), and its budget (``--max-wall-s``) counts from where it started, resumed or not."""
    return wall_s - float((init_from or {}).get("wall_s", 0.0))


def _restored(point, trainer: Trainer):
    """The run's state from its checkpoint (or exported policy), with the run's window set first: vehicles
    drawn afresh (a stage entered on the checkpoint's step, another rung or shaping) start where the run
    stands, as a stage entered straight through starts them."""
    trainer.curriculum.window = point.window
    trainer.with_window()
    return point.restore(_initial_state(trainer.algo, trainer.cfg, trainer.cfg.train.seed))


def save_milestone(out: Path, trainer: Trainer, ts, rec: dict) -> Path:
    """The policy that has just landed the curriculum's frontier, kept as ``milestones/window_<W>s/``
    (its ``policy.npz`` and ``metadata.json``): the run's best policy for starts up to W s before
    impact, which later chunks may forget while they learn further back. ``rventry evaluate``
    and ``studies/ladder.py`` take the folder as an agent."""
    c = rec["curriculum"]
    folder = out / "milestones" / f"window_{c['window_s']:04.0f}s"
    folder.mkdir(parents=True, exist_ok=True)
    cfg = trainer.cfg
    with output_set():  # the policy and its metadata replaced together, or neither
        trainer.env.export(folder / "policy.npz", trainer.algo, ts)
        write_json(folder / "metadata.json", {
            "task": trainer.task.record(), "rung": cfg.env.rung, "seed": cfg.train.seed, "timesteps": rec["timesteps"],
            "wall_s": rec["wall_s"], "config": cfg.to_dict(), "window_s": c["window_s"], "frontier": c["frontier"],
            "probes": rec.get("probes", {}),
            "provenance": policy_provenance(trainer, rec["timesteps"],
                                            milestone=f"landed {c['frontier_success']:.2f} of the starts "
                                            f"{FRONTIER_DEPTH * c['window_s']:.0f}-{c['window_s']:.0f} s before impact"),
        })  # fmt: skip
    return folder


def policy_provenance(trainer: Trainer, steps: int, **extra) -> dict:
    """What a policy of this run is: the learner, its start, curriculum, shaping, actions, rung, steps
    and seed, and the run whose checkpoint it started from, if any."""
    cfg = trainer.cfg
    start = {} if trainer.init_from is None else {"init_from": trainer.init_from}
    draws = {} if cfg.env.draws is None else {"training_draws": cfg.env.draws}
    return {"algorithm": "PPO (rejax), from scratch", "start": "scratch", "curriculum": cfg.curriculum.kind,
            "shaping": cfg.shaping.potential, "actions": cfg.env.actions, "rung": cfg.env.rung, **draws,
            "timesteps": steps, **extra, "seed": cfg.train.seed, **start}  # fmt: skip


def _starting(ts, trainer: Trainer, point, history: list[dict], source: Path | None, stages: list, stage: int | None):
    """The restored training state as this run starts from it, and what that changed (for the
    progress line): from another run's checkpoint (``source``), as if this run's stage were entered
    from it; a resumed run (``stage``, its stage now) stopped on a stage's first step, as the stage
    is entered; otherwise as it was."""
    fresh = getattr(point, "other_vehicles", False)  # the checkpoint's vehicles could not be restored on this rung
    if source is not None:
        # the stage its last chunk flew (one step before a stage that starts on the checkpoint's
        # step: the checkpoint was written before that stage was entered): the one its random key
        # was folded with and its vehicles in flight were drawn and paid under
        before, seed_before, shaping_before, draws_before = _source_stage(source, point.steps - 1,
                                                                          getattr(point, "history", []))  # fmt: skip
        for h in history:  # its records, ranked on the rung they flew
            h.setdefault("rung", before)
        ts, changes = _entered(ts, trainer.cfg, seed_before)
        return _vehicles_afresh(ts, trainer, before, changes, fresh, shaping_before, draws_before)
    if stage is not None and history and (last := history[-1].get("stage", 0)) < stage:
        ts, changes = _entered(ts, trainer.cfg, stages[last][1].train.seed)
        env_before = stages[last][1].env
        return _vehicles_afresh(ts, trainer, env_before.rung, changes, fresh, stages[last][1].shaping, env_before.draws)
    return ts, ""


def _vehicles_afresh(ts, trainer: Trainer, rung_before: str | None, changes: str, fresh: bool = False, shaping_before=None,
                     draws_before=UNKNOWN):  # fmt: skip
    """The training state as a stage (or a run from another's checkpoint) on ``trainer``'s rung,
    draws and shaping starts from one on ``rung_before`` with ``draws_before`` under
    ``shaping_before`` (None, and UNKNOWN for the draws: not known, taken as unchanged): where
    any changed, every vehicle starts afresh from the new draws
    (:func:`~rventry_agents.scratch_state.fresh_vehicles`; ``fresh``: the checkpoint's restore has
    done so already), and what that changed, for the progress line. A vehicle in flight carries
    its state's potential, which another shaping would pay against its own: the step after would
    pay gamma Phi'(s') - Phi(s), not a difference of one potential (and a potential that is on in
    one and off in the other is a state of another form)."""
    from rventry_agents.scratch_state import fresh_vehicles

    rung, shaping, draws = trainer.cfg.env.rung, trainer.cfg.shaping, trainer.cfg.env.draws
    new_rung = rung_before is not None and rung_before != rung
    new_shaping = shaping_before is not None and shaping_before != shaping
    new_draws = draws_before is not UNKNOWN and draws_before != draws
    if not (fresh or new_rung or new_shaping or new_draws):
        return ts, changes
    if not fresh:
        ts = fresh_vehicles(ts, _initial_state(trainer.algo, trainer.cfg, trainer.cfg.train.seed))
    said = [f"on the {rung} rung"] if new_rung or new_draws or (fresh and not new_shaping) else []
    if draws is not None and (new_rung or new_draws or fresh):
        said.append(f"with training draws {_described(draws)}")
    if new_shaping:
        said.append("without shaping" if shaping.potential == "none"
                    else f"under the {shaping.potential} potential ({shaping.weight:g} per km"
                    + (f", fading over the reference's last {shaping.fade_s:g} s" if shaping.fade_s else "")
                    + (f", the terminal {', '.join(shaping.terminal)} over its last {shaping.terminal_s:g} s"
                       if shaping.terminal else "") + ")")  # fmt: skip
    return ts, changes + ", every vehicle started afresh " + " ".join(said)


def _described(draws) -> str:
    """Training draws as a progress line says them: a set's name, or its fields."""
    return draws if isinstance(draws, str) else "{" + ", ".join(f"{k} = {v}" for k, v in draws.items()) + "}"


def _best(history: list[dict], rung: str) -> dict | None:
    """The best of the chunks evaluated on ``rung``'s selection set (a chunk recorded without its
    rung is one of a run that never changed it)."""
    on_rung = [h for h in history if h.get("rung", rung) == rung]
    return max(on_rung, key=chunk_rank) if on_rung else None


def _stage_now(cfg: ScratchConfig, steps: int, history: list[dict]) -> int:
    """The stage a run of ``cfg`` is in at ``steps``: as the steps say, or as its record of the chunks
    flown (``history``) says where a stage that waits on the training's progress has started."""
    return max(cfg.stage_at(steps), history[-1].get("stage", 0) if history else 0)


def _start_line(cfg: ScratchConfig, source: Path | None, point, stage: int, steps: int, changes: str) -> str:
    """The progress line a run starts with ("" where it has nothing to say): where a run from another
    run's state (``source``, read as ``point``) starts and under which stage, or what a resumed run's
    stage changed on entering."""
    if source is not None:
        return (f"starting from {source} at {steps:,d} steps, window {point.window:.0f} s, under this config"
                f"{_stage_said(cfg, stage)}{changes}")
    return f"stage {stage} from {steps:,d} steps{changes}" if changes else ""


def _stage_said(cfg: ScratchConfig, stage: int) -> str:
    """Which of ``cfg``'s stages a run started from another run's state enters, in words ("" where
    ``cfg`` has none). The steps alone place it (:meth:`ScratchConfig.stage_at`): a stage that waits
    on the training's progress starts on this run's own chunks, wherever the source had come to."""
    if not cfg.stages:
        return ""
    said = f", in its stage {stage} of {len(cfg.stages)}" + (" (its first sections)" if stage == 0 else "")
    if stage < len(cfg.stages) and cfg.stages[stage].on_progress:
        said += f", stage {stage + 1} to start on this run's own chunks once {cfg.stages[stage].waits()}"
    return said


def _stage_records(history: list[dict], stage: int) -> int:
    """Where the chunks of ``stage`` begin at the end of ``history``."""
    first = len(history)
    while first and history[first - 1].get("stage", 0) == stage:
        first -= 1
    return first


def _source_stage(run: Path, steps: int, history: list[dict] = ()) -> tuple:
    """(rung, seed, shaping, training draws) the run (or the exported policy) in ``run`` trained
    under at ``steps`` (its chunks' record up to there: ``history``): its stage's, from its
    ``config.json``, else the rung and the seed its ``metadata.json`` gives (None where neither
    says; from a metadata file the shaping None and the draws UNKNOWN: not known)."""
    try:
        cfg = load_config(json.loads((run / "config.json").read_text()))
        stage = cfg.stage_configs()[_stage_now(cfg, steps, list(history))][1]
        return stage.env.rung, stage.train.seed, stage.shaping, stage.env.draws
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        pass
    try:
        meta = json.loads((run / "metadata.json").read_text())
    except (OSError, ValueError):
        return None, None, None, UNKNOWN
    if not isinstance(meta, dict):
        return None, None, None, UNKNOWN
    rung, seed = meta.get("rung"), meta.get("seed")
    seed = seed if isinstance(seed, int) and not isinstance(seed, bool) else None
    return (None if rung is None else str(rung)), seed, None, UNKNOWN


def _key(selection: dict) -> tuple:
    """How a selection evaluation ranks: success rate, then a smaller median miss."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(selection["success_rate"], selection["miss_km_p50"])


def _by_average(rec: dict) -> bool:
    """Whether a chunk's averaged actor ranks above its own (``[train] policy_average``; a tie goes
    to the chunk's own)."""
    average = rec.get("average", {}).get("select")
    return average is not None and _key(average) > _key(rec["select"])


def selected_evaluation(rec: dict) -> dict:
    """The selection evaluation of the policy a chunk's record offers: the chunk's own actor's, or
    its averaged actor's where that ranks better (what the run exports when the chunk is its best)."""
    return rec["average"]["select"] if _by_average(rec) else rec["select"]


def chunk_rank(rec: dict) -> tuple:
    """How a chunk ranks: by the better of its policies on the selection set (:func:`selected_evaluation`)."""
    return _key(selected_evaluation(rec))


def _line(rec: dict, bar: float) -> str:
    s, c = rec["select"], rec.get("curriculum") or {}
    front = f"  window {c['window_s']:5.0f} s frontier {c['frontier_success']:.2f}{_unmet(c, bar)}" if c else ""
    front += "  probes " + " ".join(f"{k}:{v:.2f}" for k, v in rec.get("probes", {}).items())
    if "average" in rec:
        a = rec["average"]["select"]
        front += f"  average: success {a['success_rate']:.2f} miss p50 {a['miss_km_p50']:.1f} km"
    return (f"{rec['timesteps']:>12,d} steps {rec['wall_s']:7.0f} s  success {s['success_rate']:.2f}  miss p50 "
            f"{s['miss_km_p50']:7.1f} km  vertical p50 {s['vertical_error_deg_p50']:5.1f} deg{front}"
            + ("  *best*" if rec.get("best") else ""))  # fmt: skip


# the frontier's success conditions: the key of the share of episodes that met each in its
# evaluation, and of the median error, with its unit, where one is recorded
FRONTIER_CONDITIONS = (("miss", "miss_within_rate", "miss_km_p50", "km"),
                       ("vertical", "vertical_within_rate", "vertical_error_deg_p50", "deg"),
                       ("speed", "speed_within_rate", "speed_error_mps_p50", "m/s"),
                       ("bounds", "violation_rate", None, ""))  # fmt: skip


def _unmet(c: dict, bar: float) -> str:
    """What keeps the frontier from landing, for the progress line: the share of its episodes that
    met each success condition (the impact point, the vertical, the impact speed, the path bounds
    kept), where that share is under ``bar`` (the success at which the window moves back), with the
    median error (the speed's signed: below zero, too slow) where the evaluation records it; nothing
    where the frontier lands, where each share is over the bar (the conditions then fail on
    different episodes), or where the record has no breakdown."""
    f = c.get("frontier")
    if not f or c["frontier_success"] >= bar:
        return ""
    short = []
    for name, key, median, unit in FRONTIER_CONDITIONS:
        share = f.get(key)
        if share is not None and (share := 1.0 - share if name == "bounds" else share) < bar:
            short.append(f"{name} {share:.2f}" + (f" at {f[median]:.1f} {unit}" if median in f else ""))
    return f" (met: {', '.join(short)})" if short else ""


def _metadata(cfg: ScratchConfig, trainer: Trainer, history: list, best: dict, rates: list, steps: int,
              runs: list) -> dict:  # fmt: skip
    import jax

    from rventry_env import __version__

    rate = float(np.median(rates)) if rates else None
    return {
        "command": " ".join(shlex.quote(a) for a in sys.argv), "config": cfg.to_dict(), "task": trainer.task.record(),
        "actions": cfg.env.actions, "rung": cfg.env.rung, "seed": cfg.train.seed, "timesteps": steps,
        "wall_s": history[-1]["wall_s"] if history else 0.0, "env_steps_per_s": rate, "device": str(jax.devices()[0]),
        "train_compilations": len(trainer.traces), "package_version": __version__,
        "provenance": policy_provenance(trainer, steps, selected_at_timesteps=best["timesteps"] if best else None,
                                        **({"selected_policy": "the average of the chunks' actors"} if best and _by_average(best) else {})),
        "best_evaluation": best, "final_window_s": trainer.curriculum.window, "runs": runs,
    }  # fmt: skip


__all__ = ["Curriculum", "Trainer", "chunk_rank", "make_shaping", "save_milestone", "selected_evaluation", "train_scratch",
           "with_actor"]  # fmt: skip
