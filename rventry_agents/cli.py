"""``rventry train``: train a learning agent, and ship a finished run's policy.

Registered with the ``rventry`` command through the ``rventry.commands`` entry point.
"""

from __future__ import annotations

import argparse
import sys

from rventry_env.util.args import positive_int, seed


def register(sub: argparse._SubParsersAction) -> None:
    train = sub.add_parser("train", help="train a learning agent on RvEntry-v0")
    algos = train.add_subparsers(dest="algo", metavar="ALGO", required=True)
    from rventry_agents.train import DEFAULT_CONFIGS, FINETUNE_CONFIG

    for name, algorithm, config, what in (
        ("ppo", "ppo", DEFAULT_CONFIGS["ppo"], "stable-baselines3 PPO (default config: the PPO residual on the classical law)"),
        ("ppo-finetune", "ppo", FINETUNE_CONFIG, "stable-baselines3 PPO starting from the imitation student (dagger)"),
        ("recurrent-ppo", "recurrent_ppo", DEFAULT_CONFIGS["recurrent_ppo"],
         "sb3-contrib RecurrentPPO, an LSTM policy (default config: the plain baseline)"),
        ("sac", "sac", DEFAULT_CONFIGS["sac"], "stable-baselines3 SAC (default config: the plain baseline)"),
    ):  # fmt: skip
        default = config.relative_to(DEFAULT_CONFIGS["ppo"].parent.parent)
        cmd = algos.add_parser(name, help=f"{what}, on the numpy-batched vector env")
        cmd.add_argument("--timesteps", type=positive_int, help="total environment steps (default: the config's)")
        cmd.add_argument("--seed", type=seed, help="random seed (default: the config's)")
        cmd.add_argument("--out", default=f"runs/{name.replace('-', '_')}",
                         help=f"output directory (default runs/{name.replace('-', '_')})")
        cmd.add_argument("--config", default=str(config), help=f"TOML config (default {default})")
        cmd.add_argument("--resume", action="store_true",
                         help="go on with the interrupted run in --out from its latest evaluation")
        cmd.add_argument("--no-progress", action="store_true", help="no progress bar")
        cmd.set_defaults(func=_run_sb3, algorithm=algorithm)
    jx = algos.add_parser("jax-ppo", help="rejax PPO end to end in JAX on the functional env (the [jax] extra)")
    jx.add_argument("--timesteps", type=positive_int, help="total environment steps (default: the config's)")
    jx.add_argument("--seed", type=seed, help="random seed (default: the config's)")
    jx.add_argument("--out", default="runs/jax_ppo", help="output directory (default runs/jax_ppo)")
    jx.add_argument("--config", help="TOML config (default rventry_agents/baselines/jax_ppo.toml)")
    jx.add_argument("--max-wall-s", type=float, help="stop after the chunk that ends past this wall time (s)")
    jx.set_defaults(func=_run_jax_ppo)
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
    ship.add_argument("run_dir",
                      help="the --out directory of a finished `rventry train ppo | recurrent-ppo | sac | dagger`")
    ship.add_argument("--dest", help="destination (default, by what the run trained: a DAgger student to "
                                     "rventry_agents/data/dagger, PPO fine-tuning to data/ppo_finetune, the PPO "
                                     "residual to data/ppo, a plain baseline to data/baselines/ALGORITHM)")
    ship.set_defaults(func=_ship)


def _run_jax_ppo(args) -> int:
    try:
        from rventry_agents.jax_ppo import train_jax_ppo
    except ImportError as exc:
        print(f"rventry train jax-ppo needs the [jax] extra (pip install -e '.[jax]'): {exc}", file=sys.stderr)
        return 2
    meta = train_jax_ppo(args.config, args.timesteps, args.seed, args.out, max_wall_s=args.max_wall_s)
    print(f"{meta['timesteps']:,d} steps in {meta['wall_s']:.0f} s (compilation {meta['compile_s']:.0f} s, "
          f"then {meta['env_steps_per_s'] or float('nan'):,.0f} env-steps/s); written to {args.out}")
    return 0


def _run_sb3(args) -> int:
    from rventry_agents.train import train_sb3

    out = train_sb3(args.algorithm, args.config, args.timesteps, args.seed, args.out, progress_bar=not args.no_progress,
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
