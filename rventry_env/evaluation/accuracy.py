"""The control step's integration error: an env trajectory against DOP853 under the same controls.

The env integrates each control step with ``substeps`` RK4 substeps; :func:`step_accuracy` flies a
scenario (the reference replayed, a violent dive, an aggressive S-turn) through the single env,
then integrates the same piecewise-constant controls with DOP853 at rtol 1e-12, with the env's own
alpha saturation and every switch a breakpoint, and reports the position error at impact. The
benchmarks ``benchmarks/env_speed.py`` and ``benchmarks/jax_backend.py`` print it.
"""

from __future__ import annotations

import numpy as np


def _dive_actions(obs, t):
    """A violent scenario: bank to lift sideways, then pull down hard (up to ~80 g, q ~ MPa)."""
    return np.array([-0.05, 0.0]) if t < 300 else np.array([0.3, 0.4])


S_TURN_PERIOD_S = 20.0  # one bank reversal every 20 s
S_TURN_BANK_DEG = 90.0  # conventional bank held at +-90 deg (lift sideways) between reversals
S_TURN_ALPHA_DEG = 20.0


def _s_turn_actions(obs, t):
    """An aggressive S-turn: alpha driven to 20 deg, the bank reversed between +-90 deg every 20 s at the full rate.

    The conventional bank is read from the observation's lift shares (mu = atan2(right, up)); the
    rates saturate while reversing, so the vehicle weaves at up to 30 deg/s of bank.
    """
    from rventry_env.envs.observation import feature_index

    mu = np.arctan2(obs[feature_index("lift_right")], obs[feature_index("lift_up")])
    target = np.radians(S_TURN_BANK_DEG) * (1.0 if int(t // S_TURN_PERIOD_S) % 2 == 0 else -1.0)
    alpha = (obs[feature_index("alpha")] + 1.0) / 2.0 * 25.0  # deg, alpha_max = 25 deg
    d_mu = (target - mu + np.pi) % (2 * np.pi) - np.pi
    return np.clip([(S_TURN_ALPHA_DEG - alpha) / 10.0, np.degrees(d_mu) / 30.0], -1.0, 1.0)


def step_accuracy(substeps_list=(1, 2, 4), scenarios=("reference", "dive", "s-turn")) -> list[dict]:
    """Env trajectories vs DOP853 (rtol 1e-12) under the *same* piecewise-constant controls."""
    from scipy.integrate import solve_ivp

    from rventry_env.core.conversions import cartesian_from_rv_euler
    from rventry_env.envs.rv_entry import RvEntryEnv
    from rventry_env.guidance.law import Measurement
    from rventry_env.task import EntryTask
    from rventry_env.guidance.reference_replay import ReferencePolicy
    from rventry_env.physics import EntryModel, entry_rhs

    model = EntryModel()
    out = []
    for scenario in scenarios:
        for k in substeps_list:
            task = EntryTask(substeps=k)
            policy = ReferencePolicy(task)
            env = RvEntryEnv(task=task)
            obs, info = env.reset(seed=0)
            x0 = env.state.copy()
            actions, states, times, loads = [], [env.state.copy()], [0.0], [info["load_factor_g"]]
            while True:
                if scenario == "reference":
                    a = policy(Measurement.single(obs, info, env.state))[0]
                elif scenario == "dive":
                    a = _dive_actions(obs, info["time_s"])
                else:
                    a = _s_turn_actions(obs, info["time_s"])
                actions.append(np.asarray(a, float))
                obs, _, term, trunc, info = env.step(a)
                states.append(env.state.copy())
                times.append(info["time_s"])
                loads.append(info["load_factor_g"])
                if term or trunc:
                    break
            t_hit, sol = _tight_replay(x0, np.array(actions), task, model, solve_ivp, entry_rhs)
            r_env = np.array([cartesian_from_rv_euler(s)[0] for s in states])
            r_ref = np.array([cartesian_from_rv_euler(sol(t))[0] for t in times[:-1]] + [cartesian_from_rv_euler(sol(t_hit))[0]])
            err = np.linalg.norm(r_env - r_ref, axis=1)
            out.append({
                "scenario": scenario, "substeps": k, "dt_s": task.dt, "impact_position_error_m": float(err[-1]),
                "max_position_error_m": float(err.max()), "impact_time_error_s": float(times[-1] - t_hit),
                "peak_load_g": float(max(loads)),
            })  # fmt: skip
    return out


def _tight_replay(x0, actions, task, model, solve_ivp, entry_rhs):
    """DOP853 under the env's controls: the same per-substep alpha saturation, every switch a breakpoint."""
    p = task.problem
    u = actions * np.array([p.u_alpha_max, p.u_sigma_max])
    radius = model.planet.radius
    h = task.dt / task.substeps

    def ground(t, x):
        return x[0] - radius

    ground.terminal, ground.direction = True, -1
    segs, x, t = [], np.array(x0, float), 0.0
    for k in range(len(u)):
        for _ in range(task.substeps):
            # the env's rule: the applied alpha rate lands alpha on a bound at the substep's end
            ua = (min(max(x[10] + u[k, 0] * h, 0.0), p.alpha_max) - x[10]) / h
            uk = (ua, u[k, 1])
            sol = solve_ivp(lambda _t, y, uk=uk: np.array(entry_rhs(list(y), uk, model)), (t, t + h), x, method="DOP853",
                            rtol=1e-12, atol=1e-10, dense_output=True, events=ground)  # fmt: skip
            segs.append((t, sol))
            if sol.status == 1:
                t_hit = float(sol.t_events[0][0])

                def dense(tq):
                    i = max(j for j, (t0, _) in enumerate(segs) if t0 <= tq + 1e-12)
                    return segs[i][1].sol(tq)

                return t_hit, dense
            x, t = sol.y[:, -1], sol.t[-1]
    raise RuntimeError("the tight replay did not reach the ground")



__all__ = ["step_accuracy", "S_TURN_PERIOD_S", "S_TURN_BANK_DEG", "S_TURN_ALPHA_DEG"]
