"""Benchmark RvEntry-v0: speed of the single and vector envs, and the default step's accuracy.

Speed
    * single env steps/s through ``gym.make`` (with its wrappers), constant action,
      resetting at episode end;
    * vector env vehicle-steps/s at N = 1, 64, 1024, 8192, and the same for
      ``gym.make_vec(..., vectorization_mode="sync")`` (N single envs in a
      SyncVectorEnv), with the ratio.

Accuracy
    The reference's open-loop controls, held piecewise constant per control step
    (the step-mean rates, what ``rventry evaluate --agent reference`` flies), are
    integrated by the env at several substep counts and by DOP853 at rtol 1e-12
    with the *same* piecewise-constant controls, so the difference is integration
    error alone. Reports the position error at impact and the max along the way.

The reference flown at its step (``--accuracy`` too)
    The same step-mean rates flown through the env itself at dt = 1, 0.1, 0.05 and 0.02 s (one
    substep): the running cost against J*, the miss and the vertical-impact error. The optimum's
    last half second drives alpha to zero at the full rate, which a zero-order hold averages away:
    the cost converges to J* as O(dt).

Dispersion sets (``--sets``)
    vector env vehicle-steps/s at N = 8192 with the standard set and with the flight-grade sets
    (profiles, winds, sensors and navigation), measured alternately in one run, best of three
    each; the benchmark's target: ``flight`` >= 50 % of ``standard``.

Run: ``python benchmarks/env_speed.py [--json PATH] [--quick | --scale F] [--sets] [--accuracy]`` (``--accuracy``: that part
alone, which times nothing and may run on a shared machine)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rventry_env.envs.allocator import keep_freed_memory
from rventry_env.evaluation.accuracy import step_accuracy
from rventry_env.util.args import positive_float
from rventry_env.util.provenance import start_run, write_record


def time_single(n_steps: int) -> float:
    import gymnasium as gym

    import rventry_env  # noqa: F401

    env = gym.make("RvEntry-v0")
    env.reset(seed=0)
    a = np.array([0.0, 0.02], dtype=np.float32)
    for _ in range(50):  # warm-up
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    t0 = time.perf_counter()
    for _ in range(n_steps):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return n_steps / (time.perf_counter() - t0)


def time_vector(n: int, mode: str, min_vehicle_steps: int, dispersion: str | None = None) -> float:
    import gymnasium as gym

    import rventry_env  # noqa: F401

    venv = gym.make_vec("RvEntry-v0", num_envs=n, vectorization_mode=mode, dispersion=dispersion)
    venv.reset(seed=0)
    a = np.tile(np.array([0.0, 0.02], dtype=np.float32), (n, 1))
    for _ in range(3):
        venv.step(a)
    steps = max(3, min_vehicle_steps // n)
    t0 = time.perf_counter()
    for _ in range(steps):
        venv.step(a)
    rate = n * steps / (time.perf_counter() - t0)
    venv.close()
    return rate


def time_sets(n: int, min_vehicle_steps: int, sets=("standard", "flight")) -> dict:
    """Vehicle-steps/s of the vector env per dispersion set, alternating the sets, best of three."""
    best = {s: 0.0 for s in sets}
    for _ in range(3):
        for s in sets:
            best[s] = max(best[s], time_vector(n, "vector_entry_point", min_vehicle_steps, dispersion=s))
    for s in sets:
        ratio = best[s] / best["standard"]
        print(f"N = {n}: {s:9s} {best[s]:12,.0f} vehicle-steps/s  {ratio:5.2f} x standard"
              + ("  (target >= 0.50)" if s == "flight" else ""))  # fmt: skip
    return {s: {"vehicle_steps_per_s": best[s], "ratio_to_standard": best[s] / best["standard"]} for s in sets}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--quick", action="store_true", help="a fifth of the steps (noisier figures): --scale 0.2")
    ap.add_argument("--scale", type=positive_float, default=None,
                    help="the steps timed, as a fraction of the default's (1; a smoke run: 0.01)")
    ap.add_argument("--sets", action="store_true", help="only the dispersion sets' speed at N = 8192")
    ap.add_argument("--accuracy", action="store_true", help="only the default step's accuracy (no timing)")
    args = ap.parse_args()
    start_run()
    keep_freed_memory()  # what the rventry command sets: large batches keep their freed heap (envs/allocator.py)
    if args.quick and args.scale is not None:
        ap.error("--quick is --scale 0.2: give one of them")
    scale = args.scale if args.scale is not None else 0.2 if args.quick else 1.0
    res: dict = {"scale": scale}
    if args.sets or args.accuracy:
        if args.sets:
            res["sets"] = time_sets(8192, int(2e5 * scale))
        if args.accuracy:
            accuracy(res)
        if args.json:
            write_record(args.json, res)
        return
    res["single_env_steps_per_s"] = time_single(int(20000 * scale))
    print(f"single env through gym.make: {res['single_env_steps_per_s']:,.0f} steps/s  (target >= 1e4)")
    rows = []
    for n in (1, 64, 1024, 8192):
        vec = time_vector(n, "vector_entry_point", int(3e5 * scale))
        sync = time_vector(n, "sync", int(2e4 * scale))
        rows.append({"num_envs": n, "vector_vehicle_steps_per_s": vec, "sync_vehicle_steps_per_s": sync, "speedup": vec / sync})
        print(f"N = {n:5d}: vector {vec:12,.0f}  sync {sync:10,.0f} vehicle-steps/s  ratio {vec / sync:6.1f}"
              + ("  (target >= 1e6)" if n == 8192 else ""))  # fmt: skip
    res["vector"] = rows
    accuracy(res)
    if args.json:
        write_record(args.json, res)


def accuracy(res: dict) -> None:
    """The default step's accuracy, into ``res["accuracy"]``, printed."""
    res["accuracy"] = step_accuracy()  # integration error alone: the same controls, the same saturation
    for r in res["accuracy"]:
        print(f"{r['scenario']:9s} (peak {r['peak_load_g']:.0f} g) dt {r['dt_s']} s, {r['substeps']} RK4 substeps: impact position error {r['impact_position_error_m']:.3g} m, "
              f"max {r['max_position_error_m']:.3g} m, impact time error {r['impact_time_error_s']:.2g} s (vs DOP853 rtol 1e-12)")  # fmt: skip
    res["reference_dt"] = [fly_reference(dt) for dt in REFERENCE_DTS]
    for r in res["reference_dt"]:
        print(f"the reference's step-mean rates at dt {r['dt_s']:g} s, one substep: running cost {r['cost_ratio']:.3f} J*, "
              f"miss {r['miss_km'] * 1e3:.1f} m, vertical error {r['vertical_error_deg']:.3f} deg, success {r['is_success']}")  # fmt: skip


REFERENCE_DTS = (1.0, 0.1, 0.05, 0.02)


def fly_reference(dt: float) -> dict:
    """The reference's step-mean rates (``ReferencePolicy``) flown nominally through the env at ``dt``, one substep."""
    from rventry_env.envs.rv_entry import RvEntryEnv
    from rventry_env.guidance.law import Measurement
    from rventry_env.guidance.reference_replay import ReferencePolicy
    from rventry_env.reference import load_reference
    from rventry_env.task import EntryTask

    ref = load_reference()
    task = EntryTask(dt=dt, substeps=1)
    env = RvEntryEnv(task=task, max_episode_steps=int(2 * ref.tf / dt))  # room past t_f: the end is the impact's
    policy = ReferencePolicy(task, ref)
    obs, info = env.reset(seed=0)
    term = trunc = False
    while not (term or trunc):
        obs, _, term, trunc, info = env.step(policy(Measurement.single(obs, info, env.state))[0])
    if not term:
        raise RuntimeError(f"the reference flown at dt = {dt} s did not reach the ground in {env.max_episode_steps} steps")
    return {"dt_s": dt, "substeps": 1, "cost_ratio": float(info["cost"]) / ref.cost, "miss_km": float(info["miss_km"]),
            "vertical_error_deg": float(info["vertical_error_deg"]), "speed_error_mps": float(info["speed_error_mps"]),
            "is_success": bool(info["is_success"])}  # fmt: skip


if __name__ == "__main__":
    main()
