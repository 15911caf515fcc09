"""Train the learned guidance policy by DAgger from the re-planning law (``rventry train dagger``).

Everything that shapes the result is in one config file (``rventry_agents/dagger.toml``).
A run writes into its output directory:

* ``data_round_K.npz``: the features and expert labels flown in round K (so a refit needs
  no new flights);
* ``student_round_K.pt``: the network fitted after round K;
* ``student.pt`` and ``student.json``: the network selected on the task metric, and how to
  build it;
* ``rounds.json`` and ``learning_curve.png``: each round's data, fit and selection figures;
* ``metadata.json``: the exact command, seed, wall time, config and the selected round.
"""

from __future__ import annotations

import io
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from rventry_agents.imitation import (
    CollectJob,
    Horizon,
    LearnedGuidance,
    collect,
    fit,
    make_network,
    network_bytes,
    network_from_bytes,  # fmt: skip
)
from rventry_env.envs.task import EntryTask
from rventry_env.util.files import atomic_write, check_writable, save_figure, write_json

DEFAULT_CONFIG = Path(__file__).resolve().parent / "dagger.toml"
SHIPPED_DAGGER = Path(__file__).resolve().parent / "data" / "dagger"  # the run behind the README's figures


def load_config(path=None) -> dict:
    """The DAgger configuration: a TOML file (default ``rventry_agents/dagger.toml``) or a dict."""
    from rventry_agents.train import read_config

    cfg, where = read_config(path, DEFAULT_CONFIG, ("student", "data", "rounds", "fit", "select"))
    for i, r in enumerate(cfg["rounds"]):
        if not (isinstance(r.get("episodes"), int) and r["episodes"] >= 1 and 0.0 <= float(r.get("beta", -1)) <= 1.0):
            raise ValueError(f"{where}: round {i} needs episodes >= 1 and beta in [0, 1], got {r}")
    if cfg["rounds"][0]["beta"] != 1.0:
        raise ValueError(f"{where}: the first round has no student yet, so its beta must be 1")
    return cfg


def select_metric(student, cfg: dict, task: EntryTask) -> dict:
    """The student alone on the selection set: success rate, then miss."""
    from rventry_env.evaluation.rollout import rollout

    s = cfg["select"]
    b = rollout(student, int(s["episodes"]), seed=int(s["seed"]), dispersion=s["dispersion"], task=task)
    return {"success_rate": float(np.mean(b.is_success)), "miss_km_mean": float(np.mean(b.miss_km)),
            "miss_km_p50": float(np.median(b.miss_km)), "violation_rate": float(np.mean(b.constraint_violation)),
            "vertical_error_deg_p50": float(np.median(b.vertical_error_deg))}  # fmt: skip


def train_dagger(config=None, out="runs/dagger", workers: int = 2, seed: int | None = None, progress_bar: bool = True,
                 resume: bool = False) -> Path:  # fmt: skip
    """Run the config's DAgger rounds; with ``resume``, rounds already finished in ``out`` (their
    data, student and record) are taken as they are, and the run goes on from there."""
    import torch

    cfg = load_config(config)
    out = Path(out)
    check_writable(folders=(out,))
    hidden = tuple(int(h) for h in cfg["student"]["hidden"])
    task = EntryTask()
    horizon = horizon_from(cfg["student"], task)
    horizon.check_step(task.dt)  # a bad horizon fails now, not in a worker
    fit_cfg = cfg["fit"]
    fit_seed = int(fit_cfg["seed"] if seed is None else seed)
    expert_cfg = dict(cfg.get("expert", {}))
    expert = str(expert_cfg.pop("agent", "mpc"))
    expert_settings = tuple(sorted(expert_cfg.items()))
    if expert_settings:
        from rventry_env.guidance.replanning import ReplanningSettings

        if expert != "mpc":
            raise ValueError(f"[expert] settings {sorted(expert_cfg)} apply to the mpc expert only, not {expert!r}")
        ReplanningSettings(**expert_cfg)  # a bad name or value fails now, not in a worker
    torch.set_num_threads(max(1, workers))
    t0 = time.time()
    xs, ys, rounds = [], [], []
    best, best_key, student = None, None, None
    next_seed = int(cfg["data"]["train_seed"]) + (0 if seed is None else 1_000 * seed)
    done = json.loads((out / "rounds.json").read_text()) if resume and (out / "rounds.json").is_file() else []
    if done:
        t0 -= done[-1]["wall_s"]  # wall times count the whole run
    from rich.progress import Progress

    with Progress(disable=not progress_bar) as bar:
        for k, rnd in enumerate(cfg["rounds"]):
            n, beta = int(rnd["episodes"]), float(rnd["beta"])
            if k < len(done):
                if (done[k]["episodes"], done[k]["beta"]) != (n, beta):
                    raise ValueError(f"cannot resume {out}: its round {k} flew {done[k]['episodes']} episodes at beta "
                                     f"{done[k]['beta']}, the config says {n} at {beta}")  # fmt: skip
                with np.load(out / f"data_round_{k}.npz") as d:
                    if "angles" not in d:
                        raise ValueError(f"cannot resume {out}: its round {k} was recorded with another kind of label "
                                         "(the expert's rates); start a new run")  # fmt: skip
                    xs.append(d["x"])
                    ys.append(d["angles"])
                rounds.append(done[k])
                next_seed += n
                bar.console.print(f"round {k}: taken from {out}")
                if k == len(done) - 1:  # the student to go on with, and the best so far
                    student = network_from_bytes((out / f"student_round_{k}.pt").read_bytes(), hidden)
                    sel = json.loads((out / "student.json").read_text())["selected_round"]
                    best = (sel, (out / "student.pt").read_bytes())
                    best_key = (done[sel]["select_success_rate"], -done[sel]["select_miss_km_mean"])
                continue
            blob = None if student is None else network_bytes(student)
            jobs = [CollectJob(next_seed + i, cfg["data"]["dispersion"], beta if blob else 1.0, blob, hidden, task,
                               expert, expert_settings, horizon) for i in range(n)]  # fmt: skip
            next_seed += n
            tid = bar.add_task(f"round {k}: {n} episodes, beta {beta}", total=n)
            res = collect(jobs, workers, progress=lambda d, tid=tid: bar.advance(tid, d))
            x = np.concatenate([r["x"] for r in res])
            y = np.concatenate([r["angles"] for r in res])
            buf = io.BytesIO()
            np.savez_compressed(buf, x=x, angles=y)
            atomic_write(out / f"data_round_{k}.npz", buf.getvalue())
            xs.append(x)
            ys.append(y)
            flown_success = float(np.mean([r["success"] for r in res]))
            student = make_network(hidden)
            losses = fit(student, np.concatenate(xs), np.concatenate(ys), int(fit_cfg["epochs"]),
                         int(fit_cfg["batch_size"]), float(fit_cfg["learning_rate"]), fit_seed,
                         float(fit_cfg.get("weight_decay", 0.0)))  # fmt: skip
            metric = select_metric(LearnedGuidance(student, task=task, horizon=horizon), cfg, task)
            rec = {"round": k, "episodes": n, "beta": beta, "samples": int(sum(len(a) for a in xs)),
                   "flown_success_rate": flown_success, "fit_loss_first": losses[0], "fit_loss_last": losses[-1],
                   "wall_s": time.time() - t0, **{f"select_{key}": v for key, v in metric.items()}}  # fmt: skip
            rounds.append(rec)
            blob = network_bytes(student)
            atomic_write(out / f"student_round_{k}.pt", blob)
            write_json(out / "rounds.json", rounds)  # progress survives an interrupted run
            bar.console.print(
                f"round {k}: {rec['samples']} samples, flown success {flown_success:.2f}, fit loss "
                f"{losses[-1]:.4f}; student alone on the selection set: success {metric['success_rate']:.2f}, "
                f"miss p50 {metric['miss_km_p50']:.2f} km, violations {metric['violation_rate']:.2f}"
            )  # fmt: skip
            key = (metric["success_rate"], -metric["miss_km_mean"])
            if best_key is None or key > best_key:
                best_key, best = key, (k, blob)
                _write_selected(out, best, hidden, horizon)
    write_json(out / "rounds.json", rounds)
    write_json(out / "metadata.json", {
        "command": " ".join(shlex.quote(a) for a in ["rventry", *sys.argv[1:]]) if sys.argv else "",
        "seed": fit_seed, "workers": workers, "wall_s": time.time() - t0, "config": cfg,
        "selected_round": best[0], "selected": rounds[best[0]],
    })  # fmt: skip
    plot_rounds(rounds, out / "learning_curve.png")
    return out


def horizon_from(student_cfg: dict, task: EntryTask) -> Horizon:
    """The labels' and the tracker's horizon from a [student] section (or a student.json, where an
    unbounded descent rate is null); one step when it names none (the students trained before the
    horizon existed, with one-step labels and a deadbeat tracker)."""
    keys = {"lookahead_s": "max_s", "lookahead_min_s": "min_s", "lookahead_descent_mps": "descent_mps"}
    given = {keys[k]: float(v) for k, v in student_cfg.items() if k in keys and v is not None}
    if "max_s" in given:
        given.setdefault("min_s", given["max_s"])
    return Horizon(**given) if given else Horizon(task.dt, task.dt)


def _write_selected(out: Path, best: tuple, hidden: tuple, horizon: Horizon) -> None:
    atomic_write(out / "student.pt", best[1])
    write_json(out / "student.json", {"hidden": list(hidden), "inputs": "observation features without alpha, sigma, "
               "the lift shares and the load factor; 10 ln k_D, 10 ln k_LD", "outputs": "alpha and bank commands",
               "lookahead_s": horizon.max_s, "lookahead_min_s": horizon.min_s,
               "lookahead_descent_mps": horizon.descent_mps if math.isfinite(horizon.descent_mps) else None,
               "selected_round": best[0]})  # fmt: skip


def plot_rounds(rounds: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    k = [r["round"] for r in rounds]
    ax[0].plot(k, [r["select_success_rate"] for r in rounds], "o-", label="student alone (selection set)")
    ax[0].plot(k, [r["flown_success_rate"] for r in rounds], "s--", label="flown mixture")
    ax[0].set(xlabel="DAgger round", ylabel="success rate", ylim=(-0.02, 1.02))
    ax[0].legend()
    ax[1].semilogy(k, [r["select_miss_km_p50"] for r in rounds], "o-")
    ax[1].set(xlabel="DAgger round", ylabel="selection miss, median (km)")
    save_figure(fig, path)


def load_student(run_dir) -> LearnedGuidance:
    """The selected student of a finished run, as a guidance law."""
    run_dir = Path(run_dir)
    meta = json.loads((run_dir / "student.json").read_text())
    return LearnedGuidance(network_from_bytes((run_dir / "student.pt").read_bytes(), tuple(meta["hidden"])),
                           horizon=horizon_from(meta, EntryTask()))  # fmt: skip


def load_saved(path: str, task: EntryTask | None = None) -> LearnedGuidance:
    """A DAgger run directory (entry point ``rventry.agent_files``): its selected student."""
    p = Path(path)
    if not (p.is_dir() and (p / "student.json").is_file() and (p / "student.pt").is_file()):
        raise ValueError(f"{p} is not a DAgger run directory (student.json and student.pt)")
    return load_student(p)


def load_shipped(name: str = "dagger", task: EntryTask | None = None) -> LearnedGuidance:
    """The DAgger student shipped with this package (entry point ``rventry.agents``)."""
    if not (SHIPPED_DAGGER / "student.pt").is_file():
        raise FileNotFoundError(f"the shipped DAgger student is missing from {SHIPPED_DAGGER}")
    return load_student(SHIPPED_DAGGER)
