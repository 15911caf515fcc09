"""The JAX backend: the same step as NumPy, compiled; the functional env; the Gymnasium face.

Skipped where the ``[jax]`` extra (jax, gymnax) is not installed.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("gymnax")

import jax.numpy as jnp  # noqa: E402

import rventry_env  # noqa: E402,F401  (registers RvEntry-v0)
from rventry_env.core import conversions as cv  # noqa: E402
from rventry_env.core.backend import NUMPY, jax_ns  # noqa: E402
from rventry_env.envs.functional import RvEntryFunctional  # noqa: E402
from rventry_env.envs.outcome import episode_outcome  # noqa: E402
from rventry_env.envs.propagation import FLYING, IMPACT, Propagator  # noqa: E402
from rventry_env.envs.reward import RewardWeights  # noqa: E402
from rventry_env.physics import EntryModel, TabulatedAtmosphere, entry_forces  # noqa: E402
from rventry_env.physics.model import scaled_model  # noqa: E402
from rventry_env.task import EntryTask, apply_state_dispersion, draw_dispersion  # noqa: E402
from rventry_env.task.dispersion import Dispersion  # noqa: E402

F64 = jax_ns("float64")
MODEL = EntryModel()
RADIUS = MODEL.planet.radius


def _batch(n: int, seed: int, low_altitude: float = 20.0) -> np.ndarray:
    """n dispersed initial states, the first half a few metres above the ground (so a step impacts)."""
    task = EntryTask()
    rng = np.random.default_rng(seed)
    x = apply_state_dispersion(
        np.broadcast_to(task.problem.initial_state(RADIUS), (n, 12)),
        np.stack([draw_dispersion(rng, Dispersion.wide()) for _ in range(n)]),
    )
    x[: n // 2, 0] = RADIUS + low_altitude  # dives through the surface within the step
    x[: n // 2, 7:10] = cv.rv_euler_from_spherical(
        np.column_stack([x[: n // 2, 0], np.zeros(n // 2), np.zeros(n // 2), np.full(n // 2, 3000.0),
                         np.full(n // 2, -0.5), np.full(n // 2, math.pi / 2)])
    )[:, 7:10]  # fmt: skip
    x[: n // 2, 6:10] /= np.linalg.norm(x[: n // 2, 6:10], axis=1, keepdims=True)
    return x


def test_one_step_agrees_with_numpy_to_1e12_with_impacts_inside_the_step():
    task = EntryTask(substeps=2)
    x = _batch(16, 0)
    rng = np.random.default_rng(1)
    scales = 1 + rng.uniform(-0.05, 0.05, (3, 16))
    u = rng.uniform(-1, 1, (2, 16)) * np.array([[task.problem.u_alpha_max], [task.problem.u_sigma_max]])
    m_np = scaled_model(MODEL, *scales)
    xs = tuple(x.T)
    out_np = Propagator(task, NUMPY).step(xs, entry_forces(xs, m_np, NUMPY), u[0], u[1], m_np)

    @jax.jit
    def step(xj, uj, sj):
        m = scaled_model(MODEL, sj[0], sj[1], sj[2])
        return Propagator(task, F64).step(xj, entry_forces(xj, m, F64), uj[0], uj[1], m)

    out_j = step(tuple(jnp.asarray(c) for c in xs), jnp.asarray(u), jnp.asarray(scales))
    assert np.sum(out_np.status == IMPACT) == 8 and np.sum(out_np.status == FLYING) == 8
    np.testing.assert_array_equal(np.asarray(out_j.status), out_np.status)
    for a, b in zip(out_j.x, out_np.x):
        np.testing.assert_allclose(np.asarray(a), b, rtol=1e-12, atol=1e-12)
    hit = out_np.status == IMPACT
    np.testing.assert_allclose(np.asarray(out_j.x[0])[hit], RADIUS, atol=1e-6)  # located on the surface
    for k in ("elapsed", "cost", "path_penalty", "max_load_g", "min_q"):
        np.testing.assert_allclose(np.asarray(getattr(out_j, k)), getattr(out_np, k), rtol=1e-12, atol=1e-12)


def test_outcome_rule_is_the_same_in_jax():
    task = EntryTask()
    x = _batch(12, 2, low_altitude=0.0)
    xs = tuple(x.T)
    status = np.array([IMPACT, FLYING, 2, 3, 4, IMPACT] * 2, dtype=np.int8)
    terminated = status != FLYING
    rng = np.random.default_rng(3)
    max_load, min_q = rng.uniform(5, 14, 12), rng.uniform(10e3, 14e3, 12)
    target = tuple(float(c) for c in task.problem.target_unit_vector())
    from rventry_env.core.euler_parameters import dcm

    o_np = episode_outcome(xs, dcm(*xs[1:5]), status, terminated, max_load, min_q, task, RewardWeights(), target,
                           RADIUS, NUMPY)  # fmt: skip
    xj = tuple(jnp.asarray(c) for c in xs)
    o_j = episode_outcome(xj, dcm(*xj[1:5]), jnp.asarray(status), jnp.asarray(terminated), jnp.asarray(max_load),
                          jnp.asarray(min_q), task, RewardWeights(), target, RADIUS, F64)  # fmt: skip
    for a, b in zip(o_j.metrics, o_np.metrics):
        np.testing.assert_allclose(np.asarray(a), b, rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(o_j.is_success), o_np.is_success)
    np.testing.assert_array_equal(np.asarray(o_j.constraint_violation), o_np.constraint_violation)
    np.testing.assert_allclose(np.asarray(o_j.terminal_penalty), o_np.terminal_penalty, rtol=1e-12)


def test_dispersed_start_equals_the_spherical_round_trip():
    """The rotation rule against the independent formulation: spherical coordinates, east-down frames, mu kept."""
    x0 = EntryTask().problem.initial_state(RADIUS)
    rng = np.random.default_rng(4)
    d = rng.uniform(-1, 1, (50, 9)) * np.array([0, 0, 0, 900, 40, 3, 5, 2, 4.0])
    x = np.broadcast_to(x0, (50, 12)).copy()
    mu = cv.conventional_bank(x, x[:, 11])
    s = cv.spherical_from_rv_euler(x)
    s[:, 0] += d[:, 3]
    s[:, 3] += d[:, 4]
    s[:, 4] += np.radians(d[:, 5])
    s[:, 5] += np.radians(d[:, 6])
    x[:, :10] = cv.rv_euler_from_spherical(s)
    x[:, 11] += cv.wrap_angle(cv.paper_bank(x, mu) - x[:, 11]) + np.radians(d[:, 8])
    x[:, 10] += np.radians(d[:, 7])
    got = apply_state_dispersion(np.broadcast_to(x0, (50, 12)), d)
    np.testing.assert_allclose(got[:, 1:], x[:, 1:], atol=1e-11)
    np.testing.assert_allclose(got[:, 0], x[:, 0], rtol=1e-15, atol=1e-8)


def _fly_both(dtype: str, dispersion: str, n: int = 6, seed: int = 7):
    """Each copy flies one episode (autoreset disabled) in both backends with the same actions."""
    kw = dict(num_envs=n, vectorization_mode="vector_entry_point", dispersion=dispersion, autoreset_mode="Disabled")
    venv_np = gym.make_vec("RvEntry-v0", **kw)
    venv_j = gym.make_vec("RvEntry-v0", backend="jax", dtype=dtype, **kw)
    o_np, _ = venv_np.reset(seed=seed)
    o_j, _ = venv_j.reset(seed=seed)
    rng = np.random.default_rng(seed)
    worst_obs, ended_np, ended_j, finals = np.abs(o_np - o_j).max(), np.zeros(n, bool), np.zeros(n, bool), {}
    rewards = [0.0, 0.0]
    sensing = {"navigation_state": 0.0, "sensed_accel_b": 0.0}
    while not ended_np.all():
        a = np.clip(np.array([0.0, 0.03]) + rng.normal(0, 0.2, (n, 2)), -1, 1)
        o_np, r_np, te_np, tr_np, i_np = venv_np.step(a)
        o_j, r_j, te_j, tr_j, i_j = venv_j.step(a)
        worst_obs = max(worst_obs, np.abs(o_np - o_j).max())
        for k in sensing:
            scale = np.maximum(np.abs(i_np[k]), 1.0)
            sensing[k] = max(sensing[k], float(np.max(np.abs(i_np[k] - i_j[k]) / scale)))
        rewards[0] += r_np.sum()
        rewards[1] += r_j.sum()
        ended_np |= te_np | tr_np
        ended_j |= te_j | tr_j
        for i in np.nonzero(te_np | tr_np)[0]:
            finals[i] = (i_np["miss_km"][i], i_j["miss_km"][i], i_np["failure"][i], i_j["failure"][i],
                         i_np["r_ecef_m"][i], i_j["r_ecef_m"][i])  # fmt: skip
    venv_j.sensing_difference = sensing  # relative, the largest over the episodes
    return worst_obs, ended_j, finals, rewards, venv_j


def test_whole_dispersed_episodes_agree_with_numpy_float64():
    worst_obs, ended_j, finals, rewards, venv_j = _fly_both("float64", "wide")
    assert ended_j.all()
    assert worst_obs <= 1e-5  # the benchmark's target; in practice the float32 observations are equal
    assert rewards[1] == pytest.approx(rewards[0], rel=1e-9)
    for miss_np, miss_j, f_np, f_j, r_np, r_j in finals.values():
        assert miss_j == pytest.approx(miss_np, rel=1e-9) and f_j == f_np
        np.testing.assert_allclose(r_j, r_np, atol=1e-4)
    assert venv_j.unwrapped.stepper.step_fn._cache_size() == 1  # compiled once for the whole run


@pytest.mark.slow
@pytest.mark.parametrize("name", ["flight", "peer"])
def test_flight_grade_sets_fly_the_same_episodes_per_draw_in_jax(name):
    """Gaussian draws, mass, NRLMSIS and Gauss-Markov profiles, winds, Mach-varying aerodynamics, and for
    ``flight`` the accelerometer (its noise included: the same counter-based stream) and the navigation."""
    worst_obs, ended_j, finals, rewards, venv_j = _fly_both("float64", name, n=3, seed=5)
    assert ended_j.all()
    assert worst_obs <= 1e-5
    assert rewards[1] == pytest.approx(rewards[0], rel=1e-9)
    for miss_np, miss_j, f_np, f_j, r_np, r_j in finals.values():
        assert miss_j == pytest.approx(miss_np, rel=1e-9, abs=1e-9) and f_j == f_np
        np.testing.assert_allclose(r_j, r_np, atol=1e-4)
    assert max(venv_j.sensing_difference.values()) <= 1e-9
    u = venv_j.unwrapped
    assert u.stepper.sensing == (name == "flight") and u.stepper.step_fn._cache_size() == 1


@pytest.mark.slow
def test_autoresets_into_another_set_structure_keep_flying_with_numpy():
    """A one-off reset dispersion without flight-grade errors, then autoresets into the constructor's
    flight set: the running flights carry on and the new episodes fly NumPy's draws."""
    kw = dict(num_envs=3, vectorization_mode="vector_entry_point", dispersion="flight", max_episode_steps=8)
    venvs = [gym.make_vec("RvEntry-v0", **kw), gym.make_vec("RvEntry-v0", backend="jax", **kw)]
    states = _batch(3, 0)  # copy 0 starts 20 m up, diving: it ends at once and restarts mid-flight of the others
    obs = [v.reset(seed=2, options={"dispersion": "none", "state": states})[0] for v in venvs]
    rng = np.random.default_rng(0)
    ends = []
    for t in range(20):
        a = np.clip(rng.normal(0, 0.3, (3, 2)), -1, 1)
        out = [v.step(a) for v in venvs]
        np.testing.assert_allclose(out[1][0], out[0][0], atol=1e-5)
        np.testing.assert_array_equal(out[1][3], out[0][3])
        np.testing.assert_allclose(out[1][4]["navigation_state"], out[0][4]["navigation_state"], rtol=1e-9)
        ends.append(out[0][2] | out[0][3])
    assert venvs[1].unwrapped.stepper.sensing
    assert ends[0][0] and not ends[0][1:].any()  # copy 0 alone ended first


def test_float32_error_at_impact_is_bounded():
    """Float32 physics drifts from float64; the README states the figure, this bounds it (100 m)."""
    _, ended, finals, _, _ = _fly_both("float32", "standard", n=4, seed=11)
    assert ended.all()
    for _, _, f_np, f_j, r_np, r_j in finals.values():
        assert f_j == f_np
        assert np.linalg.norm(r_j - r_np) < 100.0


def test_make_vec_refuses_bad_backends():
    with pytest.raises(ValueError, match="backend must be"):
        gym.make_vec("RvEntry-v0", num_envs=2, vectorization_mode="vector_entry_point", backend="torch")
    with pytest.raises(ValueError, match="needs backend='jax'"):
        gym.make_vec("RvEntry-v0", num_envs=2, vectorization_mode="vector_entry_point", dtype="float32")
    with pytest.raises(ValueError, match="dtype must be"):
        gym.make_vec("RvEntry-v0", num_envs=2, vectorization_mode="vector_entry_point", backend="jax", dtype="float16")


def test_functional_env_is_pure_scans_and_flies_every_named_set_from_one_compilation():
    env = RvEntryFunctional(dtype="float64")
    keys = jax.random.split(jax.random.PRNGKey(0), 8)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))

    def body(carry, k):
        st, params = carry
        ks = jax.random.split(k, 8)
        o, st, r, d, info = jax.vmap(env.step, in_axes=(0, 0, None, None))(ks, st, jnp.array([0.0, 0.02]), params)
        return (st, params), (r, d)

    fly = jax.jit(lambda s, p, k: jax.lax.scan(body, (s, p), jax.random.split(k, 30)))
    h0 = EntryTask().problem.initial_state(RADIUS)[0]
    for name in ("none", "standard", "wide", "peer", "peer-0.1"):
        params = env.make_params(dispersion=name)
        obs, state = reset(keys, params)
        obs2, _ = reset(keys, params)
        np.testing.assert_array_equal(obs, obs2)  # pure: the same key, the same start
        half = Dispersion.parse(name)
        h = np.asarray(state.episode.x[0])
        assert np.all(np.abs(h - h0) <= half.largest("altitude_m") + 1e-6) and (np.ptp(h) > 0) == (half.altitude_m > 0)
        (st, _), (r, d) = fly(state, params, jax.random.PRNGKey(1))
        assert np.all(np.isfinite(np.asarray(r))) and r.shape == (30, 8)
        assert np.all(np.asarray(st.episode.steps) == 30)
    assert reset._cache_size() == 1 and fly._cache_size() == 1  # the sets are data: one compilation


def test_functional_env_draws_clipped_gaussians_and_the_mass_of_the_peer_sets():
    env = RvEntryFunctional(dtype="float64")
    n = 4000
    keys = jax.random.split(jax.random.PRNGKey(3), n)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))
    nominal = EntryTask().problem.initial_state(RADIUS)
    for name in ("peer", "peer-0.1", "standard"):
        d = Dispersion.parse(name)
        _, st = reset(keys, env.make_params(dispersion=name))
        dh = np.asarray(st.episode.x[0]) - nominal[0]
        mass = np.asarray(st.scales[:, 3]) - 1.0
        for draw, sigma in ((dh, d.altitude_m), (mass, d.mass)):
            if d.shape == "gaussian":  # clipped at 3 sigma: the std of a clipped unit normal is 0.9866
                assert np.abs(draw).max() <= 3.0 * sigma * (1 + 1e-9) and np.abs(draw).max() > 2.5 * sigma
                assert np.std(draw) == pytest.approx(0.9866 * sigma, rel=0.05)
            else:
                assert np.abs(draw).max() <= sigma * (1 + 1e-9)
                assert np.std(draw) == pytest.approx(sigma / 3**0.5, rel=0.05)
        assert (np.ptp(mass) > 0) == (d.mass > 0)
    # the mass factor is the model's: the drag acceleration of the drawn vehicle is the NumPy one of that mass
    i = int(np.argmax(np.abs(mass)))
    x = tuple(float(c[i]) for c in st.episode.x)
    s = np.asarray(st.scales[i])
    veh = MODEL.vehicle
    m = scaled_model(MODEL.replace(vehicle=type(veh)(mass=veh.mass * s[3], reference_area=veh.reference_area,
                                                     aerodynamics=veh.aerodynamics)), s[0], s[1], s[2])  # fmt: skip
    f_np = entry_forces(tuple(np.array([c]) for c in x), m, NUMPY)
    assert float(st.episode.forces.drag_accel[i]) == pytest.approx(float(f_np.drag_accel[0]), rel=1e-12)


def test_functional_env_refuses_flight_grade_params_without_their_structure():
    with pytest.raises(ValueError, match="flight-grade errors.*compiled structure.*dispersion='flight'"):
        RvEntryFunctional(dtype="float64").make_params(dispersion="flight")


@pytest.mark.slow
def test_functional_flight_grade_env_flies_a_pool_draw_as_the_numpy_truth_model_and_navigation_do():
    """A reset picks one of the pool's NumPy draws; its forces, first step and navigated observation
    are those of the NumPy VehicleErrors' truth model and sensors for that draw (noise off)."""
    import dataclasses

    from rventry_env.core.euler_parameters import dcm
    from rventry_env.envs.observation import observe
    from rventry_env.envs.uncertainty import VehicleErrors
    from rventry_env.task import FLIGHT_GRADE_ERRORS

    quiet = dataclasses.replace(Dispersion.flight_set(),
                                flight=dataclasses.replace(FLIGHT_GRADE_ERRORS, accel_noise_mps2=0.0))  # fmt: skip
    env = RvEntryFunctional(dispersion=quiet, dtype="float64", pool_size=4)
    params = env.default_params
    _, st = env.reset(jax.random.PRNGKey(5), params)
    pool = params.pool
    i = int(np.argmin(np.abs(np.asarray(pool.log_factors) - np.asarray(st.errors.row.log_factors)).sum(axis=1)))
    fs = VehicleErrors(1, MODEL)
    for name, src in (("log_factors", pool.log_factors), ("wind_east", pool.wind_east), ("wind_north", pool.wind_north),
                      ("aero", pool.aero), ("bias", pool.bias), ("scale", pool.scale),
                      ("misalignment", pool.misalignment)):  # fmt: skip
        getattr(fs, name)[0] = np.asarray(src[i])
    s = np.asarray(st.scales)
    fs.mass[0], fs.any_model, fs.any_wind = s[3], True, True
    fs.dr[:, 0], fs.dv[:, 0], fs.senses[0] = np.asarray(pool.dr[i]), np.asarray(pool.dv[i]), True
    model = fs.model(s[0:1], s[1:2], s[2:3])
    x = tuple(np.array([float(c)]) for c in st.episode.x)
    prop = Propagator(EntryTask(), NUMPY)
    f_np = prop.forces(x, model)
    for k in ("density", "dynamic_pressure", "mach", "cl", "cd", "drag_accel", "lift_accel"):
        assert float(getattr(st.episode.forces, k)) == pytest.approx(float(getattr(f_np, k)[0]), rel=1e-12), k
    # the first step: the same state as NumPy's step with the same model
    a = np.array([0.3, -0.4])
    obs, st1, _, _, _ = jax.jit(env.step_env)(jax.random.PRNGKey(6), st, jnp.asarray(a), params)
    p = EntryTask().problem
    out = prop.step(x, f_np, np.array([a[0] * p.u_alpha_max]), np.array([a[1] * p.u_sigma_max]), model)
    np.testing.assert_allclose(np.asarray([float(c) for c in st1.episode.x]), np.concatenate(out.x), rtol=1e-11)
    # what the navigation makes of it: the NumPy sensors' view of the same truth, errors integrated alike
    nav, _, feats, nav_c_ae = fs.sense(out.x, out.forces, dcm(*out.x[1:5]), MODEL.planet.g0, out.elapsed)
    want = observe(tuple(nav[:, j] for j in range(12)), feats, nav_c_ae, out.elapsed, EntryTask(), env.target,
                   RADIUS, MODEL.planet.g0, NUMPY)  # fmt: skip
    want = np.clip(np.array([float(c[0]) if np.ndim(c) else float(c) for c in want], dtype=np.float32), env.obs_low,
                   env.obs_high)  # fmt: skip
    np.testing.assert_allclose(np.asarray(obs), want, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(np.asarray(st1.errors.dr), fs.dr[:, 0], rtol=1e-12)
    assert np.abs(np.asarray(st1.errors.dr) - np.asarray(pool.dr[i])).max() > 0  # the errors did move


def test_functional_env_agrees_with_the_vector_env_over_a_nominal_episode():
    env = RvEntryFunctional(dtype="float64")
    params = env.default_params
    obs_j, st = env.reset(jax.random.PRNGKey(0), params)
    venv = gym.make_vec("RvEntry-v0", num_envs=1, vectorization_mode="vector_entry_point")
    obs_np, _ = venv.reset(seed=0)
    step = jax.jit(env.step_env)
    a = np.array([0.0, 0.02])
    worst = np.abs(obs_np[0] - np.asarray(obs_j)).max()
    for _ in range(3000):
        obs_j, st, r_j, done, info = step(jax.random.PRNGKey(1), st, jnp.asarray(a), params)
        obs_np, r_np, te, tr, i_np = venv.step(a[None])
        worst = max(worst, np.abs(obs_np[0] - np.asarray(obs_j)).max())
        assert float(r_j) == pytest.approx(r_np[0], rel=1e-9, abs=1e-12)
        assert bool(done) == bool(te[0] or tr[0])
        if done:
            break
    assert bool(done) and worst <= 1e-5
    assert float(info["miss_km"]) == pytest.approx(i_np["miss_km"][0], rel=1e-9)
    assert step._cache_size() == 1


def test_params_carry_the_model_numbers_and_tables_without_recompiling():
    table_h = np.linspace(0.0, 120e3, 25)
    atm = TabulatedAtmosphere(tuple(table_h), tuple(1.225 * np.exp(-table_h / 7200.0)))
    env = RvEntryFunctional(model=EntryModel(atmosphere=atm), dtype="float64")
    thicker = TabulatedAtmosphere(tuple(table_h), tuple(1.3 * 1.225 * np.exp(-table_h / 7200.0)))
    p1 = env.default_params
    p2 = env.make_params(model=EntryModel(atmosphere=thicker))
    step = jax.jit(env.step_env)
    _, s1 = env.reset(jax.random.PRNGKey(0), p1)
    _, s2 = env.reset(jax.random.PRNGKey(0), p2)
    a = jnp.array([0.0, 0.0])
    _, s1, _, _, _ = step(jax.random.PRNGKey(0), s1, a, p1)
    _, s2, _, _, _ = step(jax.random.PRNGKey(0), s2, a, p2)
    assert step._cache_size() == 1
    assert float(s2.episode.forces.density) == pytest.approx(1.3 * float(s1.episode.forces.density), rel=1e-3)
    # the NumPy env with the tabulated profile flies the same first step
    venv = gym.make_vec("RvEntry-v0", num_envs=1, vectorization_mode="vector_entry_point",
                        model=EntryModel(atmosphere=thicker))  # fmt: skip
    venv.reset(seed=0)
    venv.step(np.zeros((1, 2)))
    np.testing.assert_allclose(np.asarray([float(c) for c in s2.episode.x]), venv.unwrapped.state[0], rtol=1e-12)
    with pytest.raises(ValueError, match="structure differs"):
        env.make_params(model=EntryModel())


@pytest.mark.slow
def test_rejax_ppo_trains_on_the_functional_env(tmp_path):
    """A few thousand steps of rejax PPO, in a fresh process (float32 JAX, as a training run has it)."""
    pytest.importorskip("rejax")
    import subprocess
    import sys

    code = (
        "from rventry_agents.jax_ppo import load_config, train_jax_ppo\n"
        "cfg = load_config().to_dict()\n"
        "cfg['env']['num_envs'] = 16\n"
        "cfg['ppo'].update(num_steps=32, hidden_layer_sizes=[32, 32])\n"
        "cfg['train'].update(chunk_timesteps=2048, eval_episodes=4)\n"
        f"train_jax_ppo(cfg, timesteps=4096, out={str(tmp_path)!r}, progress=lambda s: None)\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    import json

    meta = json.loads((tmp_path / "metadata.json").read_text())
    assert meta["timesteps"] >= 4096
    assert meta["train_compilations"] == 1  # the second chunk ran the first one's program, not a recompiled one
    assert len(meta["evaluations"]) == 2 and all(np.isfinite(e["mean_return"]) for e in meta["evaluations"])
    params = np.load(tmp_path / "params.npz")
    assert any(k.startswith("actor") for k in params.files)
    assert (tmp_path / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
