"""The accelerometer in the env's info, and the online estimate of the aerodynamic scale factors."""

from __future__ import annotations

import numpy as np
import pytest

from rventry_env.core.backend import NUMPY
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.task import Dispersion
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.guidance.estimation import AeroScaleEstimator, EstimatorSettings
from rventry_env.physics import EntryModel, entry_forces, scaled_model


def _true_scales(draw: np.ndarray) -> np.ndarray:
    """(k_D, k_LD) of a dispersion draw: density x C_D, and C_L / C_D."""
    density, lift, drag = 1 + draw[:, 0], 1 + draw[:, 1], 1 + draw[:, 2]
    return np.stack([density * drag, lift / drag], axis=-1)


def test_the_sensed_acceleration_is_the_aerodynamic_specific_force():
    """Independent check: rebuild lift and drag from q, the coefficients and the bank angle."""
    venv = RvEntryVectorEnv(num_envs=6, dispersion="wide")
    _, info = venv.reset(seed=4)
    for _ in range(30):
        _, _, _, _, info = venv.step(np.tile(np.array([0.1, -0.3], np.float32), (6, 1)))
    d = venv.dispersion_draw
    truth = scaled_model(EntryModel(), 1 + d[:, 0], 1 + d[:, 1], 1 + d[:, 2])
    x = venv.state
    f = entry_forces(tuple(x.T), truth, NUMPY)
    k = EntryModel().vehicle.reference_area / EntryModel().vehicle.mass
    drag = f.dynamic_pressure * k * f.cd
    lift = f.dynamic_pressure * k * f.cl
    sensed = info["sensed_accel_b"]
    np.testing.assert_allclose(-sensed[:, 0], drag, rtol=1e-12)
    np.testing.assert_allclose(sensed[:, 1], lift * np.cos(x[:, 11]), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(sensed[:, 2], lift * np.sin(x[:, 11]), rtol=1e-10, atol=1e-12)
    single = RvEntryEnv(dispersion="wide")
    _, info1 = single.reset(seed=4)
    for _ in range(30):
        _, _, _, _, info1 = single.step(np.array([0.1, -0.3], np.float32))
    np.testing.assert_allclose(info1["sensed_accel_b"], sensed[0], rtol=1e-10)


def test_the_estimate_matches_the_dispersion_at_the_first_measurement():
    venv = RvEntryVectorEnv(num_envs=16, dispersion="wide")
    _, info = venv.reset(seed=11)
    est = AeroScaleEstimator(n=16)
    est.update(info["time_s"], venv.state, info["sensed_accel_b"])
    truth = _true_scales(venv.dispersion_draw)
    got = np.stack([est.drag_accel_scale, est.lift_to_drag_scale], axis=-1)
    np.testing.assert_allclose(got, truth, rtol=5e-4)  # noise-free: the prior's weight is all that remains
    assert np.all(est.sigma < 0.01)


def test_the_filter_converges_through_accelerometer_noise_within_its_stated_time():
    """0.05 m/s^2 white noise on every axis: within 1 % of the truth after 2 s, and the stated sigma is honest."""
    venv = RvEntryVectorEnv(num_envs=64, dispersion="standard")
    _, info = venv.reset(seed=21)
    truth = _true_scales(venv.dispersion_draw)
    rng = np.random.default_rng(0)
    est = AeroScaleEstimator(n=64, settings=EstimatorSettings(accel_noise=0.05))
    errors = []
    for step in range(60):
        est.update(info["time_s"], venv.state, info["sensed_accel_b"] + rng.normal(0.0, 0.05, (64, 3)))
        err = np.stack([est.drag_accel_scale, est.lift_to_drag_scale], axis=-1) / truth - 1
        errors.append(err)
        if step == 2:  # three measurements, 2 s
            assert np.all(np.abs(err) < 0.01)
        _, _, _, _, info = venv.step(np.zeros((64, 2)))
    z = np.abs(errors[-1]) / est.sigma
    assert np.mean(z < 2.0) > 0.85  # the reported uncertainty is about right: ~95 % within 2 sigma
    assert np.all(np.abs(errors[-1]) < 0.02)


def test_the_estimator_ignores_what_it_cannot_use():
    est = AeroScaleEstimator(n=2)
    venv = RvEntryVectorEnv(num_envs=2)
    _, info = venv.reset(seed=0)
    sensed = info["sensed_accel_b"].copy()
    sensed[1] = np.nan  # a dropped sample
    est.update(info["time_s"], venv.state, sensed)
    assert est.updates.tolist() == [1, 1] and np.isfinite(est.k).all()
    assert est.drag_accel_scale[1] == 1.0 and est.sigma[1, 0] == pytest.approx(0.2)  # still the prior
    with pytest.raises(ValueError, match="accel_noise must be positive"):
        EstimatorSettings(accel_noise=0.0)


def test_wide_is_a_named_set():
    wide = Dispersion.parse("wide")
    assert (wide.density, wide.lift, wide.altitude_m, wide.speed_mps, wide.flight_path_deg, wide.heading_deg) == (
        0.10, 0.05, 1000.0, 40.0, 0.4, 0.2)
    assert wide.name == "wide" and Dispersion.standard().name == "standard" and Dispersion().name == "none"
