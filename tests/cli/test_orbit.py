"""Example 1 (rventry orbit): initial states, measured error behaviour, JSON and plots."""

import json
import math

import numpy as np
import pytest

from rventry_env.cli import main
from rventry_env.core.conversions import cartesian_from_rv_euler, cartesian_from_spherical
from rventry_env.examples import orbit as ex1


@pytest.fixture(scope="module")
def runs():
    """The forms at N = 100, 200 and 1000 (about 0.1 s of integration in all)."""
    return {(form, n): ex1.propagate(form, n) for form in ex1.FORMS for n in (100, 200, 1000)}


def test_both_initial_states_are_one_cartesian_state():
    o = ex1.CircularOrbit()
    r0, v0 = o.initial_cartesian()
    x = o.initial_states()
    for r_e, v_e in (cartesian_from_rv_euler(x["rv_euler"]), cartesian_from_spherical(x["spherical"])):
        np.testing.assert_allclose(r_e, r0, rtol=0, atol=1e-15 * o.radius)
        np.testing.assert_allclose(v_e, v0, rtol=0, atol=1e-15 * o.speed)
    assert np.linalg.norm(x["rv_euler"][1:5]) == pytest.approx(1.0, abs=1e-15)
    assert np.linalg.norm(x["rv_euler"][6:10]) == pytest.approx(1.0, abs=1e-15)
    assert math.degrees(x["spherical"][5]) == pytest.approx(-172.2, abs=1e-12)  # i = 97.8 deg
    # the analytic trajectory starts there and closes after one period
    np.testing.assert_allclose(o.position(0.0), r0, atol=1e-9)
    np.testing.assert_allclose(o.position(o.period), r0, atol=1e-6)
    assert o.period == pytest.approx(5793, abs=1.0)  # the paper's T ~ 5793 s
    assert o.speed == pytest.approx(7562, abs=0.5)  # Table tab:Ex1-IC


def test_rv_euler_is_far_more_accurate_after_the_polar_pass(runs):
    """Measured at N = 1000: ratio of maxima ~900, median ratio after the South-Pole pass ~830."""
    o = ex1.CircularOrbit()
    rv, sph = runs["rv_euler", 1000], runs["spherical", 1000]
    ratio = ex1.pole_pass_ratio(rv, sph, o)
    assert 300 < ratio["ratio_of_max"] < 3000
    assert 300 < ratio["median_ratio_after_south_pole"] < 3000
    # before the pole comes near, the two forms are equally accurate: the pole is the cause
    early = (rv.t > 0) & (rv.t < 0.1 * o.period)
    assert np.all(sph.error[early] / rv.error[early] < 3)
    # absolute levels (rv-Euler 3.6e-5 m, spherical 3.2e-2 m)
    assert 1e-5 < rv.max_error < 1e-4
    assert 1e-2 < sph.max_error < 1e-1


def test_both_forms_converge_at_fourth_order(runs):
    for form in ex1.FORMS:
        ratio = runs[form, 100].max_error / runs[form, 200].max_error
        assert 12 < ratio < 21, (form, ratio)  # 2^4 = 16; measured 16.0 and 16.6


def test_quaternions_are_not_renormalized_and_drift_is_small(runs):
    drift = runs["rv_euler", 100].norm_drift
    assert 0 < drift < 1e-8  # measured 6.7e-10: nonzero, so nothing renormalizes
    assert runs["rv_euler", 1000].norm_drift < 1e-13
    assert runs["spherical", 100].norm_drift == 0.0


def test_default_n_values_are_the_papers():
    n = ex1.default_n_values()
    assert len(n) == 30 and n[0] == 10 and n[-1] == 100_000
    assert all(b > a for a, b in zip(n, n[1:]))
    np.testing.assert_allclose(np.diff(np.log10(n)), 4 / 29, atol=0.02)


def test_cli_writes_the_json_schema_and_both_panels(tmp_path, capsys):
    out = tmp_path / "ex1.json"
    plots = tmp_path / "plots"
    assert main(["orbit", "--n", "20", "--n", "60", "--json", str(out), "--plots", str(plots), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert isinstance(data["period_s"], float) and data["period_s"] == pytest.approx(5792.334, abs=1e-3)
    assert [row["n"] for row in data["results"]] == [20, 60]
    for row in data["results"]:
        assert isinstance(row["n"], int)
        assert isinstance(row["rv_euler_km"], float) and isinstance(row["spherical_km"], float)
        assert 0 < row["rv_euler_km"] < row["spherical_km"]
    assert data["n1000"]["n"] == 1000
    for name in ("ex1_error_vs_time.png", "ex1_max_error_vs_n.png"):
        assert (plots / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "N = 1000: e_r(sph)/e_r(rv)" in capsys.readouterr().out


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: ex1.propagate("polar", 10), "unknown form 'polar'"),
        (lambda: ex1.propagate("rv_euler", 0), "N must be a positive integer, got 0"),
        (lambda: ex1.propagate("rv_euler", 2.5), "N must be a positive integer, got 2.5"),
        (lambda: ex1.CircularOrbit(radius=-1.0), "radius must be positive"),
        (lambda: ex1.CircularOrbit(mu=float("nan")), "mu must be positive and finite"),
        (lambda: ex1.run_example([]), "no step counts N given"),
    ],
)
def test_bad_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_cli_rejects_a_bad_n(capsys):
    with pytest.raises(SystemExit):
        main(["orbit", "--n", "0"])
    assert "argument --n: must be a positive integer, got '0'" in capsys.readouterr().err
