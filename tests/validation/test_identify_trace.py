"""What no candidate explains is traced to a force channel; real-data noise is read as noise.

Records come from the independent Cartesian truth model with effects *outside* the candidate set
(a lift or drag change confined to an altitude band, a lift change below a Mach number, a wind
that reverses with altitude, a side force), with heavy-tailed noise, or with a start that
scatters by kilometres.
"""

import json
import math

import numpy as np
import pytest

from rventry_env.validation import identify_record
from rventry_env.validation.record import RecordError
from rventry_env.validation.search.adequacy import adequacy
from rventry_env.validation.search.statistics import difference_noise, robust_difference_noise
from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record


def _record(tmp_path, specs=(), **kw):
    kw = {"noise": (20.0, 0.2), "duration": 300.0, "rate": 0.5, "seed": 1, **kw}
    return simulate_record(tmp_path / "rec.csv", parse_effects(list(specs)), **kw)


# ------------------------------------------------------------------ heavy-tailed noise


def test_robust_difference_noise_is_the_bulk_scale_of_heavy_tails():
    rng = np.random.default_rng(0)
    t = np.arange(20000.0)
    normal = rng.normal(0.0, 10.0, t.size)
    assert robust_difference_noise(t, normal) == pytest.approx(10.0, rel=0.03)
    assert difference_noise(t, normal) == pytest.approx(10.0, rel=0.03)
    heavy = 10.0 * rng.standard_t(3, t.size) / np.sqrt(3.0)  # standard deviation 10
    # the clipped rms falls below the real scatter, the robust scale is the bulk's (MAD of t(3): 0.655 sd)
    assert difference_noise(t, heavy) < 0.97 * np.std(heavy)
    assert robust_difference_noise(t, heavy) < 0.9 * np.std(heavy)


@pytest.mark.slow
def test_heavy_tailed_noise_without_an_effect_is_none(tmp_path):
    path = _record(tmp_path, rate=10.0, noise_tails="student-t3", seed=1)
    ident = identify_record(path)
    rep = ident.report
    assert rep["effect"] == "none" and not rep["unexplained"], rep["statement"]
    assert rep["attribution"] == [] and rep["trace"] is None
    assert all(g["measure"] == "robust (MAD) scales" for g in rep["adequacy"]["size"].values())
    # the rms test on the same residual calls the tails an effect: the robust one is what decides
    screened_sigma = rep["noise"]["weights"]
    names = list(screened_sigma)
    groups = np.repeat(np.arange(len(names)), 3)
    rms = adequacy(ident.final, screened_sigma, "estimated", names, groups, np.repeat(list(screened_sigma.values()), 3))
    assert rms["unexplained"], rms["size"]


# ------------------------------------------------------------------ a start that scatters by kilometres


def _scattered(tmp_path, altitude_error_m):
    path = _record(tmp_path, observe="reduced", start_scatter=(60.0, 1500.0), noise=(50.0, 0.5), rate=1.0, seed=2)
    side_path = path.with_suffix(".json")
    side = json.loads(side_path.read_text())
    side["entry_state"]["altitude_m"] += altitude_error_m
    side_path.write_text(json.dumps(side))
    return path


def test_a_scattered_start_is_accepted_with_a_warning_and_a_wider_prior(tmp_path):
    rep = identify_record(_scattered(tmp_path, 2000.0), max_effects=0).report
    check = rep["entry_state_check"]
    assert check["window_samples"] >= 8 and check["altitude_noise_m"] > 500.0  # the scatter, not one sample
    assert any("entry_state.altitude_m" in w for w in check["warnings"])
    assert rep["initial_state_bound"]["dh0_m"] > 2000.0  # widened from 5 noise levels (250 m)
    assert rep["initial_state_offsets"]["dh0_m"] == pytest.approx(-2000.0, abs=300.0)  # the fit finds the error
    assert "dh0_m" not in rep["initial_state_at_bound"]


def test_a_grossly_wrong_sidecar_is_refused_naming_the_field(tmp_path):
    # 30 km is beyond any altitude reference (21.4 km, the WGS-84 flattening): not an offset to fit
    with pytest.raises(RecordError, match=r"entry_state\.altitude_m.*scatter of those samples.*beyond 21385 m"):
        identify_record(_scattered(tmp_path, 30000.0), max_effects=0)


# ------------------------------------------------------------------ the trace, one record per channel


def test_band_time_is_the_record_time_in_the_band():
    """The time a record spends in a band: its samples there times the median sampling interval, on
    either axis (a glide that starts at 60 km, dives to 50 km and climbs back to 59 km)."""
    from types import SimpleNamespace

    from rventry_env.validation.trace.attribution import band_time

    t = np.arange(0.0, 300.01, 0.5)
    h = 55e3 + 5e3 * np.cos(2 * np.pi * t / 300.0) - 1e3 * t / 300.0
    record = SimpleNamespace(altitude=lambda: np.concatenate([h, [np.nan]]))
    replay = SimpleNamespace(t_obs=t, rows=np.arange(t.size), record=record)
    assert band_time(replay, "time", 10.0, 20.0) == pytest.approx(10.5)  # 21 samples of 0.5 s
    top = band_time(replay, "altitude", 59.5e3, 60.0e3)  # only the first seconds reach it
    assert top == pytest.approx(0.5 * np.count_nonzero(h >= 59.5e3)) and top < 30.0
    assert band_time(replay, "altitude", 40e3, 70e3) == pytest.approx(0.5 * t.size)
    assert band_time(replay, "altitude", 61e3, 62e3) == 0.0


def _trace(tmp_path, spec):
    rep = identify_record(_record(tmp_path, [spec])).report
    assert rep["unexplained"], rep["statement"]
    assert rep["attribution"], rep["trace"]["statement"]
    return rep


@pytest.mark.slow
def test_drag_in_an_altitude_band_is_traced_to_drag_over_that_band(tmp_path):
    rep = _trace(tmp_path, "drag_band=1.15,50,53")
    (a,) = rep["attribution"]
    assert (a["channel"], a["axis"]) == ("drag", "altitude")
    assert 49e3 <= a["band"][0] and a["band"][1] <= 54e3
    assert a["size"] == pytest.approx(0.15, abs=0.04)
    assert rep["trace"]["after_trace"]["position_rms_m"] < 45.0  # the noise: 20 m per component
    assert any("drag" in p for p in rep["trace"]["points_to"])


@pytest.mark.slow
def test_lift_in_an_altitude_band_is_lift_not_the_atmosphere(tmp_path):
    rep = _trace(tmp_path, "lift_band=0.8,50,53")
    assert [a["channel"] for a in rep["attribution"]] == ["vertical_lift"]
    a = rep["attribution"][0]
    assert a["size"] < 0 and 49e3 <= a["band"][0] and a["band"][1] <= 54e3 and a["axis"] == "altitude"
    assert any("not the atmosphere" in p for p in rep["trace"]["points_to"])


@pytest.mark.slow
def test_a_lift_band_at_50_hz_is_lift_in_that_band_alone(tmp_path):
    """C_L x 0.8 between 50 and 53 km, 15001 samples. A correction over the record's top 0.5 km (its
    first 8 s) lowered the residual by standing in for an entry velocity beyond the bound the first
    samples give it: a 199 m/s wind beside the lift, a claim the record does not make. A band must be
    flown for the trace's time resolution before a correction in it is a finding."""
    from rventry_env.validation.trace.attribution import MIN_BAND_TIME, band_time

    ident = identify_record(_record(tmp_path, ["lift_band=0.8,50,53"], rate=50.0, seed=0))
    rep = ident.report
    assert rep["unexplained"], rep["statement"]
    assert [(a["channel"], a["axis"]) for a in rep["attribution"]] == [("vertical_lift", "altitude")], rep["statement"]
    a = rep["attribution"][0]
    assert a["size"] < 0 and 49e3 <= a["band"][0] and a["band"][1] <= 54e3
    assert band_time(ident.replay, "altitude", *a["band"]) >= MIN_BAND_TIME
    assert rep["trace"]["after_trace"]["position_rms_m"] < 45.0  # the noise: 20 m per component
    assert all(rv["bic_behind"] >= 0 for rv in rep["trace"]["rivals"])  # no refused fit passes for a rival


@pytest.mark.slow
def test_lift_below_a_mach_number_points_to_a_mach_dependent_lift(tmp_path):
    rep = _trace(tmp_path, "mach_lift=0.85,21")
    assert [a["channel"] for a in rep["attribution"]] == ["vertical_lift"]
    assert "below" in rep["attribution"][0]["mach_range_of_band"]
    assert any("C_L varying with Mach" in p for p in rep["trace"]["points_to"])


@pytest.mark.slow
def test_a_side_force_is_traced_across_the_lift(tmp_path):
    rep = identify_record(_record(tmp_path, ["side_force=0.02"])).report
    assert rep["unexplained"]
    (a,) = rep["attribution"]
    # the lift rotated out of its plane by g: a force across it of sin(g) L/D drags, the side force's 0.02
    assert a["channel"] == "lateral_lift" and a["across_over_drag"] == pytest.approx(0.02, abs=0.006)
    assert a["bank_offset_deg"] == pytest.approx(math.degrees(a["size"]))
    assert any("side force" in p for p in rep["trace"]["points_to"])


@pytest.mark.slow
def test_a_wind_that_reverses_with_altitude_is_traced_to_the_wind(tmp_path):
    """A 60 m/s shear on a 0.5 Hz record: the wind is found over altitude, reversing. A lateral lift in
    the same band moves the vehicle the same way within the BIC threshold on this record, so the wind
    may come out as the result or as a rival the record cannot tell from it; either way the report
    names it, with its reversal, and says when the record cannot choose."""
    rep = identify_record(_record(tmp_path, ["wind_shear=60,55"])).report
    assert rep["unexplained"], rep["statement"]
    trace = rep["trace"]
    named = list(rep["attribution"]) + [a for rv in trace["rivals"] for a in rv.get("attribution", [])]
    wind = [a for a in named if a["channel"] == "wind" and a["axis"] == "altitude"]
    assert wind, rep["statement"]
    assert wind[0]["reverses"]
    if not any(a["channel"] == "wind" for a in rep["attribution"]):
        rival = next(rv for rv in trace["rivals"] if rv["channels"] == ["wind"])
        assert 0 <= rival["bic_behind"] < trace["bic_threshold"]
        assert "cannot tell it from wind over altitude" in rep["statement"]
        assert any("shear" in p for p in rival["points_to"])
