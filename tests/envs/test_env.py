"""RvEntry-v0: API conformance, physics of the step, determinism, vector/single agreement."""

from __future__ import annotations

import copy
import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from gymnasium.vector import AutoresetMode
from scipy.integrate import solve_ivp

import rventry_env  # noqa: F401  (registers RvEntry-v0 once Gymnasium is loaded)
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.task import Dispersion, EntryProblem, EntryTask
from rventry_env.envs.steppers import FLOAT_STEP_MAX_COPIES, ArrayStepper
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.guidance.law import Law, Measurement
from rventry_env.physics import EntryModel, J2Gravity, PointMassGravity, entry_rhs

# alpha(0), sigma(0) pinned so these tests do not depend on the shipped reference
TASK = EntryTask(problem=EntryProblem(initial_alpha=math.radians(11.86), initial_sigma=math.radians(100.0)))


def dive_policy(obs: np.ndarray) -> np.ndarray:
    """A crude descending policy: bank to put lift sideways, bleed alpha slowly."""
    return np.array([-0.05, 0.0], dtype=np.float32)


def run_episode(env, policy=dive_policy, seed=0, options=None):
    obs, info = env.reset(seed=seed, options=options)
    traj = [obs]
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        traj.append(obs)
        total += r
        if term or trunc:
            return np.array(traj), total, info


def test_gymnasium_env_checker_passes():
    env = gym.make("RvEntry-v0", task=TASK, render_mode="rgb_array").unwrapped
    gym_check_env(env, skip_render_check=False)


@pytest.mark.slow
def test_stable_baselines3_env_checker_passes():
    from stable_baselines3.common.env_checker import check_env

    check_env(RvEntryEnv(task=TASK), warn=True)


def test_make_returns_registered_env_with_time_limit_and_attributes():
    env = gym.make("RvEntry-v0", task=TASK)
    assert env.unwrapped.max_episode_steps == 2000  # the env's own limit, not Gymnasium's TimeLimit
    env.reset(seed=0)
    s = env.unwrapped.state
    assert s.dtype == np.float64 and s.shape == (12,)
    assert env.unwrapped.dt == 1.0
    np.testing.assert_allclose(s[:10], [6378137.0 + 37e3, 0, 0, 0, 1, 7138.0, 0, 0, math.sqrt(0.5), math.sqrt(0.5)])


def test_same_seed_same_episode_with_dispersions():
    a, ra, ia = run_episode(gym.make("RvEntry-v0", task=TASK, dispersion="standard"), seed=7)
    b, rb, ib = run_episode(gym.make("RvEntry-v0", task=TASK, dispersion="standard"), seed=7)
    c, rc, _ = run_episode(gym.make("RvEntry-v0", task=TASK, dispersion="standard"), seed=8)
    assert a.shape == b.shape and np.array_equal(a, b) and ra == rb and ia["miss_km"] == ib["miss_km"]
    assert not (a.shape == c.shape and np.array_equal(a, c))


def test_step_after_termination_raises():
    env = RvEntryEnv(task=TASK)
    run_episode(env)
    with pytest.raises(RuntimeError, match="after the episode ended .* call reset"):
        env.step(np.zeros(2, np.float32))


END_KEYS = ("miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg", "max_load_factor_g",
            "min_dynamic_pressure_pa", "constraint_violation", "terminal_penalty", "failure", "is_success")  # fmt: skip


def _fly_level(env, steps):
    env.reset(seed=0)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        if terminated or truncated:
            return terminated, truncated, info
    return False, False, info


@pytest.mark.parametrize("limit", [7, 2000])
def test_a_truncated_episode_through_gym_make_carries_the_end_keys(limit):
    """The time limit is the env's own: truncation ends the episode like any other ending, through gym.make."""
    if limit == 2000:
        # the default limit: no gravity and no ceiling, so nothing but the limit ends the flight
        task = EntryTask(problem=TASK.problem, ceiling_altitude=1e9, min_speed=1.0)
        env = gym.make("RvEntry-v0", task=task, model=EntryModel(gravity=PointMassGravity(mu=0.0)))
    else:
        env = RvEntryEnv(task=TASK, max_episode_steps=limit)
    terminated, truncated, info = _fly_level(env, limit)
    assert truncated and not terminated
    assert info["time_s"] == pytest.approx(limit * 1.0)
    assert set(END_KEYS) <= set(info) and info["failure"] == "time limit" and info["is_success"] is False
    assert info["terminal_penalty"] == 0.0  # truncation charges nothing (Gymnasium semantics)
    with pytest.raises(RuntimeError, match="after the episode ended"):
        env.step(np.zeros(2, np.float32))


def test_gym_make_max_episode_steps_ends_with_the_end_keys_and_refuses_a_further_step():
    """gym.make(..., max_episode_steps=N), the usual way to shorten episodes: the env reads N from
    the TimeLimit's spec and closes the episode itself, and SB3's Monitor sees is_success."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.monitor import Monitor

    env = gym.make("RvEntry-v0", task=TASK, max_episode_steps=5)
    assert env.spec.max_episode_steps == 5
    terminated, truncated, info = _fly_level(env, 5)
    assert truncated and not terminated and info["time_s"] == pytest.approx(5.0)
    assert set(END_KEYS) <= set(info) and info["failure"] == "time limit" and info["is_success"] is False
    with pytest.raises(RuntimeError, match="after the episode ended"):
        env.step(np.zeros(2, np.float32))
    env.reset(seed=1)  # the next episode has the same limit
    assert _fly_level(env, 5)[1]

    monitored = Monitor(gym.make("RvEntry-v0", task=TASK, max_episode_steps=4), info_keywords=("is_success",))
    _, truncated, info = _fly_level(monitored, 4)
    assert truncated and info["episode"]["l"] == 4 and info["is_success"] is False
    venv = make_vec_env("RvEntry-v0", n_envs=2, env_kwargs={"task": TASK, "max_episode_steps": 3},
                        monitor_kwargs={"info_keywords": ("is_success",)})  # fmt: skip
    venv.reset()
    for _ in range(3):
        _, _, dones, infos = venv.step(np.zeros((2, 2), np.float32))
    assert dones.all() and all(i["failure"] == "time limit" and i["episode"]["is_success"] is False for i in infos)


def test_an_outer_time_limit_is_closed_by_the_wrapper():
    from rventry_env.envs.wrappers import EndAtTimeLimit

    wrapped = EndAtTimeLimit(gym.wrappers.TimeLimit(RvEntryEnv(task=TASK), 5))
    _, truncated, info = _fly_level(wrapped, 5)
    assert truncated and info["failure"] == "time limit" and set(END_KEYS) <= set(info)
    with pytest.raises(RuntimeError, match="after the episode ended"):
        wrapped.step(np.zeros(2, np.float32))


@pytest.mark.parametrize(
    "action, message",
    [
        (np.zeros(3), r"shape \(2,\)"),
        (np.zeros((1, 2)), r"shape \(2,\)"),
        (np.array([np.nan, 0.0]), "NaN or inf"),
        (np.array([0.0, np.inf]), "NaN or inf"),
    ],
)
def test_bad_actions_raise_value_error(action, message):
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_out_of_range_action_is_clipped_and_reported():
    e1, e2 = RvEntryEnv(task=TASK), RvEntryEnv(task=TASK)
    e1.reset(seed=0)
    e2.reset(seed=0)
    o1, r1, *_, i1 = e1.step(np.array([-3.0, 5.0]))
    o2, r2, *_, i2 = e2.step(np.array([-1.0, 1.0]))
    assert i1["action_clipped"] and not i2["action_clipped"]
    assert np.array_equal(o1, o2) and r1 == r2


def test_alpha_saturates_exactly_at_its_bounds():
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    saturated = False
    for _ in range(3):  # 11.86 deg at -10 deg/s reaches 0 within 2 s
        *_, info = env.step(np.array([-1.0, 0.0]))
        saturated |= info["alpha_saturated"]
    assert env.unwrapped.state[10] == 0.0 and saturated
    for _ in range(4):  # 0 -> 25 deg at 10 deg/s: 2.5 s
        *_, info = env.step(np.array([1.0, 0.0]))
    assert env.unwrapped.state[10] == pytest.approx(TASK.problem.alpha_max, abs=0) and info["alpha_saturated"]


def test_step_reward_is_minus_the_paper_running_cost():
    """Constant rates, no saturation, no path violation: -reward = exact integral of Eq. Ex2-Cost."""
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    p = TASK.problem
    a = np.array([0.3, -0.5])
    _, r, *_, info = env.step(a)
    ua, us = a[0] * p.u_alpha_max, a[1] * p.u_sigma_max
    t = np.linspace(0, 1, 2001)
    integrand = ((p.alpha_bar + ua * t - p.alpha_bar) / p.alpha_max) ** 2 + (ua / p.u_alpha_max) ** 2 + (
        us / p.u_sigma_max
    ) ** 2
    expected = np.trapezoid(integrand, t)
    assert -r == pytest.approx(expected, rel=1e-6)
    assert info["cost"] == pytest.approx(expected, rel=1e-6)


def test_impact_is_root_found_to_the_surface_and_matches_a_tight_integration():
    env = RvEntryEnv(task=TASK)
    obs, info = env.reset(seed=0)
    x0 = env.state.copy()
    steps = 0
    while True:
        obs, r, term, trunc, info = env.step(dive_policy(obs))
        steps += 1
        if term:
            break
    assert info["failure"] == "" and info["altitude_m"] == pytest.approx(0.0, abs=1e-5)
    assert env.state[0] == pytest.approx(6378137.0, abs=1e-5)
    assert info["time_s"] < steps  # the impact lies inside the last control step
    # the same controls (alpha rate -0.5 deg/s until alpha = 0, bank rate 0) integrated tightly
    model = EntryModel()
    ua = -0.05 * TASK.problem.u_alpha_max
    t_zero = x0[10] / -ua

    def f(t, x):
        u = ua if t < t_zero else 0.0
        return np.array(entry_rhs(list(x), (u, 0.0), model))

    def ground(t, x):
        return x[0] - 6378137.0

    ground.terminal, ground.direction = True, -1
    sol = solve_ivp(f, (0, 3000), x0, method="DOP853", rtol=1e-11, atol=1e-9, events=ground, max_step=5.0)
    t_hit = sol.t_events[0][0]
    assert info["time_s"] == pytest.approx(t_hit, abs=0.05)
    from rventry_env.core.conversions import cartesian_from_rv_euler

    r_ref, _ = cartesian_from_rv_euler(sol.y_events[0][0])
    assert np.linalg.norm(info["r_ecef_m"] - r_ref) < 200.0  # default dt = 1 s, 2 RK4 substeps


def test_skip_out_ends_the_episode_as_a_failure():
    env = RvEntryEnv(task=EntryTask(problem=EntryProblem(initial_alpha=math.radians(11.86), initial_sigma=math.pi)))
    _, total, info = run_episode(env, policy=lambda o: np.zeros(2, np.float32))
    assert info["failure"] == "skip-out" and not info["is_success"]
    assert info["altitude_m"] > 80e3 and info["terminal_penalty"] > RewardWeights().failure


def test_observations_stay_in_the_box_under_random_dispersed_episodes():
    env = gym.make("RvEntry-v0", task=TASK, dispersion="standard")
    rng = np.random.default_rng(1)
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        assert env.observation_space.contains(obs)
        while True:
            obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            assert env.observation_space.contains(obs), obs
            assert not info["observation_clipped"]
            for key in ("r_ecef_m", "v_ecef_mps", "latitude_deg", "longitude_deg", "altitude_m",
                        "dynamic_pressure_pa", "load_factor_g", "cost"):  # fmt: skip
                assert key in info
            if term or trunc:
                break
        for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg",
                    "constraint_violation", "is_success"):  # fmt: skip
            assert key in info


def test_info_positions_agree_with_latitude_longitude_and_altitude():
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    for _ in range(50):
        *_, info = env.step(np.array([0.0, 0.3]))
    r = info["r_ecef_m"]
    lat, lon = math.radians(info["latitude_deg"]), math.radians(info["longitude_deg"])
    np.testing.assert_allclose(r / np.linalg.norm(r), [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)], atol=1e-12)
    assert np.linalg.norm(r) - 6378137.0 == pytest.approx(info["altitude_m"], abs=1e-6)
    assert np.linalg.norm(info["v_ecef_mps"]) == pytest.approx(env.state[5], rel=1e-12)


def test_model_parts_are_swappable_through_make():
    a, _, _ = run_episode(gym.make("RvEntry-v0", task=TASK))
    b, _, _ = run_episode(gym.make("RvEntry-v0", task=TASK, model=EntryModel(gravity=J2Gravity())))
    assert not (a.shape == b.shape and np.allclose(a, b))
    with pytest.raises(TypeError, match="EntryModel"):
        RvEntryEnv(task=TASK, model={"gravity": "J2"})


@pytest.mark.parametrize(
    "options, message",
    [
        ({"state": np.zeros(11)}, r"shape \(12,\)"),
        ({"state": np.full(12, np.nan)}, "NaN or inf"),
        ({"seed": 3}, "unknown reset option"),
        ({"dispersion": {"densty": 0.1}}, "unknown dispersion field"),
        ({"dispersion": {"density": -0.1}}, "half-width"),
    ],
)
def test_bad_reset_options_raise(options, message):
    with pytest.raises(ValueError, match=message):
        RvEntryEnv(task=TASK).reset(seed=0, options=options)


def test_reset_with_an_explicit_state_starts_there():
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    s = env.state.copy()
    s[0] += 1000.0
    s[5] -= 100.0
    env.reset(seed=0, options={"state": s})
    np.testing.assert_array_equal(env.state, s)
    bad = s.copy()
    bad[6:10] *= 1.1
    with pytest.raises(ValueError, match="unit norm"):
        env.reset(options={"state": bad})


def test_render_returns_an_rgb_picture():
    env = RvEntryEnv(task=TASK, render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.zeros(2))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3 and frame.std() > 0


# ------------------------------------------------------------------ vector env


def test_make_vec_returns_the_batched_env():
    venv = gym.make_vec("RvEntry-v0", num_envs=3, vectorization_mode="vector_entry_point", task=TASK)
    assert isinstance(venv, RvEntryVectorEnv) and venv.max_episode_steps == 2000
    obs, info = venv.reset(seed=0)
    assert obs.shape == (3, 26) and venv.observation_space.contains(obs)


@pytest.mark.parametrize("dispersion", [None, "standard", "flight", "peer"])
def test_vector_env_reproduces_n_single_envs(dispersion):
    n = 5
    venv = RvEntryVectorEnv(num_envs=n, task=TASK, dispersion=dispersion)
    singles = [RvEntryEnv(task=TASK, dispersion=dispersion) for _ in range(n)]
    obs, _ = venv.reset(seed=11)
    sobs = np.stack([e.reset(seed=11 + i)[0] for i, e in enumerate(singles)])
    np.testing.assert_array_equal(obs, sobs)
    rng = np.random.default_rng(0)
    live = np.ones(n, bool)
    while live.any():
        a = np.column_stack([rng.uniform(-0.2, 0.05, n), rng.uniform(-1, 1, n)]).astype(np.float32)
        obs, rew, term, trunc, info = venv.step(a)
        for i, e in enumerate(singles):
            if not live[i]:
                continue
            so, sr, st, s_tr, si = e.step(a[i])
            np.testing.assert_allclose(obs[i], so, rtol=0, atol=1e-6)
            assert rew[i] == pytest.approx(sr, rel=1e-9, abs=1e-12)
            assert st == term[i]
            np.testing.assert_allclose(venv.state[i], e.state, rtol=1e-12)
            # what the vehicle measures too (its navigation and accelerometer, with the flight sets' errors)
            np.testing.assert_allclose(info["navigation_state"][i], si["navigation_state"], rtol=1e-11, atol=1e-12)
            np.testing.assert_allclose(info["sensed_accel_b"][i], si["sensed_accel_b"], rtol=1e-10, atol=1e-12)
            if st:
                live[i] = False
                assert info["_miss_km"][i] and info["miss_km"][i] == pytest.approx(si["miss_km"], rel=1e-9)
                assert info["failure"][i] == si["failure"]


def _few_copies_episode(dispersion, seed, on_floats, n=1, steps=None, **kw):
    """Every output of an ``n``-copy vector env until every episode ended (or over ``steps``
    steps), actions drawn from ``seed``."""
    venv = RvEntryVectorEnv(num_envs=n, task=TASK, dispersion=dispersion, **kw)
    if not on_floats:
        venv.stepper = ArrayStepper(venv.stepper.setup)  # the array path, as for many copies
    rng = np.random.default_rng(seed)
    out = [copy.deepcopy(venv.reset(seed=seed))]
    ended = np.zeros(n, bool)
    for _ in range(steps or 3000):
        a = np.column_stack([rng.uniform(-0.3, 0.1, n), rng.uniform(-1, 1, n)]).astype(np.float32)
        out.append(copy.deepcopy(venv.step(a)))
        ended |= out[-1][2] | out[-1][3]
        if steps is None and ended.all():
            break
    return out


def _assert_same_bits(a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), set(a) ^ set(b)
        for k in a:
            _assert_same_bits(a[k], b[k])
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _assert_same_bits(x, y)
    else:
        x, y = np.asarray(a), np.asarray(b)
        assert x.dtype == y.dtype and x.shape == y.shape and (np.array_equal(x, y) or np.array_equal(x, y, equal_nan=True)), (x, y)


@pytest.mark.parametrize("dispersion, seed, n, kw", [
    (None, 4, 1, {}), ("standard", 4, 1, {}), ("flight", 4, 1, {}), ("peer", 4, 1, {}),
    ("flight", 3, 1, {"targets": "footprint"}), ("standard", 3, 1, {"max_episode_steps": 60}),
    ("wide", 3, 1, {"dt": 50.0}), ("flight", 3, 3, {"autoreset_mode": AutoresetMode.DISABLED}),
    ("peer", 6, 3, {"targets": "footprint", "autoreset_mode": AutoresetMode.DISABLED}),
])  # fmt: skip
def test_a_few_copies_step_on_floats_with_the_array_paths_bits(dispersion, seed, n, kw):
    """Up to FLOAT_STEP_MAX_COPIES copies (an evaluation's episode per task) are each stepped on
    Python floats: every observation, reward, ending and info value equals the array path's, bit
    for bit, landing, skipping out, at the time limit, in a diverging coarse step and with copies
    frozen at their end while the others fly on."""
    fast = _few_copies_episode(dispersion, seed, True, n, **kw)
    slow = _few_copies_episode(dispersion, seed, False, n, **kw)
    assert len(fast) == len(slow) > 10
    _assert_same_bits(fast, slow)
    ends = {"dt": "non-finite state", "max_episode_steps": "time limit"}
    expected = next((v for k, v in ends.items() if k in kw), None)
    if expected is not None:
        assert fast[-1][4]["failure"][0] == expected
    if n > 1:  # the episodes ended on different steps: frozen copies beside flying ones
        assert len({int(np.argmax([o[2][i] | o[3][i] for o in fast[1:]])) for i in range(n)}) > 1


def test_a_few_copies_on_floats_keep_the_autoreset_modes_bits():
    for n, mode in ((1, AutoresetMode.NEXT_STEP), (2, AutoresetMode.SAME_STEP)):
        kw = {"autoreset_mode": mode, "max_episode_steps": 120}
        _assert_same_bits(_few_copies_episode("flight", 7, True, n, steps=300, **kw),
                          _few_copies_episode("flight", 7, False, n, steps=300, **kw))  # fmt: skip


def test_a_model_that_evaluates_on_arrays_only_keeps_a_single_copy_on_arrays():
    from rventry_env.physics import TabulatedAtmosphere

    h = np.linspace(0.0, 150e3, 61)
    model = EntryModel(atmosphere=TabulatedAtmosphere(tuple(h), tuple(1.225 * np.exp(-h / 7200.0))))
    venv = RvEntryVectorEnv(num_envs=1, task=TASK, model=model)
    assert venv.stepper.name == "arrays"  # TabulatedAtmosphere refuses Python floats
    venv.reset(seed=0)
    obs, *_ = venv.step(np.zeros((1, 2), np.float32))
    assert np.all(np.isfinite(obs))
    assert RvEntryVectorEnv(num_envs=1, task=TASK).stepper.name == "floats"
    assert RvEntryVectorEnv(num_envs=FLOAT_STEP_MAX_COPIES + 1, task=TASK).stepper.name == "arrays"


def test_vector_env_autoreset_next_step_and_same_step():
    start = RvEntryEnv(task=TASK)
    start.reset(seed=0)
    s = start.state.copy()
    s[0] = 6378137.0 + 300.0  # 300 m up: the first step impacts
    s[6:10] = [0.0, 0.0, 0.8, 0.6]  # dive: sin(gamma) = C_BA(1,1) = 1 - 2 (0.8^2) < 0
    s[6:10] /= np.linalg.norm(s[6:10])
    nxt = RvEntryVectorEnv(num_envs=2, task=TASK)
    nxt.reset(seed=0, options={"state": s})
    _, r1, t1, _, i1 = nxt.step(np.zeros((2, 2)))
    assert t1.all() and i1["_miss_km"].all()
    obs, r2, t2, tr2, i2 = nxt.step(np.zeros((2, 2)))
    assert not t2.any() and not tr2.any() and np.all(r2 == 0.0)
    np.testing.assert_allclose(nxt.state, np.stack([s, s]))
    same = RvEntryVectorEnv(num_envs=2, task=TASK, autoreset_mode=AutoresetMode.SAME_STEP)
    obs0, _ = same.reset(seed=0, options={"state": s})
    obs, r, t, tr, info = same.step(np.zeros((2, 2)))
    assert t.all() and info["_final_obs"].all()
    np.testing.assert_array_equal(obs, obs0)
    assert info["final_info"]["failure"][0] == "" and not np.array_equal(info["final_obs"], obs0)


def test_vector_env_truncates_at_its_time_limit():
    venv = RvEntryVectorEnv(num_envs=2, task=TASK, max_episode_steps=3)
    venv.reset(seed=0)
    for _ in range(3):
        _, _, term, trunc, info = venv.step(np.zeros((2, 2)))
    assert trunc.all() and not term.any() and (info["failure"] == "time limit").all()


def test_vector_env_rejects_bad_actions():
    venv = RvEntryVectorEnv(num_envs=2, task=TASK)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        venv.step(np.zeros(2))
    with pytest.raises(ValueError, match="NaN or inf"):
        venv.step(np.array([[0, 0], [np.nan, 0]]))


def test_dispersion_draws_change_the_model_per_copy():
    venv = RvEntryVectorEnv(num_envs=4, task=TASK, dispersion=Dispersion(density=0.05, lift=0.03, drag=0.03))
    venv.reset(seed=0)
    d = venv.dispersion_draw
    assert np.all(np.abs(d[:, 0]) <= 0.05) and np.all(np.abs(d[:, 1:3]) <= 0.03) and np.unique(d[:, 0]).size == 4
    np.testing.assert_allclose(venv._density, 1 + d[:, 0])


@pytest.mark.parametrize("vector", [False, True])
def test_a_reset_dispersion_option_applies_to_that_reset_only(vector):
    """``reset(options={"dispersion": ...})`` is one-off in both envs; later resets use the constructor's."""
    if vector:
        env = RvEntryVectorEnv(num_envs=2, task=TASK)

        def draw():
            return env.dispersion_draw.copy()
    else:
        env = RvEntryEnv(task=TASK)

        def draw():
            return env.dispersion_draw.copy()

    env.reset(seed=1, options={"dispersion": "standard"})
    assert np.any(draw() != 0)
    env.reset(seed=1)
    assert np.all(draw() == 0)
    assert env.dispersion == Dispersion()


def test_vector_autoreset_after_a_one_off_dispersion_draws_from_the_constructor_set():
    venv = RvEntryVectorEnv(num_envs=2, task=TASK, max_episode_steps=2)
    venv.reset(seed=3, options={"dispersion": "wide"})
    assert np.any(venv.dispersion_draw != 0)
    for _ in range(3):  # two steps end the episodes, the third autoresets them (NEXT_STEP)
        venv.step(np.zeros((2, 2)))
    assert np.all(venv.dispersion_draw == 0)


def test_success_bonus_is_paid_only_at_a_successful_impact():
    from dataclasses import replace

    from rventry_env.guidance.reference_replay import ReferencePolicy

    def last_reward(reward):
        env = RvEntryEnv(reward=reward)
        policy = ReferencePolicy(EntryTask())
        obs, info = env.reset(seed=0)
        while True:
            obs, r, term, trunc, info = env.step(policy(Measurement.single(obs, info, env.state))[0])
            if term or trunc:
                return r, info

    r0, i0 = last_reward(RewardWeights())
    r1, i1 = last_reward(RewardWeights(success_bonus=7.0))
    assert i0["is_success"] and r1 == pytest.approx(r0 + 7.0, abs=1e-9)
    # a failed episode gets no bonus
    fail = EntryTask(problem=EntryProblem(initial_alpha=math.radians(11.86), initial_sigma=math.pi))
    ra, ia = run_episode(RvEntryEnv(task=fail), policy=lambda o: np.zeros(2, np.float32))[1:]
    rb, ib = run_episode(RvEntryEnv(task=fail, reward=RewardWeights(success_bonus=7.0)),
                         policy=lambda o: np.zeros(2, np.float32))[1:]  # fmt: skip
    assert not ia["is_success"] and ra == rb


def test_vector_env_pays_the_same_success_bonus():
    from dataclasses import replace

    from rventry_env.guidance.reference_replay import ReferencePolicy

    task, reward = EntryTask(), RewardWeights(success_bonus=7.0)
    venv, env = RvEntryVectorEnv(num_envs=1, task=task, reward=reward), RvEntryEnv(task=task, reward=reward)
    policy = ReferencePolicy(task)
    obs_v, info_v = venv.reset(seed=0)
    obs, info = env.reset(seed=0)
    while True:
        a = policy(Measurement.single(obs, info, env.state))
        obs_v, rv, tv, _, info_v = venv.step(a)
        obs, r, term, trunc, info = env.step(a[0])
        assert rv[0] == pytest.approx(r, rel=1e-9, abs=1e-12)
        if term:
            assert tv[0] and info["is_success"] and info_v["is_success"][0]
            break


@pytest.mark.parametrize("make, message", [
    (lambda: RvEntryEnv(substeps=2.5), "substeps must be a positive integer"),
    (lambda: RvEntryEnv(substeps="2"), "substeps must be a positive integer"),
    (lambda: RvEntryEnv(dt=float("nan")), "dt must be a positive number"),
    (lambda: RvEntryEnv(dispersion={"speed_mps": 9000}), "dispersion speed_mps = 9000 m/s could start the vehicle below the stall"),
    (lambda: RvEntryEnv(dispersion={"altitude_m": 60000}), "dispersion altitude_m = 60000 m could start the vehicle underground"),
    (lambda: RvEntryEnv(dispersion={"density": 1.5}), "dispersion density = 1.5 is relative"),
    (lambda: RvEntryEnv(dispersion={"lift": "3%"}), "dispersion lift must be a number"),
    (lambda: RvEntryEnv(dispersion="wider"), "cannot make a Dispersion from 'wider'"),
    (lambda: RvEntryEnv(max_episode_steps=0), "max_episode_steps must be a positive integer"),
    (lambda: RvEntryVectorEnv(num_envs=2, dispersion={"altitude_m": 1e5}), "dispersion altitude_m"),
    (lambda: RvEntryVectorEnv(num_envs=2).reset(options={"state": None}), "options\\['state'\\] must be one state"),
    (lambda: RvEntryVectorEnv(num_envs=2).reset(options={"state": 3.0}), "options\\['state'\\] must be one state"),
    (lambda: RvEntryEnv().reset(options={"state": "x"}), "an initial state must be 12 numbers"),
    (lambda: RvEntryEnv().reset(options={"dispersion": {"speed_mps": 7100}}), "dispersion speed_mps"),
])  # fmt: skip
def test_bad_arguments_explain_themselves(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_integral_float_substeps_are_accepted_and_render_before_reset_is_explained():
    assert RvEntryEnv(substeps=2.0).task.substeps == 2
    venv = RvEntryVectorEnv(num_envs=2, render_mode="rgb_array")
    with pytest.raises(RuntimeError, match="call reset\\(\\) before render\\(\\)"):
        venv.render()


@pytest.mark.parametrize("dt", [10.0, 50.0])
def test_coarse_steps_end_in_a_named_failure_in_both_envs_never_an_exception(dt):
    """Python floats overflow with an exception where NumPy gives inf: both envs report "non-finite state"."""
    n = 12
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (3000, n, 2)).astype(np.float32)
    venv = RvEntryVectorEnv(num_envs=n, task=TASK, dt=dt)
    venv.reset(seed=40)
    vector_end = [None] * n
    for k in range(3000):
        _, _, term, trunc, info = venv.step(actions[k])
        for i in np.nonzero((term | trunc) & np.array([e is None for e in vector_end]))[0]:
            vector_end[i] = (k, info["failure"][i])
        if all(e is not None for e in vector_end):
            break
    if dt == 50.0:
        assert sum(e[1] == "non-finite state" for e in vector_end) >= 3  # the overflow path is exercised
    for i in range(n):
        env = RvEntryEnv(task=TASK, dt=dt)
        env.reset(seed=40 + i)
        for k in range(3000):
            _, _, term, trunc, info = env.step(actions[k, i])
            if term or trunc:
                assert (k, info["failure"]) == vector_end[i]
                break


def test_observation_batch_is_vehicle_major_and_clips_only_the_rows_out_of_bounds():
    from rventry_env.envs.common import observation_batch

    low, high = np.array([-1.0, -2.0, 0.0], np.float32), np.array([1.0, 2.0, 5.0], np.float32)
    features = [np.array([0.5, 3.0, -0.5]), np.array([1.0, 0.0, -3.0]), np.array([4.0, 4.0, 9.0])]
    obs, clipped = observation_batch(features, low, high)
    assert obs.dtype == np.float32 and obs.shape == (3, 3) and obs.flags.c_contiguous
    np.testing.assert_array_equal(obs, [[0.5, 1.0, 4.0], [1.0, 0.0, 4.0], [-0.5, -2.0, 5.0]])
    np.testing.assert_array_equal(clipped, [False, True, True])


@pytest.mark.parametrize("gamma_deg", [-0.3, -5.0, -45.0, -89.0])
def test_the_located_impact_is_the_root_of_the_rk4_map_in_at_most_four_substeps(gamma_deg):
    """The impact inside a substep is the root of tau -> r(RK4(x0, tau)) - R_e (brentq on the same map,
    written here), within 1e-6 m of the surface, from grazing to vertical, and it costs few RK4 substeps
    (the Hermite start and the Newton steps: at most four, where the regula falsi alone took six)."""
    from scipy.optimize import brentq

    from rventry_env.core import conversions as cv
    from rventry_env.core.backend import MATH
    from rventry_env.core.integrate import rk4_step
    from rventry_env.envs import propagation as prop_mod
    from rventry_env.physics import entry_forces

    model, radius = EntryModel(), 6378137.0
    speed, h = 2500.0, 1.0
    drop = -speed * math.sin(math.radians(gamma_deg)) * 0.6  # the surface is crossed 60 % into the step
    x0 = cv.rv_euler_from_spherical(np.array([[radius + drop, 0.1, 0.2, speed, math.radians(gamma_deg), 1.0]]))[0]
    x0 = list(x0[:10]) + [math.radians(8.0), math.radians(30.0)]
    u = (0.01, -0.02)
    k1 = entry_rhs(x0, u, model, MATH, forces=entry_forces(x0, model, MATH))

    def state_at(tau):
        return prop_mod._renormalize(rk4_step(lambda _t, y: entry_rhs(y, u, model, MATH), 0.0, tuple(x0), tau, k1=k1), MATH)

    xb = state_at(h)
    assert xb[0] < radius
    tau_ref = brentq(lambda tau: state_at(tau)[0] - radius, 0.0, h, xtol=1e-14, rtol=1e-15)
    evaluations = []
    counting = dataclasses.replace(MATH, while_loop=lambda c, b, carry: _count_while(c, b, carry, evaluations))
    x_hit, tau = prop_mod.Propagator(EntryTask(substeps=1), counting)._locate_impact(tuple(x0), k1, u, h, model, radius, xb)
    assert abs(x_hit[0] - radius) <= prop_mod.IMPACT_TOLERANCE_M
    assert tau == pytest.approx(tau_ref, abs=1e-6 / speed * 10)
    assert evaluations[0] <= 4


def _count_while(cond, body, carry, counter):
    n = 0
    while cond(carry):
        carry = body(carry)
        n += 1
    counter.append(n)
    return carry


def test_the_impact_tolerance_is_what_the_float_type_resolves():
    from rventry_env.envs.propagation import IMPACT_TOLERANCE_M, impact_tolerance

    radius = 6378137.0
    assert impact_tolerance(6.4e6, radius) == IMPACT_TOLERANCE_M  # Python floats and float64 resolve 1e-6 m
    assert impact_tolerance(np.float64(6.4e6), radius) == IMPACT_TOLERANCE_M
    tol32 = impact_tolerance(np.zeros(3, np.float32), radius)
    ulp = float(np.spacing(np.float32(radius)))
    assert 1.0 * ulp <= tol32 <= 4.0 * ulp  # a few units in the last place at the Earth's radius (0.5 m each)
