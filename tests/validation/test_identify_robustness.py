"""The identification on awkward but legal records: outliers, very few rows, strict JSON, no effect asked for."""

import json
import math

import numpy as np
import pytest

from rventry_env.cli import main as rventry_main
from rventry_env.validation import identify_record
from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record


def _strict_json(path):
    def bad(name):
        raise AssertionError(f"{name} in a report")

    return json.loads(path.read_text(), parse_constant=bad)


def _clean(tmp_path, **kw):
    args = {"noise": (20.0, 0.2), "duration": 200.0, "rate": 0.5, "seed": 3} | kw
    return simulate_record(tmp_path / "rec.csv", parse_effects([]), **args)


@pytest.mark.slow
def test_one_gross_outlier_is_rejected_not_explained(tmp_path):
    """A 30 km jump in one row: rejected and reported by its file line; the clean answer stands."""
    path = _clean(tmp_path)
    lines = path.read_text().splitlines()
    fields = lines[41].split(",")
    fields[1] = repr(float(fields[1]) + 30e3)  # x_m of the data row on file line 42
    lines[41] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    rep = identify_record(path, h_max=2.0).report
    assert rep["effect"] == "none" and rep["effects"] == [] and not rep["unexplained"]
    assert [(r["row"], r["group"]) for r in rep["rejected_outliers"]] == [(42, "position")]
    assert rep["rejected_outliers"][0]["deviation"] == pytest.approx(30e3, rel=0.05)


@pytest.mark.slow
def test_the_clean_record_gives_none_with_nothing_rejected(tmp_path):
    rep = identify_record(_clean(tmp_path), h_max=2.0).report
    assert rep["effect"] == "none" and not rep["rejected_outliers"] and not rep["unexplained"]
    assert rep["aliases"] == [] and rep["before"] == rep["after"]


@pytest.mark.slow
def test_five_rows_run_to_a_whole_report(tmp_path, capsys):
    path = _clean(tmp_path, duration=8.0, rate=0.5)
    assert len(path.read_text().splitlines()) == 6
    out = tmp_path / "rep.json"
    code = rventry_main(["identify", str(path), "--json", str(out), "--quiet", "--h-max", "2"])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert code in (0, 2)
    if code == 0:
        rep = _strict_json(out)
        assert rep["record"]["samples"] == 5 and "effect:" in captured.out


@pytest.mark.slow
def test_max_effects_zero_adds_nothing_and_reports_strict_json(tmp_path, capsys):
    path = simulate_record(tmp_path / "rec.csv", parse_effects(["drag_coefficient=1.1"]), noise=(20.0, 0.2),
                           duration=200.0, rate=0.5, seed=1)  # fmt: skip
    out = tmp_path / "rep.json"
    assert rventry_main(["identify", str(path), "--json", str(out), "--quiet", "--h-max", "2",
                         "--max-effects", "0", "--model-out", str(tmp_path / "m.json")]) == 0  # fmt: skip
    rep = _strict_json(out)
    assert rep["effects"] == [] and rep["effect"] == "unexplained" and rep["unexplained"] is True
    assert rep["ranking"][0]["effect"] == "drag_coefficient"  # ranked, not added
    assert "UNEXPLAINED" in capsys.readouterr().out


def test_progress_lines_do_not_wrap(tmp_path, capfd):
    from rventry_env.validation.identify import _progress

    say = _progress(True)
    long = "step 3: " + " + ".join(["density_profile", "lift_coefficient", "drag_coefficient"] * 4)
    say(long)
    err = capfd.readouterr().err
    assert len(err.strip().splitlines()) == 1 and long in err


def test_residual_plot_lines_break_at_gaps():
    from rventry_env.validation.report.plots import with_gap_breaks

    t = np.array([0.0, 1, 2, 3, 50, 51, 52])
    y = np.array([1.0, 2, np.nan, 4, 5, 6, 7])
    tt, yy = with_gap_breaks(t, y)
    # no segment from 1 to 3 (a missing value) nor from 3 to 50 (a data gap)
    segments = np.split(tt, np.flatnonzero(np.isnan(tt)))
    assert [list(s[~np.isnan(s)]) for s in segments] == [[0.0, 1.0], [3.0], [50.0, 51.0, 52.0]]
    assert math.isnan(yy[2]) and len(tt) == len(yy)
