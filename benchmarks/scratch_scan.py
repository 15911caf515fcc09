"""Training throughput of the from-scratch learner against its batch shape, on this machine.

Each variant is the shipped config (``rventry_agents/ppo_scratch.toml``, its first sections: no
stages) with a few settings changed, trained for ``--chunks`` chunks in a fresh process, nothing
else of the benchmark running beside it. It prints, per variant:

* env-steps/s of training (the median over the chunks after the first, which compiles; the
  learner's own figure, its evaluations excluded);
* env-steps/s of the wall clock, the curriculum's frontier and the selection set included (the
  median of one chunk's training and one chunk's evaluations, after the first two of each, which
  compile), which is what a training budget in hours pays;
* updates a million env-steps (epochs x minibatches per rollout), which says how much learning a
  step buys: a variant that is faster per step by taking fewer updates is not faster per update.

A variant is ``NAME:SECTION.KEY=VALUE,...`` (values read as TOML), with ``@1`` after the name to
pin it to one core (``taskset -c 0``, one XLA thread). Run:
``python benchmarks/scratch_scan.py --json docs/results/bench_scratch_scan.json``
(the default variants: the shipped shape on two cores and on one, 1,024 to 4,096 vehicles, a
longer rollout, a smaller network).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from rventry_env.util.provenance import start_run, write_record

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "rventry_agents" / "ppo_scratch.toml"

DEFAULT_VARIANTS = (
    "shipped",
    "shipped@1",
    "envs1024:env.num_envs=1024",
    "envs2048:env.num_envs=2048",
    "envs4096:env.num_envs=4096,train.chunk_timesteps=8388608",
    "steps128:ppo.num_steps=128",
    "net32:ppo.hidden_layer_sizes=[32, 32]",
)


def parse_variant(text: str) -> tuple[str, bool, dict]:
    """(name, one core, {section: {key: value}}) of ``NAME[@1][:SECTION.KEY=VALUE,...]``."""
    name, _, body = text.partition(":")
    one_core = name.endswith("@1")
    name = name.removesuffix("@1")
    changes: dict = {}
    for item in filter(None, _split(body)):
        key, sep, value = item.partition("=")
        section, dot, field = key.strip().partition(".")
        if not sep or not dot or not field:
            raise SystemExit(f"variant {text!r}: {item!r} is not SECTION.KEY=VALUE")
        try:
            changes.setdefault(section, {})[field] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError as exc:
            raise SystemExit(f"variant {text!r}: the value of {key!r} is not TOML ({exc})") from None
    return name, one_core, changes


def _split(body: str) -> list[str]:
    """``body`` split on the commas outside brackets (a list value keeps its own)."""
    parts, depth, cur = [], 0, ""
    for ch in body:
        depth += ch == "["
        depth -= ch == "]"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return parts + [cur]


def variant_config(changes: dict, chunks: int) -> dict:
    """The shipped config's first sections with ``changes``, ``chunks`` chunks long, checked."""
    from rventry_agents.scratch_config import load_config

    base = {k: v for k, v in load_config(SHIPPED).to_dict().items() if k != "stages"}
    for section, fields in changes.items():
        if section not in base:
            raise SystemExit(f"no section [{section}] in the config (it has {sorted(base)})")
        base[section] = {**base[section], **fields}
    plain = load_config(base).to_dict()  # checked here, before anything runs
    return {**plain, "train": {**plain["train"], "total_timesteps": chunks * plain["train"]["chunk_timesteps"]}}


def run_variant(name: str, one_core: bool, changes: dict, cfg: dict, workdir: Path) -> dict:
    """Train the variant (``changes``, as :func:`variant_config` made ``cfg`` of them) in a fresh process;
    its figures."""
    out = workdir / name
    shutil.rmtree(out, ignore_errors=True)
    code = (
        "import json, sys\n"
        "from rventry_agents.scratch import train_scratch\n"
        f"train_scratch(json.loads(sys.argv[1]), out={str(out)!r}, progress=lambda s: None)\n"
    )
    cmd = [sys.executable, "-c", code, json.dumps(cfg)]
    env = dict(os.environ)
    if one_core:
        cmd = ["taskset", "-c", "0", *cmd]
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} --xla_cpu_multi_thread_eigen=false".strip()
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    meta = json.loads((out / "metadata.json").read_text())
    history = json.loads((out / "evaluations.json").read_text())
    # a chunk's record is taken after its training and before its evaluations, so the difference of two
    # records' wall times is one evaluation and one chunk of training: the first two (the first chunk's
    # compilation, then the evaluation programs' compilation in the first evaluations) are left out
    walls = np.diff([h["wall_s"] for h in history])[1:]
    steps = cfg["train"]["chunk_timesteps"]
    p = cfg["ppo"]
    rollout = cfg["env"]["num_envs"] * p["num_steps"]
    return {
        "name": name, "one_core": one_core, "changes": changes, "chunks": len(history), "chunk_timesteps": steps,
        "train_env_steps_per_s": meta["env_steps_per_s"],
        "wall_env_steps_per_s": steps / float(np.median(walls)),
        "first_chunk_s": history[0]["wall_s"],
        "updates_per_million_steps": p["num_epochs"] * p["num_minibatches"] * 1e6 / rollout,
        "minibatch": rollout // p["num_minibatches"], "process_s": wall, "device": meta["device"],
    }  # fmt: skip


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("variants", nargs="*", default=list(DEFAULT_VARIANTS), help="NAME[@1][:SECTION.KEY=VALUE,...]")
    ap.add_argument("--chunks", type=int, default=4,
                    help="chunks a variant trains (the first two cycles compile and are not timed; default 4)")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    if args.chunks < 3:
        ap.error("--chunks must be at least 3: the first two cycles compile and are not timed")
    # every variant read and checked before the first trains
    parsed = [(*variant, variant_config(variant[2], args.chunks)) for variant in map(parse_variant, args.variants)]
    start_run()
    record: dict = {"chunks": args.chunks, "variants": []}
    rows = record["variants"]
    with tempfile.TemporaryDirectory(prefix="scratch_scan_") as tmp:
        for i, (name, one_core, changes, cfg) in enumerate(parsed, 1):
            print(f"[{i}/{len(parsed)}] {name}{' (one core)' if one_core else ''}: {changes or 'as shipped'}", flush=True)
            row = run_variant(name, one_core, changes, cfg, Path(tmp))
            rows.append(row)
            print(f"    training {row['train_env_steps_per_s']:,.0f} env-steps/s, wall clock {row['wall_env_steps_per_s']:,.0f} "
                  f"env-steps/s (evaluations included), {row['updates_per_million_steps']:.0f} updates a million steps",
                  flush=True)  # fmt: skip
            if args.json:  # after each variant, so a stopped scan keeps what it measured
                write_record(args.json, record)
    base = next((r for r in rows if r["name"] == "shipped" and not r["one_core"]), None)
    if base:
        print("\nagainst the shipped shape on two cores (wall clock):")
        for r in rows:
            print(f"  {r['name']:<12}{' @1' if r['one_core'] else '   '} {r['wall_env_steps_per_s'] / base['wall_env_steps_per_s']:.2f}x")


if __name__ == "__main__":
    main()
