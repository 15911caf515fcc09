"""Re-planning guidance (mpc): lands, survives failed solves, sees only what a vehicle measures, runs anywhere.

A coarse mesh and rare re-plans keep these short; the benchmark (studies/mpc_settings.py) flies the defaults.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rventry_env.task import EntryTask
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.guidance.law import Law, Measurement
from rventry_env.evaluation.parallel import EvaluationJob, evaluate
from rventry_env.evaluation.rollout import rollout
from rventry_env.guidance.replanning import PlanSolver, ReplanningGuidance, ReplanningSettings
from rventry_env.guidance.tvlqr import NeighboringOptimalGuidance
from rventry_env.physics import EntryModel, scaled_model

COARSE = ReplanningSettings(mesh_intervals=10, mesh_degree=4, replan_s=60.0)


@pytest.fixture(scope="module")
def law():
    return ReplanningGuidance(settings=COARSE)


@pytest.mark.slow
def test_mpc_lands_the_nominal_case_within_the_success_thresholds(law):
    b = rollout(law, 1)
    assert b.is_success[0] and b.failure[0] == ""
    assert b.miss_km[0] < 0.5 and b.vertical_error_deg[0] < 2.0 and abs(b.speed_error_mps[0]) < 20.0
    stats = b.law_stats[0]
    assert stats["replans"] >= 10 and stats["replan_failures"] == 0
    assert len(stats["solve_times_s"]) == stats["replans"]


@pytest.mark.slow
def test_a_failed_resolve_keeps_the_previous_plan_and_is_counted(monkeypatch):
    law = ReplanningGuidance(settings=COARSE)
    original = PlanSolver.solve
    calls = {"n": 0}
    kept = {}

    def failing_second_and_third(self, x0, theta, guess, warm=None):
        calls["n"] += 1
        sol = original(self, x0, theta, guess, warm)
        if calls["n"] in (2, 3):
            kept[calls["n"]] = law.tracks[0].solution
            sol.success, sol.status = False, "Injected_Failure"
        return sol

    monkeypatch.setattr(PlanSolver, "solve", failing_second_and_third)
    b = rollout(law, 1)
    stats = b.law_stats[0]
    assert stats["replan_failures"] == 2
    assert [e[1] for e in stats["replan_failure_events"]] == ["Injected_Failure"] * 2
    assert kept[2] is kept[3]  # the plan of the first solve was flown on through both failures
    assert b.failure[0] == "" and b.miss_km[0] < 5.0  # and the episode still ends on the target


def test_a_failed_first_solve_falls_back_to_the_nominal_plan(monkeypatch):
    law = ReplanningGuidance(settings=COARSE)
    original = PlanSolver.solve

    def fail_once(self, x0, theta, guess, warm=None):
        sol = original(self, x0, theta, guess, warm)
        sol.success = False
        return sol

    monkeypatch.setattr(PlanSolver, "solve", fail_once)
    venv = RvEntryVectorEnv(num_envs=1)
    obs, info = venv.reset(seed=0)
    law.reset(1)
    law(Measurement.of(obs, info["time_s"], venv.state, info["sensed_accel_b"]))
    assert law.tracks[0].solution is law.nominal and law.logs[0].replan_failures == 1


def _fly(law, venv, obs, info, steps):
    actions = []
    for _ in range(steps):
        a = law(Measurement.of(obs, info["time_s"], venv.state, info["sensed_accel_b"]))
        actions.append(a.copy())
        obs, _, _, _, info = venv.step(a)
    return np.array(actions)


@pytest.mark.parametrize("make", [lambda: NeighboringOptimalGuidance(estimate=True),
                                  lambda: ReplanningGuidance(settings=COARSE)])  # fmt: skip
def test_a_law_cannot_tell_a_dispersion_draw_from_the_same_vehicle_built_by_hand(make):
    """Guidance laws never receive the dispersion draw: a dispersed episode, and the same initial
    state and model given explicitly with no draw at all, get the very same actions."""
    drawn = RvEntryVectorEnv(num_envs=2, dispersion="wide")
    obs_a, info_a = drawn.reset(seed=5)
    d = drawn.dispersion_draw.copy()
    assert np.any(d != 0)
    model = scaled_model(EntryModel(), 1 + d[:, 0], 1 + d[:, 1], 1 + d[:, 2])
    built = RvEntryVectorEnv(num_envs=2, model=model)
    obs_b, info_b = built.reset(seed=99, options={"state": drawn.state})
    assert np.all(built.dispersion_draw == 0)
    law_a, law_b = make(), make()
    law_a.reset(2)
    law_b.reset(2)
    np.testing.assert_array_equal(_fly(law_a, drawn, obs_a, info_a, 25), _fly(law_b, built, obs_b, info_b, 25))


def test_rollout_hands_a_law_only_what_a_vehicle_measures():
    seen = []

    class Spy(Law):
        def __call__(self, *args, **kwargs):
            (m,) = args
            assert not kwargs and isinstance(m, Measurement)
            seen.append({f: np.shape(getattr(m, f)) for f in m.__dataclass_fields__})
            return np.zeros((m.n, 2), np.float32)

    rollout(Spy(), 3, dispersion="standard", max_episode_steps=4)
    assert seen and all(s == {"observation": (3, 26), "time_s": (3,), "navigation_state": (3, 12),
                              "sensed_accel_b": (3, 3), "flying": (3,), "target_e": ()} for s in seen)  # fmt: skip
    # on a footprint task the target it is told is the only addition
    seen.clear()
    Spy.retargets = True
    rollout(Spy(), 3, dispersion="standard", max_episode_steps=4, task=EntryTask(targets="footprint"))
    assert seen and all(s["target_e"] == (3, 3) for s in seen)


def test_rollout_hands_a_law_the_navigation_state_and_the_sensors_not_the_truth_or_the_draw():
    """With sensor and navigation errors, a law is given what the vehicle's navigation and
    accelerometer say (info["navigation_state"], info["sensed_accel_b"]), never the true state,
    the true acceleration or the draw (info["dispersion_draw"])."""
    seen = []

    class Spy(Law):
        def __call__(self, m):
            seen.append(m)
            return np.zeros((m.n, 2), np.float32)

    rollout(Spy(), 2, seed=4, dispersion="flight", max_episode_steps=3)
    venv = RvEntryVectorEnv(num_envs=2, dispersion="flight")
    obs, info = venv.reset(seed=4)
    first = seen[0]
    np.testing.assert_array_equal(first.observation, obs)
    np.testing.assert_array_equal(first.navigation_state, info["navigation_state"])
    np.testing.assert_array_equal(first.sensed_accel_b, info["sensed_accel_b"])
    assert np.all(np.abs(first.navigation_state[:, 0] - venv.state[:, 0]) > 1e-3)
    assert np.all(np.abs(first.sensed_accel_b - np.stack(venv.true_forces.aero_b, axis=-1)) > 0)
    # the target is part of the mission a law is told, not of the draw
    assert set(Measurement.__dataclass_fields__) == {"observation", "time_s", "navigation_state", "sensed_accel_b",
                                                     "flying", "target_e"}  # fmt: skip
    assert "dispersion_draw" in info


def test_rollout_refuses_what_is_not_a_guidance_law():
    with pytest.raises(TypeError, match="lacks reset, episode_stats, episodes_per_task"):
        rollout(lambda m: np.zeros((m.n, 2)), 1, max_episode_steps=2)


def test_every_shipped_law_implements_the_interface():
    from rventry_env.evaluation.agents import agent_names, load_agent
    from rventry_env.guidance.law import GuidanceLaw

    for name in agent_names():
        if name == "mpc":
            law = ReplanningGuidance(settings=COARSE)
        else:
            law = load_agent(name)
        assert isinstance(law, GuidanceLaw) and isinstance(law, Law), name


@pytest.mark.slow
def test_local_processes_and_a_dask_cluster_give_identical_episodes():
    distributed = pytest.importorskip("distributed")
    job = EvaluationJob("mpc", "standard", EntryTask(), options=(("settings", COARSE),))
    seeds = [3, 4]
    here = evaluate(job, seeds, workers=1)
    pool = evaluate(job, seeds, workers=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        dask = evaluate(job, seeds, cluster=cl.scheduler_address)
    for other in (pool, dask):
        for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "cost", "time_s"):
            np.testing.assert_array_equal(getattr(here, key), getattr(other, key))
        assert [s["replans"] for s in other.law_stats] == [s["replans"] for s in here.law_stats]
    assert here.seeds.tolist() == seeds


@pytest.mark.slow
def test_final_replanning_replans_every_final_replan_s_near_the_end_and_still_lands(law):
    base = rollout(law, 1)
    final = ReplanningSettings(mesh_intervals=10, mesh_degree=4, replan_s=60.0, final_replan_s=10.0,
                               final_window_s=120.0, freeze_s=5.0)  # fmt: skip
    b = rollout(ReplanningGuidance(settings=final), 1)
    assert b.is_success[0] and b.miss_km[0] < 0.5 and b.vertical_error_deg[0] < 2.0
    extra = b.law_stats[0]["replans"] - base.law_stats[0]["replans"]
    # about 11 plans in the last 120 s (every 10 s, to 5 s before impact) instead of about 2
    assert 7 <= extra <= 11, extra


def test_settings_are_checked():
    with pytest.raises(ValueError, match=r"ReplanningSettings.replan_s must be > 0, got 0"):
        ReplanningSettings(replan_s=0.0)
    with pytest.raises(ValueError, match=r"final_replan_s must be None \(off\) or > 0 and <= 30, got 45"):
        ReplanningSettings(final_replan_s=45.0)
    with pytest.raises(ValueError, match="final_window_s must be finite, got nan"):
        ReplanningSettings(final_window_s=float("nan"))
    s = ReplanningSettings(final_replan_s=5.0, final_window_s=100.0)
    assert (s.replan_interval(500.0), s.replan_interval(100.0), s.replan_interval(3.0)) == (30.0, 5.0, 5.0)
    assert ReplanningSettings().replan_interval(3.0) == 30.0  # off by default
    with pytest.raises(ValueError, match=r"q_margin must be >= 0 and < 0.5, got 0.6"):
        ReplanningSettings(q_margin=0.6)
    with pytest.raises(ValueError, match="mesh_degree must be an integer, got 2.5"):
        ReplanningSettings(mesh_degree=2.5)
    with pytest.raises(ValueError, match=r"vertical_dive_m must be >= 0 and <= 20000, got -100"):
        ReplanningSettings(vertical_dive_m=-100.0)


def test_a_straight_dive_meets_the_final_speed_at_the_target():
    """Cross-check of the dive's entry speed (backward, by the environment's equations of motion)
    against a one-dimensional fall written from the force parts alone: speed down, drag at alpha 0
    against it, gravity with it, solved forward by scipy to the ground."""
    from scipy.integrate import solve_ivp

    from rventry_env.core.backend import NUMPY
    from rventry_env.guidance.terminal import dive_entry_speed

    task, model = EntryTask(), EntryModel()
    p, re = task.problem, model.planet.radius
    veh = model.vehicle
    speeds = [dive_entry_speed(task, model, h) for h in (0.0, 800.0, 2000.0)]
    assert speeds[0] == pytest.approx(p.final_speed, abs=1e-9) and speeds[0] < speeds[1] < speeds[2]

    def fall(_, y):
        h, v = y
        rho, a = model.atmosphere.density(h, NUMPY), model.atmosphere.speed_of_sound(h, NUMPY)
        _, cd = veh.aerodynamics.coefficients(p.final_alpha, v / a, NUMPY)
        g = abs(model.gravity.acceleration_a(re + h, (0.0, 0.0, 1.0), NUMPY)[0])
        return [-v, g - 0.5 * rho * v * v * veh.reference_area * cd / veh.mass]

    ground = lambda _, y: y[0]  # noqa: E731
    ground.terminal = True
    for h, v0 in ((800.0, speeds[1]), (2000.0, speeds[2])):
        sol = solve_ivp(fall, (0.0, 10.0), [h, v0], events=ground, rtol=1e-10, atol=1e-8)
        assert sol.status == 1
        assert sol.y_events[0][0][1] == pytest.approx(p.final_speed, abs=0.5)
    with pytest.raises(ValueError, match="the dive's height must be a finite number of metres >= 0"):
        dive_entry_speed(task, model, float("nan"))


def test_mpc_lands_the_nominal_case_with_alpha_at_zero():
    """Example 2's alpha(t_f) = 0, flown by default: tracking alone left 0.9 deg at impact on this mesh."""
    assert (COARSE.terminal_alpha, COARSE.terminal_alpha_deg) == (True, 0.5)  # the law's defaults
    b = rollout(ReplanningGuidance(settings=COARSE), 1)
    assert b.is_success[0] and b.miss_km[0] < 0.1 and b.vertical_error_deg[0] < 2.0
    assert abs(b.alpha_final_deg[0]) <= 0.5
    without = rollout(ReplanningGuidance(settings=replace(COARSE, terminal_alpha=False)), 1)
    assert abs(without.alpha_final_deg[0]) > 0.5  # the check can fail: without the bound it does
    assert not ReplanningSettings.flight_grade().terminal_alpha  # it cost mpc-flight landings on the flight set


def test_the_terminal_alpha_bound_takes_alpha_out_by_impact_and_nothing_before():
    import math

    from rventry_env.core import conversions as cv
    from rventry_env.guidance.terminal import alpha_rate_bound, time_to_impact

    task, radius = EntryTask(), EntryModel().planet.radius

    def state(h, v, gamma_deg, alpha_deg):
        s = np.array([[radius + h, 0.0, 0.0, v, math.radians(gamma_deg), 0.0]])
        x = np.zeros((1, 12))
        x[:, :10] = cv.rv_euler_from_spherical(s)
        x[:, 10] = math.radians(alpha_deg)
        return x

    x = state(600.0, 1200.0, -90.0 + 1e-3, 3.0)  # vertical, 0.5 s to go: this is the last step
    assert time_to_impact(x, radius)[0] == pytest.approx(0.5, rel=1e-6)
    assert alpha_rate_bound(x, task, radius)[0] == pytest.approx(-math.radians(3.0), rel=1e-6)  # zero at its end
    x = state(1920.0, 1200.0, -90.0 + 1e-3, 5.0)  # 1.6 s: the next step is the last, impact 0.6 s into it
    at_last = math.radians(0.2) / (1 - 0.6 + 0.05)  # what then leaves 0.2 deg at impact
    assert alpha_rate_bound(x, task, radius)[0] == pytest.approx(at_last - math.radians(5.0), rel=1e-6)
    x = state(3120.0, 1200.0, -90.0 + 1e-3, 12.0)  # 2.6 s: one step of 0.8 * 10 deg/s before the last
    assert alpha_rate_bound(x, task, radius)[0] == pytest.approx(at_last + math.radians(8.0 - 12.0), rel=1e-6)
    high = state(30e3, 6000.0, -2.0, 12.0)  # high up the bound is far above any rate
    assert alpha_rate_bound(high, task, radius)[0] > 10 * task.problem.u_alpha_max
    assert np.isinf(alpha_rate_bound(state(30e3, 6000.0, 1.0, 12.0), task, radius)[0])  # climbing: no bound


def test_evaluation_results_do_not_depend_on_the_machines_speed(monkeypatch):
    """No wall-time cap by default: the iteration budget alone decides, so a slowed clock flies the same."""
    import time as _time

    law = ReplanningGuidance(settings=COARSE)
    assert "max_wall_time" not in law.solver.ipopt_options
    venv = RvEntryVectorEnv(num_envs=1, dispersion="standard")

    def fly():
        obs, info = venv.reset(seed=7)
        law.reset(1)
        return _fly(law, venv, obs, info, 40)

    normal = fly()
    real = _time.perf_counter
    monkeypatch.setattr(_time, "perf_counter", lambda: 50.0 * real())  # every solve looks 50x slower
    np.testing.assert_array_equal(fly(), normal)
    assert PlanSolver(EntryTask(), EntryModel(), replace(COARSE, max_wall_s=1.5)).ipopt_options["max_wall_time"] == 1.5
    with pytest.raises(ValueError, match=r"max_wall_s must be None \(off\) or > 0, got 0"):
        ReplanningSettings(max_wall_s=0.0)


@pytest.mark.slow
def test_mpc_with_load_relief_reports_its_capped_steps_and_lands():
    b = rollout(ReplanningGuidance(settings=replace(COARSE, load_relief_margin=0.02)), 1)
    assert b.is_success[0] and b.max_load_factor_g[0] <= 12.0 * 0.98 + 0.05
    assert set(b.law_stats[0]) >= {"replans", "load_relief_steps"}
    with pytest.raises(ValueError, match=r"load_relief_margin must be None \(off\) or >= 0 and < 1, got 1.5"):
        ReplanningSettings(load_relief_margin=1.5)


def test_density_margins_tighten_each_point_by_the_density_uncertainty_at_its_altitude():
    """With the atmosphere's Gauss-Markov bands known, a collocation point's load and q bounds are
    tightened by k sigma of the density ratio there given the one measured at the current
    altitude: nothing at the current altitude, s sqrt(2 (1 - exp(-dh/L))) away from it."""
    from rventry_env.task import FLIGHT_GRADE_ERRORS
    from rventry_env.task.flight_grade import band_profile

    bands = FLIGHT_GRADE_ERRORS.density_bands
    solver = PlanSolver(EntryTask(), EntryModel(), replace(COARSE, density_bands=bands, density_sigmas=2.0))
    plan = solver.nominal_plan(EntryTask())
    x0 = EntryTask().problem.initial_state(EntryModel().planet.radius)
    lbg, ubg = solver.path_bounds(x0, plan)
    tr = solver.transcription
    rows = tr.g_groups["path"]
    nodes = tr.mesh.nodes()[: tr.mesh.n_collocation]
    h = plan.state(nodes * plan.tf)[:, 0] - solver.radius
    rms, corr = band_profile(bands, h)
    sigma = rms * np.sqrt(2 * (1 - np.exp(-np.abs(h - 37e3) / corr)))
    np.testing.assert_allclose(ubg[rows][0::2], tr.ubg[rows][0::2] * np.exp(-2 * sigma), rtol=1e-12)
    np.testing.assert_allclose(lbg[rows][1::2], tr.lbg[rows][1::2] * np.exp(2 * sigma), rtol=1e-12)
    assert sigma[0] == 0.0 and sigma.max() > 0.05  # measured where it starts, uncertain far below
    # the other constraints keep their bounds, and without bands nothing changes
    outside = np.ones(tr.lbg.size, bool)
    outside[rows] = False
    np.testing.assert_array_equal(lbg[outside], tr.lbg[outside])
    assert PlanSolver(EntryTask(), EntryModel(), COARSE).path_bounds(x0, plan) == (None, None)


def test_aero_margins_follow_the_mach_uncertainty_of_the_physics_part():
    """The law's spread of C_L between two Mach numbers matches the flight set's Mach-varying
    aerodynamics (its own physics part) sampled with the same coefficient rms; the load bound is
    tightened by it in quadrature with the density term, q only by the density term; the plans'
    L/D is lowered by sqrt(2) of it toward the impact's Mach, the drag scale untouched."""
    from rventry_env.core.backend import NUMPY
    from rventry_env.physics.uncertainty import MachVaryingAerodynamics
    from rventry_env.task import FLIGHT_GRADE_ERRORS as F

    rms = 0.03
    settings = replace(COARSE, aero_mach_rms=rms, aero_sigmas=2.0, density_bands=F.density_bands,
                       density_sigmas=1.0)  # fmt: skip
    solver = PlanSolver(EntryTask(), EntryModel(), settings)
    machs = np.array([4.0, 6.0, 12.0, 20.0])
    rng = np.random.default_rng(5)
    a = rng.normal(0.0, rms, size=(2, 200_000))
    part = MachVaryingAerodynamics(EntryModel().vehicle.aerodynamics, lift_p1=a[0], lift_p2=a[1])

    def lift_error(m):
        cl, _ = part.coefficients(np.radians(10.0), np.full(a.shape[1], m), NUMPY)
        cl0, _ = part.base.coefficients(np.radians(10.0), m, NUMPY)
        return cl / cl0 - 1.0

    for m in machs:
        empirical = np.std(lift_error(m) - lift_error(20.0))
        assert solver.aero_sigma(20.0, m) == pytest.approx(empirical, rel=0.01, abs=1e-12)
    assert solver.aero_sigma(20.0, 20.0) == 0.0

    plan = solver.nominal_plan(EntryTask())
    x0 = EntryTask().problem.initial_state(EntryModel().planet.radius)
    lbg, ubg = solver.path_bounds(x0, plan)
    only_density = PlanSolver(EntryTask(), EntryModel(), replace(settings, aero_mach_rms=None))
    lbg_d, ubg_d = only_density.path_bounds(x0, plan)
    tr = solver.transcription
    rows = tr.g_groups["path"]
    nodes = tr.mesh.nodes()[: tr.mesh.n_collocation]
    k_a = 2.0 * solver.aero_sigma(solver.mach(x0)[0], solver.mach(plan.state(nodes * plan.tf)))
    k_q = -np.log(ubg_d[rows][0::2] / tr.ubg[rows][0::2])
    np.testing.assert_allclose(ubg[rows][0::2], tr.ubg[rows][0::2] * np.exp(-np.hypot(k_q, k_a)), rtol=1e-12)
    np.testing.assert_array_equal(lbg[rows][1::2], lbg_d[rows][1::2])  # q: the density term alone
    assert k_a.max() > 0.05

    law = ReplanningGuidance(EntryTask(), settings=settings)
    theta = np.array([[0.1, -0.05], [0.0, 0.0]])
    states = np.array([x0, plan.state(0.95 * plan.tf)])
    out = law.planning_scales(states, theta)
    np.testing.assert_array_equal(out[:, 0], theta[:, 0])
    drop = theta[:, 1] - out[:, 1]
    expected = 2.0 * np.sqrt(2.0) * solver.aero_sigma(solver.mach(states), law.mach_end)
    np.testing.assert_allclose(drop, expected, rtol=1e-12)
    assert drop[0] > drop[1] > 0  # the farther the impact's Mach, the lower the planned L/D
    assert ReplanningGuidance(EntryTask(), settings=COARSE).planning_scales(states, theta) is theta


@pytest.mark.parametrize("change, match", [
    ({"aero_mach_rms": -0.1}, "aero_mach_rms must be None"),
    ({"aero_sigmas": float("nan")}, "aero_sigmas must be"),
    ({"aero_mach_range": (10.0, 5.0)}, "aero_mach_range must be"),
])  # fmt: skip
def test_aero_margin_settings_are_checked(change, match):
    with pytest.raises(ValueError, match=match):
        replace(ReplanningSettings(), **change)


def test_the_flight_grade_preset_is_what_mpc_flight_flies():
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.task import FLIGHT_GRADE_ERRORS as F

    s = ReplanningSettings.flight_grade()
    from rventry_env.guidance.estimation import FlightEstimator

    assert (s.load_relief_margin, s.q_margin, s.density_sigmas, s.aero_sigmas) == (0.04, 0.10, 1.0, 1.0)
    assert s.density_bands == F.density_bands and s.aero_mach_rms == F.lift_mach
    assert ReplanningSettings.flight_grade(q_margin=0.08).q_margin == 0.08
    law = load_agent("mpc-flight", EntryTask(), settings=replace(s, mesh_intervals=10, replan_s=60.0))
    assert law.settings.aero_mach_rms == 0.03 and law.relief is not None and law.q_floor is None  # no q floor
    # the flight-grade estimator, on the flight set's published statistics, with the wind
    assert isinstance(law.estimator, FlightEstimator) and law.estimator.settings.wind_sigma == F.wind_mean_mps
    assert law.estimator.settings.density_bands == F.density_bands


def test_mpc_peer_is_mpc_flight_sized_by_the_peer_sets_published_statistics():
    """The peer set's density is one constant factor (a band over every altitude flown, correlated far
    beyond the flight) and its C_D error splits the q bound; everything else is mpc-flight's."""
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.guidance.estimation import FlightEstimator
    from rventry_env.task import Dispersion
    from rventry_env.task.flight_grade import band_spread

    d = Dispersion.peer()
    law = load_agent("mpc-peer", EntryTask())
    flight = load_agent("mpc-flight", EntryTask())
    ((top, rms, length),) = law.settings.density_bands
    assert (rms, law.settings.drag_rms) == (d.density, d.drag) == (0.25, 0.20)
    entry_h = EntryTask().problem.initial_state(0.0)[0]
    assert top >= entry_h and band_spread(law.settings.density_bands, 0.0, entry_h) < 0.03 * rms  # one factor
    assert replace(law.settings, density_bands=None, drag_rms=None) == replace(flight.settings, density_bands=None,
                                                                               drag_rms=None)  # fmt: skip
    assert isinstance(law.estimator, FlightEstimator) and law.estimator.settings == flight.estimator.settings


def test_the_q_bound_carries_the_drag_scale_share_that_is_not_density():
    """With the density's rms at the current altitude and C_D's, the posterior share of ln k_D on C_D
    tightens every q node by exp(share + k spread), on top of nothing else; a high measured drag
    (more likely a high C_D) tightens it, a low one loosens it, and the load rows are untouched."""
    from rventry_env.task import FLIGHT_GRADE_ERRORS
    from rventry_env.task.flight_grade import band_profile

    bands = FLIGHT_GRADE_ERRORS.density_bands
    settings = replace(COARSE, density_bands=bands, density_sigmas=0.0, drag_rms=0.05, split_sigmas=1.5)
    solver = PlanSolver(EntryTask(), EntryModel(), settings)
    plan = solver.nominal_plan(EntryTask())
    x0 = EntryTask().problem.initial_state(EntryModel().planet.radius)
    s_rho = band_profile(bands, np.array([37e3]))[0][0]
    tr = solver.transcription
    rows = tr.g_groups["path"]
    for ln_kd in (0.12, -0.08):
        mean, spread = solver.drag_split(x0, ln_kd)
        assert mean == pytest.approx(ln_kd * 0.05**2 / (s_rho**2 + 0.05**2), rel=1e-12)
        assert spread == pytest.approx(s_rho * 0.05 / np.hypot(s_rho, 0.05), rel=1e-12)
        lbg, ubg = solver.path_bounds(x0, plan, np.array([ln_kd, 0.0]))
        np.testing.assert_allclose(lbg[rows][1::2], tr.lbg[rows][1::2] * np.exp(mean + 1.5 * spread), rtol=1e-12)
        np.testing.assert_array_equal(ubg, tr.ubg)
    assert solver.drag_split(x0, 0.12)[0] > 0 > solver.drag_split(x0, -0.08)[0]
    assert PlanSolver(EntryTask(), EntryModel(), replace(settings, drag_rms=None)).drag_split(x0, 0.12) == (0.0, 0.0)
    with pytest.raises(ValueError, match="drag_rms needs density_bands"):
        ReplanningSettings(drag_rms=0.05)  # nothing to split against without the density's bands
    with pytest.raises(ValueError, match="split_sigmas must be >= 0, got -1"):
        ReplanningSettings(split_sigmas=-1.0)


def test_tracking_compares_the_plan_with_its_own_scales_unless_told_to_feed_the_estimate(monkeypatch):
    """With the aerodynamic margin the plans use a lowered L/D; tracking gets the same lowered
    scales by default, and the unlowered estimate with ``track_estimate``."""
    settings = replace(COARSE, aero_mach_rms=0.03)
    venv = RvEntryVectorEnv(num_envs=1)
    obs, info = venv.reset(seed=0)
    m = Measurement(obs, np.zeros(1), info["navigation_state"], info["sensed_accel_b"], np.ones(1, bool))
    seen = {}
    for track in (False, True):
        law = ReplanningGuidance(settings=replace(settings, track_estimate=track))
        monkeypatch.setattr(law, "rates", lambda t, x, theta, law=law: seen.setdefault(track, theta.copy()) * 0.0)
        law(m)
        estimate = law.estimator.log_scales()
        planned = law.planning_scales(m.navigation_state, estimate)
        assert planned[0, 1] < estimate[0, 1] - 0.01
        np.testing.assert_array_equal(seen[track], estimate if track else planned)
    with pytest.raises(ValueError, match="track_estimate must be True or False"):
        ReplanningSettings(track_estimate=1)


def test_a_q_floor_between_plans_is_flown_and_counted():
    """``q_floor_margin`` puts :class:`~rventry_env.guidance.q_floor.QFloor` before the load relief;
    each episode's record counts the steps it took the bank."""
    law = ReplanningGuidance(settings=replace(COARSE, q_floor_margin=0.05, load_relief_margin=0.02))
    assert law.q_floor.margin == 0.05
    b = rollout(law, seeds=[0], dispersion="standard", max_episode_steps=20)
    assert {"q_floor_steps", "load_relief_steps"} <= set(b.law_stats[0]) and b.law_stats[0]["q_floor_steps"] == 0
