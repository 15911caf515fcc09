"""Flight-grade uncertainty: draw statistics, the zero set, single/vector agreement, sensors and
navigation, the climatology offline, the named sets, the precision tier and its intervals."""

from __future__ import annotations

import dataclasses
import math
import socket

import numpy as np
import pytest

from rventry_env.core.backend import MATH, NUMPY, casadi_ns
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.physics import EntryModel, ExponentialAtmosphere
from rventry_env.physics.sensors import accelerometer, propagate_navigation_error, white_noise
from rventry_env.physics.uncertainty import MachVaryingAerodynamics, ProfileAtmosphere, uniform_table
from rventry_env.task import (FLIGHT_GRADE_ERRORS, Dispersion, EntryProblem, FlightGradeErrors, draw_dispersion,
                              draw_extras)
from rventry_env.task.flight_grade import GRID_M, band_profile, gauss_markov, msis_log_density

TASK_PROBLEM = EntryProblem()


# ------------------------------------------------------------------ draw statistics
def _profiles(field: str, n: int = 600) -> np.ndarray:
    return np.stack([draw_extras(np.random.default_rng(s), Dispersion(flight=FLIGHT_GRADE_ERRORS), TASK_PROBLEM)[field]
                     for s in range(n)])  # fmt: skip


@pytest.mark.parametrize("field, bands", [("density_perturbation", FLIGHT_GRADE_ERRORS.density_bands)])
def test_drawn_profiles_have_the_documented_rms_and_correlation_length(field, bands):
    """Per band: the rms of the drawn ln-density perturbation and its correlation at one grid step
    match the documented (rms, L) within sampling error (600 profiles)."""
    p = _profiles(field)
    rms, corr = band_profile(bands)
    lo = 0.0
    for top, sigma, length in bands:
        inside = np.nonzero((GRID_M > lo) & (GRID_M <= top))[0]
        lo = top
        sd = np.sqrt(np.mean(p[:, inside] ** 2))
        # the variance of a mean of ~600 x (band points) correlated squares: a few percent
        assert sd == pytest.approx(sigma, rel=0.08), (top, sd, sigma)
        pairs = inside[1:]
        r = np.mean(p[:, pairs] * p[:, pairs - 1]) / np.mean(p[:, pairs] ** 2)
        assert r == pytest.approx(math.exp(-1000.0 / length), abs=0.03), (top, r)
    assert np.allclose(rms[GRID_M <= 10e3], bands[0][1]) and np.allclose(corr[GRID_M > 50e3], bands[-1][2])


def test_wind_profiles_have_the_documented_mean_and_perturbation_rms():
    east = _profiles("wind_east")
    # the constant part is shared by every altitude of a profile: its rms is the profile mean's
    assert np.std(east.mean(axis=1)) == pytest.approx(FLIGHT_GRADE_ERRORS.wind_mean_mps, rel=0.15)
    dev = east - east.mean(axis=1, keepdims=True)
    top = GRID_M > 50e3
    # the Gauss-Markov part's rms above 50 km (the profile mean takes a little of it)
    assert np.sqrt(np.mean(dev[:, top] ** 2)) == pytest.approx(FLIGHT_GRADE_ERRORS.wind_bands[-1][1], rel=0.2)


def test_the_flight_atmosphere_departs_from_the_mean_without_bias():
    """The climatology's departure from its own mean: mean zero over the drawn days, local times
    and indices (the laws' exponential model stands for that mean), and a few percent of spread
    below the entry altitude, growing with altitude as NRLMSIS's seasonal and diurnal terms do."""
    c = _profiles("log_density_climate", n=300)
    below = (GRID_M >= 5e3) & (GRID_M <= 40e3)
    se = c.std(axis=0) / math.sqrt(c.shape[0])
    assert np.all(np.abs(c.mean(axis=0)[below]) < 4 * se[below] + 2e-3)
    assert 0.003 < c.std(axis=0)[37] < 0.05 and c.std(axis=0)[80] > c.std(axis=0)[20]


def test_gauss_markov_is_unit_variance_across_a_band_change():
    bands = ((20e3, 1.0, 2e3), (100e3, 3.0, 20e3))
    rng = np.random.default_rng(1)
    p = np.stack([gauss_markov(rng.standard_normal(GRID_M.size), bands) for _ in range(3000)])
    assert np.std(p[:, 15]) == pytest.approx(1.0, rel=0.05) and np.std(p[:, 60]) == pytest.approx(3.0, rel=0.05)


def test_standard_and_wide_draw_exactly_as_before():
    """The nine uniform numbers, and nothing more, for the sets that existed before the flight sets."""
    for name in ("standard", "wide"):
        d = Dispersion.parse(name)
        a, b = np.random.default_rng(4), np.random.default_rng(4)
        half = np.array([d.density, d.lift, d.drag, d.altitude_m, d.speed_mps, d.flight_path_deg, d.heading_deg,
                         d.alpha_deg, d.sigma_deg])  # fmt: skip
        np.testing.assert_array_equal(draw_dispersion(a, d), b.uniform(-1.0, 1.0, size=9) * half)
        assert draw_extras(a, d, TASK_PROBLEM) is None
        assert a.uniform() == b.uniform()  # nothing else was drawn


def test_named_sets_round_trip_and_refuse_what_they_cannot_be():
    for name in ("none", "standard", "wide", "flight", "peer", "peer-0.1"):
        assert Dispersion.parse(name).name == name
    peer = Dispersion.parse("peer")
    assert (peer.altitude_m, peer.speed_mps, peer.heading_deg, peer.mass, peer.density) == (5000.0, 60.0, 1.0, 0.05, 0.25)
    assert Dispersion.parse("peer-0.1").altitude_m == pytest.approx(500.0)
    with pytest.raises(ValueError, match="dispersion density = 0.4 is relative and its largest draw"):
        Dispersion(density=0.4, shape="gaussian")
    with pytest.raises(ValueError, match="shape must be one of"):
        Dispersion(shape="normal")
    with pytest.raises(ValueError, match="unknown flight error field"):
        Dispersion.parse({"flight": {"gusts": 1.0}})
    with pytest.raises(ValueError, match="band tops must increase"):
        FlightGradeErrors(density_bands=((30e3, 0.1, 5e3), (10e3, 0.1, 5e3)))


# ------------------------------------------------------------------ the zero set
def _zeroed(d: Dispersion) -> Dispersion:
    f = d.flight
    zero_bands = lambda bands: tuple((top, 0.0, length) for top, _, length in bands)  # noqa: E731
    flight = dataclasses.replace(
        f, climatology=False, density_bands=zero_bands(f.density_bands), wind_bands=zero_bands(f.wind_bands),
        **{k: 0.0 for k in ("wind_mean_mps", "lift_mach", "drag_mach", "accel_bias_mps2", "accel_scale",
                            "accel_misalignment_rad", "accel_noise_mps2", "nav_position_m", "nav_velocity_mps")},
    )  # fmt: skip
    scalars = {k: 0.0 for k in ("density", "lift", "drag", "altitude_m", "speed_mps", "flight_path_deg",
                                "heading_deg", "alpha_deg", "sigma_deg", "mass")}  # fmt: skip
    return dataclasses.replace(d, flight=flight, **scalars)


@pytest.mark.parametrize("vector", [False, True])
def test_the_flight_set_with_every_magnitude_zero_flies_the_nominal_episode_bit_for_bit(vector):
    zero = _zeroed(Dispersion.parse("flight"))
    assert zero.is_zero and zero.flight is not None

    def fly(dispersion):
        env = RvEntryVectorEnv(num_envs=2, dispersion=dispersion) if vector else RvEntryEnv(dispersion=dispersion)
        obs, _ = env.reset(seed=3)
        out = [obs]
        a = np.array([[0.0, 0.02], [-0.01, -0.02]], np.float32)
        for _ in range(60):
            obs, rew, term, *_ = env.step(a if vector else a[0])
            out += [obs, np.atleast_1d(rew), env.state]
            if np.any(term):
                break
        return out

    for x, y in zip(fly(zero), fly(None)):
        np.testing.assert_array_equal(x, y)


def test_a_profile_of_zeros_leaves_the_density_unchanged_exactly():
    base = ExponentialAtmosphere()
    h = np.linspace(-5e3, 120e3, 57)
    part = ProfileAtmosphere(base, 0.0, 1000.0, np.zeros((57, GRID_M.size)))
    np.testing.assert_array_equal(part.density(h, NUMPY), base.density(h, NUMPY))


# ------------------------------------------------------------------ single and vector env agree per draw
@pytest.mark.parametrize("dispersion", ["flight", "peer"])
def test_vector_env_draws_what_single_envs_draw(dispersion):
    """Copy i of a vector env reset with seed s draws exactly what a single env reset with s + i
    does (their episodes then agree step for step: tests/envs/test_env.py)."""
    n = 3
    venv = RvEntryVectorEnv(num_envs=n, dispersion=dispersion)
    obs, info = venv.reset(seed=21)
    for i in range(n):
        so, si = RvEntryEnv(dispersion=dispersion).reset(seed=21 + i)
        np.testing.assert_allclose(obs[i], so, atol=1e-6)
        for k, v in si["dispersion_draw"].items():
            mine = info["dispersion_draw"][k]
            np.testing.assert_array_equal(mine if k == "altitude_grid_m" else np.asarray(mine)[i], v)


def test_the_flight_set_draws_a_different_profile_per_vehicle_and_leaves_the_truth_alone():
    venv = RvEntryVectorEnv(num_envs=4, dispersion="flight")
    _, info = venv.reset(seed=0)
    lf = info["dispersion_draw"]["density_log_factor"]
    assert lf.shape == (4, GRID_M.size) and np.all(np.std(lf, axis=0)[:60] > 0)
    rho = venv.stepper.model.atmosphere.density(np.full(4, 30e3), NUMPY)
    assert len(set(np.round(rho, 12))) == 4
    # the law sees a navigation state off the truth, and a sensed acceleration off the true one
    assert np.all(np.abs(info["navigation_state"][:, 0] - venv.state[:, 0]) > 0)
    truth_accel = np.stack(venv.true_forces.aero_b, axis=-1)
    assert np.all(np.abs(info["sensed_accel_b"] - truth_accel) > 0)
    assert info["dispersion_draw"]["climate"].shape == (4, 5)


# ------------------------------------------------------------------ sensors and navigation
def test_white_noise_is_standard_normal_and_independent_of_which_vehicles_are_drawn_together():
    keys = np.arange(1, 20001, dtype=np.uint64) * np.uint64(7919)
    z = white_noise(keys, np.full(keys.size, 5))
    assert abs(z.mean()) < 0.02 and z.std() == pytest.approx(1.0, abs=0.02)
    assert abs(np.corrcoef(z[:, 0], z[:, 1])[0, 1]) < 0.03
    np.testing.assert_array_equal(white_noise(keys[7:8], [5]), z[7:8])
    assert not np.array_equal(white_noise(keys[:4], np.full(4, 6)), z[:4])


def test_an_accelerometer_bias_grows_the_navigation_error_as_half_b_t_squared():
    bias = np.array([[1e-3, -2e-3, 0.5e-3]])
    dr, dv = (np.zeros(1),) * 3, (np.zeros(1),) * 3  # components, one vehicle
    for _ in range(300):
        dr, dv = propagate_navigation_error(dr, dv, tuple(bias.T), np.array([1.0]))
    np.testing.assert_allclose(np.stack(dr, axis=-1), 0.5 * bias * 300.0**2, rtol=1e-12)
    np.testing.assert_allclose(np.stack(dv, axis=-1), bias * 300.0, rtol=1e-12)


def test_accelerometer_errors_follow_the_documented_formula():
    a = (np.array([-50.0]), np.array([20.0]), np.array([3.0]))
    z = (np.zeros(1),) * 3  # per axis, one vehicle
    assert np.allclose(accelerometer(a, z, z, z, z), a)
    comps = lambda v: tuple(np.array([c]) for c in v)  # noqa: E731
    s = accelerometer(a, comps([0.1, 0.2, 0.3]), comps([0.01, 0.0, 0.0]), comps([0.0, 0.0, 1e-3]), z)
    # theta = (0, 0, 1e-3): theta x a = (-1e-3 a2, 1e-3 a1, 0)
    np.testing.assert_allclose([c[0] for c in s], [-50.0 * 1.01 - 0.02 + 0.1, 20.0 - 0.05 + 0.2, 3.3])


def test_a_navigation_position_error_moves_the_observed_altitude_not_the_truth():
    flight = FlightGradeErrors(nav_position_m=100.0)
    env = RvEntryEnv(dispersion=Dispersion(flight=flight))
    obs, info = env.reset(seed=2)
    truth = RvEntryEnv()
    obs_t, _ = truth.reset(seed=2)
    dr = info["dispersion_draw"]["nav_position_error_m"]
    a1 = info["navigation_state"][0] - env.state[0]
    # the E-frame error moves the navigated position: entry over (0 deg, 0 deg), r_E = r e1
    r_e = env.state[0] * np.array([1.0, 0.0, 0.0])
    assert a1 == pytest.approx(np.linalg.norm(r_e + dr) - env.state[0], abs=1e-6)
    assert obs[0] - obs_t[0] == pytest.approx(a1 / 40e3, abs=1e-6)
    np.testing.assert_array_equal(env.state, truth.state)


# ------------------------------------------------------------------ the parts on every namespace
def test_profile_parts_agree_on_floats_arrays_and_casadi():
    """Floats and arrays interpolate linearly; CasADi's cubic spline passes through the same knots
    and stays within the profile's step-to-step change between them, flat beyond the ends."""
    import casadi as ca

    values = np.cumsum(np.random.default_rng(3).normal(size=GRID_M.size)) * 0.01
    hs = [-100.0, 0.0, 1234.5, 36999.0, 99999.0, 150e3]
    ref = np.interp(hs, GRID_M, values)
    f = ca.Function("f", [x := ca.MX.sym("h")], [uniform_table(x, 0.0, 1000.0, values, casadi_ns())])
    for h, r in zip(hs, ref):
        assert uniform_table(h, 0.0, 1000.0, values, MATH) == pytest.approx(r, abs=1e-14)
        assert float(f(h)) == pytest.approx(r, abs=0.01)
    for h in (0.0, 7000.0, 50000.0, 100000.0, -5000.0, 130e3):
        assert float(f(h)) == pytest.approx(np.interp(h, GRID_M, values), abs=1e-12)
    np.testing.assert_allclose(uniform_table(np.array(hs), 0.0, 1000.0, np.tile(values, (6, 1)), NUMPY), ref, atol=1e-14)
    aero = MachVaryingAerodynamics(EntryModel().vehicle.aerodynamics, 0.1, 0.05, -0.02, 0.03)
    cl, cd = aero.coefficients(0.2, 14.0, MATH)  # mid-range: s = 0, P2 = -1/2
    cl0, cd0 = EntryModel().vehicle.aerodynamics.coefficients(0.2, 14.0, MATH)
    assert (cl, cd) == pytest.approx((cl0 * (1 - 0.025), cd0 * (1 - 0.015)))


def test_the_climatology_never_touches_the_network(monkeypatch):
    """NRLMSIS gets every space-weather index from the draw: with sockets refused and its index
    look-up made to fail, the flight set still resets and flies."""
    import pymsis.utils

    def refuse(*args, **kwargs):
        raise AssertionError("network or index-file access attempted")

    monkeypatch.setattr(socket, "socket", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(pymsis.utils, "get_f107_ap", refuse)
    monkeypatch.setattr(pymsis.utils, "download_f107_ap", refuse, raising=False)
    rho = np.exp(msis_log_density(172.0, 12.0, 150.0, 150.0, 10.0, TASK_PROBLEM))
    # NRLMSIS at the equator: ~1.2 kg/m^3 at sea level, within 20 % of the exponential model at 30 km
    assert 1.0 < rho[0] < 1.3 and rho[30] == pytest.approx(1.225 * math.exp(-30 / 7.2), rel=0.2)
    env = RvEntryEnv(dispersion="flight")
    env.reset(seed=0)
    env.step(np.zeros(2, np.float32))


# ------------------------------------------------------------------ precision tier and intervals
def test_wilson_interval_matches_the_closed_form():
    from rventry_env.evaluation.summary import rate_interval

    lo, hi = rate_interval([True] * 8 + [False] * 2)
    assert (lo, hi) == pytest.approx((0.4902, 0.9433), abs=1e-4)
    assert rate_interval([True] * 5) == pytest.approx([0.5655, 1.0], abs=1e-4)


def test_the_precision_tier_is_met_only_within_every_bound():
    from rventry_env.task import EntryTask

    p = EntryTask().precision
    ok = dict(impact=True, miss_km=0.09, vertical_error_deg=1.5, alpha_final_deg=-1.9, speed_error_mps=-24.0,
              constraint_violation=False)  # fmt: skip
    assert p.met(**ok)
    for k, bad in (("miss_km", 0.11), ("vertical_error_deg", 2.1), ("alpha_final_deg", 2.5), ("speed_error_mps", 26.0),
                   ("constraint_violation", True), ("impact", False)):  # fmt: skip
        assert not p.met(**{**ok, k: bad}), k


# ------------------------------------------------------------------ the oracle
def test_perfect_sensing_leaves_every_truth_draw_unchanged():
    from rventry_env.evaluation.oracle import draw_episode, perfect_sensing
    from rventry_env.task import EntryTask

    x_a, m_a = draw_episode("flight", 5, EntryTask())
    x_b, m_b = draw_episode(perfect_sensing("flight"), 5, EntryTask())
    np.testing.assert_array_equal(x_a, x_b)
    np.testing.assert_array_equal(m_a.atmosphere.log_factors, m_b.atmosphere.log_factors)
    np.testing.assert_array_equal(m_a.wind.east, m_b.wind.east)
    assert m_a.vehicle.mass == m_b.vehicle.mass and not perfect_sensing("flight").has_sensing


def test_the_oracle_solves_and_flies_one_flight_draw_on_a_coarse_mesh():
    from rventry_env.evaluation.oracle import OracleSettings, draw_episode, oracle
    from rventry_env.physics.entry import entry_forces
    from rventry_env.task import EntryTask

    task = EntryTask()
    x0, model = draw_episode("flight", 1, task)
    # the draw's truth departs from the nominal atmosphere by its perturbation's rms below entry
    h = np.linspace(5e3, 37e3, 9)
    assert np.max(np.abs(model.atmosphere.density(h, NUMPY) / EntryModel().atmosphere.density(h, NUMPY) - 1)) > 0.02
    out = oracle("flight", [1], task, OracleSettings(mesh_intervals=10, end_intervals=2))
    rec, s = out["draws"][0], out["summary"]
    assert rec["converged"], rec["status"]
    assert 0.5 < rec["J"] < 5.0 and rec["replay"]["failure"] == ""  # it flew to the ground
    assert rec["flyable"] == rec["replay"]["success"]
    assert s["draws"] == 1 and s["flyable_fraction"] == float(rec["flyable"]) and len(s["flyable_fraction_ci"]) == 2


def test_the_navigation_state_is_the_true_position_and_velocity_plus_the_errors():
    """Cross-check against the Cartesian conversion: the navigated state's r_E and v_E are the
    truth's plus the navigation errors, its bank angle the vehicle's own."""
    from rventry_env.core.conversions import cartesian_from_rv_euler, conventional_bank

    venv = RvEntryVectorEnv(num_envs=3, dispersion="flight")
    venv.reset(seed=8)
    for _ in range(40):
        _, _, _, _, info = venv.step(np.tile(np.array([0.0, 0.03], np.float32), (3, 1)))
    nav, truth = info["navigation_state"], venv.state
    r_n, v_n = cartesian_from_rv_euler(nav)
    r_t, v_t = cartesian_from_rv_euler(truth)
    dr, dv = venv._errors.dr.T, venv._errors.dv.T
    assert np.all(np.linalg.norm(dr, axis=1) > 1.0)
    np.testing.assert_allclose(r_n, r_t + dr, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v_n, v_t + dv, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(nav[:, 1:5], axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(conventional_bank(nav, nav[:, 11]), conventional_bank(truth, truth[:, 11]), atol=1e-4)


def test_the_miss_splits_into_the_navigations_error_and_the_miss_guidance_believed():
    """Evaluation records where navigation put the vehicle at the end: with perfect sensing the
    errors are zero and the believed miss is the miss, bit for bit; on ``flight`` the two misses
    differ by no more than the horizontal error (the triangle inequality on the ground), the errors
    are the environment's own navigation errors, and the summary reports their percentiles."""
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.evaluation.rollout import rollout
    from rventry_env.evaluation.summary import summarize

    law = load_agent("lqr")
    clean = rollout(law, seeds=[0, 1, 2], dispersion="standard")
    np.testing.assert_array_equal(clean.navigation[:, :2], 0.0)
    np.testing.assert_array_equal(clean.navigation[:, 2], clean.miss_km.astype(float))
    b = rollout(law, seeds=[3, 4, 5, 6], dispersion="flight")
    h, v, believed = b.navigation.T
    assert np.all(h > 10.0) and np.all(np.abs(v) > 1.0)
    assert np.all(np.abs(b.miss_km.astype(float) - believed) * 1000.0 <= h * 1.001 + 1.0)
    assert np.any(np.abs(b.miss_km.astype(float) - believed) * 1000.0 > 0.3 * h)
    nav = summarize(b, 1.0, law.task)["navigation"]
    assert nav["horizontal_error_m"]["p50"] == pytest.approx(np.percentile(h, 50))
    assert summarize(clean, 1.0, law.task)["navigation"]["horizontal_error_m"]["p95"] == 0.0
    rec = b.records()[0]
    assert rec["navigation_error_m"] == {"horizontal": h[0], "vertical": v[0]} and rec["navigated_miss_km"] == believed[0]


def test_the_oracle_splits_the_intervals_where_its_plan_leaves_the_bounds_between_nodes():
    """Collocation holds the path bounds at the nodes only: a plan that bulges above the q bound's
    altitude inside one interval (and only there) has that interval, and no other, split."""
    from types import SimpleNamespace

    from rventry_env.evaluation.oracle import intervals_leaving_bounds, split_intervals
    from rventry_env.reference.collocation import Mesh
    from rventry_env.task import EntryTask

    task = EntryTask()
    model = EntryModel()
    mesh = Mesh(np.array([0.0, 0.25, 0.5, 1.0]), np.array([4, 4, 3]))
    x_nominal = task.problem.initial_state(model.planet.radius)

    def state(t):
        # 37 km everywhere (q far above q_min), except 70 km in the middle of the second interval
        x = np.tile(x_nominal, (np.size(t), 1))
        s = np.asarray(t) / 100.0
        x[:, 0] += np.where(np.abs(s - 0.375) < 0.05, 33e3, 0.0)
        return x

    sol = SimpleNamespace(mesh=mesh, t0=0.0, tf=100.0, state=state)
    assert intervals_leaving_bounds(sol, model, task.problem, 0.005).tolist() == [1]
    finer = split_intervals(mesh, [1])
    np.testing.assert_array_equal(finer.breaks, [0.0, 0.25, 0.375, 0.5, 1.0])
    np.testing.assert_array_equal(finer.degrees, [4, 4, 4, 3])
