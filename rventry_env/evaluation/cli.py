"""``rventry evaluate`` (one guidance law) and ``rventry compare`` (the shipped laws side by side).

Both fly ``RvEntry-v0`` episodes through :func:`~rventry_env.evaluation.rollout.rollout`
and write a JSON report (whole or not at all) and PNG plots. Agents are named
through :mod:`rventry_env.evaluation.agents`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rventry_env.evaluation.rungs import RUNGS, rung as ladder_rung
from rventry_env.task.glossary import terms_line
from rventry_env.task.benchmark import DISPERSED_SUCCESS_TARGETS, MARGIN_OVER_LQR, NOMINAL_TARGETS, target_checks
from rventry_env.task.definition import TARGETS
from rventry_env.task.dispersion import SET_CHOICES
from rventry_env.util.args import agent_spec, positive_int, seed
from rventry_env.util.files import check_writable, output_set, write_json

DISPERSIONS = SET_CHOICES
# mpc's dispersed episodes in `rventry compare`: about 17 s each on two cores (a re-plan every 30 s,
# 0.3 s each), which keeps the README's main command, installation included, under 5 minutes
MPC_EPISODES = 10
# the memory an evaluated episode holds until the report is written: its outcome and its JSON
# record, and with --plots its every step's state and action. Measured with /usr/bin/time on
# `rventry evaluate --agent reference --dispersion standard`: 20,000 episodes peaked at 247 MB,
# 2,000 with --plots at 1.3 GB; these are those figures per episode, rounded up
EPISODE_BYTES = 12e3
EPISODE_HISTORY_BYTES = 7e5


def register(sub: argparse._SubParsersAction) -> None:
    from rventry_env.evaluation.agents import agent_names

    names = ", ".join(agent_names())
    ev = sub.add_parser("evaluate", help="evaluate a guidance law on RvEntry-v0 against the collocation reference")
    ev.add_argument("--agent", required=True, type=agent_spec, help=f"{names}, or the path of a saved policy")
    ev.add_argument("--episodes", type=positive_int, default=1, help="number of episodes (default 1)")
    _dispersion_arguments(ev)
    ev.add_argument("--seed", type=seed, default=0, help="episode i uses seed SEED + i (default 0)")
    ev.add_argument("--rung", choices=list(RUNGS), default=None,
                    help="a rung of the training ladder: its episodes start where the rung says (late, half: on the "
                         "reference before impact) and fly its dispersion set unless --dispersion names another "
                         "(default: the task's own initial state)")  # fmt: skip
    _targets_argument(ev)
    ev.add_argument("--json", metavar="PATH",
                    help="write the summary and per-episode records here (default out/evaluate_AGENT_DISPERSION.json)")
    ev.add_argument("--plots", metavar="DIR", help="write PNG plots here")
    _parallel_arguments(ev)
    ev.set_defaults(func=_evaluate)

    cmp_ = sub.add_parser(
        "compare", help="evaluate the shipped guidance laws, nominal and dispersed, against the optimal reference"
    )
    cmp_.add_argument("--episodes", type=positive_int, default=200, help="dispersed episodes per agent (default 200)")
    cmp_.add_argument("--mpc-episodes", type=positive_int, default=MPC_EPISODES,
                      help=f"dispersed episodes for the laws that re-plan in flight, such as mpc (default "
                           f"{MPC_EPISODES}: about 17 s each on two cores)")  # fmt: skip
    cmp_.add_argument("--seed", type=seed, default=0, help="dispersed episode i uses seed SEED + i (default 0)")
    cmp_.add_argument("--agent", default="learned", type=agent_spec,
                      help="the learned agent to compare (default: the shipped learned policy)")  # fmt: skip
    _dispersion_arguments(cmp_, default="standard")
    cmp_.add_argument("--json", default="out/compare.json", metavar="PATH", help="default out/compare.json")
    cmp_.add_argument("--plots", default="out/plots", metavar="DIR", help="default out/plots")
    _parallel_arguments(cmp_)
    cmp_.set_defaults(func=_compare)


def _parallel_arguments(parser) -> None:
    from rventry_env.evaluation.parallel import default_workers

    n = default_workers()
    parser.add_argument("--workers", type=positive_int, default=n,
                        help=f"local processes for laws that run one episode per task, such as mpc (default {n}, "
                             "the cores available)")  # fmt: skip
    parser.add_argument("--cluster", metavar="ADDRESS",
                        help="run the episodes on this Dask scheduler instead (tcp://host:8786; needs rventry[cluster])")


def _targets_argument(parser) -> None:
    parser.add_argument("--targets", choices=TARGETS, default="fixed",
                        help="fixed: the paper's target; footprint: a target per episode within +/-300 km downrange "
                             "and +/-150 km crossrange of it, told to the law (laws that cannot re-target are "
                             "refused)")  # fmt: skip


def _dispersion_arguments(parser, default: str = "none") -> None:
    parser.add_argument(
        "--dispersion", choices=DISPERSIONS, default=None,
        help=f"initial-state and model dispersions (default {default}): standard = density 5 %%, C_L and C_D "
        "3 %%, altitude 0.5 km, speed 20 m/s, flight-path angle 0.2 deg; wide = 10 %%, 5 %%, 1 km, 40 m/s, "
        "0.4 deg and heading 0.2 deg (uniform half-widths); flight = altitude-varying NRLMSIS density and "
        "Gauss-Markov perturbations, winds, Mach-dependent C_L and C_D, mass, accelerometer and navigation errors; "
        "peer = RLReentry's clipped Gaussians, peer-0.1 a tenth of them (docs/uncertainty.md)",
    )  # fmt: skip
    parser.add_argument("--dispersed", action="store_true", help="the same as --dispersion standard")
    parser.set_defaults(dispersion_default=default)


def dispersion_name(args) -> str:
    """The dispersion set the arguments ask for (``--dispersed`` is ``--dispersion standard``)."""
    if args.dispersed and args.dispersion not in (None, "standard"):
        raise ValueError(f"--dispersed means --dispersion standard; it contradicts --dispersion {args.dispersion}")
    if args.dispersed:
        return "standard"
    return args.dispersion or args.dispersion_default


def available_memory() -> float | None:
    """Bytes this process may still use: the kernel's MemAvailable, or less under a cgroup limit (None: unknown)."""
    try:
        meminfo = Path("/proc/meminfo").read_text()
    except OSError:
        return None
    fields = dict(line.split(":", 1) for line in meminfo.splitlines() if ":" in line)
    if "MemAvailable" not in fields:
        return None
    free = float(fields["MemAvailable"].split()[0]) * 1024
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = float(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            free = min(free, float(limit) - used)
    except (OSError, ValueError):
        pass
    return free


def check_memory(episodes: int, history: bool, option: str = "--episodes", per_episode: float | None = None,
                 unit: str = "episode") -> None:  # fmt: skip
    """Refuse at once a request whose episodes will not fit in memory, rather than after hours or at the kernel's hand.

    :param per_episode: bytes per episode (default: the evaluation's, :data:`EPISODE_BYTES` or
        :data:`EPISODE_HISTORY_BYTES` with ``history``); ``unit`` names an episode in the message.
    """
    free = available_memory()
    per = per_episode if per_episode is not None else EPISODE_HISTORY_BYTES if history else EPISODE_BYTES
    if free is None:
        return
    fits = max(1, int(0.8 * free // per))
    if episodes <= fits:
        return
    need = f"about {episodes * per / 1e9:.3g} GB of memory" if episodes < 1e20 else "more memory than any machine has"
    raise ValueError(
        f"{option} {episodes} needs {need} ({per / 1e3:.0f} kB per {unit}"
        f"{' with --plots' if history else ''}), more than the {free / 1e9:.3g} GB available now; run it in parts of "
        f"at most {fits} {unit}s with --seed S, S + {fits}, ..." + (", or without --plots" if history else "")
    )


def run_agent(agent: str, episodes: int, dispersion: str, seed: int, history: bool, workers: int = 1,
              cluster: str | None = None, progress=None, targets: str = "fixed", rung: str | None = None):  # fmt: skip
    """Evaluate one agent on the episodes of seeds ``seed`` to ``seed + episodes - 1``; returns (batch, summary).

    :param targets: the task's targets (``"fixed"`` or ``"footprint"``); a law that cannot
        re-target is refused here, before any episode flies.
    :param rung: a rung of the ladder whose start states replace the task's initial state, or None.
    """
    from rventry_env.task import EntryTask
    from rventry_env.evaluation.parallel import EvaluationJob, cached_law, evaluate
    from rventry_env.evaluation.summary import summarize
    from rventry_env.guidance.law import check_retargets
    from rventry_env.reference import load_reference

    task = EntryTask(targets=targets)
    if targets != "fixed":
        check_retargets(cached_law(agent, task), task)
    job = EvaluationJob(agent, dispersion, task, record_history=history, rung=rung)
    batch = evaluate(job, list(range(seed, seed + episodes)), workers=workers, cluster=cluster, progress=progress)
    return batch, summarize(batch, float(load_reference().cost), task)


def _document(agent, episodes, dispersion, seed, batch, summary, targets: str = "fixed", rung: str | None = None) -> dict:
    from rventry_env.task import Dispersion
    from rventry_env.reference import load_reference

    ref = load_reference()
    return {
        "agent": agent,
        "n_episodes": episodes,
        "dispersion_set": dispersion,
        "dispersion": Dispersion.parse(dispersion).describe(),
        "seed": seed,
        "target_set": targets,
        "rung": rung,
        "provenance": batch.provenance,
        "reference": {"cost": float(ref.cost), "tf_s": float(ref.tf)},
        "summary": summary,
        "episodes": batch.records(float(ref.cost)),
    }


def _label(agent: str) -> str:
    from rventry_env.evaluation.agents import agent_names

    return agent if agent in agent_names() else Path(agent).stem


def progress_bar(transient: bool = True):
    """The progress display of the commands that fly episodes: a spinner and the elapsed time run even
    while a batched law flies all its episodes in one task (its bar moves only when the task ends)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    return Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), transient=transient)  # fmt: skip


def default_report(agent: str, dispersion: str) -> str:
    """Where ``rventry evaluate`` writes its report when ``--json`` is not given."""
    return f"out/evaluate_{_label(agent)}_{dispersion}.json"


def _evaluate(args) -> int:
    from rventry_env.task import EntryTask
    from rventry_env.evaluation.plots import plot_outcomes, plot_trajectories
    from rventry_env.reference import load_reference

    from rventry_env.evaluation.agents import check_agent

    # every argument first: a refused command creates nothing
    rung = args.rung
    on = None if rung is None else ladder_rung(rung)
    dispersion = on.dispersion if on is not None and not (args.dispersion or args.dispersed) else dispersion_name(args)
    if on is not None and on.targets != "fixed" and args.targets == "fixed":
        args.targets = on.targets
    check_agent(args.agent)
    if args.json is None:
        args.json = default_report(args.agent, dispersion if rung is None else f"{rung}_{dispersion}")
    check_writable(args.json, folders=(args.plots,) if args.plots else ())
    check_memory(args.episodes, bool(args.plots))
    t0 = time.time()
    with progress_bar() as progress:
        where = dispersion if rung is None else f"the {rung} rung, {dispersion}"
        job = progress.add_task(f"{args.agent}: {args.episodes} episode(s), {where}", total=args.episodes)
        batch, summary = run_agent(args.agent, args.episodes, dispersion, args.seed, history=bool(args.plots),
                                   workers=args.workers, cluster=args.cluster,
                                   progress=lambda n: progress.advance(job, n), targets=args.targets, rung=rung)  # fmt: skip
    doc = _document(args.agent, args.episodes, dispersion, args.seed, batch, summary, args.targets, rung)
    doc["wall_time_s"] = time.time() - t0
    doc["workers"] = None if args.cluster else args.workers
    with output_set():  # the report and its plots: all replaced, or none
        write_json(args.json, doc)
        if args.plots:
            label = _label(args.agent)
            plot_trajectories({label: batch}, Path(args.plots) / f"trajectories_{label}.png",
                              reference=load_reference())  # fmt: skip
            plot_outcomes({label: batch}, Path(args.plots) / f"outcomes_{label}.png", EntryTask().success)
    _print_summary(args.agent, summary)
    print(f"wrote {args.json}" + (f" and {args.plots}/" if args.plots else "") + f" in {time.time() - t0:.0f} s")
    printed = [*EVALUATE_TERMS, *(["load relief"] if summary.get("load_relief") else []),
               *(["navigation"] if _navigation_shown(summary) else [])]  # fmt: skip
    print(terms_line(printed))
    return 0


def _fly_compare_plan(plan: list, task, dispersion: str, args) -> list:
    """Fly every (case, agent) of ``rventry compare``'s plan on one pool, with a progress bar each.

    :return: the episode batches, in the plan's order.
    """
    from rventry_env.evaluation.parallel import EvaluationJob, evaluate_many

    # every law's episodes on one pool: the batched laws fly beside mpc's episodes, not after them
    jobs = [(EvaluationJob(agent, d, task, record_history=True), list(range(args.seed, args.seed + n)))
            for _, agent, _, n, d in plan]  # fmt: skip
    with progress_bar(transient=False) as progress:
        overall = progress.add_task(f"rventry compare ({dispersion} set)", total=sum(p[3] for p in plan))
        bars = [progress.add_task(f"  {case}: {agent}", total=n) for case, agent, _, n, _ in plan]

        def advance(j, k):
            progress.advance(bars[j], k)
            progress.advance(overall, k)

        batches = evaluate_many(jobs, workers=args.workers, cluster=args.cluster, progress=advance)
    return batches


def _compare(args) -> int:
    from rich.console import Console

    from rventry_env.task import EntryTask
    from rventry_env.evaluation import compare_report as cr
    from rventry_env.evaluation.summary import summarize
    from rventry_env.evaluation.agents import agent_cards, check_agent, compared_agents
    from rventry_env.reference import load_reference

    dispersion = dispersion_name(args)
    check_agent(args.agent)
    check_writable(args.json, folders=(args.plots,))
    t0 = time.time()
    # the columns: the agent given by --agent first, then every law whose card asks to be compared
    label = _label(args.agent)
    agents = ((args.agent, label), *((c.name, c.compare_label) for c in compared_agents() if c.name != args.agent))
    cards = agent_cards()
    episodes = {name: (args.mpc_episodes if agent in cards and cards[agent].replans else args.episodes)
                for agent, name in agents}  # fmt: skip
    check_memory(sum(episodes.values()) + len(agents), history=True)  # every law's histories, for the plots
    plan = [(case, agent, name, 1 if case == "nominal" else episodes[name], "none" if case == "nominal" else dispersion)
            for case in ("nominal", "dispersed") for agent, name in agents]  # fmt: skip
    runs = {}
    task = EntryTask()
    j_star = float(load_reference().cost)
    batches = _fly_compare_plan(plan, task, dispersion, args)
    for (case, agent, name, n, d), batch in zip(plan, batches):
        summary = summarize(batch, j_star, task)
        runs[(case, name)] = (batch, summary, _document(agent, n, d, args.seed, batch, summary))
    doc = {
        "agent": args.agent,
        "seed": args.seed,
        "dispersion_set": dispersion,
        "episodes": episodes,
        "targets": _target_checks(runs, label, dispersion),
        "runs": {f"{case}/{name}": d for (case, name), (_, _, d) in runs.items()},
        "wall_time_s": None,
        "workers": None if args.cluster else args.workers,
    }
    doc["verdict"] = cr.verdict(doc)
    plots = Path(args.plots)
    doc["wall_time_s"] = time.time() - t0
    with output_set():  # the report and its plots: all replaced, or none
        write_json(args.json, doc)
        _compare_plots(runs, agents, label, dispersion, args.seed, episodes, plots)
    print_compare(doc, Console(width=100))
    print(f"wrote {args.json} and {plots}/ (nominal_trajectories.png, dispersed_trajectories.png, dispersed_outcomes.png)"
          f" in {time.time() - t0:.0f} s")  # fmt: skip
    print(terms_line(cr.TERMS))
    return 0


def _compare_plots(runs: dict, agents, label: str, dispersion: str, seed: int, episodes: dict, plots: Path) -> None:
    """``rventry compare``'s three figures: the nominal and the dispersed trajectories, and the outcomes."""
    from rventry_env.evaluation import compare_report as cr
    from rventry_env.evaluation.plots import plot_outcomes, plot_trajectories
    from rventry_env.reference import load_reference
    from rventry_env.task import EntryTask

    ref = load_reference()
    shown = {name: cr.display_name(runs[("dispersed", name)][2]) for _, name in agents}
    counts = sorted(set(episodes.values()), reverse=True)
    n_text = f"{counts[0]} episodes per law" + (f" (mpc: {counts[-1]})" if len(counts) > 1 else "")
    plot_trajectories({shown[name]: runs[("nominal", name)][0] for _, name in agents},
                      plots / "nominal_trajectories.png", reference=ref,
                      title="Nominal flight (no dispersion): every law against the optimal reference",
                      headline=shown[label])  # fmt: skip
    plot_trajectories({shown[name]: runs[("dispersed", name)][0] for _, name in agents},
                      plots / "dispersed_trajectories.png", reference=ref,
                      title=f"{dispersion.capitalize()} set, seeds {seed}-{seed + counts[0] - 1}: "
                            f"{n_text}", headline=shown[label])  # fmt: skip
    plot_outcomes({shown[name]: runs[("dispersed", name)][0] for _, name in agents},
                  plots / "dispersed_outcomes.png", EntryTask().success,
                  title=f"Outcomes on the {dispersion} set: {n_text}")  # fmt: skip


def print_compare(doc: dict, console) -> None:
    """The tables and the verdict of a compare report (also used to print a saved one)."""
    from rventry_env.evaluation import compare_report as cr

    console.print(cr.rich_table(*cr.nominal_table(doc), caption=cr.title(doc, "nominal")))
    console.print()
    console.print(cr.rich_table(*cr.dispersed_table(doc), caption=cr.title(doc, "dispersed")))
    console.print(cr.success_note(doc) + ".", highlight=False)
    for line in cr.limiter_lines(doc):
        console.print(line, highlight=False)
    console.print()
    for line in doc.get("verdict") or cr.verdict(doc):
        console.print(line, highlight=False)


def _target_checks(runs: dict, label: str, dispersion: str) -> dict:
    """The benchmark's targets for a learned policy, checked on the agent given by ``--agent``: kept in the
    JSON report as a record; the console shows the laws against the success definition instead."""
    lqr = runs.get(("dispersed", "TV-LQR")) if label != "TV-LQR" else None
    return target_checks(runs[("nominal", label)][1], runs[("dispersed", label)][1], dispersion,
                         None if lqr is None else lqr[1])  # fmt: skip


# the terms `rventry evaluate` prints, besides the load relief and navigation where they appear
EVALUATE_TERMS = ("success", "95 % CI", "precision", "miss", "p5 / p50 / p95", "vertical-impact error", "speed error",
                  "J/J*", "path violation", "endings")  # fmt: skip


def _navigation_shown(s: dict) -> bool:
    return bool((n := s.get("navigation")) and n["horizontal_error_m"]["p95"] > 0)


def _print_summary(agent: str, s: dict) -> None:
    p = s["percentiles"]

    def pair(key, scale=1.0, fmt=".3g"):
        q = p[key]
        return " / ".join("-" if q[k] is None else format(q[k] * scale, fmt) for k in ("p50", "p95"))

    lines = [
        f"{agent}: {s['episodes']} episode(s)",
        f"  success                  {s['success_rate']:.3g} [{s['success_rate_ci'][0]:.2f}, {s['success_rate_ci'][1]:.2f}]"
        f"   precision {s['precision_success_rate']:.2f} [{s['precision_success_rate_ci'][0]:.2f}, "
        f"{s['precision_success_rate_ci'][1]:.2f}]",
        f"  miss p50 / p95 / p99     {s['miss_m']['p50']:.0f} / {s['miss_m']['p95']:.0f} / {s['miss_m']['p99']:.0f} m",
        f"  vertical-impact error    {pair('vertical_error_deg')} deg (p50 / p95)",
        f"  |speed error|            {pair('abs_speed_error_mps')} m/s (p50 / p95)",
        f"  J/J*                     {s['cost_ratio']:.3f} (mean)",
        f"  path violations          {s['constraint_violation_rate']:.3g} of the episodes",
        "  endings                  " + ", ".join(f"{k} {v}" for k, v in s["endings"].items()),
    ]  # fmt: skip
    if r := s.get("load_relief"):
        lines.append(f"  load relief              capped {r['capped_steps']} step(s) in {r['episodes_capped']} episode(s)")
    if _navigation_shown(s):
        n = s["navigation"]
        lines.append(f"  navigation at the end    horizontal error p50 / p95 {n['horizontal_error_m']['p50']:.0f} / "
                     f"{n['horizontal_error_m']['p95']:.0f} m, vertical {n['vertical_error_abs_m']['p50']:.0f} / "
                     f"{n['vertical_error_abs_m']['p95']:.0f} m; the miss it believed p50 "
                     f"{n['navigated_miss_m']['p50']:.0f} m")  # fmt: skip
    print("\n".join(lines))


__all__ = ["register", "run_agent", "dispersion_name", "NOMINAL_TARGETS", "DISPERSED_SUCCESS_TARGETS",
           "MARGIN_OVER_LQR"]
