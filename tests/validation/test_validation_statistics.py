"""Noise estimation, BIC and whiteness, on series whose answers are known."""

import math

import numpy as np
import pytest

from rventry_env.validation.search.statistics import (
    bic,
    bic_effective,
    difference_noise,
    effective_size,
    whiteness,
)


def test_difference_noise_recovers_sigma_under_a_smooth_signal():
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 400.0)
    signal = 6.4e6 + 7000.0 * t + 3e3 * np.sin(2 * np.pi * t / 150)
    for sigma in (0.5, 20.0):
        assert difference_noise(t, signal + rng.normal(0, sigma, t.size)) == pytest.approx(sigma, rel=0.13)


def test_difference_noise_skips_gaps_and_refuses_sparse_records():
    rng = np.random.default_rng(1)
    t = np.arange(200.0)
    y = rng.normal(0, 3.0, t.size)
    y[50:55] = np.nan
    assert difference_noise(t, y) == pytest.approx(3.0, rel=0.2)  # 3 sigma of the estimator at n = 190
    assert math.isnan(difference_noise(np.array([0.0, 1, 5, 6, 20, 21, 22]), np.zeros(7)))


def test_whiteness_tells_white_from_correlated():
    rng = np.random.default_rng(2)
    e = rng.normal(size=(500, 2))
    w = whiteness(e)
    assert abs(w["lag1_autocorrelation"]) < 0.1 and w["ljung_box_p"] > 0.01
    ar = np.zeros(500)
    for k in range(1, 500):
        ar[k] = 0.8 * ar[k - 1] + rng.normal()
    w = whiteness(ar[:, None])
    assert w["lag1_autocorrelation"] == pytest.approx(0.8, abs=0.08) and w["ljung_box_p"] < 1e-6


def test_bic_penalises_parameters_and_rewards_fit():
    assert bic([100.0], [100], 3) > bic([100.0], [100], 2)
    assert bic([50.0], [100], 3) < bic([100.0], [100], 2)
    assert bic_effective([100.0], [100], 2, 100.0) == pytest.approx(bic([100.0], [100], 2))
    assert effective_size(100, 0.0) == 100 and effective_size(100, 0.8) == pytest.approx(100 * 0.2 / 1.8)
