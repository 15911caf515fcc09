"""Train the learned guidance policy by DAgger from the re-planning law (``rventry train dagger``).

Everything that shapes the result is in one config file (``rventry_agents/dagger.toml``).
A run writes into its output directory:

* ``data_round_K.npz``: the features and expert labels flown in round K (so a refit needs
  no new flights);
* ``student_round_K.pt``: the network fitted after round K (``rounds.json`` keeps its SHA-256: a
  resume that finds the file gone fits it again from the seed and data, and checks it);
* ``student_final.pt`` and ``final.json``: with ``[final] members`` > 1, an ensemble refitted
  on all the rounds' data after the last round, and its selection figures;
* ``student_distilled.pt`` and ``distil.json``: with ``[distil]``, one network fitted to the
  selected network's commands (an ensemble's mean) on all the rounds' states, which replaces it
  (one network costs a third of three per decision; with ``keep_teacher_if_better``, a teacher
  that is one network of the same widths keeps flying if it does better on the selection set),
  and its selection figures;
* ``deploy.json``: with ``[deploy] tracking``, the selected network flown on the selection set
  with each candidate tracker horizon, and the one chosen; with ``[deploy] load_relief_margins``,
  then with the chosen tracker and each candidate load-relief margin, and the one chosen;
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
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rventry_agents.config import ConfigError, read_json
from rventry_agents.dagger_config import (  # noqa: F401  (the trainer's names for its config)
    DEFAULT_CONFIG,
    DaggerConfig,
    DataSection,
    ExpertSection,
    FitSection,
    SelectSection,
    StudentSection,
    load_config,
)
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
from rventry_agents.records import RunRecord, StudentDeploy, StudentRecord, horizon_keys  # noqa: F401
from rventry_env.task import EntryTask
from rventry_env.util.files import atomic_write, check_writable, dumps_json, save_figure, write_json

SHIPPED_DAGGER = Path(__file__).resolve().parent / "data" / "dagger"  # dagger.toml's run: the student of mpc
SHIPPED_DAGGER_FLIGHT = Path(__file__).resolve().parent / "data" / "dagger_flight"  # dagger_flight.toml's run
# the shipped students by agent name (held out on `flight`, 200 episodes: dagger-flight 0.75 [0.69, 0.80],
# dagger 0.23 [0.17, 0.29]); `learned` (rventry_agents/learned.py) names the best learned policy there
SHIPPED_STUDENTS = {"dagger": SHIPPED_DAGGER, "dagger-flight": SHIPPED_DAGGER_FLIGHT}


def _law(run: "RunSetup", law: dict | None) -> dict:
    """``law``, or the [student] one where none is given."""
    return run.law if law is None else law


def round_law(run: "RunSetup", k: int) -> dict:
    """The law round ``k``'s student flies, in the round and in its selection: the [student] one,
    with the round's own ``load_relief_margin`` where it names one (rounds that fly the margin
    chosen after the earlier rounds: the states they visit are those of the student as it will fly)."""
    margin = run.cfg.rounds[k].load_relief_margin
    return run.law if margin is None else {**run.law, "load_relief_margin": margin}


def select_metric(student, cfg: DaggerConfig, task: EntryTask) -> dict:
    """The student alone on the selection set: success rate, then miss."""
    from rventry_env.evaluation.rollout import rollout

    s = cfg.select
    b = rollout(student, s.episodes, seed=s.seed, dispersion=s.dispersion, task=task)
    return {"success_rate": float(np.mean(b.is_success)), "miss_km_mean": float(np.mean(b.miss_km)),
            "miss_km_p50": float(np.median(b.miss_km)), "violation_rate": float(np.mean(b.constraint_violation)),
            "vertical_error_deg_p50": float(np.median(b.vertical_error_deg))}  # fmt: skip


# the config sections that shape the rounds already flown: a resumed run must keep them
# ([final], [distil] and [deploy] come after the rounds, and each checks its own record on resume)
RUN_SECTIONS = {"student": StudentSection, "expert": ExpertSection, "data": DataSection, "fit": FitSection,
                "select": SelectSection}  # fmt: skip
RUN_FILE = "run.json"
DEPLOY_RECORD = "deploy.json"  # [deploy]'s choice (flight.json in runs from before the name)


@dataclass(frozen=True)
class Selected:
    """A network chosen to fly: where it comes from, its weights and its shape.

    :param source: a round's index, ``"final"`` (the ensemble refitted after the rounds) or
        ``"distilled"`` (one network fitted to the selected one's commands).
    :param weights: the network's state dict (:func:`network_bytes`).
    """

    source: int | str
    weights: bytes
    members: int
    hidden: tuple[int, ...]
    law: dict | None = None  # the law it was selected flying (:func:`round_law`); None: the [student] one

    def network(self):
        return network_from_bytes(self.weights, self.hidden, self.members)


@dataclass(frozen=True)
class RunSetup:
    """A DAgger run's settings, checked before anything is flown (:func:`prepare_run`)."""

    cfg: DaggerConfig
    out: Path
    workers: int
    seed: int | None  # --seed, which offsets the training vehicles and replaces the fit seed
    task: EntryTask
    hidden: tuple[int, ...]
    members: int
    law: dict  # LearnedGuidance keywords: horizon, load_relief_margin
    trackers: list
    margins: list  # [deploy] load_relief_margins
    fit_seed: int
    expert: str
    expert_settings: tuple  # (name, value) pairs of ReplanningSettings
    first_seed: int  # the seed of round 0's first training vehicle
    cluster: str | None = None  # a Dask scheduler's address: the expert flies there instead of on local workers

    def fit_settings(self) -> dict:
        """Keywords of :func:`fit` (and :func:`fit_commands`) after the data: the [fit] section."""
        f = self.cfg.fit
        return {"epochs": f.epochs, "batch_size": f.batch_size, "lr": f.learning_rate, "seed": self.fit_seed,
                "weight_decay": f.weight_decay}  # fmt: skip


class RunClock:
    """The run's wall time, counting the work an earlier run did and this one takes as it was."""

    def __init__(self):
        self.t0 = time.time()

    def elapsed(self) -> float:
        return time.time() - self.t0

    def credit(self, seconds: float) -> None:
        """Work taken from an earlier run that took ``seconds`` beyond what is counted already."""
        self.t0 -= seconds

    def at_least(self, seconds: float) -> None:
        """The run has lasted at least ``seconds`` (a record that counts the run's whole time so far)."""
        self.t0 = min(self.t0, time.time() - seconds)


@dataclass
class Rounds:
    """What the DAgger rounds leave (:func:`run_rounds`): every round's data and record, and the best network."""

    xs: list = field(default_factory=list)  # features per round
    ys: list = field(default_factory=list)  # expert labels per round
    records: list = field(default_factory=list)
    laws: list = field(default_factory=list)  # the law each round's student flew (:func:`round_law`)
    best: Selected | None = None

    @property
    def samples(self) -> int:
        return self.records[-1]["samples"]

    def features(self) -> np.ndarray:
        return np.concatenate(self.xs)

    def labels(self) -> np.ndarray:
        return np.concatenate(self.ys)


def new_network(hidden: tuple[int, ...], members: int, seed: int, stage: str):
    """:func:`make_network` with its initial weights drawn from torch's global generator seeded
    from the run's seed and the ``stage`` (``"round 3"``, ``"final"``, ``"distil"``): two runs of
    one config and seed start every network alike, and a resumed run starts the networks it fits
    as the uninterrupted run did."""
    import torch

    digest = hashlib.sha256(f"{seed}/{stage}".encode()).digest()
    torch.manual_seed(int.from_bytes(digest[:8], "little"))
    return make_network(hidden, members)


def prepare_run(config, out, workers: int, seed: int | None, cluster: str | None = None) -> RunSetup:
    """Read and check the config, the expert and the output directory: a bad setting fails here,
    before anything is written or flown (only the output folder is made, last)."""
    from rventry_env.evaluation.agents import agent_names

    cfg = load_config(config)
    out = Path(out)
    task = EntryTask()
    law = cfg.student.law(task)
    law.pop("q_floor_margin")  # none: refused by the [student] section
    trackers = cfg.deploy.trackers()
    for h in (law["horizon"], *trackers):
        h.check_step(task.dt)
    expert = cfg.expert.agent
    if expert not in agent_names() and not Path(expert).exists():
        raise ValueError(f"[expert] agent {expert!r} is neither an agent ({', '.join(agent_names())}) nor a saved policy")
    check_writable(folders=(out,))
    return RunSetup(
        cfg=cfg, out=out, workers=workers, seed=seed, task=task, hidden=cfg.student.hidden, members=cfg.student.members,
        law=law, trackers=trackers, margins=list(cfg.deploy.load_relief_margins),
        fit_seed=cfg.fit.seed if seed is None else seed, expert=expert, expert_settings=cfg.expert.setting_pairs,
        first_seed=cfg.data.train_seed + (0 if seed is None else 1_000 * seed), cluster=cluster,
    )  # fmt: skip


def _identity(seed, sections: dict) -> dict:
    """What the rounds were flown with: the --seed and the sections of :data:`RUN_SECTIONS`, each
    through its schema (so that a record that left a default out compares by its value)."""
    identity = {"seed": seed}
    for name, cls in RUN_SECTIONS.items():
        value = sections.get(name, {})
        try:
            identity[name] = cls.from_dict(value).to_dict()
        except ConfigError:
            identity[name] = value  # compared as it is: it differs
    return json.loads(dumps_json(identity))


def _run_identity(run: RunSetup) -> dict:
    return _identity(run.seed, {name: getattr(run.cfg, name) for name in RUN_SECTIONS})


def _differences(old, new, prefix: str = "") -> list[str]:
    """The dotted names of the fields that differ between two JSON-like values."""
    if isinstance(old, dict) and isinstance(new, dict):
        return [d for k in sorted(set(old) | set(new)) for d in _differences(old.get(k), new.get(k), f"{prefix}{k}.")]
    return [] if old == new else [f"{prefix.rstrip('.')} ({json.dumps(old)} -> {json.dumps(new)})"]


def _started_with(run: RunSetup, identity: dict) -> tuple[dict | None, dict]:
    """What the run in ``run.out`` was started with, and this run's identity to compare it with: its
    ``run.json``, or for a run from before that record was kept, its ``metadata.json`` (its config
    and the fit seed it used); (None, identity) for a run with neither."""
    if (run.out / RUN_FILE).is_file():
        started = read_json(run.out / RUN_FILE)
        return _identity(started.get("seed"), started), identity
    if (run.out / "metadata.json").is_file():
        meta = RunRecord.read_json(run.out / "metadata.json")
        config = meta.config or {}
        started = _identity(identity["seed"], {**config, "fit": {**config.get("fit", {}), "seed": meta.seed}})
        return started, {**identity, "fit": {**identity["fit"], "seed": run.fit_seed}}
    return None, identity


def check_resumable(run: RunSetup, resume: bool) -> None:
    """Refuse to resume a run with another config than it was started with, naming the fields;
    then record this run's (``run.json``). A run from before the record was kept is checked
    against its ``metadata.json``, where it has one."""
    identity = _run_identity(run)
    if resume:
        started, mine = _started_with(run, identity)
        changed = [] if started is None else _differences(started, mine)
        if changed:
            raise ValueError(f"cannot resume {run.out}: it was started with another config; changed: "
                             f"{', '.join(changed)}. Resume with the same config and --seed, or start a new run "
                             "(another --out)")  # fmt: skip
    write_json(run.out / RUN_FILE, identity)


ROUND_KEYS = ("round", "episodes", "beta", "samples", "wall_s", "select_success_rate", "select_miss_km_mean")


def _read_rounds(path: Path) -> list[dict]:
    """An earlier run's ``rounds.json``, checked: one record per round, in order."""
    done = read_json(path, list)
    for k, rec in enumerate(done):
        missing = [key for key in ROUND_KEYS if not isinstance(rec, dict) or key not in rec]
        if missing or rec["round"] != k:
            raise ConfigError(f"{path}: round {k}'s record is malformed (missing {', '.join(missing) or 'nothing'}, "
                              f"round {rec.get('round') if isinstance(rec, dict) else rec!r})", located=True)  # fmt: skip
    return done


def _round_data(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A round's recorded features and expert labels; an unreadable file is refused naming it."""
    import zipfile

    try:
        with np.load(path) as d:
            data = {k: d[k] for k in d.files}
    except (OSError, ValueError, EOFError, AttributeError, zipfile.BadZipFile) as exc:  # junk, truncated, a bare array
        raise ValueError(f"cannot resume: {path} is unreadable ({type(exc).__name__}: {exc})") from None
    if "angles" not in data:
        raise ValueError(f"cannot resume: {path} was recorded with another kind of label (the expert's rates, or "
                         f"none: {sorted(data)}); start a new run")  # fmt: skip
    x, y = data.get("x", np.zeros((0, 0))), data["angles"]
    if x.ndim != 2 or y.shape != (len(x), 2):
        raise ValueError(f"cannot resume: {path} holds features {x.shape} and labels {y.shape}, not one row each")
    return x, y


def _take_round(run: RunSetup, k: int, n: int, beta: float, record: dict, rounds: Rounds) -> None:
    """Round ``k`` as an earlier run flew it: its data and record."""
    if (record["episodes"], record["beta"]) != (n, beta):
        raise ValueError(f"cannot resume {run.out}: its round {k} flew {record['episodes']} episodes at beta "
                         f"{record['beta']}, the config says {n} at {beta}")  # fmt: skip
    law = round_law(run, k)
    # records of before name no margin: they flew the [student] one
    flown = record.get("load_relief_margin", run.law["load_relief_margin"])
    if flown != law["load_relief_margin"]:
        raise ValueError(f"cannot resume {run.out}: its round {k} flew the load-relief margin {flown}, the config "
                         f"says {law['load_relief_margin']}")  # fmt: skip
    x, y = _round_data(run.out / f"data_round_{k}.npz")
    rounds.xs.append(x)
    rounds.ys.append(y)
    rounds.records.append(record)
    rounds.laws.append(law)


def _fly_round(run: RunSetup, k: int, n: int, beta: float, first_seed: int, student, rounds: Rounds, clock: RunClock,
               bar) -> tuple[object, dict]:  # fmt: skip
    """Round ``k``: fly ``n`` episodes (the expert's action with probability ``beta``), label every
    state, refit a new student on all the data so far and select it alone; returns it and its record."""
    blob = None if student is None else network_bytes(student)
    law = round_law(run, k)
    jobs = [CollectJob(seed=first_seed + i, dispersion=run.cfg.data.dispersion,
                       beta=beta if blob else 1.0, student=blob, hidden=run.hidden, task=run.task, expert=run.expert,
                       expert_settings=run.expert_settings, horizon=law["horizon"],
                       load_relief_margin=law["load_relief_margin"], members=run.members)
            for i in range(n)]  # fmt: skip
    tid = bar.add_task(f"round {k}: {n} episodes, beta {beta}", total=n)
    res = collect(jobs, run.workers, progress=lambda d: bar.advance(tid, d), cluster=run.cluster)
    x = np.concatenate([r["x"] for r in res])
    y = np.concatenate([r["angles"] for r in res])
    buf = io.BytesIO()
    np.savez_compressed(buf, x=x, angles=y)
    atomic_write(run.out / f"data_round_{k}.npz", buf.getvalue())
    rounds.xs.append(x)
    rounds.ys.append(y)
    rounds.laws.append(law)
    flown_success = float(np.mean([r["success"] for r in res]))
    student = new_network(run.hidden, run.members, run.fit_seed, f"round {k}")
    losses = fit(student, rounds.features(), rounds.labels(), **run.fit_settings())
    metric = select_metric(LearnedGuidance(student, task=run.task, **law), run.cfg, run.task)
    weights = network_bytes(student)
    rec = {"round": k, "episodes": n, "beta": beta, "samples": int(sum(len(a) for a in rounds.xs)),
           "load_relief_margin": law["load_relief_margin"], "network_sha256": hashlib.sha256(weights).hexdigest(),
           "flown_success_rate": flown_success, "fit_loss_first": losses[0], "fit_loss_last": losses[-1],
           "wall_s": clock.elapsed(), **{f"select_{key}": v for key, v in metric.items()}}  # fmt: skip
    rounds.records.append(rec)
    atomic_write(run.out / f"student_round_{k}.pt", weights)
    write_json(run.out / "rounds.json", rounds.records)  # progress survives an interrupted run
    bar.console.print(
        f"round {k}: {rec['samples']} samples, flown success {flown_success:.2f}, fit loss "
        f"{losses[-1]:.4f}; student alone on the selection set: success {metric['success_rate']:.2f}, "
        f"miss p50 {metric['miss_km_p50']:.2f} km, violations {metric['violation_rate']:.2f}"
    )  # fmt: skip
    return student, rec


def _round_network(run: RunSetup, k: int, rounds: Rounds) -> bytes:
    """Round ``k``'s network as its run saved it; where the file is gone, fitted again from the
    run's seed and the data of rounds 0..k (the fit is deterministic for one torch thread count)
    and checked against the SHA-256 its record keeps, then saved."""
    path = run.out / f"student_round_{k}.pt"
    if path.is_file():
        return path.read_bytes()
    net = new_network(run.hidden, run.members, run.fit_seed, f"round {k}")
    fit(net, np.concatenate(rounds.xs[: k + 1]), np.concatenate(rounds.ys[: k + 1]), **run.fit_settings())
    blob = network_bytes(net)
    want, got = rounds.records[k].get("network_sha256"), hashlib.sha256(blob).hexdigest()
    if want is not None and got != want:
        raise ValueError(f"cannot resume {run.out}: {path.name} is missing, and fitting it again from the run's seed "
                         f"and data gave another network (SHA-256 {got[:12]}..., recorded {want[:12]}...); the fit's "
                         "result depends on torch's thread count: resume with the --workers the run was started "
                         "with, or start a new run")  # fmt: skip
    print(f"round {k}: {path.name} was missing; fitted again from the run's seed and data"
          + ("" if want is None else ", the recorded network bit for bit"))  # fmt: skip
    atomic_write(path, blob)
    return blob


def _round_student(run: RunSetup, k: int, rounds: Rounds):
    """Round ``k``'s network, to go on from (:func:`_round_network`)."""
    try:
        return network_from_bytes(_round_network(run, k, rounds), run.hidden, run.members)
    except ValueError as exc:
        raise ValueError(f"cannot resume {run.out}: student_round_{k}.pt: {exc}") from None


def run_rounds(run: RunSetup, clock: RunClock, resume: bool, progress_bar: bool = True) -> Rounds:
    """The config's DAgger rounds; with ``resume``, the rounds an earlier run finished in ``run.out``
    are taken as they are and the run goes on from the last one's student. The best round on the
    task metric is selected (student.pt, student.json) as the rounds go."""
    from rich.progress import Progress

    done = _read_rounds(run.out / "rounds.json") if resume and (run.out / "rounds.json").is_file() else []
    if done:
        clock.credit(done[-1]["wall_s"])  # wall times count the whole run
    rounds, student, next_seed = Rounds(), None, run.first_seed
    with Progress(disable=not progress_bar) as bar:
        for k, rnd in enumerate(run.cfg.rounds):
            n, beta = rnd.episodes, rnd.beta
            if k < len(done):
                _take_round(run, k, n, beta, done[k], rounds)
                bar.console.print(f"round {k}: taken from {run.out}")
                if k == len(done) - 1:  # the student to go on with, and the best so far
                    student = _round_student(run, k, rounds)
                    sel = max(range(len(done)), key=lambda j: _select_key(done[j]))  # the first of equals, as below
                    rounds.best = Selected(sel, _round_network(run, sel, rounds), run.members, run.hidden,
                                           rounds.laws[sel])  # fmt: skip
            else:
                student, rec = _fly_round(run, k, n, beta, next_seed, student, rounds, clock, bar)
                if rounds.best is None or _select_key(rec) > _select_key(rounds.records[rounds.best.source]):
                    rounds.best = Selected(k, network_bytes(student), run.members, run.hidden, rounds.laws[k])
                    _write_selected(run.out, rounds.best, rounds.best.law, run.task)
            next_seed += n
    write_json(run.out / "rounds.json", rounds.records)
    return rounds


def refit_ensemble(run: RunSetup, rounds: Rounds, clock: RunClock, resume: bool) -> tuple[Selected, dict | None]:
    """``[final] members`` > 1: an ensemble refitted on all the rounds' data, selected if it beats the
    best round; on resume, an earlier run's ensemble of the same size and data is taken as it is.
    Returns the selected network and the ensemble's record (None without one)."""
    n_final = run.cfg.final.members
    best = rounds.best
    law = _law(run, rounds.laws[-1] if rounds.laws else None)  # the last round's: the newest data was flown with it
    if n_final == 1:
        (run.out / "final.json").unlink(missing_ok=True)  # an earlier run's ensemble, which this run does not refit
        return best, None
    path = run.out / "final.json"
    done = read_json(path) if resume and path.is_file() else None
    if done is not None and done.get("members") == n_final and done.get("samples") == rounds.samples:
        final = done
        clock.at_least(final["wall_s"])  # its fit counts in the run's wall time
        print(f"final ensemble: taken from {run.out}")
    else:
        ensemble = new_network(run.hidden, n_final, run.fit_seed, "final")
        losses = fit(ensemble, rounds.features(), rounds.labels(), **run.fit_settings())
        metric = select_metric(LearnedGuidance(ensemble, task=run.task, **law), run.cfg, run.task)
        final = {"members": n_final, "samples": rounds.samples, "fit_loss_last": losses[-1],
                 "wall_s": clock.elapsed(), **{f"select_{key}": v for key, v in metric.items()}}  # fmt: skip
        atomic_write(run.out / "student_final.pt", network_bytes(ensemble))
        write_json(path, final)
        print(f"final ensemble of {n_final}: student alone on the selection set: success "
              f"{metric['success_rate']:.2f}, miss p50 {metric['miss_km_p50']:.2f} km")  # fmt: skip
    if _select_key(final) > _select_key(rounds.records[best.source]):
        best = Selected("final", (run.out / "student_final.pt").read_bytes(), n_final, run.hidden, law)
        _write_selected(run.out, best, law, run.task)
    return best, final


def distil_selected(run: RunSetup, rounds: Rounds, teacher: Selected, clock: RunClock,
                    resume: bool) -> tuple[Selected, dict | None]:  # fmt: skip
    """``[distil]``: one network fitted to the selected network's commands (:func:`_distil`), which
    flies in its place (with ``keep_teacher_if_better``, not where its teacher is one network of the
    same widths that does better on the selection set); returns the network that flies and the
    distillation's record (None without one, or when the teacher flies)."""
    if run.cfg.distil is None:
        for name in ("distil.json", "student_distilled.pt"):
            (run.out / name).unlink(missing_ok=True)  # an earlier run's, which this run does not distil
        return teacher, None
    law = _law(run, teacher.law)  # the distilled network flies as its teacher does
    distilled, taken = _distil(run.cfg, run.out, teacher, rounds.xs, rounds.samples, law, run.task,
                               run.fit_seed, resume)  # fmt: skip
    if taken:
        clock.credit(distilled["wall_s"])  # a distillation taken as it was counts in the run's wall time
    if (run.cfg.distil.keep_teacher_if_better and teacher.members == 1
            and tuple(distilled["hidden"]) == teacher.hidden and isinstance(teacher.source, int)
            and _select_key(distilled) < _select_key(rounds.records[teacher.source])):  # fmt: skip
        # one network of its teacher's widths saves nothing per decision: it flies only if it does as well
        write_json(run.out / "distil.json", {**distilled, "flies": False})
        print(f"the distilled network does worse than round {teacher.source} on the selection set and saves nothing "
              f"per decision: round {teacher.source} flies")  # fmt: skip
        _write_selected(run.out, teacher, law, run.task)
        return teacher, None
    best = Selected("distilled", (run.out / "student_distilled.pt").read_bytes(), 1, tuple(distilled["hidden"]), law)
    _write_selected(run.out, best, law, run.task, distilled_from=distilled["teacher"])
    return best, distilled


def choose_deployment(run: RunSetup, best: Selected, distilled: dict | None) -> dict | None:
    """``[deploy]``: the selected network flown with the trained tracker and each candidate, then,
    with the chosen tracker, with the trained load-relief margin and each candidate margin; the
    best on the task metric is kept at each step (the trained one among equals). Returns the chosen
    record (None: no scan)."""
    if not run.trackers and not run.margins:
        (run.out / DEPLOY_RECORD).unlink(missing_ok=True)  # an earlier run's choice, for a tracker this run does not fly
        return None
    law = _law(run, best.law)
    network, horizons, trained = best.network(), [law["horizon"], *run.trackers], law["load_relief_margin"]
    scan = choose_tracker(network, horizons, trained, run.cfg, run.task)
    i = max(range(len(scan)), key=lambda j: _select_key(scan[j]))  # the first of equals: the trained horizon
    record = {"student": best.source, "candidates": scan}
    chosen, margin = scan[i], trained
    if run.margins:
        margins = [trained, *(m for m in run.margins if m != trained)]
        relief = [chosen, *(choose_tracker(network, [horizons[i]], m, run.cfg, run.task)[0] for m in margins[1:])]
        k = max(range(len(relief)), key=lambda j: _select_key(relief[j]))
        record["relief_candidates"] = relief
        chosen, margin = relief[k], margins[k]
    write_json(run.out / DEPLOY_RECORD, record)
    _write_selected(run.out, best, {**law, "load_relief_margin": margin}, run.task,
                    tracker=None if i == 0 else run.trackers[i - 1],
                    distilled_from=None if distilled is None else distilled["teacher"],
                    trained_margin=trained)  # fmt: skip
    print(f"tracker: horizon {_tracker_words(chosen)}; selection success {chosen['select_success_rate']:.2f}, "
          f"miss mean {chosen['select_miss_km_mean']:.3f} km, vertical error p50 "
          f"{chosen['select_vertical_error_deg_p50']:.2f} deg")  # fmt: skip
    return chosen


def write_run_record(run: RunSetup, rounds: Rounds, best: Selected, final: dict | None, distilled: dict | None,
                     tracking: dict | None, clock: RunClock) -> None:  # fmt: skip
    """metadata.json (command, seed, wall time, config, the selected network's record) and the learning curve."""
    if distilled is not None:
        selected = distilled
    else:
        selected = final if best.source == "final" else rounds.records[best.source]
    if tracking is not None:
        selected = {**selected, "tracking": tracking}
    write_json(run.out / "metadata.json", {
        "command": " ".join(shlex.quote(a) for a in ["rventry", *sys.argv[1:]]) if sys.argv else "",
        "seed": run.fit_seed, "workers": run.workers, "wall_s": clock.elapsed(), "config": run.cfg.to_dict(),
        "selected_round": best.source, "selected": selected,
    })  # fmt: skip
    after = {} if final is None else {f"ensemble of {final['members']}, all rounds' data": final}
    if distilled is not None:
        after[f"distilled from {_student_words(distilled['teacher'], distilled['teacher_members'])}"] = distilled
    if tracking is not None:
        after[f"selected, tracker {_tracker_words(tracking)}"] = tracking
    plot_rounds(rounds.records, run.out / "learning_curve.png", after)


def train_dagger(config=None, out="runs/dagger", workers: int = 2, seed: int | None = None, progress_bar: bool = True,
                 resume: bool = False, cluster: str | None = None) -> Path:  # fmt: skip
    """Run the config's DAgger rounds, then the ensemble refit, the distillation and the tracker
    choice the config asks for. With ``resume``, the work an earlier run finished in ``out`` is
    taken as it is (each phase checks its own), and a run started with another config is refused.
    With ``cluster`` (a Dask scheduler's address) the expert's episodes fly on its workers; every
    episode is seeded, so the run is the same as on local workers."""
    run = prepare_run(config, out, workers, seed, cluster)  # a bad setting is refused before torch even loads
    check_resumable(run, resume)
    import torch

    torch.set_num_threads(max(1, workers))
    clock = RunClock()
    rounds = run_rounds(run, clock, resume, progress_bar)
    best, final = refit_ensemble(run, rounds, clock, resume)
    best, distilled = distil_selected(run, rounds, best, clock, resume)
    tracking = choose_deployment(run, best, distilled)
    write_run_record(run, rounds, best, final, distilled, tracking, clock)
    return run.out


def _tracker_words(rec: dict) -> str:
    hi, lo = rec["tracking_s"], rec["tracking_min_s"]
    words = f"{hi:g} s" if hi == lo else f"{hi:g} s, down to {lo:g} s near the ground"
    margin = rec.get("load_relief_margin")
    return words if margin is None else f"{words}, load relief {100 * margin:g} % under the bound"


def _select_key(rec: dict) -> tuple[float, float]:
    """How a round's (or the final ensemble's) record ranks on the selection set
    (:func:`~rventry_env.evaluation.summary.task_metric_key`)."""
    from rventry_env.evaluation.summary import task_metric_key

    return task_metric_key(rec["select_success_rate"], rec["select_miss_km_mean"])


def choose_tracker(network, horizons: list[Horizon], relief: float | None, cfg: DaggerConfig, task: EntryTask) -> list[dict]:
    """The network flown alone on the selection set with each tracker horizon and the load-relief
    margin ``relief``: one record each."""
    scan = []
    for h in horizons:
        metric = select_metric(LearnedGuidance(network, task=task, horizon=h, load_relief_margin=relief), cfg, task)
        scan.append({**horizon_keys(h, "tracking"), "load_relief_margin": relief,
                     **{f"select_{key}": v for key, v in metric.items()}})  # fmt: skip
    return scan


def student_law(student: StudentDeploy | dict, task: EntryTask) -> dict:
    """The student's law options (:class:`LearnedGuidance` keywords) from a [student] section, a
    student.json or a fine-tuned policy's spec (:meth:`~rventry_agents.records.StudentDeploy.law`)."""
    if isinstance(student, dict):
        student = StudentDeploy.from_dict({k: v for k, v in student.items() if k in StudentDeploy.__dataclass_fields__},
                                          "the student's settings")  # fmt: skip
    return student.law(task)


def _write_selected(out: Path, best: Selected, law: dict, task: EntryTask, tracker: Horizon | None = None,
                    distilled_from=None, trained_margin=None) -> None:  # fmt: skip
    """student.pt and student.json for the network ``best``, trained with ``law`` (its load-relief
    margin the one it flies); ``tracker``, the tracker horizon chosen after training (None: the
    trained one); ``distilled_from``, the round or "final" a distilled network was fitted to;
    ``trained_margin``, the rounds' load-relief margin where a margin was chosen after training."""
    record = {
        "hidden": list(best.hidden), "members": best.members,
        "inputs": "observation features without alpha, sigma, the lift shares and the load factor; 10 ln k_D, 10 ln k_LD",
        "input_features": list(INPUT_NAMES), "task": task.record(), "outputs": "alpha and bank commands",
        **horizon_keys(law["horizon"], "lookahead"), **({} if tracker is None else horizon_keys(tracker, "tracking")),
        "load_relief_margin": law["load_relief_margin"], "selected_round": best.source,
        **({} if trained_margin in (None, law["load_relief_margin"]) else {"trained_load_relief_margin": trained_margin}),
        **({} if distilled_from is None else {"distilled_from": distilled_from}),
    }  # fmt: skip
    StudentRecord.from_dict(record, str(out / "student.json"))  # what a loader reads back
    atomic_write(out / "student.pt", best.weights)
    write_json(out / "student.json", record)


def _student_words(name, members: int) -> str:
    return f"the ensemble of {members}" if members > 1 else ("the final refit" if name == "final" else f"round {name}")


def _distil(cfg: DaggerConfig, out: Path, teacher: Selected, xs: list, samples: int, law: dict, task: EntryTask,
            seed: int, resume: bool) -> tuple[dict, bool]:  # fmt: skip
    """``[distil]``: one network of ``hidden`` widths fitted, by the [fit] settings and ``epochs``,
    to the selected network's commands on every state the rounds visited, those below
    ``emphasis_below_m`` counted ``emphasis`` times; written as
    ``student_distilled.pt`` and ``distil.json`` (its own ``wall_s``). Returns the record and
    whether it was taken as it was from an earlier run (on resume, when it matches)."""
    from rventry_agents.imitation import fit_commands, network_commands
    from rventry_env.envs.observation import ALTITUDE_SCALE, feature_index

    d, f = cfg.distil, cfg.fit
    rec = {"teacher": teacher.source, "teacher_members": teacher.members, "teacher_hidden": list(teacher.hidden),
           "teacher_sha256": hashlib.sha256(teacher.weights).hexdigest(), "seed": seed, "hidden": list(d.hidden),
           "epochs": d.epochs or f.epochs, "samples": samples, "emphasis_below_m": d.emphasis_below_m,
           "emphasis": d.emphasis}  # fmt: skip
    done = read_json(out / "distil.json") if resume and (out / "distil.json").is_file() else None
    if done is not None and all(done.get(k) == v for k, v in rec.items()):
        print(f"distilled network: taken from {out}")
        return done, True
    t0 = time.time()
    x = np.concatenate(xs)
    low = x[:, feature_index("altitude")] * ALTITUDE_SCALE < rec["emphasis_below_m"]
    x = np.concatenate([x, np.repeat(x[low], rec["emphasis"] - 1, axis=0)])  # the few seconds near the ground
    net = new_network(tuple(rec["hidden"]), 1, seed, "distil")
    losses = fit_commands(net, x, network_commands(teacher.network(), x), rec["epochs"], f.batch_size, f.learning_rate,
                          seed, f.weight_decay)  # fmt: skip
    metric = select_metric(LearnedGuidance(net, task=task, **law), cfg, task)
    rec.update({"emphasized": int(low.sum()), "fit_loss_first": losses[0], "fit_loss_last": losses[-1],
                "wall_s": time.time() - t0, **{f"select_{key}": v for key, v in metric.items()}})  # fmt: skip
    atomic_write(out / "student_distilled.pt", network_bytes(net))
    write_json(out / "distil.json", rec)
    print(f"one network distilled from {_student_words(teacher.source, teacher.members)}: fit loss {losses[-1]:.4f}; on the "
          f"selection set: success {metric['success_rate']:.2f}, miss p50 {metric['miss_km_p50']:.2f} km")  # fmt: skip
    return rec, False


def plot_rounds(rounds: list[dict], path: Path, after: dict | None = None) -> None:
    """Each round's selection and flown figures; ``after``: records made after the last round
    (the final ensemble, the distilled network, the chosen tracker), drawn side by side one step
    to its right."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rventry_env.util.files import plain_log_labels

    fig, ax = plt.subplots(1, 2, figsize=(9, 4.6))
    k = [r["round"] for r in rounds]
    ax[0].plot(k, [r["select_success_rate"] for r in rounds], "o-", label="student alone (selection set)")
    ax[0].plot(k, [r["flown_success_rate"] for r in rounds], "s--", label="flown mixture")
    for i, ((label, rec), marker) in enumerate(zip((after or {}).items(), "D^v")):
        x = k[-1] + 1 + 0.3 * i  # side by side, not on top of each other
        ax[0].plot([x], [rec["select_success_rate"]], marker, ls="none", color=f"C{2 + i}", label=label)
        ax[1].semilogy([x], [rec["select_miss_km_p50"]], marker, ls="none", color=f"C{2 + i}", label=label)
    ax[0].set(xlabel="DAgger round", ylabel="success rate", ylim=(-0.02, 1.02))
    ax[1].semilogy(k, [r["select_miss_km_p50"] for r in rounds], "o-", color="C0")
    ax[1].set(xlabel="DAgger round", ylabel="selection miss, median (km)")
    plain_log_labels(ax[1])
    # one legend for both panels, under them: the labels of the records after the rounds are long
    fig.tight_layout(rect=(0.0, 0.22, 1.0, 1.0))
    fig.legend(*ax[0].get_legend_handles_labels(), loc="lower center", ncol=2, fontsize="small", frameon=False)
    save_figure(fig, path, tight=False)  # laid out above, leaving the legend its band


def load_student(run_dir, task: EntryTask | None = None) -> LearnedGuidance:
    """The selected student of a finished run, as a guidance law for ``task`` (default: the task it
    was trained on). Its files are read through their schemas: a corrupt one is refused, named.

    :raises ValueError: ``task`` differs from the training task (each difference named), the
        network reads its features in another order than this package builds them, or a file is
        corrupt.
    """
    run_dir = Path(run_dir)
    meta = StudentRecord.read_json(run_dir / "student.json")
    if task is None:
        task = EntryTask()
    task.check_trained(meta.task or EntryTask().record(), f"the DAgger student in {run_dir}")  # none: the default
    names = meta.input_features
    if names is not None and tuple(names) != INPUT_NAMES:
        raise ValueError(f"the DAgger student in {run_dir} reads {len(names)} input features in another order than "
                         f"this package builds; first difference: "
                         + next(f"index {i}: {a!r} saved, {b!r} now" for i, (a, b) in enumerate(zip(names, INPUT_NAMES))
                                if a != b))  # fmt: skip
    try:
        network = network_from_bytes((run_dir / "student.pt").read_bytes(), meta.hidden, meta.members)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{run_dir / 'student.pt'}: {exc}") from None
    law = LearnedGuidance(network, task=task, **meta.law(task))
    run = RunRecord.read_json(run_dir / "metadata.json") if (run_dir / "metadata.json").is_file() else RunRecord()
    where = f"{run_dir / 'metadata.json'} [config]"
    teacher = load_config(run.config, where).expert.agent if run.config is not None else "mpc"
    law.provenance = {"algorithm": f"DAgger (supervised imitation of {teacher})", "start": "scratch",
                      "samples": (run.selected or {}).get("samples"), "seed": run.seed,
                      "selected": meta.selected_round}  # fmt: skip
    return law


def load_saved(path: str, task: EntryTask | None = None) -> LearnedGuidance:
    """A DAgger run directory (entry point ``rventry.agent_files``): its selected student."""
    p = Path(path)
    if not (p.is_dir() and (p / "student.json").is_file() and (p / "student.pt").is_file()):
        raise ValueError(f"{p} is not a DAgger run directory (student.json and student.pt)")
    return load_student(p, task)


def load_shipped(name: str = "dagger-flight", task: EntryTask | None = None) -> LearnedGuidance:
    """The DAgger students shipped with this package: ``dagger``, the student of ``mpc`` on the wide
    set; ``dagger-flight``, the student of ``mpc-flight`` on the flight set (the start of ``ppo``)."""
    if name not in SHIPPED_STUDENTS:
        raise ValueError(f"no shipped DAgger student is called {name!r}; the shipped ones: {', '.join(SHIPPED_STUDENTS)}")
    where = SHIPPED_STUDENTS[name]
    if not (where / "student.pt").is_file():
        raise FileNotFoundError(f"the shipped DAgger student {name!r} is missing from {where}")
    return load_student(where, task)
