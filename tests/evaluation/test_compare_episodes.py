"""studies/compare_episodes.py: two policies on the same episodes, paired."""

import json
import math

import pytest
from script_modules import load_script  # (tests/ is on the path)

THRESHOLDS = {"miss_km": 5.0, "vertical_error_deg": 5.0, "speed_error_mps": 100.0, "constraint_tolerance": 0.01}


@pytest.fixture(scope="module")
def ce():
    return load_script("studies/compare_episodes")


def _report(successes, seeds=None, agent="a"):
    eps = []
    for i, ok in enumerate(successes):
        eps.append({"seed": (seeds or range(len(successes)))[i], "dispersion": {"density": 0.01 * i}, "success": ok,
                    "miss_km": 1.0 if ok else 7.0, "vertical_error_deg": 2.0 if ok else 6.0,
                    "speed_error_mps": -20.0 if ok else -150.0, "constraint_violation": 0.0,
                    "max_load_factor_g": 11.5, "min_dynamic_pressure_pa": 13000.0})  # fmt: skip
    return {"agent": agent, "summary": {"success_thresholds": THRESHOLDS}, "episodes": eps, "seed": 0}


def test_paired_counts_and_the_exact_sign_test(ce):
    a = _report([True] * 10 + [True] * 4 + [False] * 1 + [False] * 5)
    b = _report([True] * 10 + [False] * 4 + [True] * 1 + [False] * 5)
    p = ce.paired(a, b)
    assert (p["both"], p["only_a"], p["only_b"], p["neither"]) == (10, 4, 1, 5)
    # 4 against 1 of 5 discordant: two-sided exact binomial, 2 * P(X >= 4 | n = 5, 1/2) = 2 * 6 / 32
    assert p["sign_test_p"] == pytest.approx(2 * (math.comb(5, 4) + math.comb(5, 5)) / 32)
    assert ce.paired(a, a)["sign_test_p"] == 1.0  # nothing discordant


def test_failures_are_counted_by_criterion(ce):
    f = ce.failures(_report([True, False, False]))
    assert f == {"failures": 2, "miss": 2, "vertical": 2, "speed": 2, "path_bound": 0}


def test_reports_of_different_episodes_are_refused(ce):
    with pytest.raises(ValueError, match="did not fly the same episodes"):
        ce.paired(_report([True, False]), _report([True, False], seeds=[5, 6]))


def test_a_file_that_is_not_a_report_is_refused_by_name(ce, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"summary": {}}))
    with pytest.raises(ValueError, match=r"bad\.json is not an `rventry evaluate --json` report"):
        ce.load_report(str(bad))


def test_the_command_writes_the_figure_and_the_counts(ce, tmp_path):
    for name, s in (("a.json", [True, True, False]), ("b.json", [True, False, False])):
        (tmp_path / name).write_text(json.dumps(_report(s)))
    png, js = tmp_path / "c.png", tmp_path / "c.json"
    assert ce.main([str(tmp_path / "a.json"), str(tmp_path / "b.json"), "--png", str(png), "--json", str(js)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert json.loads(js.read_text())["paired"]["only_a"] == 1
