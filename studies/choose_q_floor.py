"""Choose the q floor of a policy fine-tuned from a student, on selection seeds, and record the choice.

The q floor (:class:`rventry_env.guidance.q_floor.QFloor`) rolls the lift away from the vertical
where a climb's coming apex is predicted below q_min (1 + margin). A policy trained without it
flies each candidate margin, and without one, on ``--episodes`` episodes of each ``--sets`` set
from seed ``--seed`` (100000: away from the evaluation's seeds 0-199); the margin with the highest
mean success over the sets is chosen (a tie goes to no floor, then to the smaller margin). With
``--write`` the choice and every candidate's figures go into the run's ``policy.json``, which the
policy then flies by (``student.q_floor_margin``, ``student.q_floor_selection``).

Run: ``python studies/choose_q_floor.py rventry_agents/data/ppo_finetune [--margins 0.02 0.05 0.08]
[--sets flight wide] [--episodes 200] [--seed 100000] [--write] --json out/q_floor.json``, or
``python studies/choose_q_floor.py RUN --record out/q_floor.json`` to record an earlier run's choice.
In place of a run, a student's agent name (``dagger-flight``) flies that student with each floor: the
start a fine-tuned policy is measured against with its limiters equal (nothing is written to it).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rventry_env.util.provenance import start_run, write_record


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", help="a run directory with policy.json and model.zip (a policy fine-tuned from a student), "
                                "or a student's agent name (dagger-flight) to measure the start with each floor")
    ap.add_argument("--margins", type=float, nargs="+", default=[0.02, 0.05, 0.08])
    ap.add_argument("--sets", nargs="+", default=["flight", "wide"])
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=100000)
    ap.add_argument("--write", action="store_true", help="record the choice in the run's policy.json")
    ap.add_argument("--record", metavar="JSON", help="record the choice of an earlier run of this script (its --json) "
                                                     "in the run's policy.json, without flying again")
    ap.add_argument("--json", help="write the candidates' figures here")
    args = ap.parse_args()
    start_run()
    if (args.write or args.record) and not Path(args.run).is_dir():
        raise SystemExit(f"--write and --record record a choice in a run directory's policy.json; {args.run!r} is not one")
    if args.record:
        return record_choice(Path(args.run), json.loads(Path(args.record).read_text()))
    if not args.json:
        ap.error("--json is required unless --record is given")

    from rich.progress import Progress

    from rventry_agents.sb3_policy import SB3Policy
    from rventry_env.evaluation.rollout import rollout
    from rventry_env.guidance.q_floor import QFloor
    from rventry_env.util.files import check_writable

    run = Path(args.run)
    if run.is_dir():
        spec_path = run / "policy.json"
        spec = json.loads(spec_path.read_text())
        if spec.get("mode") != "student":
            raise SystemExit(f"{spec_path}: a q floor is chosen for a policy fine-tuned from a student (mode 'student')")

        def flown(margin):
            return SB3Policy(run).with_q_floor(margin)
    else:  # an imitation student by name: what its fine-tuned policies are measured against
        from rventry_agents.finetune import load_start
        from rventry_env.task import EntryTask

        def flown(margin):
            return load_start(args.run, EntryTask(), margin)

        flown(None)  # not a student: fails here, naming it
    for m in args.margins:
        QFloor(margin=m)  # a bad margin fails here
    check_writable(args.json)
    seeds = list(range(args.seed, args.seed + args.episodes))
    candidates = [None, *sorted(set(args.margins))]
    table: dict = {}
    t0 = time.time()
    with Progress(transient=True) as bar:
        job = bar.add_task("q floor candidates", total=len(candidates) * len(args.sets))
        for m in candidates:
            label = "none" if m is None else f"{m:g}"
            policy = flown(m)
            table[label] = {}
            for s in args.sets:
                b = rollout(policy, seeds=seeds, dispersion=s)
                table[label][s] = float(b.is_success.mean())
                bar.advance(job)
            print(f"q floor {label:>5s}: " + ", ".join(f"{s} {v:.3f}" for s, v in table[label].items()), flush=True)
    score = {k: sum(v.values()) / len(v) for k, v in table.items()}
    chosen = max(score, key=lambda k: (score[k], -candidates.index(None if k == "none" else float(k))))
    margin = None if chosen == "none" else float(chosen)
    record = {"chosen": margin, "sets": args.sets, "seeds": [seeds[0], seeds[-1]], "episodes": args.episodes,
              "success": table, "command": "python studies/choose_q_floor.py " + " ".join(
                  [str(run), "--margins", *map(str, args.margins), "--sets", *args.sets, "--episodes",
                   str(args.episodes), "--seed", str(args.seed)])}  # fmt: skip
    out = {"run": str(run), **record, "wall_s": time.time() - t0}
    write_record(args.json, out)
    print(f"chosen: {chosen} (mean success {score[chosen]:.3f} over {', '.join(args.sets)})")
    if args.write:
        record_choice(run, out)


def record_choice(run: Path, out: dict) -> None:
    """The choice in ``out`` (this script's --json) into the run's policy.json."""
    from rventry_env.util.files import write_json

    if Path(out["run"]).resolve() != run.resolve():
        raise SystemExit(f"the choice was made for {out['run']}, not for {run}")
    spec_path = run / "policy.json"
    spec = json.loads(spec_path.read_text())
    spec["student"]["q_floor_margin"] = out["chosen"]
    spec["student"]["q_floor_selection"] = {k: out[k] for k in ("chosen", "sets", "seeds", "episodes", "success",
                                                                   "command")}  # fmt: skip
    write_json(spec_path, spec)
    print(f"recorded in {spec_path}: q floor {out['chosen']}")


if __name__ == "__main__":
    main()
