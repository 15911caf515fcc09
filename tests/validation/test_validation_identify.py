"""The validation loop on synthetic records whose effect it is not told.

Records come from ``simulate_record`` (the independent Cartesian truth model,
written without a sidecar, effects only in ``<record>.truth.json``), 200 s at
0.5 Hz so the suite stays fast; the replay then steps at 2 s.
"""

import json
import math

import numpy as np
import pytest

from rventry_env.cli import main as rventry_main
from rventry_env.validation import identify_record, load_model
from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record

DURATION, RATE, H_MAX = 200.0, 0.5, 2.0


def _run(tmp_path, specs, noise, seed, observe="ecef"):
    path = simulate_record(tmp_path / "rec.csv", parse_effects(specs), noise=noise, duration=DURATION,
                           rate=RATE, seed=seed, observe=observe)  # fmt: skip
    return identify_record(path, h_max=H_MAX).report


def _truth_density_log_ratio(h, amplitude):
    return amplitude * np.sin(2 * np.pi * (np.asarray(h) - 30e3) / 80e3)


def _check_parameters(effect, value, params):
    if effect == "lift_coefficient":
        assert params["cl_scale"] == pytest.approx(value, rel=0.01)
    elif effect == "drag_coefficient":
        assert params["cd_scale"] == pytest.approx(value, rel=0.01)
    elif effect == "j2_gravity":
        assert params["j2"] == pytest.approx(value, rel=0.1)
    elif effect == "wind":
        east, north = (list(value) + [0.0])[:2]
        assert abs(params["wind_east_mps"] - east) < 8 and abs(params["wind_north_mps"] - north) < 8
    elif effect == "density_profile":
        for name, v in params.items():
            h = float(name[len("dlnrho_"):-2]) * 1e3
            assert v == pytest.approx(_truth_density_log_ratio(h, value), abs=0.03), name


# effect, value, noise (position m, velocity m/s): several magnitudes and noise levels each
CASES = [
    ("lift_coefficient", 0.9, (20.0, 0.2)),
    ("lift_coefficient", 1.15, (50.0, 0.5)),
    ("drag_coefficient", 1.1, (20.0, 0.2)),
    ("drag_coefficient", 0.94, (5.0, 0.05)),
    ("density_profile", 0.2, (20.0, 0.2)),
    ("density_profile", -0.35, (50.0, 0.5)),
    ("wind", (150.0,), (10.0, 0.1)),
    ("wind", (-60.0, 90.0), (5.0, 0.05)),
    ("j2_gravity", 1.08262668e-3, (3.0, 0.03)),
]


@pytest.mark.parametrize("effect,value,noise", CASES, ids=[f"{c[0]}={c[1]}@{c[2][0]:g}m" for c in CASES])
def test_names_the_undeclared_effect(tmp_path, effect, value, noise):
    text = ",".join(str(v) for v in value) if isinstance(value, tuple) else repr(value)
    rep = _run(tmp_path, [f"{effect}={text}"], noise, seed=len(text))
    assert rep["effect"] == effect, rep["ranking"]
    assert rep["effects"] == [effect], rep["steps"]
    assert rep["margin_to_runner_up"] > 10
    before, after = rep["before"], rep["after"]
    assert before["position_rms_m"] >= 5 * after["position_rms_m"], (before, after)
    # after: the residual is the noise (3 components of sigma), and white
    assert rep["after"]["position_rms_m"] < 1.25 * math.sqrt(3) * noise[0]
    assert rep["whiteness"]["after"]["ljung_box_p"] > 1e-3
    w = rep["whiteness"]
    assert w["before"]["lag1_autocorrelation"] > w["after"]["lag1_autocorrelation"]
    _check_parameters(effect, value, rep["parameters"])


def test_no_effect_gives_none(tmp_path):
    rep = _run(tmp_path, [], (20.0, 0.2), seed=3)
    assert rep["effect"] == "none" and rep["effects"] == []
    assert rep["improvement_over_baseline"] <= rep["bic_threshold"]
    assert rep["before"] == rep["after"]
    assert rep["parameters"] == {}
    # the noise estimated from the record alone is close to the truth
    assert rep["noise"]["difference_estimate"]["position"] == pytest.approx(20.0, rel=0.2)


TWO = [
    (["drag_coefficient=1.1", "wind=120"], (10.0, 0.1), {"drag_coefficient": 1.1, "wind": (120.0,)}),
    (["lift_coefficient=0.92", "j2_gravity"], (5.0, 0.05), {"lift_coefficient": 0.92, "j2_gravity": 1.08262668e-3}),
    (["j2_gravity", "drag_coefficient=1.06"], (5.0, 0.05), {"drag_coefficient": 1.06, "j2_gravity": 1.08262668e-3}),
]


@pytest.mark.parametrize("specs,noise,truth", TWO, ids=["+".join(t[0]) for t in TWO])
def test_two_effects_are_both_found(tmp_path, specs, noise, truth):
    rep = _run(tmp_path, specs, noise, seed=5)
    assert sorted(rep["effects"]) == sorted(truth), rep["steps"]
    assert not rep["unexplained"]
    assert rep["before"]["position_rms_m"] >= 5 * rep["after"]["position_rms_m"]
    for effect, value in truth.items():
        _check_parameters(effect, value, rep["parameters"])


def test_clean_record_at_10_hz_gives_none(tmp_path):
    path = simulate_record(tmp_path / "rec.csv", {}, noise=(20.0, 0.2), duration=100.0, rate=10.0, seed=9)
    rep = identify_record(path).report
    assert rep["effect"] == "none" and not rep["unexplained"] and rep["record"]["samples"] == 1001


def test_cli_on_a_reduced_record(tmp_path, capsys):
    """simulate-record -> identify through the command line, altitude and speed only (entry-state sidecar)."""
    rec = tmp_path / "red.csv"
    assert rventry_main(["simulate-record", "--effect", "drag_coefficient=1.1", "--noise", "20,0.2",
                         "--duration", str(DURATION), "--rate", str(RATE), "--observe", "reduced",
                         "--out", str(rec)]) == 0  # fmt: skip
    assert (tmp_path / "red.json").is_file() and (tmp_path / "red.truth.json").is_file()
    assert "drag" not in (tmp_path / "red.json").read_text()  # the sidecar does not tell the effect
    out = tmp_path / "out"
    assert rventry_main(["identify", str(rec), "--json", str(out / "rep.json"), "--plots", str(out / "plots"),
                         "--model-out", str(out / "model.json"), "--h-max", str(H_MAX),
                         "--quiet"]) == 0  # fmt: skip
    rep = json.loads((out / "rep.json").read_text())
    assert rep["effect"] == "drag_coefficient"
    assert set(rep) >= {"effect", "effects", "parameters", "ranking", "before", "after"}
    assert {"altitude_rms_m", "altitude_max_m", "speed_rms_mps"} <= set(rep["before"])
    assert "position_rms_m" not in rep["after"]
    assert rep["before"]["altitude_rms_m"] >= 5 * rep["after"]["altitude_rms_m"]
    assert [r["effect"] for r in rep["ranking"]][0] == "drag_coefficient"
    assert rep["ranking"][0]["delta_bic"] == 0 and all(r["delta_bic"] > 0 for r in rep["ranking"][1:])
    for png in ("residuals.png", "ranking.png"):
        assert (out / "plots" / png).stat().st_size > 10_000
    model = load_model(out / "model.json")
    assert model.vehicle.aerodynamics.cd_scale == pytest.approx(rep["parameters"]["cd_scale"])
    assert "effect: drag_coefficient" in capsys.readouterr().out


def test_gaps_are_handled_and_reported(tmp_path):
    """Empty fields (scattered in every column, and a 20 s block of observations) leave the answer unchanged.

    Not a 20 s block of *controls*: bridging it by interpolation is a real model
    error (here worth a spurious J2 of 3e-4), which the notes report as the
    longest control gap.
    """
    import csv

    path = simulate_record(tmp_path / "rec.csv", parse_effects(["drag_coefficient=1.1"]), noise=(20.0, 0.2),
                           duration=DURATION, rate=RATE, seed=11)  # fmt: skip
    rows = list(csv.reader(open(path)))
    header, data = rows[0], rows[1:]
    rng = np.random.default_rng(0)
    for i in range(1, len(data)):  # keep the first row complete: the replay starts there
        for j in range(1, len(header)):
            is_control = header[j] in ("alpha_rad", "bank_rad")
            if rng.random() < 0.1 or (40 <= i < 50 and not is_control):
                data[i][j] = ""
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows([header] + data)
    rep = identify_record(path, h_max=H_MAX).report
    assert rep["effect"] == "drag_coefficient" and rep["effects"] == ["drag_coefficient"]
    assert rep["parameters"]["cd_scale"] == pytest.approx(1.1, rel=0.01)
    assert rep["before"]["position_rms_m"] >= 5 * rep["after"]["position_rms_m"]
    notes = " ".join(rep["record"]["notes"])
    assert "empty observation field(s) in rows with observations are left out" in notes
    assert "10 row(s) carry only controls" in notes
