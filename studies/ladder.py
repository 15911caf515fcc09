"""The ladder study: what plain and from-scratch learners reach on each rung, over training seeds.

Each entry of the record is one learner on one rung (``rventry_env.evaluation.rungs``): its runs,
one per training seed, each evaluated deterministically on episodes held out from training and
selection (seeds 1000 and up, ``--episodes`` of them, the rung's own starts and dispersion), and
the interquartile mean (IQM) of their success rates with rliable's 95 % stratified-bootstrap
interval. Steps and wall time are each run's own, on the machine named in the record.

    # plain stable-baselines3 PPO, the README's quick start, trained on a rung from scratch
    python studies/ladder.py sb3 --rung late --seeds 0 1 2 --timesteps 300000
    # runs of `rventry train ppo-scratch` (rejax), or their milestones (RUN/milestones/window_<W>s),
    # each evaluated on the rungs named
    python studies/ladder.py jax RUN [RUN ...] --learner "rejax PPO, reverse curriculum" --rungs late half nominal
    # one policy (an agent name or a saved policy's folder) on rungs, held out, to its own record
    python studies/ladder.py agent RUN --rungs nominal standard wide flight --episodes 200 --json PATH
    # what runs of `rventry train ppo-scratch` reached as they trained (their windows, probes)
    python studies/ladder.py histories RUN [RUN ...] --json docs/results/scratch_runs.json

An entry is replaced whole when the same learner and rung are measured again; the record is
written whole or not at all. ``docs/tools/tables.py`` renders it in the manual.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from rventry_env.util.provenance import current_provenance, start_run

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "docs" / "results" / "ladder.json"
EVAL_SEED = 1000  # evaluation episodes: seeds from here, never a training or selection seed


def evaluate_on_rung(agent: str, rung: str, episodes: int, workers: int = 1) -> dict:
    """The deterministic policy ``agent`` (a name or a saved policy's folder) on ``episodes`` held-out
    episodes of ``rung``: its success rate, miss and vertical-impact error (p50)."""
    from rventry_env.evaluation.cli import run_agent
    from rventry_env.evaluation.rungs import rung as ladder_rung

    r = ladder_rung(rung)
    _, summary = run_agent(agent, episodes, r.dispersion, EVAL_SEED, history=False, workers=workers, targets=r.targets,
                           rung=rung)  # fmt: skip
    pct = summary["percentiles"]
    return {"rung": rung, "episodes": episodes, "success": summary["success_rate"],
            "success_ci": summary["success_rate_ci"], "miss_km_p50": summary["miss_m"]["p50"] / 1e3,
            "vertical_error_deg_p50": pct["vertical_error_deg"]["p50"] if "vertical_error_deg" in pct else None}  # fmt: skip


def train_sb3(rung: str, seed: int, timesteps: int, out: Path, gamma: float = 0.99, n_envs: int = 8) -> dict:
    """The README's quick start: plain PPO from scratch on ``rung``, saved as an agent folder."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    import rventry_env  # noqa: F401  (registers RvEntry-v0)
    from rventry_env.evaluation.rungs import rung as ladder_rung

    t0 = time.perf_counter()
    kwargs = ladder_rung(rung).env_kwargs()
    if rung not in ("late", "half"):  # the whole flight: a time-limit cut is a failure, as the JAX learner trains
        kwargs["time_limit_is_failure"] = True
    venv = VecNormalize(make_vec_env("RvEntry-v0", n_envs=n_envs, seed=seed, env_kwargs=kwargs), gamma=gamma)
    model = PPO("MlpPolicy", venv, gamma=gamma, n_steps=512, batch_size=256, seed=seed, device="cpu")
    model.learn(timesteps)
    wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    return {"seed": seed, "timesteps": int(timesteps), "wall_s": wall, "folder": str(out)}


def _entry(learner: str, rung: str, runs: list[dict], settings: dict) -> dict:
    from rventry_env.evaluation.seeds import seed_statistics

    scores = np.array([[r["evaluation"]["success"]] for r in runs])
    stats = seed_statistics({learner: scores})[learner]
    return {"learner": learner, "rung": rung, "settings": settings, "runs": runs, "seeds": len(runs),
            "iqm": stats["iqm"], "iqm_ci": stats["iqm_ci"], "mean": stats["mean"]}  # fmt: skip


def _write(path: Path, entries: list[dict]) -> None:
    from rventry_env.util.provenance import write_record

    old = json.loads(path.read_text()) if path.is_file() else {"entries": []}
    keep = [e for e in old["entries"] if (e["learner"], e["rung"]) not in {(n["learner"], n["rung"]) for n in entries}]
    doc = {"about": __doc__.split("\n\n")[0], "evaluation_seed": EVAL_SEED, "entries": keep + entries}
    write_record(path, doc)


def _sb3(args) -> None:
    from rich.progress import track

    runs = []
    for seed in track(args.seeds, description=f"SB3 PPO on the {args.rung} rung"):
        folder = Path(args.out) / f"sb3_{args.rung}_seed{seed}"
        run = train_sb3(args.rung, seed, args.timesteps, folder, gamma=args.gamma)
        run["evaluation"] = evaluate_on_rung(str(folder), args.rung, args.episodes, args.workers)
        run["provenance"] = current_provenance()
        print(f"seed {seed}: success {run['evaluation']['success']:.2f} after {args.timesteps:,} steps in "
              f"{run['wall_s']:.0f} s", flush=True)  # fmt: skip
        runs.append(run)
    settings = {"algorithm": "PPO (stable-baselines3), from scratch", "n_envs": 8, "n_steps": 512, "batch_size": 256,
                "gamma": args.gamma, "normalization": "VecNormalize", "curriculum": "none", "shaping": "none"}  # fmt: skip
    _write(Path(args.json), [_entry(args.learner or "SB3 PPO (plain)", args.rung, runs, settings)])


def _run_metadata(folder: Path) -> dict:
    """A from-scratch run's metadata (for a run stopped before its end, no metadata.json: the same
    fields from its config and its last chunk's record), with the window its curriculum had reached;
    or a run's milestone (``milestones/window_<W>s``: the policy that landed the window W)."""
    if (folder / "metadata.json").is_file() and not (folder / "evaluations.json").is_file():
        meta = json.loads((folder / "metadata.json").read_text())
        if "window_s" not in meta:
            raise ValueError(f"{folder} is neither a run of rventry train ppo-scratch nor one of its milestones")
        return meta
    last = json.loads((folder / "evaluations.json").read_text())[-1]
    if (folder / "metadata.json").is_file():
        meta = json.loads((folder / "metadata.json").read_text())
    else:
        config = json.loads((folder / "config.json").read_text())
        meta = {"seed": config["train"]["seed"], "timesteps": last["timesteps"], "wall_s": last["wall_s"],
                "rung": config["env"]["rung"], "config": config, "stopped_early": True}
    meta["window_s"] = last["curriculum"]["window_s"] if last.get("curriculum") else None
    return meta


def _jax(args) -> None:
    entries = []
    metas = [_run_metadata(Path(r)) for r in args.runs]
    for rung in args.rungs:
        runs = []
        for folder, meta in zip(args.runs, metas):
            ev = evaluate_on_rung(str(folder), rung, args.episodes, args.workers)
            print(f"{folder}: {rung} success {ev['success']:.2f}", flush=True)
            # the seed the run was started with (a staged run folds its stages' own seeds into it), and
            # the rung and seed of the stage in force at its end (its provenance), where a stage changed them
            seed = meta.get("config", {}).get("train", {}).get("seed", meta["seed"])
            last = meta.get("provenance", {})
            runs.append({"seed": seed, "last_stage_seed": last.get("seed", meta["seed"]), "timesteps": meta["timesteps"],
                         "wall_s": meta["wall_s"], "trained_on": last.get("rung", meta["rung"]),
                         "folder": str(folder), "evaluation": ev,
                         "env_steps_per_s": meta.get("env_steps_per_s"), "device": meta.get("device"),
                         "curriculum_window_s": meta["window_s"]})  # fmt: skip
        c = metas[0]["config"]
        settings = {"algorithm": "PPO (rejax), from scratch", "curriculum": c["curriculum"]["kind"],
                    "shaping": c.get("shaping", {}).get("potential", "none"), "actions": c["env"]["actions"],
                    "network": c["ppo"]["hidden_layer_sizes"], "gamma": c["ppo"]["gamma"],
                    "num_envs": c["env"]["num_envs"]}  # fmt: skip
        if c["ppo"].get("critic_hidden_layer_sizes"):  # a critic of its own widths
            settings["critic_network"] = c["ppo"]["critic_hidden_layer_sizes"]
        entries.append(_entry(args.learner, rung, runs, settings))
    _write(Path(args.json), entries)


ABSENT = "not in the run's config"  # a setting younger than the run: the run flew what came before it


def _changed(config: dict, default: dict, prefix: str = "") -> dict:
    """The settings of ``config`` that differ from ``default`` (dotted names), and those it lacks."""
    out = {}
    for k, d in default.items():
        v = config.get(k, ABSENT) if isinstance(config, dict) else ABSENT
        if isinstance(d, dict):
            out.update(_changed(v if isinstance(v, dict) else {}, d, f"{prefix}{k}."))
        elif v != d:
            out[f"{prefix}{k}"] = v
    return out


def _first_sections() -> dict:
    """The shipped config's first sections, without its stages: what each run is compared with."""
    from rventry_agents.scratch_config import load_config

    return load_config().stage_configs()[0][1].to_dict()


def history(folder: Path) -> dict:
    """What a from-scratch run reached as it trained: from its config and ``evaluations.json`` (a run
    stopped before its end has no metadata, but every chunk's record)."""
    from rventry_agents.scratch import chunk_rank, selected_evaluation
    from rventry_agents.scratch_config import load_config

    config = json.loads((folder / "config.json").read_text())
    hist = json.loads((folder / "evaluations.json").read_text())
    last = hist[-1]
    windows = [(h["curriculum"]["window_s"], h["timesteps"]) for h in hist if h.get("curriculum")]
    reached = {}
    for w, steps in windows:
        reached.setdefault(f"{w:.0f}", steps)
    best = selected_evaluation(max(hist, key=chunk_rank))  # as training selects
    load_config(config)  # checked: a run of this trainer
    state = folder / "checkpoint" / "state.json"  # a run started from another's checkpoint names it there
    start = json.loads(state.read_text()).get("init_from") if state.is_file() else None
    return {"run": folder.name, "init_from": start, "changed": _changed(config, _first_sections()),
            "timesteps": last["timesteps"], "wall_s": last["wall_s"],
            "window_s": windows[-1][0] if windows else None, "window_reached_at": reached,
            "frontier_success": last["curriculum"]["frontier_success"] if last.get("curriculum") else None,
            "probes": last.get("probes", {}), "select_success": best["success_rate"],
            "select_miss_km_p50": best["miss_km_p50"],
            "exploration_std": last.get("exploration_std")}  # fmt: skip


def _histories(args) -> None:
    from rventry_env.util.provenance import write_record

    runs = [history(Path(r)) for r in args.runs]
    for r in runs:
        print(f"{r['run']}: {r['timesteps']:,} steps, {r['wall_s'] / 60:.0f} min, window {r['window_s']} s, "
              f"full task success {r['select_success']:.2f}; changed: {r['changed']}")  # fmt: skip
    write_record(args.json, {"about": "runs of rventry train ppo-scratch: the settings each changed from the shipped "
                                      "config's first sections (its stages left out), and where each stood when it stopped", "runs": runs})


def _agent(args) -> None:
    """One policy on each rung named, held out, written to its own record (not the ladder's)."""
    from rventry_env.util.provenance import write_record

    results = {}
    for r in args.rungs:
        t0 = time.perf_counter()
        results[r] = {**evaluate_on_rung(args.agent, r, args.episodes, args.workers), "eval_s": time.perf_counter() - t0}
        lo, hi = results[r]["success_ci"]
        print(f"{args.agent} on {r}: success {results[r]['success']:.3f} [{lo:.3f}, {hi:.3f}]", flush=True)
    write_record(args.json, {"agent": args.agent, "eval_seed": EVAL_SEED, "results": results})


def _summary(path: Path) -> None:
    doc = json.loads(Path(path).read_text())
    for e in doc["entries"]:
        print(f"{e['learner']} on {e['rung']}: success IQM {e['iqm']:.2f} [{e['iqm_ci'][0]:.2f}, {e['iqm_ci'][1]:.2f}] "
              f"over {e['seeds']} seed(s)")  # fmt: skip


def main() -> None:
    start_run()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sb3", help="train plain SB3 PPO on a rung, over seeds, and evaluate it there")
    s.add_argument("--rung", required=True)
    s.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    s.add_argument("--timesteps", type=int, default=300_000)
    s.add_argument("--gamma", type=float, default=0.99)
    s.add_argument("--learner", help="the entry's name (default: SB3 PPO (plain))")
    s.add_argument("--out", default="out/ladder", help="where the trained models go (default out/ladder)")
    j = sub.add_parser("jax", help="evaluate runs of `rventry train ppo-scratch` on rungs")
    j.add_argument("runs", nargs="+")
    j.add_argument("--learner", required=True, help="the entry's name, e.g. 'rejax PPO, reverse curriculum'")
    j.add_argument("--rungs", nargs="+", required=True)
    for p in (s, j):
        p.add_argument("--episodes", type=int, default=100, help="held-out evaluation episodes (default 100)")
        p.add_argument("--workers", type=int, default=1)
        p.add_argument("--json", default=str(RECORD), help=f"the record (default {RECORD.relative_to(ROOT)})")
    a = sub.add_parser("agent", help="evaluate one policy on rungs, held out, to its own record")
    a.add_argument("agent", help="an agent name or a saved policy's folder")
    a.add_argument("--rungs", nargs="+", required=True)
    a.add_argument("--episodes", type=int, default=200, help="held-out evaluation episodes (default 200)")
    a.add_argument("--workers", type=int, default=1)
    a.add_argument("--json", required=True, help="the record to write")
    h = sub.add_parser("histories", help="summarize runs of rventry train ppo-scratch as they trained")
    h.add_argument("runs", nargs="+")
    h.add_argument("--json", default=str(RECORD.parent / "scratch_runs.json"))
    args = ap.parse_args()
    own_record = {"histories": _histories, "agent": _agent}  # each writes its own record, not the ladder's
    if args.what in own_record:
        return own_record[args.what](args)
    (_sb3 if args.what == "sb3" else _jax)(args)
    _summary(Path(args.json))


if __name__ == "__main__":
    sys.exit(main())
