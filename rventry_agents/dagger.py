"""Train the learned guidance policy by DAgger from the re-planning law (``rventry train dagger``).

Everything that shapes the result is in one config file (``rventry_agents/dagger.toml``).
A run writes into its output directory:

* ``data_round_K.npz``: the features and expert labels flown in round K (so a refit needs
  no new flights);
* ``student_round_K.pt``: the network fitted after round K;
* ``student_final.pt`` and ``final.json``: with ``[final] members`` > 1, an ensemble refitted
  on all the rounds' data after the last round, and its selection figures;
* ``student_distilled.pt`` and ``distil.json``: with ``[distil]``, one network fitted to the
  selected network's commands (an ensemble's mean) on all the rounds' states, which replaces it
  (one network costs a third of three per decision), and its selection figures;
* ``flight.json``: with ``[flight] tracking``, the selected network flown on the selection set
  with each candidate tracker horizon, and the one chosen;
* ``student.pt`` and ``student.json``: the network selected on the task metric (a round's, or the
  final ensemble when it does better; with ``[distil]``, the network distilled from it), and how
  to build and fly it;
* ``rounds.json`` and ``learning_curve.png``: each round's data, fit and selection figures;
* ``metadata.json``: the exact command, seed, wall time, config and the selected round.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from rventry_agents.imitation import (
    INPUT_NAMES,
    CollectJob,
    Horizon,
    LearnedGuidance,
    collect,
    fit,
    make_network,
    network_bytes,
    network_from_bytes,  # fmt: skip
)
from rventry_env.task import EntryTask
from rventry_env.guidance.load_relief import LoadRelief
from rventry_env.util.files import atomic_write, check_writable, save_figure, write_json

DEFAULT_CONFIG = Path(__file__).resolve().parent / "dagger.toml"
SHIPPED_DAGGER = Path(__file__).resolve().parent / "data" / "dagger"  # the run behind the README's figures


def load_config(path=None) -> dict:
    """The DAgger configuration: a TOML file (default ``rventry_agents/dagger.toml``) or a dict."""
    from rventry_agents.config import read_config

    cfg, where = read_config(path, DEFAULT_CONFIG, ("student", "data", "rounds", "fit", "select"))
    for i, r in enumerate(cfg["rounds"]):
        if not (isinstance(r.get("episodes"), int) and r["episodes"] >= 1 and 0.0 <= float(r.get("beta", -1)) <= 1.0):
            raise ValueError(f"{where}: round {i} needs episodes >= 1 and beta in [0, 1], got {r}")
    for section in ("student", "final"):
        members = cfg.get(section, {}).get("members", 1)
        if not (isinstance(members, int) and members >= 1):
            raise ValueError(f"{where}: [{section}] members must be a whole number >= 1, got {members!r}")
    if "distil" in cfg:
        d = cfg["distil"]
        hidden = d.get("hidden")
        if not (isinstance(hidden, list) and hidden and all(isinstance(h, int) and h >= 1 for h in hidden)):
            raise ValueError(f"{where}: [distil] hidden takes a list of layer widths (whole numbers >= 1), got {hidden!r}")
        for key in ("epochs", "emphasis"):
            value = d.get(key, 1)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{where}: [distil] {key} must be a whole number >= 1, got {value!r}")
        below = d.get("emphasis_below_m", 0.0)
        if not (isinstance(below, (int, float)) and below >= 0):
            raise ValueError(f"{where}: [distil] emphasis_below_m must be an altitude >= 0 (m), got {below!r}")
    if cfg["rounds"][0]["beta"] != 1.0:
        raise ValueError(f"{where}: the first round has no student yet, so its beta must be 1")
    try:
        flight_trackers(cfg)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    return cfg


def flight_trackers(cfg: dict) -> list[Horizon]:
    """The candidate tracker horizons of ``[flight]``: ``tracking`` pairs [max_s, min_s], with the
    altitude over ``tracking_descent_mps`` between them (none: no choice after training)."""
    flight = cfg.get("flight", {})
    pairs = flight.get("tracking", [])
    descent = float(flight.get("tracking_descent_mps", math.inf))
    if not isinstance(pairs, list) or not all(isinstance(p, list) and len(p) == 2 for p in pairs):
        raise ValueError(f"[flight] tracking takes a list of [max_s, min_s] pairs, got {pairs!r}")
    return [Horizon(float(hi), float(lo), descent) for hi, lo in pairs]


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
    members = int(cfg["student"].get("members", 1))
    task = EntryTask()
    law = student_law(cfg["student"], task)
    horizon, relief = law["horizon"], law["load_relief_margin"]
    trackers = flight_trackers(cfg)
    for h in (horizon, *trackers):
        h.check_step(task.dt)  # a bad horizon fails now, not in a worker
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
                    student = network_from_bytes((out / f"student_round_{k}.pt").read_bytes(), hidden, members)
                    sel = max(range(len(done)), key=lambda j: _select_key(done[j]))  # the first of equals, as below
                    best = (sel, (out / f"student_round_{sel}.pt").read_bytes(), members, hidden)
                    best_key = _select_key(done[sel])
                continue
            blob = None if student is None else network_bytes(student)
            jobs = [CollectJob(next_seed + i, cfg["data"]["dispersion"], beta if blob else 1.0, blob, hidden, task,
                               expert, expert_settings, horizon, relief, members) for i in range(n)]  # fmt: skip
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
            student = make_network(hidden, members)
            losses = fit(student, np.concatenate(xs), np.concatenate(ys), int(fit_cfg["epochs"]),
                         int(fit_cfg["batch_size"]), float(fit_cfg["learning_rate"]), fit_seed,
                         float(fit_cfg.get("weight_decay", 0.0)))  # fmt: skip
            metric = select_metric(LearnedGuidance(student, task=task, **law), cfg, task)
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
            key = _select_key(rec)
            if best_key is None or key > best_key:
                best_key, best = key, (k, blob, members, hidden)
                _write_selected(out, best, law, task)
    write_json(out / "rounds.json", rounds)
    final = None
    n_final = int(cfg.get("final", {}).get("members", 1))
    if n_final == 1:
        (out / "final.json").unlink(missing_ok=True)  # an earlier run's ensemble, which this run does not refit
    if n_final > 1:  # an ensemble refitted on all the rounds' data, kept if it beats the best round
        done_final = json.loads((out / "final.json").read_text()) if resume and (out / "final.json").is_file() else None
        if done_final is not None and done_final["members"] == n_final and done_final["samples"] == rounds[-1]["samples"]:
            final = done_final
            t0 = min(t0, time.time() - final["wall_s"])  # its fit counts in the run's wall time
            print(f"final ensemble: taken from {out}")
        else:
            ensemble = make_network(hidden, n_final)
            losses = fit(ensemble, np.concatenate(xs), np.concatenate(ys), int(fit_cfg["epochs"]),
                         int(fit_cfg["batch_size"]), float(fit_cfg["learning_rate"]), fit_seed,
                         float(fit_cfg.get("weight_decay", 0.0)))  # fmt: skip
            metric = select_metric(LearnedGuidance(ensemble, task=task, **law), cfg, task)
            final = {"members": n_final, "samples": rounds[-1]["samples"], "fit_loss_last": losses[-1],
                     "wall_s": time.time() - t0, **{f"select_{key}": v for key, v in metric.items()}}  # fmt: skip
            atomic_write(out / "student_final.pt", network_bytes(ensemble))
            write_json(out / "final.json", final)
            print(f"final ensemble of {n_final}: student alone on the selection set: success "
                  f"{metric['success_rate']:.2f}, miss p50 {metric['miss_km_p50']:.2f} km")  # fmt: skip
        if _select_key(final) > best_key:
            best = ("final", (out / "student_final.pt").read_bytes(), n_final, hidden)
            _write_selected(out, best, law, task)
    selected = final if best[0] == "final" else rounds[best[0]]
    distilled, taken = None, False
    if "distil" in cfg:  # one network fitted to the selected one: one network's cost per decision
        distilled, taken = _distil(cfg, out, best, xs, rounds[-1]["samples"], law, task, fit_seed, resume)
    teacher = None if distilled is None else distilled["teacher"]
    if distilled is None:
        for name in ("distil.json", "student_distilled.pt"):
            (out / name).unlink(missing_ok=True)  # an earlier run's, which this run does not distil
    else:
        t0 -= distilled["wall_s"] if taken else 0.0  # a distillation taken as it was counts in the run's wall time
        best = ("distilled", (out / "student_distilled.pt").read_bytes(), 1, tuple(distilled["hidden"]))
        selected = distilled
        _write_selected(out, best, law, task, distilled_from=teacher)
    if trackers:  # the selected network's tracker: the trained horizon unless a candidate does better
        scan = choose_tracker(network_from_bytes(best[1], best[3], best[2]), [horizon, *trackers], relief, cfg, task)
        write_json(out / "flight.json", {"student": best[0], "candidates": scan})
        i = max(range(len(scan)), key=lambda j: _select_key(scan[j]))  # the first of equals: the trained horizon
        _write_selected(out, best, law, task, tracker=None if i == 0 else trackers[i - 1], distilled_from=teacher)
        chosen = scan[i]
        selected = {**selected, "tracking": chosen}
        print(f"tracker: horizon {_tracker_words(chosen)}; selection success {chosen['select_success_rate']:.2f}, "
              f"miss mean {chosen['select_miss_km_mean']:.3f} km, vertical error p50 "
              f"{chosen['select_vertical_error_deg_p50']:.2f} deg")  # fmt: skip
    else:
        (out / "flight.json").unlink(missing_ok=True)  # an earlier run's choice, for a tracker this run does not fly
    write_json(out / "metadata.json", {
        "command": " ".join(shlex.quote(a) for a in ["rventry", *sys.argv[1:]]) if sys.argv else "",
        "seed": fit_seed, "workers": workers, "wall_s": time.time() - t0, "config": cfg,
        "selected_round": best[0], "selected": selected,
    })  # fmt: skip
    after = {} if final is None else {f"ensemble of {final['members']}, all rounds' data": final}
    if distilled is not None:
        after[f"distilled from {_student_words(distilled['teacher'], distilled['teacher_members'])}"] = distilled
    if trackers:
        after[f"selected, tracker {_tracker_words(chosen)}"] = chosen
    plot_rounds(rounds, out / "learning_curve.png", after)
    return out


def _tracker_words(rec: dict) -> str:
    hi, lo = rec["tracking_s"], rec["tracking_min_s"]
    return f"{hi:g} s" if hi == lo else f"{hi:g} s, down to {lo:g} s near the ground"


def _select_key(rec: dict) -> tuple[float, float]:
    """How a round's (or the final ensemble's) record ranks on the selection set
    (:func:`~rventry_env.evaluation.summary.task_metric_key`)."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(rec["select_success_rate"], rec["select_miss_km_mean"])


def choose_tracker(network, horizons: list[Horizon], relief: float | None, cfg: dict, task: EntryTask) -> list[dict]:
    """The network flown alone on the selection set with each tracker horizon: one record each."""
    scan = []
    for h in horizons:
        metric = select_metric(LearnedGuidance(network, task=task, horizon=h, load_relief_margin=relief), cfg, task)
        scan.append({**_horizon_keys(h, "tracking"), **{f"select_{key}": v for key, v in metric.items()}})
    return scan


def _horizon_keys(h: Horizon, prefix: str) -> dict:
    """A horizon as student.json keys (an unbounded descent rate as null)."""
    return {f"{prefix}_s": h.max_s, f"{prefix}_min_s": h.min_s,
            f"{prefix}_descent_mps": h.descent_mps if math.isfinite(h.descent_mps) else None}  # fmt: skip


def _horizon_from(student_cfg: dict, prefix: str) -> Horizon | None:
    keys = {f"{prefix}_s": "max_s", f"{prefix}_min_s": "min_s", f"{prefix}_descent_mps": "descent_mps"}
    given = {keys[k]: float(v) for k, v in student_cfg.items() if k in keys and v is not None}
    if "max_s" in given:
        given.setdefault("min_s", given["max_s"])
    return Horizon(**given) if given else None


def student_law(student_cfg: dict, task: EntryTask) -> dict:
    """The student's law options (:class:`LearnedGuidance` keywords) from a [student] section or
    a student.json (where an unbounded descent rate and no load relief are null):

    * ``horizon``, the tracker's: ``tracking_*`` where a tracker was chosen after training
      (``[flight]``), else the labels' ``lookahead_*``, which the rounds fly; one step when none is
      named (the students trained before the horizon existed, with one-step labels and a deadbeat
      tracker);
    * ``load_relief_margin``, None when none is named (no load relief)."""
    horizon = _horizon_from(student_cfg, "tracking") or _horizon_from(student_cfg, "lookahead")
    margin = student_cfg.get("load_relief_margin")
    if margin is not None:
        margin = LoadRelief(task=task, margin=float(margin)).margin  # a bad margin fails here, not in a worker
    return {"horizon": horizon or Horizon(task.dt, task.dt), "load_relief_margin": margin}


def _write_selected(out: Path, best: tuple, law: dict, task: EntryTask, tracker: Horizon | None = None,
                    distilled_from=None) -> None:  # fmt: skip
    """student.pt and student.json for ``best`` = (round, "final" or "distilled"; network bytes;
    members; hidden widths), trained with ``law``; ``tracker``, the tracker horizon chosen after
    training (None: the trained one); ``distilled_from``, the round or "final" a distilled
    network was fitted to."""
    atomic_write(out / "student.pt", best[1])
    write_json(out / "student.json", {"hidden": list(best[3]), "members": best[2], "inputs": "observation features "
               "without alpha, sigma, the lift shares and the load factor; 10 ln k_D, 10 ln k_LD",
               "input_features": list(INPUT_NAMES), "task": task.record(), "outputs": "alpha and bank commands",
               **_horizon_keys(law["horizon"], "lookahead"), **({} if tracker is None else _horizon_keys(tracker, "tracking")),
               "load_relief_margin": law["load_relief_margin"], "selected_round": best[0],
               **({} if distilled_from is None else {"distilled_from": distilled_from})})  # fmt: skip


def _student_words(name, members: int) -> str:
    return f"the ensemble of {members}" if members > 1 else ("the final refit" if name == "final" else f"round {name}")


def _distil(cfg: dict, out: Path, teacher: tuple, xs: list, samples: int, law: dict, task: EntryTask, seed: int,
            resume: bool) -> tuple[dict, bool]:  # fmt: skip
    """``[distil]``: one network of ``hidden`` widths fitted, by the [fit] settings and ``epochs``,
    to the selected network's commands on every state the rounds visited, those below
    ``emphasis_below_m`` counted ``emphasis`` times; written as
    ``student_distilled.pt`` and ``distil.json`` (its own ``wall_s``). Returns the record and
    whether it was taken as it was from an earlier run (on resume, when it matches)."""
    from rventry_agents.imitation import fit_commands, network_commands
    from rventry_env.envs.observation import ALTITUDE_SCALE, feature_index

    d, fit_cfg = cfg["distil"], cfg["fit"]
    rec = {"teacher": teacher[0], "teacher_members": teacher[2], "teacher_hidden": list(teacher[3]),
           "teacher_sha256": hashlib.sha256(teacher[1]).hexdigest(), "seed": seed,
           "hidden": [int(h) for h in d["hidden"]], "epochs": int(d.get("epochs", fit_cfg["epochs"])), "samples": samples,
           "emphasis_below_m": float(d.get("emphasis_below_m", 0.0)), "emphasis": int(d.get("emphasis", 1))}  # fmt: skip
    done = json.loads((out / "distil.json").read_text()) if resume and (out / "distil.json").is_file() else None
    if done is not None and all(done.get(k) == v for k, v in rec.items()):
        print(f"distilled network: taken from {out}")
        return done, True
    t0 = time.time()
    x = np.concatenate(xs)
    low = x[:, feature_index("altitude")] * ALTITUDE_SCALE < rec["emphasis_below_m"]
    x = np.concatenate([x, np.repeat(x[low], rec["emphasis"] - 1, axis=0)])  # the few seconds near the ground
    net = make_network(tuple(rec["hidden"]), 1)
    losses = fit_commands(net, x, network_commands(network_from_bytes(teacher[1], teacher[3], teacher[2]), x),
                          rec["epochs"], int(fit_cfg["batch_size"]), float(fit_cfg["learning_rate"]), seed,
                          float(fit_cfg.get("weight_decay", 0.0)))  # fmt: skip
    metric = select_metric(LearnedGuidance(net, task=task, **law), cfg, task)
    rec.update({"emphasized": int(low.sum()), "fit_loss_first": losses[0], "fit_loss_last": losses[-1],
                "wall_s": time.time() - t0, **{f"select_{key}": v for key, v in metric.items()}})  # fmt: skip
    atomic_write(out / "student_distilled.pt", network_bytes(net))
    write_json(out / "distil.json", rec)
    print(f"one network distilled from {_student_words(teacher[0], teacher[2])}: fit loss {losses[-1]:.4f}; on the "
          f"selection set: success {metric['success_rate']:.2f}, miss p50 {metric['miss_km_p50']:.2f} km")  # fmt: skip
    return rec, False


def plot_rounds(rounds: list[dict], path: Path, after: dict | None = None) -> None:
    """Each round's selection and flown figures; ``after``: records made after the last round
    (the final ensemble, the distilled network, the chosen tracker), drawn side by side one step
    to its right."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    k = [r["round"] for r in rounds]
    ax[0].plot(k, [r["select_success_rate"] for r in rounds], "o-", label="student alone (selection set)")
    ax[0].plot(k, [r["flown_success_rate"] for r in rounds], "s--", label="flown mixture")
    for i, ((label, rec), marker) in enumerate(zip((after or {}).items(), "D^v")):
        x = k[-1] + 1 + 0.3 * i  # side by side, not on top of each other
        ax[0].plot([x], [rec["select_success_rate"]], marker, ls="none", label=label)
        ax[1].semilogy([x], [rec["select_miss_km_p50"]], marker, ls="none", label=label)
    ax[0].set(xlabel="DAgger round", ylabel="success rate", ylim=(-0.02, 1.02))
    ax[0].legend(fontsize="small")
    ax[1].semilogy(k, [r["select_miss_km_p50"] for r in rounds], "o-")
    ax[1].set(xlabel="DAgger round", ylabel="selection miss, median (km)")
    if after:
        ax[1].legend(fontsize="small")
    save_figure(fig, path)


def load_student(run_dir, task: EntryTask | None = None) -> LearnedGuidance:
    """The selected student of a finished run, as a guidance law for ``task`` (default: the task it
    was trained on).

    :raises ValueError: ``task`` differs from the training task (each difference named), or the
        network reads its features in another order than this package builds them.
    """
    run_dir = Path(run_dir)
    meta = json.loads((run_dir / "student.json").read_text())
    trained = meta.get("task", EntryTask().record())  # runs before the task was recorded trained on the default
    if task is None:
        task = EntryTask()
    task.check_trained(trained, f"the DAgger student in {run_dir}")
    names = meta.get("input_features")
    if names is not None and tuple(names) != INPUT_NAMES:
        raise ValueError(f"the DAgger student in {run_dir} reads {len(names)} input features in another order than "
                         f"this package builds; first difference: "
                         + next(f"index {i}: {a!r} saved, {b!r} now" for i, (a, b) in enumerate(zip(names, INPUT_NAMES))
                                if a != b))  # fmt: skip
    network = network_from_bytes((run_dir / "student.pt").read_bytes(), tuple(meta["hidden"]), int(meta.get("members", 1)))
    return LearnedGuidance(network, task=task, **student_law(meta, task))


def load_saved(path: str, task: EntryTask | None = None) -> LearnedGuidance:
    """A DAgger run directory (entry point ``rventry.agent_files``): its selected student."""
    p = Path(path)
    if not (p.is_dir() and (p / "student.json").is_file() and (p / "student.pt").is_file()):
        raise ValueError(f"{p} is not a DAgger run directory (student.json and student.pt)")
    return load_student(p, task)


def load_shipped(name: str = "learned", task: EntryTask | None = None) -> LearnedGuidance:
    """The DAgger student shipped with this package (entry point ``dagger``), today's best learned
    policy (entry point ``learned``)."""
    if not (SHIPPED_DAGGER / "student.pt").is_file():
        raise FileNotFoundError(f"the shipped DAgger student is missing from {SHIPPED_DAGGER}")
    return load_student(SHIPPED_DAGGER, task)
