"""Benchmark the JAX backend against NumPy, at the task's settings (dt, ``--substeps``).

Prints, on the default JAX device (say which in the output: CPU, or a GPU where one is found):

* the default step's accuracy in an aggressive S-turn (``env_speed.py``'s scenario) against
  DOP853 at rtol 1e-12, at 1, 2 and 4 RK4 substeps;
* vehicle-steps/s at N = 8192 (``--num-envs``) of the NumPy vector env and of the JAX face
  (``backend="jax"``, float64 and float32), timed in interleaved rounds in the same run, and of
  the compiled functional env (``jax.lax.scan`` over ``vmap``-ed steps, nothing back on the
  host), float64 and float32;
* JAX vs NumPy observations over whole float64 episodes (same seed, same actions): the largest
  difference;
* float32's impact-position error against float64 (same seed, same actions);
* PPO env-steps/s during training: rejax PPO on the functional env (``baselines/jax_ppo.toml``),
  its compile time, the from-scratch learner as it trains (``ppo_scratch.toml``: attitude
  commands, curriculum starts, optimistic autoreset), and stable-baselines3 PPO
  (``baselines/ppo.toml``) in the same run.

Run: ``python benchmarks/jax_backend.py [--json PATH] [--quick]``

On a GPU the functional env wants millions of vehicles, and PPO a bigger batch: the manual's GPU
figures come from ``--functional-sizes 65536 1048576 4194304 --functional-steps 100``
(``--functional-parts`` splits a step's time between the physics and the autoreset) and from
``rventry train jax-ppo --config rventry_agents/baselines/jax_ppo_gpu.toml``
(or ``--ppo-config`` of that file here, with ``--skip sb3``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from rventry_env.util.provenance import start_run, write_record


def _actions(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return lambda: np.clip(np.array([0.0, 0.03]) + rng.normal(0.0, 0.2, (n, 2)), -1.0, 1.0)


def vector_speeds(n: int, rounds: int, steps: int, substeps: int) -> dict:
    """Vehicle-steps/s of the three Gymnasium vector envs, timed in interleaved rounds (best round each)."""
    import gymnasium as gym

    import rventry_env  # noqa: F401

    kinds = {"numpy": {}, "jax_float64": {"backend": "jax", "dtype": "float64"},
             "jax_float32": {"backend": "jax", "dtype": "float32"}}  # fmt: skip
    envs = {k: gym.make_vec("RvEntry-v0", num_envs=n, vectorization_mode="vector_entry_point", dispersion="standard",
                            substeps=substeps, **kw) for k, kw in kinds.items()}  # fmt: skip
    a = np.tile(np.array([0.0, 0.02]), (n, 1))
    compile_s = {}
    for k, e in envs.items():
        e.reset(seed=0)
        t0 = time.perf_counter()
        e.step(a)
        compile_s[k] = time.perf_counter() - t0
    best = {k: 0.0 for k in envs}
    for _ in range(rounds):
        for k, e in envs.items():
            e.reset(seed=0)
            t0 = time.perf_counter()
            for _ in range(steps):
                e.step(a)
            best[k] = max(best[k], n * steps / (time.perf_counter() - t0))
    return {"num_envs": n, "vehicle_steps_per_s": best, "first_step_s": compile_s}


def numpy_substeps_speed(n: int, rounds: int = 3, steps: int = 10) -> dict:
    """The NumPy vector env at 1 and 2 RK4 substeps, interleaved rounds (best round each)."""
    import gymnasium as gym

    import rventry_env  # noqa: F401

    envs = {k: gym.make_vec("RvEntry-v0", num_envs=n, vectorization_mode="vector_entry_point", dispersion="standard",
                            substeps=k) for k in (1, 2)}  # fmt: skip
    a = np.tile(np.array([0.0, 0.02]), (n, 1))
    best = {1: 0.0, 2: 0.0}
    for _ in range(rounds):
        for k, e in envs.items():
            e.reset(seed=0)
            e.step(a)
            t0 = time.perf_counter()
            for _ in range(steps):
                e.step(a)
            best[k] = max(best[k], n * steps / (time.perf_counter() - t0))
    return {"num_envs": n, "vehicle_steps_per_s": {str(k): v for k, v in best.items()}}


def functional_speed(n: int, dtype: str, steps: int, substeps: int, dispersion: str = "standard",
                     parts: bool = False, resets: int = 0) -> dict:  # fmt: skip
    """Vehicle-steps/s of the functional env: lax.scan over vmap-ed gymnax steps (autoreset), all compiled.

    With ``parts``, also the same scan over ``step_env`` alone (no autoreset) and over ``reset_env``
    alone (the reset that gymnax's autoreset draws for every vehicle at every step): where the time goes.
    With ``resets`` > 0, also the scan over :func:`~rventry_env.envs.functional.step_batch`, the
    optimistic autoreset that draws ``resets`` fresh starts a step.
    """
    import jax
    import jax.numpy as jnp

    from rventry_env.envs.functional import RvEntryFunctional, step_batch

    env = RvEntryFunctional(dispersion=dispersion, dtype=dtype, substeps=substeps)
    p = env.default_params
    obs, st = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.PRNGKey(0), n), p)
    a = jnp.tile(jnp.array([0.0, 0.02]), (n, 1))

    def step(s, k):
        _, s, r, _, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(jax.random.split(k, n), s, a, p)
        return s, r

    def optimistic(s, k):
        _, s, r, _, _ = step_batch(env, jax.random.split(k, n), s, a, p, resets)
        return s, r

    def step_env(s, k):
        _, s, r, _, _ = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))(jax.random.split(k, n), s, a, p)
        return s, r

    def reset_env(s, k):
        o, s2 = jax.vmap(env.reset_env, in_axes=(0, None))(jax.random.split(k, n), p)
        # every output summed, so that XLA cannot drop the parts of the reset nothing reads
        return s, sum(jnp.sum(jnp.asarray(x, jnp.float32)) for x in jax.tree.leaves((o, s2)))

    def rate(body):
        roll = jax.jit(lambda s, k: jax.lax.scan(body, s, jax.random.split(k, steps)))
        t0 = time.perf_counter()
        _, r = roll(st, jax.random.PRNGKey(1))
        jax.block_until_ready(r)
        first = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, r = roll(st, jax.random.PRNGKey(2))
        jax.block_until_ready(r)
        return n * steps / (time.perf_counter() - t0), first

    out = {"dtype": dtype, "dispersion": dispersion, "num_envs": n, "steps": steps}
    out["vehicle_steps_per_s"], out["first_call_s"] = rate(step)
    if resets > 0:
        out["resets"] = resets
        out["optimistic_vehicle_steps_per_s"], _ = rate(optimistic)
    if parts:
        out["step_env_only_per_s"], _ = rate(step_env)
        out["reset_env_only_per_s"], _ = rate(reset_env)
    return out


def agreement(n: int, substeps: int, seed: int = 0) -> dict:
    """Whole episodes (autoreset off) in NumPy, JAX float64 and JAX float32 with the same seed and actions."""
    import gymnasium as gym

    import rventry_env  # noqa: F401

    kw = dict(num_envs=n, vectorization_mode="vector_entry_point", dispersion="standard", autoreset_mode="Disabled",
              substeps=substeps)
    envs = {"numpy": gym.make_vec("RvEntry-v0", **kw),
            "float64": gym.make_vec("RvEntry-v0", backend="jax", dtype="float64", **kw),
            "float32": gym.make_vec("RvEntry-v0", backend="jax", dtype="float32", **kw)}  # fmt: skip
    obs = {k: e.reset(seed=seed)[0] for k, e in envs.items()}
    worst = {"float64": np.abs(obs["numpy"] - obs["float64"]).max(), "float32": np.abs(obs["numpy"] - obs["float32"]).max()}
    end = {k: [None] * n for k in envs}
    act = _actions(n, seed)
    steps = 0
    while any(v is None for v in end["numpy"]) or any(v is None for v in end["float32"]):
        a = act()
        out = {k: e.step(a) for k, e in envs.items()}
        steps += 1
        for k in ("float64", "float32"):
            worst[k] = max(worst[k], np.abs(out["numpy"][0] - out[k][0]).max())
        for k, (o, r, te, tr, info) in out.items():
            for i in np.nonzero(te | tr)[0]:
                end[k][i] = (info["r_ecef_m"][i].copy(), info["failure"][i], info["miss_km"][i])
        if steps > 4000:
            raise RuntimeError("episodes did not end")
    pos32 = [np.linalg.norm(end["float32"][i][0] - end["float64"][i][0]) for i in range(n)]
    pos64 = [np.linalg.norm(end["numpy"][i][0] - end["float64"][i][0]) for i in range(n)]
    same_end = sum(end["float32"][i][1] == end["float64"][i][1] for i in range(n))
    return {
        "episodes": n, "steps": steps, "max_obs_diff_float64": float(worst["float64"]),
        "max_obs_diff_float32": float(worst["float32"]), "impact_position_error_float64_vs_numpy_m": float(max(pos64)),
        "float32_end_position_error_m": {"median": float(np.median(pos32)), "max": float(np.max(pos32))},
        "float32_same_ending": int(same_end),
    }  # fmt: skip


def jax_ppo_speed(timesteps: int, config: str | None = None) -> dict:
    """rejax PPO on the functional env with a config (default the baseline's): compile time and
    env-steps/s after it.

    In a fresh process: rejax's float32 training state needs JAX without float64 enabled, which
    the float64 runs above turned on for this one.
    """
    import subprocess

    out = Path(os.environ.get("TMPDIR", "/tmp")) / "bench_jax_ppo"
    code = (
        "from rventry_agents.jax_ppo import load_config, train_jax_ppo\n"
        f"cfg = load_config({config!r}).to_dict()\n"
        "chunk = int(cfg['env']['num_envs']) * int(cfg['ppo']['num_steps']) * 16\n"
        "cfg['train']['chunk_timesteps'] = chunk\n"
        f"train_jax_ppo(cfg, timesteps=max({timesteps}, 3 * chunk), out={str(out)!r}, progress=lambda s: None)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    meta = json.loads((out / "metadata.json").read_text())
    return {"env_steps_per_s": meta["env_steps_per_s"], "compile_s": meta["compile_s"], "timesteps": meta["timesteps"],
            "num_envs": meta["config"]["env"]["num_envs"], "config": config or "rventry_agents/baselines/jax_ppo.toml",
            "device": meta["device"]}  # fmt: skip


def scratch_ppo_speed(timesteps: int, config: str | None = None) -> dict:
    """The from-scratch learner (``rventry train ppo-scratch``, default its shipped config) as it
    trains: rejax PPO with attitude commands, the reverse curriculum's starts and the optimistic
    autoreset, evaluations excluded; env-steps/s is the median over the chunks after the first
    (which compiles). In a fresh process, for the same reason as :func:`jax_ppo_speed`."""
    import subprocess

    out = Path(os.environ.get("TMPDIR", "/tmp")) / "bench_ppo_scratch"
    code = (
        "from rventry_agents.scratch import train_scratch\n"
        "from rventry_agents.scratch_config import DEFAULT_CONFIG, load_config\n"
        f"path = {config!r} or str(DEFAULT_CONFIG)\n"
        "chunk = load_config(path).train.chunk_timesteps\n"
        f"train_scratch(path, out={str(out)!r}, timesteps=max({timesteps}, 3 * chunk), progress=lambda s: None)\n"
    )
    shutil.rmtree(out, ignore_errors=True)  # a fresh run, not a resumed one
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    meta = json.loads((out / "metadata.json").read_text())
    return {"env_steps_per_s": meta["env_steps_per_s"], "timesteps": meta["timesteps"], "wall_s": time.perf_counter() - t0,
            "num_envs": meta["config"]["env"]["num_envs"], "resets": meta["config"]["env"]["resets"],
            "config": config or "rventry_agents/ppo_scratch.toml", "device": meta["device"]}  # fmt: skip


def sb3_ppo_speed(timesteps: int) -> dict:
    """stable-baselines3 PPO with the plain baseline's config (baselines/ppo.toml): env-steps/s of ``learn``."""
    import torch

    from rventry_agents.train import BASELINES, algorithm_class, load_config, make_task, make_vec_env, policy_kwargs

    cfg = load_config(BASELINES / "ppo.toml", "ppo")
    torch.set_num_threads(cfg.train.torch_threads)
    venv = make_vec_env(cfg, make_task(cfg), algorithm="ppo")
    model = algorithm_class("ppo")("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs=policy_kwargs(cfg, "ppo"),
                                   verbose=0, **cfg.ppo.kwargs())  # fmt: skip
    model.learn(cfg.env.num_envs * cfg.ppo.n_steps)  # warm-up: one rollout and update
    t0 = time.perf_counter()
    model.learn(timesteps, reset_num_timesteps=False)
    return {"env_steps_per_s": timesteps / (time.perf_counter() - t0), "timesteps": timesteps}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--quick", action="store_true", help="fewer steps (noisier figures)")
    ap.add_argument("--num-envs", type=int, default=8192)
    ap.add_argument("--substeps", type=int, help="RK4 substeps of the speed and agreement runs (default: the task's)")
    ap.add_argument("--functional-sizes", type=int, nargs="+", help="vehicle counts of the functional env's runs "
                    "(default: --num-envs; a GPU wants millions)")  # fmt: skip
    ap.add_argument("--functional-steps", type=int, help="steps of each functional run (default 50, 12 with --quick)")
    ap.add_argument("--functional-parts", action="store_true",
                    help="also time step_env alone and reset_env alone (where an autoreset step's time goes)")
    ap.add_argument("--functional-resets", type=int, default=0,
                    help="also time the optimistic autoreset with this many fresh starts a step (e.g. N / 16)")
    ap.add_argument("--functional-dispersions", nargs="+", default=["standard"], help="sets the functional env flies")
    ap.add_argument("--ppo-config", help="the JAX PPO run's config (default rventry_agents/baselines/jax_ppo.toml; "
                    "rventry_agents/baselines/jax_ppo_gpu.toml on a GPU)")  # fmt: skip
    ap.add_argument("--ppo-timesteps", type=int, help="JAX PPO steps timed (default 2M, at least 3 chunks)")
    ap.add_argument("--scratch-config", help="the from-scratch learner's config (default rventry_agents/ppo_scratch.toml)")
    ap.add_argument("--scratch-timesteps", type=int, help="from-scratch steps timed (default 4 chunks)")
    ap.add_argument("--skip", nargs="*", default=[],
                    choices=["accuracy", "speed", "numpy-substeps", "functional", "agreement", "ppo", "scratch", "sb3"])  # fmt: skip
    args = ap.parse_args()
    start_run()

    def save():  # after each part, so that a run stopped midway keeps what it measured
        if args.json:
            write_record(args.json, res)

    from rventry_env.core.backend import prefer_fused_cpu_runtime
    from rventry_env.envs.allocator import keep_freed_memory

    prefer_fused_cpu_runtime()  # what the rventry command asks for, before JAX loads
    keep_freed_memory()  # and for the NumPy vector env's large batches
    import jax

    from rventry_env.task import EntryTask

    q = 0.25 if args.quick else 1.0
    task = EntryTask() if args.substeps is None else EntryTask(substeps=args.substeps)
    res: dict = {"machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "jax": jax.__version__,
                             "xla_flags": os.environ.get("XLA_FLAGS", ""),
                             "device": str(jax.devices()[0]), "device_kind": jax.devices()[0].device_kind,
                             "load_average": os.getloadavg()},
                 "task": {"dt": task.dt, "substeps": task.substeps}}  # fmt: skip
    print(f"JAX {jax.__version__} on {jax.devices()[0]} ({jax.devices()[0].device_kind}); {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.1f}; dt {task.dt} s, {task.substeps} RK4 substeps (task default {EntryTask().substeps})")  # fmt: skip
    if "accuracy" not in args.skip:
        from rventry_env.evaluation.accuracy import step_accuracy

        res["accuracy"] = step_accuracy((1, 2, 4), ("s-turn",))
        save()
        for r in res["accuracy"]:
            print(f"S-turn (peak {r['peak_load_g']:.1f} g), {r['substeps']} RK4 substeps: impact position error "
                  f"{r['impact_position_error_m']:.3g} m vs DOP853 (target <= 5 m)")  # fmt: skip
    if "speed" not in args.skip:
        v = vector_speeds(args.num_envs, 3, max(3, int(40 * q)), task.substeps)
        res["vector"] = v
        save()
        s = v["vehicle_steps_per_s"]
        print(f"vector envs, N = {args.num_envs}: NumPy {s['numpy']:,.0f}, JAX float64 {s['jax_float64']:,.0f} "
              f"({s['jax_float64'] / s['numpy']:.2f}x; target >= 2x), JAX float32 {s['jax_float32']:,.0f} "
              f"({s['jax_float32'] / s['numpy']:.2f}x) vehicle-steps/s; first step (compilation) "
              f"{v['first_step_s']['jax_float64']:.1f} s / {v['first_step_s']['jax_float32']:.1f} s")  # fmt: skip
    if "numpy-substeps" not in args.skip:
        ns_ = numpy_substeps_speed(args.num_envs)
        res["numpy_substeps"] = ns_
        save()
        v1, v2 = ns_["vehicle_steps_per_s"]["1"], ns_["vehicle_steps_per_s"]["2"]
        print(f"NumPy vector env, N = {args.num_envs}: {v1:,.0f} vehicle-steps/s at 1 substep, {v2:,.0f} at 2 "
              f"({v1 / v2:.2f}x the cost)")  # fmt: skip
    if "functional" not in args.skip:
        numpy = res.get("vector", {}).get("vehicle_steps_per_s", {}).get("numpy")
        res["functional"] = []
        for disp in args.functional_dispersions:
            for n in args.functional_sizes or [args.num_envs]:
                for d in ("float64", "float32"):
                    f = functional_speed(n, d, args.functional_steps or max(5, int(50 * q)), task.substeps, disp,
                                         args.functional_parts, min(args.functional_resets, n))
                    res["functional"].append(f)
                    save()
                    ratio = f" ({f['vehicle_steps_per_s'] / numpy:.2f}x the NumPy vector env above)" if numpy else ""
                    print(f"functional env (jit of lax.scan over vmap-ed gymnax steps, autoreset: what JAX RL libraries "
                          f"run), {disp}, {d}, N = {n:,}: {f['vehicle_steps_per_s']:,.0f} vehicle-steps/s{ratio}"
                          + ("  (target >= 5e6 on two cores)" if d == "float32" else "")
                          + f"; compile {f['first_call_s']:.1f} s", flush=True)  # fmt: skip
                    if "optimistic_vehicle_steps_per_s" in f:
                        print(f"  with the optimistic autoreset ({f['resets']:,} fresh starts a step): "
                              f"{f['optimistic_vehicle_steps_per_s']:,.0f} vehicle-steps/s "
                              f"({f['optimistic_vehicle_steps_per_s'] / f['vehicle_steps_per_s']:.2f}x gymnax's)", flush=True)  # fmt: skip
                    if args.functional_parts:
                        print(f"  its parts: step_env alone (no autoreset) {f['step_env_only_per_s']:,.0f}/s, "
                              f"reset_env alone {f['reset_env_only_per_s']:,.0f}/s", flush=True)  # fmt: skip
    if "agreement" not in args.skip:
        a = agreement(max(4, int(64 * q)), task.substeps)
        res["agreement"] = a
        save()
        print(f"whole episodes ({a['episodes']}, standard set, {a['steps']} steps): largest observation difference "
              f"JAX float64 vs NumPy {a['max_obs_diff_float64']:.2g} (target <= 1e-5), float32 {a['max_obs_diff_float32']:.2g}; "
              f"final position, float64 vs NumPy {a['impact_position_error_float64_vs_numpy_m']:.2g} m; "
              f"float32 vs float64: median {a['float32_end_position_error_m']['median']:.3g} m, max "
              f"{a['float32_end_position_error_m']['max']:.3g} m, same ending in {a['float32_same_ending']}/{a['episodes']}")  # fmt: skip
    res["ppo"] = {}
    if "ppo" not in args.skip:
        j = jax_ppo_speed(args.ppo_timesteps or int(2_000_000 * q), args.ppo_config)
        res["ppo"]["jax"] = j
        save()
        print(f"PPO training: rejax on the functional env ({j['num_envs']:,} envs, {j['device']}) "
              f"{j['env_steps_per_s']:,.0f} env-steps/s (compile {j['compile_s']:.0f} s)", flush=True)  # fmt: skip
    if "scratch" not in args.skip:
        sc = scratch_ppo_speed(args.scratch_timesteps or 0, args.scratch_config)
        res["ppo"]["scratch"] = sc
        save()
        print(f"PPO training from scratch (rejax, {sc['num_envs']:,} envs, {sc['resets']} fresh starts a step, "
              f"{sc['device']}): {sc['env_steps_per_s']:,.0f} env-steps/s", flush=True)  # fmt: skip
    if "sb3" not in args.skip:
        s3 = sb3_ppo_speed(int(200_000 * q))
        res["ppo"]["sb3"] = s3
        save()
        ratios = "; ".join(f"{name} {res['ppo'][key]['env_steps_per_s'] / s3['env_steps_per_s']:.1f}x"
                           for key, name in (("jax", "rejax baseline"), ("scratch", "from scratch")) if key in res["ppo"])
        print(f"PPO training: SB3 {s3['env_steps_per_s']:,.0f} env-steps/s in the same run: {ratios} (target >= 5x)")  # fmt: skip
    res["machine"]["load_average_end"] = os.getloadavg()
    print(f"load average (1, 5, 15 min) at the end: {', '.join(f'{v:.1f}' for v in os.getloadavg())} on "
          f"{os.cpu_count()} CPUs (figures taken on a busy machine are noisy: compare only those of one run)")
    save()


if __name__ == "__main__":
    main()
