"""stable-baselines3 callbacks of a training run: the selection on the task metric.

:class:`TaskMetricEval` flies the fixed evaluation set with the policy being trained every
``eval_every`` steps, keeps the best model on the task metric (success rate, then mean miss), and
writes the evaluation history and a resume point after each evaluation.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from rventry_env.task import EntryTask
from rventry_env.util.files import write_json

# the evaluation figures logged to TensorBoard under task/
LOGGED = ("success_rate", "miss_km", "median_miss_km", "vertical_error_deg", "abs_speed_error_mps", "impact_rate")


def evaluation_key(rec: dict) -> tuple[float, float]:
    """How a training evaluation ranks (:func:`~rventry_env.evaluation.summary.task_metric_key`)."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(rec["success_rate"], rec["miss_km"])


class TaskMetricEval(BaseCallback):
    """Every ``eval_every`` steps: fly the fixed dispersed evaluation set deterministically,
    log the task metrics, and keep the best model by (success rate, -mean miss).

    :param train: the config's ``[train]`` section (the evaluation set and its period).
    :param law_of: the model being trained as a guidance law (deterministic).
    :param task: the task flown.
    :param max_episode_steps: the evaluation episodes' time limit.
    :param out: the run's directory: ``model.zip`` and ``vecnormalize.pkl`` (the best),
        ``evaluations.json`` and the resume point (:func:`save_resume_point`) go there.
    :param reference_cost: the optimal cost J* the cost ratio is taken against (None: no ratio).
    :param resumed: the resume point a resumed run starts from (:func:`rventry_agents.train.read_resume_point`).
    """

    def __init__(self, train, law_of: Callable, task: EntryTask, max_episode_steps: int, out: Path,
                 reference_cost: float | None, resumed: dict | None = None):  # fmt: skip
        super().__init__()
        self.train, self.law_of, self.task, self.out = train, law_of, task, Path(out)
        self.max_episode_steps, self.reference_cost = int(max_episode_steps), reference_cost
        self.next_eval = train.eval_every
        self.history: list[dict] = []
        self.best_key = (-1.0, -np.inf)
        self.wall_before = 0.0  # the wall time of the run's earlier segments, when resumed
        self.resumes: list[int] = []  # the step counts the run was resumed at
        self.t0: float | None = None  # when this segment's first learn() started
        self.resumed = resumed is not None
        if resumed is not None:
            self.resumes = [*resumed.get("resumes", []), int(resumed["timesteps"])]
            self.history = list(resumed["history"])
            self.best_key = max(map(evaluation_key, self.history))
            self.next_eval = int(resumed["timesteps"]) + train.eval_every
            self.wall_before = float(resumed["wall_s"])

    def _on_step(self) -> bool:
        if self.num_timesteps < self.next_eval:
            return True
        self.next_eval += self.train.eval_every
        self.evaluate()
        return True

    def _on_training_start(self) -> None:
        if self.t0 is None:  # a fine-tuning's second learn() goes on counting from the first
            self.t0 = time.time()
        if not self.resumed and not self.history:
            # the untrained policy competes too: the residual starts as the classical law. A
            # fine-tuning's second phase starts where its critic warm-up ended, with the actor
            # the warm-up never moved: the evaluation at step 0 already flew it.
            self.evaluate()

    def flown(self) -> dict:
        """The evaluation set flown by the policy as it is now: the task metrics."""
        from rventry_env.evaluation.rollout import rollout
        from rventry_env.evaluation.summary import summarize

        t = self.train
        batch = rollout(self.law_of(self.model), t.eval_episodes, seed=t.eval_seed, dispersion=t.eval_dispersion,
                        task=self.task, max_episode_steps=self.max_episode_steps)  # fmt: skip
        s = summarize(batch, self.reference_cost or 1.0, self.task)
        returns = [e["r"] for e in self.model.ep_info_buffer]
        return {
            "timesteps": int(self.num_timesteps),
            "wall_s": self.wall_before + time.time() - self.t0,
            "success_rate": s["success_rate"],
            "miss_km": s["miss_km"],
            "median_miss_km": s["percentiles"]["miss_km"]["p50"],
            "vertical_error_deg": s["vertical_error_deg"],
            "abs_speed_error_mps": s["abs_speed_error_mps"],
            "cost_ratio": s["cost_ratio"] if self.reference_cost else None,
            "impact_rate": s["impact_rate"],
            "train_ep_return": float(np.mean(returns)) if returns else None,
        }

    def evaluate(self) -> dict:
        """Fly the evaluation set, keep the model if it is the best yet, and write the history."""
        rec = self.flown()
        self.history.append(rec)
        for k in LOGGED:
            if rec[k] is not None:
                self.logger.record(f"task/{k}", rec[k])
        key = evaluation_key(rec)
        vecnorm = self.model.get_vec_normalize_env()
        if key > self.best_key:
            self.best_key = key
            self.model.save(self.out / "model.zip")
            vecnorm.save(str(self.out / "vecnormalize.pkl"))
            rec["best"] = True
        write_json(self.out / "evaluations.json", self.history)
        save_resume_point(self.model, self.out, rec["timesteps"], rec["wall_s"], self.resumes)
        print(f"[eval @ {rec['timesteps']:,}] success {rec['success_rate']:.2f} miss {rec['miss_km']:.1f} km "
              f"(median {rec['median_miss_km']:.1f}) vertical {rec['vertical_error_deg']:.1f} deg "
              f"|dv| {rec['abs_speed_error_mps']:.0f} m/s impact {rec['impact_rate']:.2f}"
              + (" *best*" if rec.get("best") else ""), flush=True)  # fmt: skip
        return rec


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


__all__ = ["LOGGED", "TaskMetricEval", "evaluation_key", "save_resume_point"]
