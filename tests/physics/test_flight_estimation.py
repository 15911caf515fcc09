"""The flight-grade estimator: scales as processes in altitude and Mach, and the horizontal wind.

The truth here is built from the physics parts directly (a known wind, a known density profile),
flown along the shipped optimum, so the estimate can be held to it at every second.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rventry_env.core.backend import NUMPY
from rventry_env.guidance.estimation import (
    AeroScaleEstimator, FlightEstimator, FlightEstimatorSettings, make_estimator,
)  # fmt: skip
from rventry_env.physics import EntryModel, entry_forces
from rventry_env.physics.atmosphere import ExponentialAtmosphere
from rventry_env.physics.model import with_aero_scales
from rventry_env.physics.sensors import accelerometer
from rventry_env.physics.uncertainty import ProfileAtmosphere
from rventry_env.physics.wind import HorizontalWind
from rventry_env.reference import load_reference
from rventry_env.task import FLIGHT_GRADE_ERRORS

R_E = EntryModel().planet.radius


@pytest.fixture(scope="module")
def track():
    """The shipped optimum at 1 Hz: times (K,) and states (K, 12)."""
    ref = load_reference()
    t = np.arange(0.0, ref.tf, 1.0)
    return t, np.asarray(ref.state(t), dtype=float)


def _sensed(x, model, rng, errors=True):
    """The flight set's accelerometer (bias, scale, misalignment at their 1-sigma magnitudes, and
    its white noise) on the true aerodynamic force of ``model`` at states ``x``."""
    aero = entry_forces(tuple(x.T), model, NUMPY).aero_b
    f = FLIGHT_GRADE_ERRORS
    if not errors:
        return np.stack(aero, axis=-1)
    sign = np.array([1.0, -1.0, 1.0])
    noise = f.accel_noise_mps2 * rng.standard_normal((len(x), 3))
    sensed = accelerometer(aero, tuple(f.accel_bias_mps2 * sign), tuple(f.accel_scale * sign),
                           tuple(f.accel_misalignment_rad * sign), tuple(noise.T))  # fmt: skip
    return np.stack(sensed, axis=-1)


def _fly(estimators, t, x, sensed):
    out = []
    for k in range(len(t)):
        for e in estimators:
            e.update(t[k : k + 1], x[k : k + 1], sensed[k : k + 1])
        out.append([(e.drag_accel_scale[0], e.lift_to_drag_scale[0], *getattr(e, "wind_en", np.zeros((1, 2)))[0])
                    for e in estimators])  # fmt: skip
    return np.asarray(out)  # (K, n_estimators, 4)


def test_a_constant_wind_is_found_and_kept_out_of_the_lift(track):
    """A 15 / -12 m/s wind and scales k_D 1.06, k_LD 0.93, through the flight set's sensor errors:
    the wind within 3.5 m/s per component from 800 s on (the sensor errors alone move it by up to 3) (it becomes observable as the bank and the
    flight-path angle turn the drag across it), and k_LD within 0.5 % over the whole final dive,
    where the scalar filters read the drag the cross wind tilts into the lift plane as lift."""
    t, x = track
    truth = replace(with_aero_scales(EntryModel(), 1.06, 0.93), wind=HorizontalWind(east=15.0, north=-12.0))
    sensed = _sensed(x, truth, np.random.default_rng(3))
    flight = FlightEstimator(settings=FlightEstimatorSettings(wind_sigma=10.0))
    scalar = AeroScaleEstimator()
    est = _fly([flight, scalar], t, x, sensed)
    late = t >= 800.0
    np.testing.assert_allclose(est[late, 0, 2], 15.0, atol=3.5)
    np.testing.assert_allclose(est[late, 0, 3], -12.0, atol=3.5)
    dive = t >= t[-1] - 60.0
    assert np.max(np.abs(est[dive, 0, 1] / 0.93 - 1.0)) < 0.005
    assert np.max(np.abs(est[dive, 1, 1] / 0.93 - 1.0)) > 0.02  # the scalar filters' error it removes
    assert np.all(flight.wind_sigma[0] < 3.0) and flight.rejected[0] == 0


def test_density_that_varies_with_altitude_is_followed_at_the_apex(track):
    """Air 15 % thinner than the model above 50 km, as the model below 40 km (a ramp between): the
    skips' apexes, where q is lowest, fly in it. With the atmosphere's published bands the filter lets
    ln k_D move as the altitude does, and its k_D is within 1 % of the truth at every second above
    48 km; the fixed-drift filter, which averages over time, lags by more than 2 %."""
    t, x = track
    grid = np.arange(0.0, 101e3, 1e3)
    log_f = np.log(1.0 - 0.15 * np.clip((grid - 40e3) / 10e3, 0.0, 1.0))
    truth = replace(EntryModel(), atmosphere=ProfileAtmosphere(ExponentialAtmosphere(), 0.0, 1e3, log_f))
    sensed = _sensed(x, truth, np.random.default_rng(4))
    settings = FlightEstimatorSettings(density_bands=FLIGHT_GRADE_ERRORS.density_bands)
    est = _fly([FlightEstimator(settings=settings), AeroScaleEstimator()], t, x, sensed)
    h = x[:, 0] - R_E
    high = h > 48e3
    assert high.sum() > 50
    true_kd = np.exp(np.interp(h[high], grid, log_f))
    assert np.max(np.abs(est[high, 0, 0] / true_kd - 1.0)) < 0.01
    assert np.max(np.abs(est[high, 1, 0] / true_kd - 1.0)) > 0.02


def test_the_stated_uncertainty_is_honest(track):
    """Over 32 draws of wind and scales (one batch), the errors normalized by the filter's own sigma
    have an rms below 1.5 (never overconfident) and above 0.2 (cautious, not blind: its accelerometer
    error of 0.05 m/s^2 leaves room for a sensor far worse than the flight set's) for k_LD and each
    wind component at the end of the glide (850 s)."""
    t, x = track
    rng = np.random.default_rng(5)
    n = 32
    k = int(np.searchsorted(t, 850.0))
    kd, kld = np.exp(0.05 * rng.standard_normal((2, n)))
    we, wn = 10.0 * rng.standard_normal((2, n))
    truth = replace(with_aero_scales(EntryModel(), kd, kld), wind=HorizontalWind(east=we, north=wn))
    e = FlightEstimator(n=n, settings=FlightEstimatorSettings(wind_sigma=10.0))
    for j in range(k + 1):
        xs = np.repeat(x[j : j + 1], n, axis=0)
        e.update(np.full(n, t[j]), xs, _sensed(xs, truth, rng))
    z = np.stack([(e.lift_to_drag_scale - kld) / e.sigma[:, 1], *((e.wind_en - np.stack([we, wn], -1)) / e.wind_sigma).T])
    rms = np.sqrt(np.mean(np.square(z), axis=1))
    assert np.all((rms > 0.2) & (rms < 1.5)), rms


def test_without_wind_states_it_is_the_two_scale_filter_in_logarithms(track):
    """No bands, no wind: on the noise-free constant-scale truth both filters give the same scales."""
    t, x = track
    truth = with_aero_scales(EntryModel(), 1.08, 0.95)
    sensed = _sensed(x[:200], truth, None, errors=False)
    est = _fly([FlightEstimator(), AeroScaleEstimator()], t[:200], x[:200], sensed)
    np.testing.assert_allclose(est[-1, 0, :2], [1.08, 0.95], rtol=2e-4)
    np.testing.assert_allclose(est[-1, 0, :2], est[-1, 1, :2], rtol=5e-4)


def test_settings_and_factory_name_what_is_wrong():
    assert isinstance(make_estimator(EntryModel(), 2, None), AeroScaleEstimator)
    e = make_estimator(EntryModel(), 2, FlightEstimatorSettings.flight_grade())
    assert isinstance(e, FlightEstimator) and e.theta.shape == (2, 4)
    assert e.settings.wind_sigma == FLIGHT_GRADE_ERRORS.wind_mean_mps
    with pytest.raises(ValueError, match="wind_bands need wind_sigma"):
        FlightEstimatorSettings(wind_bands=FLIGHT_GRADE_ERRORS.wind_bands)
    with pytest.raises(ValueError, match="wind_sigma must be None"):
        FlightEstimatorSettings(wind_sigma=-1.0)
    with pytest.raises(ValueError, match="accel_noise must be positive"):
        FlightEstimatorSettings(accel_noise=math.nan)
    with pytest.raises(ValueError, match="density_bands"):
        FlightEstimatorSettings(density_bands=((10e3, 0.02),))


def test_an_update_past_the_bounds_is_refused_and_counted(track):
    """A sensed force the model cannot explain (a wind of 1000 m/s) moves nothing past the bounds."""
    t, x = track
    e = FlightEstimator(settings=FlightEstimatorSettings(wind_sigma=500.0, prior_sigma=50.0))
    truth = replace(EntryModel(), wind=HorizontalWind(east=0.0, north=3000.0))
    sensed = _sensed(x[600:640], truth, None, errors=False)
    for j in range(40):
        e.update(t[600 + j : 601 + j], x[600 + j : 601 + j], sensed[j : j + 1])
    assert e.rejected[0] > 0
    assert np.all(np.abs(e.wind_en) <= 250.0) and np.all(np.isfinite(e.theta))
