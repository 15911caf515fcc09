"""Why a from-scratch run's window stands: its policy flown from the reference lo-hi s before impact.

    python studies/frontier.py RUN --from 85 --to 94 [--episodes 128] [--json out/frontier.json]

RUN is a run of ``rventry train ppo-scratch``. Its last checkpoint is restored under the stage the
run was in, and its deterministic policy (the actor's mean) flies ``--episodes`` episodes started
along the shipped reference ``--from``-``--to`` s before impact, with the curriculum's perturbations
(what the run's frontier and probes fly), in the training environment itself. It prints:

* the task metrics and the share of episodes that met each success condition;
* where the impacts fell: the miss along the track (> 0: short of the target) and across it
  (> 0: the target to the right), from the last observation's range to go and heading error;
* the network's raw outputs: each episode's mean per output, and the share of its steps on which
  the output lay past the bounds its action map clips it to (``rventry_agents.commands``). A
  Gaussian policy whose mean lies there has no gradient on that output: every sample flies the
  bound, whatever the noise;
* the exploration noise (the actor's log standard deviations);
* what the network's first layer sees: the inputs as the actor reads them (scaled by the run's
  observation statistics where it normalizes them, the features themselves where not), the
  features whose first input lies furthest out, and the share of the first layer's units past
  saturation (|pre-activation| > 2, where tanh's slope is under 0.071) over each episode. Starts
  whose inputs lie many standard deviations out of what the statistics have counted put the policy
  where it extrapolates, and saturated units pass little gradient to learn there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rventry_agents.commands import clipped_outputs
from rventry_agents.scratch import last_state
from rventry_env.util.provenance import start_run

PERCENTILES = (10, 50, 90)
SATURATED = 2.0  # |pre-activation| past which a tanh unit's slope is under 0.071


def fly(trainer, ts, lo: float, hi: float, episodes: int, seed: int = 0) -> dict:
    """Per-episode outcomes, raw output means and clipped-step shares, and the last observation,
    of the deterministic policy from the reference ``lo``-``hi`` s before impact."""
    import jax
    import jax.numpy as jnp

    from rventry_agents.jax_env import OUTCOME_KEYS, actor_inputs

    env, algo = trainer.env, trainer.algo
    params = trainer.params._replace(starts=env.base.start_params(trainer.curriculum.starts_between(lo, hi)))
    clipped = jnp.asarray(clipped_outputs(env.actions))
    first = ts.actor_ts.params["params"]["features"]["Dense_0"]

    def saturated(obs):
        return jnp.mean(jnp.abs(actor_inputs(algo, ts, obs) @ first["kernel"] + first["bias"]) > SATURATED)

    def one(k):
        obs, state = env.reset(k, params)
        _, _, _, _, info0 = env.step_env(k, state, jnp.zeros(2), params)  # the info's structure
        first_inputs = actor_inputs(algo, ts, obs)

        def step(c):
            obs, state, _, info, n, total, past, sat = c
            out = env.raw_action(algo, ts, obs)
            sat = sat + saturated(obs)
            obs, state, _, done, info = env.step_env(k, state, out, params)
            return obs, state, done, info, n + 1, total + out, past + (clipped & (jnp.abs(out) > 1.0)), sat

        zeros = jnp.zeros(2, obs.dtype)
        c = jax.lax.while_loop(lambda c: jnp.logical_not(c[2]), step,
                               (obs, state, jnp.array(False), info0, 0, zeros, zeros, jnp.zeros((), obs.dtype)))  # fmt: skip
        obs, _, _, info, n, total, past, sat = c
        return {**{key: info[key] for key in OUTCOME_KEYS}, "steps": n, "output_mean": total / n,
                "clipped_share": past / n, "last_obs": obs, "first_inputs": first_inputs,
                "saturated_share": sat / n}  # fmt: skip

    run = jax.jit(jax.vmap(one))
    return jax.device_get(run(jax.random.split(jax.random.PRNGKey(seed), episodes)))


def summarize(trainer, o: dict, steps: int, lo: float, hi: float, log_std) -> dict:
    """The record of :func:`fly`'s episodes: task metrics, the miss split, the outputs and the
    exploration noise ``log_std``."""
    from rventry_agents.jax_env import summarize_outcomes
    from rventry_env.envs.observation import RANGE_SCALE, feature_index, feature_names

    metrics = summarize_outcomes(o, np.zeros(len(o["steps"])), trainer.task)
    metrics.pop("mean_return")  # not flown with the training's reward statistics: not comparable
    last = np.asarray(o["last_obs"], float)
    to_go = last[:, feature_index("range_to_go")] * RANGE_SCALE / 1e3
    along = to_go * last[:, feature_index("cos_heading_error")]
    across = to_go * last[:, feature_index("sin_heading_error")]

    def pct(x) -> list[float]:
        return [float(v) for v in np.percentile(np.asarray(x, float), PERCENTILES)]

    mean, share = np.asarray(o["output_mean"], float), np.asarray(o["clipped_share"], float)
    names = ("alpha", "bank")
    size = np.median(np.abs(np.asarray(o["first_inputs"], float)), axis=0)  # per feature, over the episodes
    furthest = {feature_names()[i]: float(size[i]) for i in np.argsort(-size)[:5]}
    return {"timesteps": steps, "starts_s": [lo, hi], "actions": trainer.env.actions, **metrics,
            "percentiles": list(PERCENTILES), "miss_along_km": pct(along), "miss_across_km": pct(across),
            "output_mean": {n: pct(mean[:, i]) for i, n in enumerate(names)},
            "clipped_share": {n: pct(share[:, i]) for i, n in enumerate(names)},
            "clipped": dict(zip(names, map(bool, clipped_outputs(trainer.env.actions)))),
            "log_std": [float(v) for v in np.ravel(log_std)],
            "normalized_inputs": bool(trainer.algo.normalize_observations), "first_input_p50_furthest": furthest,
            "saturated_share": pct(o["saturated_share"])}  # fmt: skip


def report(r: dict) -> str:
    p = "/".join(f"p{q}" for q in r["percentiles"])

    def three(x) -> str:
        return " / ".join(f"{v:.2f}" for v in x)

    head = (f"{r['timesteps']:,d} steps, {r['episodes']} starts {r['starts_s'][0]:g}-{r['starts_s'][1]:g} s before "
            f"impact, actions {r['actions']}")
    met = (f"success {r['success_rate']:.2f}; met: miss {r['miss_within_rate']:.2f}, vertical "
           f"{r['vertical_within_rate']:.2f}, speed {r['speed_within_rate']:.2f}, bounds kept "
           f"{1 - r['violation_rate']:.2f}; impact {r['impact_rate']:.2f}")
    medians = (f"miss p50 {r['miss_km_p50']:.2f} km, vertical p50 {r['vertical_error_deg_p50']:.2f} deg, speed error "
               f"p50 {r['speed_error_mps_p50']:.1f} m/s")
    split = (f"miss along the track ({p}, > 0 short) {three(r['miss_along_km'])} km; across (> 0 target to the "
             f"right) {three(r['miss_across_km'])} km")
    lines = [head, met, medians, split]
    for name in ("alpha", "bank"):
        past = (f"; steps past its clip ({p}) {three(r['clipped_share'][name])}" if r["clipped"][name]
                else " (read on the circle: not clipped)")  # fmt: skip
        lines.append(f"{name} output: episode mean ({p}) {three(r['output_mean'][name])}{past}")
    lines.append("log std " + " ".join(f"{v:.2f}" for v in r["log_std"]))
    scale = "standard deviations of the run's observation statistics" if r["normalized_inputs"] else "features as they are"
    far = ", ".join(f"{k} {v:.1f}" for k, v in r["first_input_p50_furthest"].items())
    lines.append(f"first inputs furthest out (|input| p50, {scale}): {far}")
    lines.append(f"first-layer units past |pre-activation| {SATURATED:g}, share of each episode's steps ({p}) "
                 f"{three(r['saturated_share'])}")
    return "\n".join(lines)


def main() -> None:
    start_run()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--from", dest="lo", type=float, required=True, help="latest start, s before impact")
    ap.add_argument("--to", dest="hi", type=float, required=True, help="earliest start, s before impact")
    ap.add_argument("--episodes", type=int, default=128)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, help="write the record here")
    args = ap.parse_args()
    if not 0 < args.lo < args.hi:
        ap.error(f"--from and --to must satisfy 0 < from < to, got {args.lo:g} and {args.hi:g}")
    if args.episodes < 1:
        ap.error(f"--episodes must be at least 1, got {args.episodes}")
    trainer, ts, steps = last_state(args.run)
    log_std = np.asarray(ts.actor_ts.params["params"]["action_log_std"])
    r = summarize(trainer, fly(trainer, ts, args.lo, args.hi, args.episodes, args.seed), steps, args.lo, args.hi,
                  log_std)
    print(report(r))
    if args.json:
        from rventry_env.util.provenance import write_record

        write_record(args.json, {**r, "run": str(args.run)})


if __name__ == "__main__":
    sys.exit(main())
