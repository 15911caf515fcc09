"""``rventry train``: train a learning agent, and ship a finished run's policy.

Registered with the ``rventry`` command through the ``rventry.commands`` entry point.
"""

from __future__ import annotations

import argparse
import sys

from rventry_env.util.args import positive_float, positive_int, seed


# the stable-baselines3 commands: name, aliases, algorithm, default config, the [policy] mode it
# trains (None: any), what it trains
SB3_COMMANDS = (
    ("ppo-residual", (), "ppo", "ppo.toml", "residual",
     ("the PPO residual on TV-LQR: stable-baselines3 PPO learns an angle offset on the classical law "
      "(ships as the agent ppo-residual)")),
    ("ppo-finetune", (), "ppo", "ppo_finetune.toml", "student",
     ("PPO fine-tuning of an imitation student: the actor starts as the config's student ({start}) "
      "and commands its angles (ships as the agent ppo)")),
    ("ppo-plain", (), "ppo", "baselines/ppo.toml", "direct",
     "plain stable-baselines3 PPO from scratch: direct rate actions, no guide (ships as the agent ppo-plain)"),
    ("recurrent-ppo-plain", ("recurrent-ppo",), "recurrent_ppo", "baselines/recurrent_ppo.toml", "direct",
     "plain sb3-contrib RecurrentPPO (an LSTM policy) from scratch (ships as the agent recurrent-ppo-plain)"),
    ("sac-plain", ("sac",), "sac", "baselines/sac.toml", "direct",
     "plain stable-baselines3 SAC from scratch (ships as the agent sac-plain)"),
    ("ppo", (), "ppo", "ppo.toml", None,
     ("stable-baselines3 PPO in the mode --config names (without --config: the PPO residual, as "
      "ppo-residual); kept for older scripts, the commands above say what they train")),
)  # fmt: skip
COMMAND_OF_MODE = {"residual": "ppo-residual", "student": "ppo-finetune", "direct": "ppo-plain"}


def _start_words() -> str:
    """The student the shipped fine-tuning config starts from, for the help."""
    from rventry_agents.sb3_config import FINETUNE_CONFIG, load_config

    try:
        return f"{load_config(FINETUNE_CONFIG).policy.start}, by default"
    except (OSError, ValueError):
        return "its [policy] start"


def _add_sb3_commands(algos: argparse._SubParsersAction) -> None:
    from rventry_agents.sb3_config import HERE

    for name, aliases, algorithm, config, mode, what in SB3_COMMANDS:
        folder = f"runs/{name.replace('-', '_')}"
        what = what.format(start=_start_words()) if "{start}" in what else what
        cmd = algos.add_parser(name, aliases=list(aliases), help=what)
        cmd.add_argument("--timesteps", type=positive_int, help="total environment steps (default: the config's)")
        cmd.add_argument("--seed", type=seed, help="random seed (default: the config's)")
        cmd.add_argument("--out", default=folder, help=f"output directory (default {folder})")
        cmd.add_argument("--config", default=str(HERE / config),
                         help=f"TOML config (default rventry_agents/{config})"
                         + (f"; its [policy] mode must be {mode!r}" if mode else ""))  # fmt: skip
        cmd.add_argument("--resume", action="store_true",
                         help="go on with the interrupted run in --out from its latest evaluation")
        cmd.add_argument("--no-progress", action="store_true", help="no progress bar")
        cmd.set_defaults(func=_run_sb3, algorithm=algorithm, mode=mode, command_name=name)


def register(sub: argparse._SubParsersAction) -> None:
    train = sub.add_parser("train", help="train a learning agent on RvEntry-v0")
    algos = train.add_subparsers(dest="algo", metavar="ALGO", required=True)
    _add_sb3_commands(algos)
    jx = algos.add_parser("jax-ppo", help="rejax PPO end to end in JAX on the functional env (the [jax] extra)")
    jx.add_argument("--timesteps", type=positive_int, help="total environment steps (default: the config's)")
    jx.add_argument("--seed", type=seed, help="random seed (default: the config's)")
    jx.add_argument("--out", default="runs/jax_ppo", help="output directory (default runs/jax_ppo)")
    jx.add_argument("--config", help="TOML config (default rventry_agents/baselines/jax_ppo.toml)")
    jx.add_argument("--max-wall-s", type=positive_float, help="stop after the chunk that ends past this wall time (s)")
    jx.set_defaults(func=_run_jax_ppo)
    sc = algos.add_parser("ppo-scratch", help=("PPO from scratch with a reverse curriculum: rejax PPO end to end in "
                                               "JAX, no teacher (the [jax] extra; ships as the agent ppo-scratch)"))
    sc.add_argument("--timesteps", type=positive_int, help="total environment steps (default: the config's)")
    sc.add_argument("--seed", type=seed, help="random seed (default: the config's)")
    sc.add_argument("--out", default="runs/ppo_scratch", help="output directory (default runs/ppo_scratch)")
    sc.add_argument("--config", help="TOML config (default rventry_agents/ppo_scratch.toml)")
    sc.add_argument("--max-wall-s", type=positive_float, help="stop after the chunk that ends past this wall time (s): "
                    "a resumed run's segments together, a run from --init-from its own time alone")
    sc.add_argument("--resume", action="store_true", help="go on with the interrupted run in --out from its checkpoint")
    sc.add_argument("--init-from", metavar="RUN",
                    help="start from another run's checkpoint (its training state, window and history) under this "
                         "config, in a new --out: a changed curriculum or learning rate from where that run stood "
                         "(RUN/selected: from its selected chunk); "
                         "or from an exported policy (a folder with policy.npz and metadata.json, a shipped one "
                         "included): its actor and observation statistics, with a new critic")
    sc.set_defaults(func=_run_scratch)
    dag = algos.add_parser("dagger", help="the learned guidance policy: DAgger from the re-planning law (mpc)")
    dag.add_argument("--seed", type=seed, help="fit seed; also shifts the training vehicles (default: the config's)")
    dag.add_argument("--workers", type=positive_int, default=2, help="local processes flying the expert (default 2)")
    dag.add_argument("--cluster", metavar="ADDRESS",
                     help="fly the expert's episodes on the Dask cluster at this scheduler address instead")
    dag.add_argument("--out", default="runs/dagger", help="output directory (default runs/dagger)")
    dag.add_argument("--config", help="TOML config (default rventry_agents/dagger.toml)")
    dag.add_argument("--resume", action="store_true", help="take the rounds already finished in --out, go on from there")
    dag.add_argument("--no-progress", action="store_true", help="no progress bar")
    dag.set_defaults(func=_run_dagger)
    ship = algos.add_parser("ship", help="copy a finished run's selected policy into the package")
    ship.add_argument("run_dir", help="the --out directory of a finished `rventry train` run (ppo-residual, "
                                      "ppo-finetune, ppo-plain, recurrent-ppo-plain, sac-plain, dagger, ppo-scratch), "
                                      "or a ppo-scratch run's milestones/window_<W>s folder")
    ship.add_argument("--dest", help="destination (default, by what the run trained: a DAgger student to "
                                     "rventry_agents/data/dagger, PPO fine-tuning to data/ppo_finetune, the PPO "
                                     "residual to data/ppo_residual, a plain baseline to data/baselines/ALGORITHM, a from-scratch "
                                     "policy to data/ppo_scratch)")
    ship.set_defaults(func=_ship)


def _rate(meta: dict) -> str:
    """The training speed a run measured, or why it has none: the first chunk of a process includes the
    compilation of its program, so a process that trained one chunk timed none."""
    rate = meta["env_steps_per_s"]
    return "no chunk timed after the one that compiled" if rate is None else f"{rate:,.0f} env-steps/s"


def _run_scratch(args) -> int:
    try:
        from rventry_agents.scratch import selected_evaluation, train_scratch
    except ImportError as exc:
        print(f"rventry train ppo-scratch needs the [jax] extra (pip install -e '.[jax]'): {exc}", file=sys.stderr)
        return 2
    meta = train_scratch(args.config, args.out, seed=args.seed, timesteps=args.timesteps, max_wall_s=args.max_wall_s,
                         resume=args.resume, init_from=args.init_from)  # fmt: skip
    best = selected_evaluation(meta["best_evaluation"]) if meta["best_evaluation"] else {}
    selected = (f"success {best['success_rate']:.2f} on the selection set" if "success_rate" in best
                else "none (no chunk was evaluated)")
    print(f"{meta['timesteps']:,d} steps in {meta['wall_s']:.0f} s ({_rate(meta)}); selected policy: {selected}; "
          f"written to {args.out}")
    return 0


def _run_jax_ppo(args) -> int:
    try:
        from rventry_agents.jax_ppo import train_jax_ppo
    except ImportError as exc:
        print(f"rventry train jax-ppo needs the [jax] extra (pip install -e '.[jax]'): {exc}", file=sys.stderr)
        return 2
    meta = train_jax_ppo(args.config, args.timesteps, args.seed, args.out, max_wall_s=args.max_wall_s)
    print(f"{meta['timesteps']:,d} steps in {meta['wall_s']:.0f} s (compilation {meta['compile_s']:.0f} s, "
          f"then {_rate(meta)}); written to {args.out}")
    return 0


def _run_sb3(args) -> int:
    from rventry_agents.sb3_config import load_config
    from rventry_agents.train import train_sb3

    cfg = load_config(args.config, args.algorithm)
    if args.mode is not None and cfg.policy.mode != args.mode:
        raise ValueError(f"{args.config} trains [policy] mode = {cfg.policy.mode!r}; `rventry train {args.command_name}` "
                         f"trains mode = {args.mode!r}: use `rventry train {COMMAND_OF_MODE[cfg.policy.mode]}`")  # fmt: skip
    out = train_sb3(args.algorithm, cfg, args.timesteps, args.seed, args.out, progress_bar=not args.no_progress,
                    resume=args.resume)
    print(f"wrote {out}/model.zip (best on the task metric), learning_curve.png, metadata.json")
    return 0


def _run_dagger(args) -> int:
    from rventry_agents.dagger import train_dagger

    out = train_dagger(args.config, args.out, workers=args.workers, seed=args.seed, progress_bar=not args.no_progress,
                       resume=args.resume, cluster=args.cluster)
    print(f"wrote {out}/student.pt (best on the task metric), rounds.json, learning_curve.png, metadata.json")
    return 0


def _ship(args) -> int:
    from rventry_agents.ship import ship

    print(f"shipped {args.run_dir} -> {ship(args.run_dir, args.dest)}")
    return 0
