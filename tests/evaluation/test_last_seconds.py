"""studies/last_seconds.py: where flights stand seconds before their impact."""

import numpy as np
import pytest
from script_modules import load_script  # (tests/ is on the path)


@pytest.fixture(scope="module")
def ls():
    return load_script("studies/last_seconds")


def test_the_reference_read_as_a_flight_gives_its_own_states_before_its_end(ls):
    from rventry_env.physics.model import EntryModel
    from rventry_env.reference import load_reference

    ref, radius = load_reference(), EntryModel().planet.radius
    r = ls.reference_flight()
    assert r["duration_s"] == pytest.approx(ref.tf - ref.t0, abs=1e-9)
    k = ls.BEFORE_S.index(60.0)
    x = ref.state(np.array([ref.tf - 60.0]))[0]
    # states each second, read between them: to the interpolation's error over 1 s
    assert r["altitude_km"][k] == pytest.approx((x[0] - radius) / 1e3, abs=0.05)
    assert r["speed_mps"][k] == pytest.approx(x[5], abs=1.0)
    assert r["from_vertical_deg"][-1] < 1.0  # the reference ends vertical (its terminal condition)
    assert 80.0 < r["from_vertical_deg"][k] < 95.0  # and flies level a minute before (its pull-up)


def test_a_flight_is_read_up_to_its_last_finite_state_and_not_before_its_start(ls):
    t = np.array([0.0, 10.0, 20.0, 30.0, np.nan, np.nan])
    x = np.zeros((6, 12))
    x[:, 0] = 6378137.0 + np.array([30e3, 20e3, 10e3, 0.0, 0.0, 0.0])
    x[:, 5] = [3000.0, 2000.0, 1500.0, 1000.0, 0.0, 0.0]
    x[:, 6] = np.sin(np.radians(45.0))  # 2 asin(sin 45 deg) = 90 deg from vertical: level flight
    x[4:, :] = np.nan  # past the flight's end, as a batch pads it
    f = ls.read_flight(t, x, 6378137.0, before_s=(40.0, 15.0, 0.0))
    assert np.isnan(f["altitude_km"][0])  # 40 s before a 30 s flight's end: before its start
    assert f["altitude_km"][1] == pytest.approx(15.0) and f["speed_mps"][1] == pytest.approx(1750.0)
    assert f["altitude_km"][2] == pytest.approx(0.0) and f["duration_s"] == 30.0
    assert f["from_vertical_deg"][2] == pytest.approx(90.0)
    s = ls.summarize([f, f])
    assert s["episodes"] == 2 and s["altitude_km"]["p50"][1] == pytest.approx(15.0)
    assert s["altitude_km"]["p50"][0] is None  # no flight reached that far back: none, not NaN in the JSON
    with pytest.raises(ValueError, match=r"t \(n,\) and x \(n, 12\)"):
        ls.read_flight(t, x[:, :6], 6378137.0)
    with pytest.raises(ValueError, match="at least two finite"):
        ls.read_flight(np.array([0.0, np.nan]), np.full((2, 12), np.nan), 6378137.0)
