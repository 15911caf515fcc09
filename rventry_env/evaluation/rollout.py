"""Fly a guidance law through RvEntry-v0 episodes, batched, and record the task metrics.

The law implements :class:`~rventry_env.guidance.law.GuidanceLaw`: ``reset(n)`` before the
first step, then at every step one :class:`~rventry_env.guidance.law.Measurement` (observation,
time, navigation state, sensed acceleration, flying mask) and N actions in [-1, 1] back; after
the last step its ``episode_stats()`` are merged into the records. That is everything a law is
given: never the dispersion draw or the true model. Copies whose episode has ended stay frozen
and are still measured (``flying`` False) until every episode has ended; their actions are not
flown.

All N episodes run side by side in one :class:`RvEntryVectorEnv`, so episode i is
exactly a single ``RvEntry-v0`` episode reset with seed ``seeds[i]`` (``seed + i`` by
default).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from gymnasium.vector import AutoresetMode

from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.guidance.law import GuidanceLaw, Measurement, check_law, check_retargets
from rventry_env.physics.model import EntryModel
from rventry_env.task import SCALAR_FIELDS, Dispersion, EntryTask
from rventry_env.task.starts import StartStates


@dataclass
class EpisodeBatch:
    """Per-episode outcomes (arrays of length N) and, optionally, the flown histories."""

    miss_km: np.ndarray
    vertical_error_deg: np.ndarray
    speed_error_mps: np.ndarray
    alpha_final_deg: np.ndarray
    cost: np.ndarray
    max_load_factor_g: np.ndarray
    min_dynamic_pressure_pa: np.ndarray
    constraint_violation: np.ndarray
    is_success: np.ndarray
    failure: np.ndarray
    time_s: np.ndarray
    dispersion_draw: np.ndarray
    seeds: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    # flight-grade draws with one number per episode (mass, climate drivers), name -> (N,)
    flight_draw: dict = field(default_factory=dict)
    # each episode's target on a footprint task (target_latitude_deg, target_longitude_deg -> (N,)); empty: fixed
    targets: dict = field(default_factory=dict)
    law_stats: list = field(default_factory=list)  # per episode, from the law's episode_stats()
    provenance: dict | None = None  # the law's (GuidanceLaw.provenance)
    # histories: time (T,), states (T, N, 12), actions (T, N, 2); T = longest episode
    history_t: np.ndarray | None = None
    history_x: np.ndarray | None = None
    history_a: np.ndarray | None = None
    lengths: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    # where the vehicle's navigation put it at the end (N, 3): the horizontal and the vertical
    # position error (navigated minus true, m; vertical positive when navigation is above the
    # truth) and the miss it believed (km, from the navigated position): the part of a miss
    # that navigation, not guidance, made. Without navigation errors they are 0, 0 and miss_km.
    navigation: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def records(self, reference_cost: float | None = None) -> list[dict]:
        """One JSON-friendly dict per episode."""
        out = []
        for i in range(self.miss_km.size):
            rec = {
                "miss_km": float(self.miss_km[i]),
                "vertical_error_deg": float(self.vertical_error_deg[i]),
                "speed_error_mps": float(self.speed_error_mps[i]),
                "alpha_final_deg": float(self.alpha_final_deg[i]),
                "cost": float(self.cost[i]),
                "cost_ratio": float(self.cost[i] / reference_cost) if reference_cost else None,
                "max_load_factor_g": float(self.max_load_factor_g[i]),
                "min_dynamic_pressure_pa": float(self.min_dynamic_pressure_pa[i]),
                "constraint_violation": bool(self.constraint_violation[i]),
                "success": bool(self.is_success[i]),
                "failure": str(self.failure[i]),
                "tf_s": float(self.time_s[i]),
                "dispersion": {**dict(zip(SCALAR_FIELDS, map(float, self.dispersion_draw[i]))),
                               **{k: float(v[i]) for k, v in self.flight_draw.items()}},
            }
            rec.update({k: float(v[i]) for k, v in self.targets.items()})
            if self.seeds.size:
                rec["seed"] = int(self.seeds[i])
            if self.navigation.size:
                h, v, m = map(float, self.navigation[i])
                rec["navigation_error_m"] = {"horizontal": h, "vertical": v}
                rec["navigated_miss_km"] = m
            if self.law_stats:
                rec.update(self.law_stats[i])
            out.append(rec)
        return out


_OUTCOME_KEYS = ("miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg", "cost", "max_load_factor_g",
                 "min_dynamic_pressure_pa", "constraint_violation", "is_success", "failure", "time_s")  # fmt: skip


def _episode_seeds(n_episodes: int | None, seed: int, seeds) -> list[int]:
    """The episodes' seeds: ``seeds`` as given, or ``seed + i`` for each of ``n_episodes``; checked."""
    if seeds is None:
        if n_episodes is None or n_episodes < 1:
            raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
        seeds = [seed + i for i in range(n_episodes)]
    seeds = [int(s) for s in seeds]
    if not seeds or (n_episodes is not None and n_episodes != len(seeds)):
        raise ValueError(f"give n_episodes >= 1 or a non-empty list of seeds, got {n_episodes} and {len(seeds)} seeds")
    if any(s < 0 for s in seeds):
        raise ValueError("seeds must be >= 0")
    return seeds


def _fly(venv: RvEntryVectorEnv, policy: GuidanceLaw, obs, info, record_history: bool):
    """Fly every copy of the reset ``venv`` with ``policy`` to its end, the law seeing only measurements.

    :return: ``(final, lengths, navigation, (hist_t, hist_x, hist_a))``: each outcome of
        `_OUTCOME_KEYS` per copy, the episode lengths in steps, the navigation errors at the end
        and the history lists (empty unless ``record_history``).
    """
    n = venv.num_envs
    fixed_target = venv.task.targets == "fixed"
    done = np.zeros(n, bool)
    keys = _OUTCOME_KEYS
    final = {k: np.zeros(n, dtype=object if k == "failure" else (bool if k in ("constraint_violation", "is_success") else float)) for k in keys}
    lengths = np.zeros(n, int)
    navigation = np.full((n, 3), np.nan)
    hist_t, hist_x, hist_a = [], [], []
    time_s = np.array(info["time_s"], dtype=float)  # 0, or a start state's time
    while not done.all():
        state = venv.state
        # what the law is given: the navigation state and the sensors, never the truth or the draw
        measured = Measurement(obs, time_s.copy(), info["navigation_state"].copy(), info["sensed_accel_b"].copy(), ~done,
                               None if fixed_target else info["target_e"].copy())  # fmt: skip
        actions = np.asarray(policy(measured), dtype=np.float32)
        if record_history:
            hist_t.append(time_s.copy())
            hist_x.append(state)
            hist_a.append(actions.copy())
        obs, _, term, trunc, info = venv.step(actions)
        time_s = info["time_s"]
        ended = (term | trunc) & ~done
        for k in keys:
            final[k][ended] = info[k][ended]
        lengths[ended] = venv.episode_steps[ended]
        if np.any(ended):
            navigation[ended] = navigation_at_end(venv.state[ended], info["navigation_state"][ended],
                                                  info["target_e"][ended], venv.task, venv.model.planet.radius)  # fmt: skip
        done |= ended
        if record_history:
            # the ended copy stays frozen: keep its final state once, NaN afterwards
            if np.any(ended):
                hist_t.append(np.where(ended, time_s, np.nan))
                hist_x.append(np.where(ended[:, None], venv.state, np.nan))
                hist_a.append(np.full((n, 2), np.nan, np.float32))
    return final, lengths, navigation, (hist_t, hist_x, hist_a)


def rollout(
    policy: GuidanceLaw,
    n_episodes: int | None = None,
    *,
    seed: int = 0,
    seeds=None,
    dispersion: Dispersion | dict | str | None = None,
    task: EntryTask | None = None,
    model: EntryModel | None = None,
    max_episode_steps: int | None = None,
    record_history: bool = False,
    starts: StartStates | None = None,
) -> EpisodeBatch:
    """Run ``n_episodes`` episodes of ``policy`` side by side; episode i uses seed ``seed + i``.

    :param policy: the guidance law (see module docstring).
    :param n_episodes: number of episodes (one copy each).
    :param seed: base seed: episode i uses ``seed + i``.
    :param seeds: the seeds of the episodes, one each (instead of ``n_episodes`` and ``seed``).
    :param dispersion: initial-state and model dispersions (None = nominal).
    :param task: the task (default :class:`EntryTask`).
    :param model: the force model (default :class:`EntryModel`).
    :param max_episode_steps: time limit in steps (default the registration's).
    :param record_history: keep the state and action of every step (for plots).
    :param starts: start states that replace the task's initial state (a rung of the ladder such as
        ``late``, :mod:`rventry_env.evaluation.rungs`); None: the task's own start.
    """
    seeds = _episode_seeds(n_episodes, seed, seeds)
    n = len(seeds)
    kwargs = {} if max_episode_steps is None else {"max_episode_steps": max_episode_steps}
    # one episode per copy: an ended copy stays frozen (no autoreset), so the law's memory and
    # time for it stand still too
    venv = RvEntryVectorEnv(num_envs=n, task=task, model=model, dispersion=dispersion,
                            autoreset_mode=AutoresetMode.DISABLED, starts=starts, **kwargs)  # fmt: skip
    check_retargets(check_law(policy), venv.task)
    obs, info = venv.reset(seed=seeds)
    policy.reset(n)
    fixed_target = venv.task.targets == "fixed"
    draws = venv.dispersion_draw.copy()
    flight_draw = episode_draws(info["dispersion_draw"])
    targets = {} if fixed_target else target_degrees(info["target_e"])
    final, lengths, navigation, (hist_t, hist_x, hist_a) = _fly(venv, policy, obs, info, record_history)
    stats = list(policy.episode_stats())
    batch = EpisodeBatch(**{k: final[k] for k in _OUTCOME_KEYS}, dispersion_draw=draws, lengths=lengths,
                         seeds=np.array(seeds), law_stats=stats, provenance=policy.provenance,
                         flight_draw=flight_draw, targets=targets, navigation=navigation)  # fmt: skip
    if record_history:
        batch.history_t, batch.history_x, batch.history_a = _tidy_history(hist_t, hist_x, hist_a, lengths)
    return batch


def navigation_at_end(true_state, nav_state, target_e, task: EntryTask, radius: float) -> np.ndarray:
    """(N, 3): the navigation's horizontal and vertical position errors (m; vertical positive when
    navigation is above the truth) and the miss (km) the navigated position makes, for states (N, 12)."""
    from rventry_env.core.backend import NUMPY
    from rventry_env.core.conversions import cartesian_from_rv_euler
    from rventry_env.core.euler_parameters import dcm
    from rventry_env.envs.outcome import terminal_metrics

    r_true, _ = cartesian_from_rv_euler(true_state)
    r_nav, _ = cartesian_from_rv_euler(nav_state)
    up = r_true / np.linalg.norm(r_true, axis=-1, keepdims=True)
    d = r_nav - r_true
    vertical = np.sum(d * up, axis=-1)
    horizontal = np.linalg.norm(d - vertical[:, None] * up, axis=-1)
    nav = np.asarray(nav_state, dtype=float)
    believed = terminal_metrics(tuple(nav.T), dcm(*nav[:, 1:5].T), task, tuple(np.asarray(target_e, float).T),
                                radius, NUMPY).miss_km  # fmt: skip
    return np.stack([horizontal, vertical, np.asarray(believed, dtype=float)], axis=-1)


CLIMATE_NAMES = ("day_of_year", "local_time_h", "f107_sfu", "f107a_sfu", "ap")


def target_degrees(target_e: np.ndarray) -> dict:
    """Latitude and longitude (deg) of targets given as unit vectors in E (N, 3)."""
    t = np.asarray(target_e, dtype=float)
    return {"target_latitude_deg": np.degrees(np.arcsin(np.clip(t[:, 2], -1.0, 1.0))),
            "target_longitude_deg": np.degrees(np.arctan2(t[:, 1], t[:, 0]))}  # fmt: skip


def episode_draws(draw: dict) -> dict:
    """The per-episode numbers of a reset's ``info["dispersion_draw"]`` beyond the nine scalars:
    the mass offset and, with a climatology, its drivers (name -> (N,))."""
    out = {}
    if "mass" in draw:
        out["mass"] = np.asarray(draw["mass"], dtype=float)
    climate = np.asarray(draw.get("climate", np.empty((0, 0))), dtype=float)
    if climate.size and np.all(np.isfinite(climate)):
        out.update({name: climate[:, j] for j, name in enumerate(CLIMATE_NAMES)})
    return out


def _tidy_history(ts, xs, acts, lengths):
    """Per-episode histories as (T, N, .) arrays with NaN after each episode's end."""
    n = lengths.size
    tmax = int(lengths.max()) + 1
    t_out = np.full((tmax, n), np.nan)
    x_out = np.full((tmax, n, 12), np.nan)
    a_out = np.full((tmax, n, 2), np.nan)
    k = np.zeros(n, int)
    alive = np.ones(n, bool)
    for t, x, a in zip(ts, xs, acts):
        rows = np.nonzero(alive & ~np.isnan(t))[0]
        t_out[k[rows], rows] = t[rows]
        x_out[k[rows], rows] = x[rows]
        a_out[k[rows], rows] = a[rows]
        k[rows] += 1
        alive &= k <= lengths
    return t_out, x_out, a_out
