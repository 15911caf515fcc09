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

import math
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from rventry_agents.config import ALGORITHMS, algorithm_class, check_algorithm, read_config
from rventry_env.envs.reward import RewardWeights
from rventry_env.task import Dispersion, EntryTask
from rventry_env.util.files import save_figure, write_json

DEFAULT_CONFIG = Path(__file__).resolve().parent / "ppo.toml"
BASELINES = Path(__file__).resolve().parent / "baselines"
# the config each algorithm's command reads when none is given
DEFAULT_CONFIGS = {"ppo": DEFAULT_CONFIG, "recurrent_ppo": BASELINES / "recurrent_ppo.toml", "sac": BASELINES / "sac.toml"}
FINETUNE_CONFIG = Path(__file__).resolve().parent / "ppo_finetune.toml"  # PPO from the imitation student


def load_config(path: str | Path | dict | None = None, algorithm: str = "ppo") -> dict:
    """The training configuration of ``algorithm``: a TOML file (default: the algorithm's, see
    :data:`DEFAULT_CONFIGS`) or an already-loaded dict, with a section of the algorithm's keyword arguments."""
    check_algorithm(algorithm)
    return read_config(path, DEFAULT_CONFIGS[algorithm], ("env", "normalize", algorithm, "policy", "train"))[0]


def discount(cfg: dict, algorithm: str) -> float:
    """The algorithm's discount factor (also the reward normalization's and the shaping's)."""
    return float(cfg[algorithm].get("gamma", 0.99))


def make_task(cfg: dict, base: EntryTask | None = None) -> EntryTask:
    """The training task: the base task with the config's dt and substeps."""
    from dataclasses import replace

    base = EntryTask() if base is None else base
    return replace(base, dt=float(cfg["env"]["dt"]), substeps=int(cfg["env"]["substeps"]))


def make_reward(cfg: dict) -> RewardWeights:
    """The training reward: the environment's weights with the config's [reward] overrides."""
    from dataclasses import fields, replace

    base = RewardWeights()
    overrides = dict(cfg.get("reward", {}))
    known = {f.name for f in fields(base)}
    unknown = set(overrides) - known
    if unknown:
        raise ValueError(f"[reward] has unknown weight(s) {sorted(unknown)}; known: {sorted(known)}")
    return replace(base, **{k: float(v) for k, v in overrides.items()})


POLICY_MODES = ("direct", "residual", "student")


def policy_mode(cfg: dict) -> tuple[str, list[float]]:
    """("direct" | "residual" | "student", (alpha, sigma) authority in rad) from the config's [policy]
    section. ``student``: PPO fine-tuning from an imitation student, [policy] ``start`` (an agent
    name or a DAgger run's directory; :mod:`rventry_agents.finetune`)."""
    pol = cfg["policy"]
    mode = pol.get("mode", "direct")
    if mode not in POLICY_MODES:
        raise ValueError(f"[policy] mode must be one of {POLICY_MODES}, got {mode!r}")
    authority = [math.radians(float(pol.get("alpha_authority_deg", 0.0))), math.radians(float(pol.get("sigma_authority_deg", 0.0)))]
    if mode == "residual" and not all(a > 0 for a in authority):
        raise ValueError("[policy] mode = 'residual' needs alpha_authority_deg > 0 and sigma_authority_deg > 0")
    privileged = pol.get("privileged_critic", False)
    if not isinstance(privileged, bool):
        raise ValueError(f"[policy] privileged_critic must be true or false, got {privileged!r}")
    if privileged and mode != "student":
        raise ValueError(f"[policy] privileged_critic = true is built for mode = 'student' (PPO from a student), not {mode!r}")
    if mode == "student" and not isinstance(pol.get("start"), str):
        raise ValueError("[policy] mode = 'student' needs start = the student's agent name or DAgger run directory")
    return mode, authority


def make_vec_env(cfg: dict, task: EntryTask, n_envs: int | None = None, algorithm: str = "ppo", student=None):
    """The training VecEnv: batched env -> [residual | student] -> VecMonitor -> [range shaping] -> VecNormalize.

    ``student``: for [policy] mode = "student", the (law, scales) the fine-tuning starts from.

    VecMonitor sits inside the shaping, so logged episode returns are the
    environment's own (unshaped) rewards.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from rventry_agents.residual import ResidualGuidance, ResidualVecEnv
    from rventry_agents.sb3_vec import RangePotentialShaping, RvEntrySB3VecEnv

    e = cfg["env"]
    venv = RvEntrySB3VecEnv(
        n_envs or int(e["num_envs"]), task=task, reward=make_reward(cfg), dispersion=Dispersion.parse(e.get("dispersion", {})),
        max_episode_steps=int(e["max_episode_steps"]), time_limit_is_failure=bool(e["time_limit_is_failure"]),
    )  # fmt: skip
    mode, authority = policy_mode(cfg)
    if mode == "residual":
        venv = ResidualVecEnv(venv, ResidualGuidance(authority, task))
    elif mode == "student":
        from rventry_agents.finetune import StudentVecEnv

        venv = StudentVecEnv(venv, *student, privileged=bool(cfg["policy"].get("privileged_critic", False)))
    venv = VecMonitor(venv, info_keywords=("miss_km", "is_success"))
    shaping = cfg.get("shaping", {})
    if float(shaping.get("range_weight", 0.0)) > 0:
        venv = RangePotentialShaping(venv, float(shaping["range_weight"]), discount(cfg, algorithm))
    n = cfg["normalize"]
    return VecNormalize(
        venv, norm_obs=bool(n["norm_obs"]), norm_reward=bool(n["norm_reward"]), clip_obs=float(n["clip_obs"]),
        clip_reward=float(n["clip_reward"]), gamma=discount(cfg, algorithm),
    )  # fmt: skip


def live_policy(model, vecnorm, cfg: dict, task: EntryTask, spec: dict | None = None):
    """The model being trained as a rollout policy (deterministic, normalized observations);
    ``spec``, a student-started policy's :func:`~rventry_agents.finetune.student_spec`."""
    from rventry_agents.sb3_policy import Predictor, make_policy

    mode, authority = policy_mode(cfg)
    if mode == "student":
        from rventry_agents.finetune import fine_tuned_law

        return fine_tuned_law(model.policy, spec, task)
    return make_policy(Predictor(model, vecnorm.normalize_obs), mode, authority, task)


def evaluation_key(rec: dict) -> tuple[float, float]:
    """How a training evaluation ranks (:func:`~rventry_env.evaluation.summary.task_metric_key`)."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(rec["success_rate"], rec["miss_km"])


def _make_callbacks(cfg: dict, task: EntryTask, out: Path, reference_cost: float | None, algorithm: str,
                    resumed: dict | None = None, spec: dict | None = None):  # fmt: skip
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

    from rventry_env.evaluation.rollout import rollout
    from rventry_env.evaluation.summary import summarize

    t = cfg["train"]

    class TaskMetricEval(BaseCallback):
        """Every ``eval_every`` steps: fly the fixed dispersed evaluation set deterministically,
        log the task metrics, and keep the best model by (success rate, -mean miss)."""

        def __init__(self):
            super().__init__()
            self.next_eval = int(t["eval_every"])
            self.history: list[dict] = []
            self.best_key = (-1.0, -np.inf)
            self.wall_before = 0.0  # the wall time of the run's earlier segments, when resumed
            self.resumes: list[int] = []  # the step counts the run was resumed at
            self.t0: float | None = None  # when this segment's first learn() started
            if resumed is not None:
                self.resumes = [*resumed.get("resumes", []), int(resumed["timesteps"])]
                self.history = list(resumed["history"])
                self.best_key = max(map(evaluation_key, self.history))
                self.next_eval = int(resumed["timesteps"]) + int(t["eval_every"])
                self.wall_before = float(resumed["wall_s"])

        def _on_step(self) -> bool:
            if self.num_timesteps < self.next_eval:
                return True
            self.next_eval += int(t["eval_every"])
            self.evaluate()
            return True

        def evaluate(self):
            vecnorm = self.model.get_vec_normalize_env()
            batch = rollout(
                live_policy(self.model, vecnorm, cfg, task, spec), int(t["eval_episodes"]), seed=int(t["eval_seed"]),
                dispersion=t["eval_dispersion"], task=task, max_episode_steps=int(cfg["env"]["max_episode_steps"]),
            )  # fmt: skip
            s = summarize(batch, reference_cost or 1.0, task)
            rec = {
                "timesteps": int(self.num_timesteps),
                "wall_s": self.wall_before + time.time() - self.t0,
                "success_rate": s["success_rate"],
                "miss_km": s["miss_km"],
                "median_miss_km": s["percentiles"]["miss_km"]["p50"],
                "vertical_error_deg": s["vertical_error_deg"],
                "abs_speed_error_mps": s["abs_speed_error_mps"],
                "cost_ratio": s["cost_ratio"] if reference_cost else None,
                "impact_rate": s["impact_rate"],
                "train_ep_return": float(np.mean([e["r"] for e in self.model.ep_info_buffer]))
                if self.model.ep_info_buffer else None,
            }  # fmt: skip
            self.history.append(rec)
            for k in ("success_rate", "miss_km", "median_miss_km", "vertical_error_deg", "abs_speed_error_mps",
                      "impact_rate"):  # fmt: skip
                if rec[k] is not None:
                    self.logger.record(f"task/{k}", rec[k])
            key = evaluation_key(rec)
            if key > self.best_key:
                self.best_key = key
                self.model.save(out / "model.zip")
                vecnorm.save(str(out / "vecnormalize.pkl"))
                rec["best"] = True
            write_json(out / "evaluations.json", self.history)
            save_resume_point(self.model, out, rec["timesteps"], rec["wall_s"], self.resumes)
            print(
                f"[eval @ {rec['timesteps']:,}] success {rec['success_rate']:.2f} miss {rec['miss_km']:.1f} km "
                f"(median {rec['median_miss_km']:.1f}) vertical {rec['vertical_error_deg']:.1f} deg "
                f"|dv| {rec['abs_speed_error_mps']:.0f} m/s impact {rec['impact_rate']:.2f}"
                + (" *best*" if rec.get("best") else ""),
                flush=True,
            )

        def _on_training_start(self) -> None:
            if self.t0 is None:  # a fine-tuning's second learn() goes on counting from the first
                self.t0 = time.time()
            if resumed is None and not self.history:
                # the untrained policy competes too: the residual starts as the classical law. A
                # fine-tuning's second phase starts where its critic warm-up ended, with the actor
                # the warm-up never moved: the evaluation at step 0 already flew it.
                self.evaluate()

    ckpt = CheckpointCallback(
        save_freq=max(int(t["checkpoint_every"]) // int(cfg["env"]["num_envs"]), 1),
        save_path=str(out / "checkpoints"), name_prefix=algorithm, save_vecnormalize=True,
    )  # fmt: skip
    return TaskMetricEval(), ckpt


def save_resume_point(model, out: Path, timesteps: int, wall_s: float, resumes: list[int]) -> None:
    """Write ``out/resume/`` whole: the model, its normalization statistics, an off-policy
    algorithm's replay buffer, and the step count and wall time they belong to."""
    import shutil

    tmp, final = out / "resume.tmp", out / "resume"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    model.save(tmp / "model.zip")
    model.get_vec_normalize_env().save(str(tmp / "vecnormalize.pkl"))
    if hasattr(model, "replay_buffer") and model.replay_buffer is not None:
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    write_json(tmp / "state.json", {"timesteps": int(timesteps), "wall_s": float(wall_s), "resumes": resumes})
    old = out / "resume.old"
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def read_resume_point(out: Path, algorithm: str, cfg: dict) -> dict:
    """What a resumed run starts from (see :func:`save_resume_point`), checked against the run's
    algorithm and config; raises ValueError naming what does not match."""
    import json

    state = out / "resume" / "state.json"
    if not state.is_file():
        raise ValueError(f"cannot resume {out}: it has no resume/ point (a run writes one at each evaluation)")
    started = json.loads((out / "policy.json").read_text()).get("algorithm") if (out / "policy.json").is_file() else None
    if started != algorithm:
        raise ValueError(f"cannot resume {out}: it is a {started} run, not {algorithm}")
    recorded = json.loads((out / "config.json").read_text()) if (out / "config.json").is_file() else None
    if recorded != json.loads(json.dumps(cfg)):
        diff = sorted(k for k in set(cfg) | set(recorded or {}) if (recorded or {}).get(k) != json.loads(json.dumps(cfg.get(k))))
        raise ValueError(f"cannot resume {out}: the config differs from the one it started with (sections {diff})")
    point = json.loads(state.read_text())
    history = [r for r in json.loads((out / "evaluations.json").read_text()) if r["timesteps"] <= point["timesteps"]]
    return {**point, "history": history, "dir": out / "resume"}


def policy_kwargs(cfg: dict, algorithm: str) -> dict[str, Any]:
    """The policy network's keyword arguments from the config's [policy] section."""
    import torch

    pol = cfg["policy"]
    heads = {"sac": ("pi", "qf")}.get(algorithm, ("pi", "vf"))
    kwargs: dict[str, Any] = {
        "net_arch": {h: list(pol[f"net_arch_{h}"]) for h in heads},
        "activation_fn": {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "elu": torch.nn.ELU}[pol["activation"]],
    }
    if "log_std_init" in pol:
        kwargs["log_std_init"] = float(pol["log_std_init"])
    if algorithm == "recurrent_ppo":
        for key in ("lstm_hidden_size", "n_lstm_layers"):
            kwargs[key] = int(pol[key])
        for key in ("shared_lstm", "enable_critic_lstm"):
            kwargs[key] = bool(pol[key])
    return kwargs


def train_ppo(config: str | Path | dict | None = None, timesteps: int | None = None, seed: int | None = None,
              out: str | Path = "runs/ppo", task: EntryTask | None = None, progress_bar: bool = True) -> Path:  # fmt: skip
    """Train PPO as the config says (default ``rventry_agents/ppo.toml``); see :func:`train_sb3`."""
    return train_sb3("ppo", config, timesteps, seed, out, task, progress_bar)


def train_sb3(algorithm: str, config: str | Path | dict | None = None, timesteps: int | None = None,
              seed: int | None = None, out: str | Path = "runs/ppo", task: EntryTask | None = None,
              progress_bar: bool = True, resume: bool = False) -> Path:  # fmt: skip
    """Train ``algorithm`` (``ppo``, ``recurrent_ppo`` or ``sac``) as the config says; returns the output directory.

    With ``resume``, an interrupted run in ``out`` goes on from its latest evaluation
    (``out/resume/``) up to the total steps: its evaluation history and wall time carry over. The
    environments and the algorithm are re-seeded with ``seed + steps done``, so a resumed run is
    not bit-identical to one that was never stopped.

    :param config: TOML config path (default: the algorithm's, :data:`DEFAULT_CONFIGS`) or a loaded config dict.
    :param timesteps: override ``[train] total_timesteps``.
    :param seed: override ``[train] seed``.
    :param out: output directory.
    :param task: the task (default :class:`EntryTask` with the config's dt/substeps).
    :param progress_bar: show SB3's progress bar.
    """
    import torch
    from stable_baselines3.common.callbacks import CallbackList

    cfg = load_config(config, algorithm)
    t = cfg["train"]
    timesteps = int(timesteps if timesteps is not None else t["total_timesteps"])
    seed = int(seed if seed is not None else t["seed"])
    if timesteps < 1:
        raise ValueError(f"timesteps must be positive, got {timesteps}")
    mode, authority = policy_mode(cfg)
    if mode in ("residual", "student") and algorithm != "ppo":
        raise ValueError(f"[policy] mode = {mode!r} is built for ppo, not {algorithm}; use mode = 'direct'")
    kwargs = policy_kwargs(cfg, algorithm)
    out = Path(out)
    resumed = read_resume_point(out, algorithm, cfg) if resume else None
    if resumed is not None and resumed["timesteps"] >= timesteps:
        raise ValueError(f"cannot resume {out}: it has done {resumed['timesteps']:,} of {timesteps:,} steps already")
    torch.set_num_threads(int(t.get("torch_threads", 1)))
    task = make_task(cfg, task)
    student = spec = None
    if mode == "student":  # the starting point is checked before anything is written
        from rventry_agents.finetune import StudentScales, load_start, student_spec

        law = load_start(cfg["policy"]["start"], task, cfg["policy"].get("q_floor_margin"))
        student = (law, StudentScales.of(law.network))
        spec = student_spec(law, student[1], cfg["policy"]["start"])
        kwargs["net_arch"] = {"pi": list(law.network.hidden), "vf": kwargs["net_arch"]["vf"]}
        kwargs["activation_fn"] = torch.nn.Tanh  # the student's
    out.mkdir(parents=True, exist_ok=True)
    # how to fly any model saved under ``out`` (best, final, checkpoints)
    write_json(out / "policy.json", {"algorithm": algorithm, "mode": mode, "authority_rad": authority,
                                     **({} if spec is None else {"student": spec})})  # fmt: skip
    write_json(out / "config.json", cfg)
    try:
        from rventry_env.reference import load_reference

        reference_cost = float(load_reference().cost)
    except Exception:  # training does not need the reference; the cost ratio does
        reference_cost = None
    venv = make_vec_env(cfg, task, algorithm=algorithm, student=student)
    done = 0 if resumed is None else int(resumed["timesteps"])
    venv.seed(seed + done)
    try:
        import tensorboard  # noqa: F401

        tb = str(out / "tb")
    except ImportError:
        tb = None
    if mode == "residual":
        from rventry_agents.zero_policy import ZeroOnReferencePolicy

        from rventry_env.envs.observation import feature_index

        policy_cls = ZeroOnReferencePolicy
        kwargs["n_raw_features"] = feature_index("load_factor") + 1  # the raw features come first
    elif mode == "student" and bool(cfg["policy"].get("privileged_critic", False)):
        from rventry_agents.finetune import PrivilegedCriticPolicy

        policy_cls = PrivilegedCriticPolicy  # the actor sees the student's inputs, the critic the draw too
        kwargs["n_actor_inputs"] = len(student[1].mean)
    else:
        policy_cls = "MlpLstmPolicy" if algorithm == "recurrent_ppo" else "MlpPolicy"
    if resumed is not None:
        from stable_baselines3.common.vec_env import VecNormalize

        venv = VecNormalize.load(str(resumed["dir"] / "vecnormalize.pkl"), venv.venv)
        model = algorithm_class(algorithm).load(resumed["dir"] / "model.zip", env=venv, device="cpu", tensorboard_log=tb)
        model.set_random_seed(seed + done)
        if (resumed["dir"] / "replay_buffer.pkl").is_file():
            model.load_replay_buffer(resumed["dir"] / "replay_buffer.pkl")
    else:
        model = algorithm_class(algorithm)(policy_cls, venv, seed=seed, device="cpu", tensorboard_log=tb,
                                           policy_kwargs=kwargs, verbose=0, **dict(cfg[algorithm]))  # fmt: skip
    if resumed is None and mode == "residual" and bool(cfg["policy"].get("zero_init_residual", False)):
        # start exactly on the reference: a residual of 0.02 alone moves the impact by ~265 km
        with torch.no_grad():
            model.policy.action_net.weight.zero_()
            model.policy.action_net.bias.zero_()
    warmup = 0
    if resumed is None and mode == "student":
        from rventry_agents.finetune import init_actor_from_student

        init_actor_from_student(model.policy, student[0].network)  # step 0 flies exactly the student
        warmup = min(int(cfg["policy"].get("critic_warmup_steps", 0)), timesteps)
    evaluator, ckpt = _make_callbacks(cfg, task, out, reference_cost, algorithm, resumed, spec)
    start = time.time()
    if warmup:
        from rventry_agents.finetune import set_actor_trainable

        # the critic learns the student's values first; an actor updated against a random critic
        # takes its first steps from noise
        set_actor_trainable(model.policy, False)
        model.learn(warmup, callback=CallbackList([evaluator, ckpt]), progress_bar=progress_bar)
        set_actor_trainable(model.policy, True)
        done = model.num_timesteps
    if timesteps > done:
        model.learn(timesteps - done, callback=CallbackList([evaluator, ckpt]), progress_bar=progress_bar,
                    reset_num_timesteps=resumed is None and not warmup)  # fmt: skip
    evaluator.evaluate()  # the final iterate competes for "best" too
    wall = evaluator.wall_before + time.time() - start
    model.save(out / "final_model.zip")
    venv.save(str(out / "final_vecnormalize.pkl"))
    best = max(evaluator.history, key=evaluation_key)
    meta = {
        "command": " ".join(shlex.quote(a) for a in sys.argv),
        "algorithm": algorithm,
        "seed": seed,
        "timesteps": timesteps,
        "wall_time_s": wall,
        "resumed_at_timesteps": evaluator.resumes,
        "torch_threads": int(t.get("torch_threads", 1)),
        "config": cfg,
        # the run's steps, and those of the policy it keeps (model.zip: the best evaluation's)
        **({} if spec is None else {"provenance": {"algorithm": "PPO (stable-baselines3)", "start": spec["start"],
                                                   "start_sha256": spec["start_sha256"],
                                                   "critic_warmup_steps": warmup, "timesteps": timesteps,
                                                   "selected_at_timesteps": best["timesteps"]}}),  # fmt: skip
        "best_evaluation": best,
        "reference_cost": reference_cost,
    }
    write_json(out / "metadata.json", meta)
    plot_learning_curve(evaluator.history, out / "learning_curve.png")
    return out


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
