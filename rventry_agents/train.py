"""Train stable-baselines3 agents on the numpy-batched RvEntry-v0: PPO, RecurrentPPO (sb3-contrib), SAC.

Everything that shapes a result is in one config file: ``rventry_agents/ppo.toml`` (the PPO
residual on the classical law), ``rventry_agents/baselines/*.toml`` (the plain baselines, from
scratch). The algorithm's keyword arguments are the config section named after it
(``[ppo]``, ``[recurrent_ppo]``, ``[sac]``). A run writes into its output directory:

* ``policy.json``: how to fly the saved models (the algorithm; direct, or residual on the reference);
* ``model.zip`` + ``vecnormalize.pkl``: the policy selected on the *task* metric
  (success rate on a fixed dispersed evaluation set, then mean miss distance),
  not on the shaped return;
* ``final_model.zip`` + ``final_vecnormalize.pkl``: the last iterate;
* ``checkpoints/``: periodic snapshots with their normalization statistics;
* ``resume/``: the state after the latest evaluation (model, normalization statistics, SAC's
  replay buffer, the evaluation history's place), from which ``resume=True`` goes on;
* ``config.json``: the config the run started with (a resumed run must use the same);
* ``tb/``: TensorBoard logs (needs the ``train`` extra: ``pip install -e .[train]``);
* ``evaluations.json`` and ``learning_curve.png``: the evaluation history;
* ``metadata.json``: the exact command, seed, wall time, config and best evaluation.
"""

from __future__ import annotations

import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rventry_agents.config import ALGORITHMS, ConfigError, algorithm_class, read_json  # noqa: F401
from rventry_agents.sb3_config import (  # noqa: F401  (the trainer's names for its config)
    BASELINES,
    DEFAULT_CONFIG,
    DEFAULT_CONFIGS,
    FINETUNE_CONFIG,
    SB3Config,
    load_config,
)
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import Dispersion, EntryTask
from rventry_env.util.files import check_writable, save_figure, write_json


def make_task(cfg: SB3Config, base: EntryTask | None = None) -> EntryTask:
    """The training task: the base task with the config's dt and substeps."""
    return cfg.env.task(base)


def make_reward(cfg: SB3Config) -> RewardWeights:
    """The training reward: the environment's weights with the config's [reward] overrides."""
    return cfg.reward


def policy_kwargs(cfg: SB3Config, algorithm: str | None = None) -> dict[str, Any]:
    """The policy network's keyword arguments from the config's [policy] section."""
    return cfg.policy.policy_kwargs(algorithm or cfg.algorithm)


def make_vec_env(cfg: SB3Config, task: EntryTask, n_envs: int | None = None, algorithm: str | None = None, mode=None):
    """The training VecEnv: batched env -> the mode's view (residual, student) -> VecMonitor ->
    [range shaping] -> VecNormalize.

    :param mode: the config's :class:`~rventry_agents.modes.PolicyMode` when already built (default:
        built here; a student-mode config then loads its student).

    VecMonitor sits inside the shaping, so logged episode returns are the
    environment's own (unshaped) rewards.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from rventry_agents.sb3_vec import RangePotentialShaping, RvEntrySB3VecEnv

    if algorithm is not None and algorithm != cfg.algorithm:
        raise ValueError(f"the config is for {cfg.algorithm}, not {algorithm}")
    e, n = cfg.env, cfg.normalize
    venv = RvEntrySB3VecEnv(
        n_envs or e.num_envs, task=task, reward=cfg.reward, dispersion=Dispersion.parse(e.dispersion),
        max_episode_steps=e.max_episode_steps, time_limit_is_failure=e.time_limit_is_failure,
    )  # fmt: skip
    venv = (cfg.policy.build(task) if mode is None else mode).wrap_env(venv, task)
    venv = VecMonitor(venv, info_keywords=("miss_km", "is_success"))
    if cfg.shaping.range_weight > 0:
        venv = RangePotentialShaping(venv, cfg.shaping.range_weight, cfg.discount)
    return VecNormalize(venv, norm_obs=n.norm_obs, norm_reward=n.norm_reward, clip_obs=n.clip_obs,
                        clip_reward=n.clip_reward, gamma=cfg.discount)  # fmt: skip


def evaluation_key(rec: dict) -> tuple[float, float]:
    """How a training evaluation ranks (:func:`~rventry_env.evaluation.summary.task_metric_key`)."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(rec["success_rate"], rec["miss_km"])


def read_resume_point(out: Path, algorithm: str, cfg: SB3Config) -> dict:
    """What a resumed run starts from (see :func:`~rventry_agents.callbacks.save_resume_point`),
    checked against the run's algorithm and config; raises ValueError naming what does not match.
    The config the run started with (``config.json``) is read through the schema, so a run of an
    older version, whose record left defaults out, compares by what it ran with."""
    from rventry_agents.records import PolicyRecord

    state = out / "resume" / "state.json"
    if not state.is_file():
        raise ValueError(f"cannot resume {out}: it has no resume/ point (a run writes one at each evaluation)")
    started = PolicyRecord.read_json(out / "policy.json").algorithm if (out / "policy.json").is_file() else None
    if started != algorithm:
        raise ValueError(f"cannot resume {out}: it is a {started} run, not {algorithm}")
    recorded = read_json(out / "config.json") if (out / "config.json").is_file() else {}
    try:
        recorded = load_config(recorded, algorithm, str(out / "config.json")).to_dict()
    except ConfigError:
        pass  # compared as it is: it differs
    mine = cfg.to_dict()
    if recorded != mine:
        diff = sorted(k for k in set(mine) | set(recorded) if recorded.get(k) != mine.get(k))
        raise ValueError(f"cannot resume {out}: the config differs from the one it started with (sections {diff})")
    point = read_json(state)
    history = [r for r in _read_history(out / "evaluations.json") if r["timesteps"] <= point.get("timesteps", -1)]
    if not (isinstance(point.get("timesteps"), int) and isinstance(point.get("wall_s"), (int, float)) and history):
        raise ValueError(f"cannot resume {out}: {state} names no evaluation of evaluations.json ({point})")
    return {**point, "history": history, "dir": out / "resume"}


def _read_history(path: Path) -> list[dict]:
    """A run's ``evaluations.json``, checked: each evaluation's steps and task metric."""
    history = read_json(path, list)
    for i, rec in enumerate(history):
        if not (isinstance(rec, dict) and isinstance(rec.get("timesteps"), int)
                and all(isinstance(rec.get(k), (int, float)) for k in ("success_rate", "miss_km"))):  # fmt: skip
            raise ConfigError(f"{path}: evaluation {i} lacks its timesteps, success_rate or miss_km: {rec}", located=True)
    return history


@dataclass(frozen=True)
class SB3Run:
    """A stable-baselines3 run's settings, every one checked before anything is written (:func:`prepare_sb3_run`)."""

    cfg: SB3Config
    out: Path
    timesteps: int
    seed: int
    task: EntryTask
    mode: object  # the config's PolicyMode, built (a student loaded)
    resumed: dict | None = None  # the resume point it goes on from

    @property
    def algorithm(self) -> str:
        return self.cfg.algorithm

    @property
    def done(self) -> int:
        """The steps done before this segment."""
        return 0 if self.resumed is None else int(self.resumed["timesteps"])


def prepare_sb3_run(algorithm: str, config=None, timesteps: int | None = None, seed: int | None = None,
                    out: str | Path = "runs/ppo", task: EntryTask | None = None, resume: bool = False) -> SB3Run:  # fmt: skip
    """Read and check the config, the overrides, the resume point and the output folder; build the
    policy mode (loading a student). Nothing is written before this returns, but the folder."""
    import torch

    cfg = load_config(config, algorithm)
    timesteps = int(timesteps if timesteps is not None else cfg.train.total_timesteps)
    seed = int(seed if seed is not None else cfg.train.seed)
    if timesteps < 1:
        raise ValueError(f"timesteps must be positive, got {timesteps}")
    out = Path(out)
    resumed = read_resume_point(out, algorithm, cfg) if resume else None
    if resumed is not None and resumed["timesteps"] >= timesteps:
        raise ValueError(f"cannot resume {out}: it has done {resumed['timesteps']:,} of {timesteps:,} steps already")
    torch.set_num_threads(cfg.train.torch_threads)
    task = make_task(cfg, task)
    mode = cfg.policy.build(task)  # a student-mode start is checked here
    check_writable(folders=(out,))
    return SB3Run(cfg=cfg, out=out, timesteps=timesteps, seed=seed, task=task, mode=mode, resumed=resumed)


def build_model(run: SB3Run):
    """The training VecEnv and the model: new, or the resume point's."""
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        import tensorboard  # noqa: F401

        tb = str(run.out / "tb")
    except ImportError:
        tb = None
    venv = make_vec_env(run.cfg, run.task, mode=run.mode)
    venv.seed(run.seed + run.done)
    algo = algorithm_class(run.algorithm)
    if run.resumed is not None:
        where = run.resumed["dir"]
        venv = VecNormalize.load(str(where / "vecnormalize.pkl"), venv.venv)
        model = algo.load(where / "model.zip", env=venv, device="cpu", tensorboard_log=tb)
        model.set_random_seed(run.seed + run.done)
        if (where / "replay_buffer.pkl").is_file():
            model.load_replay_buffer(where / "replay_buffer.pkl")
        return venv, model
    policy_cls, kwargs = run.mode.network(run.algorithm, policy_kwargs(run.cfg))
    model = algo(policy_cls, venv, seed=run.seed, device="cpu", tensorboard_log=tb, policy_kwargs=kwargs, verbose=0,
                 **run.cfg.hyperparameters.kwargs())  # fmt: skip
    return venv, model


def learn(run: SB3Run, model, callbacks: list, progress_bar: bool) -> int:
    """Train ``model`` up to the run's steps; a new student-mode model first trains its critic
    alone (the actor frozen) for its warm-up. Returns the warm-up's steps."""
    from stable_baselines3.common.callbacks import CallbackList

    warmup, done = 0, run.done
    if run.resumed is None:
        warmup = run.mode.start(model, run.timesteps)  # the starting weights: TV-LQR's zero residual, the student
    if warmup:
        from rventry_agents.finetune import set_actor_trainable

        # the critic learns the student's values first; an actor updated against a random critic
        # takes its first steps from noise
        set_actor_trainable(model.policy, False)
        model.learn(warmup, callback=CallbackList(callbacks), progress_bar=progress_bar)
        set_actor_trainable(model.policy, True)
        done = model.num_timesteps
    if run.timesteps > done:
        model.learn(run.timesteps - done, callback=CallbackList(callbacks), progress_bar=progress_bar,
                    reset_num_timesteps=run.resumed is None and not warmup)  # fmt: skip
    return warmup


def _reference_cost() -> float | None:
    try:
        from rventry_env.reference import load_reference

        return float(load_reference().cost)
    except Exception:  # training does not need the reference; the cost ratio does
        return None


def train_ppo(config: str | Path | dict | None = None, timesteps: int | None = None, seed: int | None = None,
              out: str | Path = "runs/ppo", task: EntryTask | None = None, progress_bar: bool = True) -> Path:  # fmt: skip
    """Train PPO as the config says (default ``rventry_agents/ppo.toml``); see :func:`train_sb3`."""
    return train_sb3("ppo", config, timesteps, seed, out, task, progress_bar)


def train_sb3(algorithm: str, config: str | Path | dict | SB3Config | None = None, timesteps: int | None = None,
              seed: int | None = None, out: str | Path = "runs/ppo", task: EntryTask | None = None,
              progress_bar: bool = True, resume: bool = False) -> Path:  # fmt: skip
    """Train ``algorithm`` (``ppo``, ``recurrent_ppo`` or ``sac``) as the config says; returns the output directory.

    With ``resume``, an interrupted run in ``out`` goes on from its latest evaluation
    (``out/resume/``) up to the total steps: its evaluation history and wall time carry over. The
    environments and the algorithm are re-seeded with ``seed + steps done``, so a resumed run is
    not bit-identical to one that was never stopped.

    :param config: TOML config path (default: the algorithm's, :data:`DEFAULT_CONFIGS`), a loaded
        config, or a dict of one (checked by :func:`~rventry_agents.sb3_config.load_config`).
    :param timesteps: override ``[train] total_timesteps``.
    :param seed: override ``[train] seed``.
    :param out: output directory.
    :param task: the task (default :class:`EntryTask` with the config's dt/substeps).
    :param progress_bar: show SB3's progress bar.
    """
    from stable_baselines3.common.callbacks import CheckpointCallback

    from rventry_agents.callbacks import TaskMetricEval

    run = prepare_sb3_run(algorithm, config, timesteps, seed, out, task, resume)
    cfg, out = run.cfg, run.out
    # how to fly any model saved under ``out`` (best, final, checkpoints)
    write_json(out / "policy.json", {"algorithm": algorithm, **run.mode.record()})
    write_json(out / "config.json", cfg.to_dict())
    reference_cost = _reference_cost()
    venv, model = build_model(run)
    evaluator = TaskMetricEval(cfg.train, lambda m: run.mode.law(m, m.get_vec_normalize_env().normalize_obs, run.task),
                               run.task, cfg.env.max_episode_steps, out, reference_cost, run.resumed)  # fmt: skip
    ckpt = CheckpointCallback(save_freq=max(cfg.train.checkpoint_every // cfg.env.num_envs, 1),
                              save_path=str(out / "checkpoints"), name_prefix=algorithm, save_vecnormalize=True)  # fmt: skip
    start = time.time()
    warmup = learn(run, model, [evaluator, ckpt], progress_bar)
    evaluator.evaluate()  # the final iterate competes for "best" too
    wall = evaluator.wall_before + time.time() - start
    model.save(out / "final_model.zip")
    venv.save(str(out / "final_vecnormalize.pkl"))
    write_run_metadata(run, evaluator, wall, warmup, reference_cost)
    plot_learning_curve(evaluator.history, out / "learning_curve.png")
    return out


def write_run_metadata(run: SB3Run, evaluator, wall: float, warmup: int, reference_cost: float | None) -> None:
    """``metadata.json``: the exact command, seed, wall time, config and best evaluation, and for a
    student-mode run the provenance of the policy it keeps (``model.zip``: the best evaluation's)."""
    best = max(evaluator.history, key=evaluation_key)
    provenance = run.mode.provenance(warmup, run.timesteps, best["timesteps"])
    write_json(run.out / "metadata.json", {
        "command": " ".join(shlex.quote(a) for a in sys.argv),
        "algorithm": run.algorithm,
        "seed": run.seed,
        "timesteps": run.timesteps,
        "wall_time_s": wall,
        "resumed_at_timesteps": evaluator.resumes,
        "torch_threads": run.cfg.train.torch_threads,
        "config": run.cfg.to_dict(),
        **({} if provenance is None else {"provenance": provenance}),
        "best_evaluation": best,
        "reference_cost": reference_cost,
    })  # fmt: skip


def plot_learning_curve(history: list[dict], path: Path) -> None:
    """Success rate and miss distance on the evaluation set against training steps (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not history:
        return
    steps = np.array([h["timesteps"] for h in history]) / 1e6
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    axes[0].plot(steps, [h["success_rate"] for h in history], "o-")
    axes[0].set(xlabel="timesteps (M)", ylabel="success rate (dispersed eval)", ylim=(-0.02, 1.02))
    axes[1].semilogy(steps, [h["miss_km"] for h in history], "o-", label="mean")
    axes[1].semilogy(steps, [h["median_miss_km"] for h in history], "s--", label="median")
    axes[1].set(xlabel="timesteps (M)", ylabel="miss (km)")
    axes[1].legend()
    ret = [h["train_ep_return"] for h in history]
    axes[2].plot(steps, [np.nan if r is None else r for r in ret], "o-")
    axes[2].set(xlabel="timesteps (M)", ylabel="training episode return")
    for ax in axes:
        ax.grid(alpha=0.3)
    save_figure(fig, path)
