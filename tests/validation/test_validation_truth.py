"""The truth model (Cartesian ECEF, its own forces and integrator) against the rv-Euler entry model.

The truth model exists to generate records for the validation loop, so it must
agree with the rv-Euler model where both have the same physics, and disagree
where they do not. Pointwise (accelerations at random states) and along whole
flights (sampled trajectories).
"""

import math

import numpy as np
import pytest

from rventry_env.core.conversions import cartesian_from_rv_euler, paper_bank, rv_euler_from_cartesian
from rventry_env.physics import (
    CAVHAerodynamics,
    EntryModel,
    HorizontalWind,
    J2Gravity,
    ScaledAerodynamics,
    Vehicle,
    entry_rhs,
)
from rventry_env.validation.record import FlightRecord
from rventry_env.validation.replay.controls import control_schedule
from rventry_env.validation.replay.record_replay import Replay
from rventry_env.validation.replay.replay_setup import replay_setup
from rventry_env.validation.synthetic import truth
from rventry_env.validation.synthetic.simulate import Scenario

WORLDS_AND_MODELS = {
    "no effect": (truth.TruthWorld(), EntryModel()),
    "j2": (truth.TruthWorld(j2=truth.EARTH_J2), EntryModel(gravity=J2Gravity(j2=truth.EARTH_J2))),
    "wind": (
        truth.TruthWorld(wind_east=60.0, wind_north=-35.0),
        EntryModel(wind=HorizontalWind(60.0, -35.0)),
    ),
    "aero scales": (
        truth.TruthWorld(cl_scale=0.9, cd_scale=1.15),
        EntryModel(vehicle=Vehicle(aerodynamics=ScaledAerodynamics(CAVHAerodynamics(), 0.9, 1.15))),
    ),
}


def _random_state(rng):
    lat, lon = rng.uniform(-1.2, 1.2), rng.uniform(-math.pi, math.pi)
    r, v = truth.ecef_from_spherical(
        6378137.0 + rng.uniform(30e3, 80e3), lon, lat, rng.uniform(2000, 7500),
        rng.uniform(-0.3, 0.2), rng.uniform(-math.pi, math.pi),
    )  # fmt: skip
    return r, v, rng.uniform(0.0, 0.4), rng.uniform(-math.pi, math.pi)


@pytest.mark.parametrize("case", list(WORLDS_AND_MODELS))
def test_accelerations_agree_pointwise(case):
    """Newton in ECEF vectors == d/dt of the velocity implied by the rv-Euler rates, at random states.

    The rv-Euler side uses only public functions: ``entry_rhs`` for x_dot and
    ``cartesian_from_rv_euler`` for v_E(x); d(v_E)/dt is the central difference
    of v_E along x_dot.
    """
    world, model = WORLDS_AND_MODELS[case]
    rng = np.random.default_rng(7)
    eps = 1e-3  # s
    for _ in range(25):
        r, v, alpha, mu = _random_state(rng)
        a_truth = truth.acceleration(r, v, alpha, mu, world)
        x10 = rv_euler_from_cartesian(r, v)
        x = np.concatenate([x10, [alpha, float(paper_bank(x10, mu))]])
        x_dot = np.array(entry_rhs(x, (0.0, 0.0), model), dtype=float)
        v_plus = cartesian_from_rv_euler(x + eps * x_dot)[1]
        v_minus = cartesian_from_rv_euler(x - eps * x_dot)[1]
        a_rv = (v_plus - v_minus) / (2 * eps)
        assert np.allclose(a_rv, a_truth, rtol=0, atol=1e-6 * np.linalg.norm(a_truth)), (case, a_rv, a_truth)
        # and the position rate is the velocity
        r_plus = cartesian_from_rv_euler(x + eps * x_dot)[0]
        r_dot = (r_plus - cartesian_from_rv_euler(x - eps * x_dot)[0]) / (2 * eps)
        assert np.allclose(r_dot, v, rtol=0, atol=1e-6 * np.linalg.norm(v))


def _flight_record(world, duration=300.0, rate=1.0, scenario=Scenario()):
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    r0, v0 = truth.ecef_from_spherical(
        6378137.0 + scenario.altitude, math.radians(scenario.longitude_deg),
        math.radians(scenario.latitude_deg), scenario.speed, math.radians(scenario.flight_path_deg),
        math.radians(scenario.azimuth_deg),
    )  # fmt: skip
    r, v = truth.fly(world, r0, v0, scenario.controls, t)
    ctrl = np.array([scenario.controls(ti) for ti in t])
    return FlightRecord(t=t, kind="ecef", observations=np.hstack([r, v]), observation_names=(),
                        alpha=ctrl[:, 0], bank=ctrl[:, 1])  # fmt: skip


def _replay_error(rec, model):
    setup = replay_setup(rec)
    replay = Replay(rec, setup, control_schedule(rec, None, True), h_max=1.0)
    e = replay.predict(model, np.zeros((1, 6)))[..., 0] - replay.y
    return np.linalg.norm(e[:, :3], axis=1).max(), np.linalg.norm(e[:, 3:], axis=1).max()


@pytest.mark.parametrize("case", ["no effect", "j2", "wind"])
def test_flights_agree(case):
    """A 300 s glide flown by both models (truth: DOP853; rv-Euler: the shared RK4 at 1 s)."""
    world, model = WORLDS_AND_MODELS[case]
    dr, dv = _replay_error(_flight_record(world), model)
    # integration and control-interpolation error only: millimetres after 2000 km of flight
    assert dr < 0.05 and dv < 1e-3, (case, dr, dv)


def test_flights_disagree_without_the_effect():
    """The cross-check can fail: the rv-Euler model without J2 misses the truth flown with it."""
    world, _ = WORLDS_AND_MODELS["j2"]
    dr, _ = _replay_error(_flight_record(world), EntryModel())
    assert dr > 10.0


def test_truth_density_profile_effect():
    """The density effect is the documented sinusoid in log density, zero-mean over a wavelength."""
    w = truth.TruthWorld(density_amplitude=0.3)
    base = truth.TruthWorld()
    h = np.linspace(20e3, 100e3, 81)
    lr = np.array([math.log(truth.density(x, w) / truth.density(x, base)) for x in h])
    assert np.allclose(lr, 0.3 * np.sin(2 * np.pi * (h - 30e3) / 80e3), atol=1e-12)
    assert abs(truth.density(0.0, base) - 1.225) < 1e-12
