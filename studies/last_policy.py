"""The policy of a from-scratch run's last chunk, exported beside the one the run selected.

    python studies/last_policy.py RUN OUT

RUN is a run of ``rventry train ppo-scratch``; its ``policy.npz`` is the chunk its selection set
ranked best. Its last checkpoint is restored under the stage the run was in, and that chunk's actor
(the deterministic policy, with its observation statistics) is written to ``OUT/policy.npz`` with
``OUT/metadata.json`` (the run's task and the policy's provenance, at the last chunk's step), and
``OUT/exported.json`` (this export's own record), so that
``rventry evaluate --agent OUT`` or ``python studies/ladder.py agent OUT`` fly it held out. A
policy kept by selection over many chunks is the best of them on one set of episodes; the last
chunk's is what the training itself ends with.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rventry_agents.scratch import last_state, policy_provenance
from rventry_env.util.files import output_set, write_json
from rventry_env.util.provenance import start_run, write_record


def export_last(run: Path, out: Path) -> dict:
    """Write the last chunk's policy of ``run`` to ``out``; its metadata."""
    trainer, ts, steps = last_state(run)
    last = json.loads((run / "evaluations.json").read_text())[-1]
    if last["timesteps"] != steps:
        raise ValueError(f"{run}: its checkpoint stands at {steps:,d} steps and its record's last chunk at "
                         f"{last['timesteps']:,d}")  # fmt: skip
    meta = {"task": trainer.task.record(), "rung": trainer.cfg.env.rung, "seed": trainer.cfg.train.seed,
            "timesteps": steps, "wall_s": last["wall_s"], "config": trainer.cfg.to_dict(), "run": str(run),
            "select": last["select"],
            "provenance": policy_provenance(trainer, steps, chunk="the run's last (not its selected one)")}  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    with output_set():  # the policy and its metadata together, or neither
        trainer.env.export(out / "policy.npz", trainer.algo, ts)
        write_json(out / "metadata.json", meta)
        write_record(out / "exported.json", {"run": str(run), "timesteps": steps, "select": last["select"]})
    return meta


def main() -> None:
    start_run()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("out", type=Path)
    args = ap.parse_args()
    meta = export_last(args.run, args.out)
    s = meta["select"]
    print(f"{args.out}: the policy of {args.run}'s last chunk, {meta['timesteps']:,d} steps "
          f"(selection set: success {s['success_rate']:.2f})")


if __name__ == "__main__":
    main()
