"""The solver on Betts' Space Shuttle maximum-crossrange re-entry (Example 6.1)."""

import pytest

from rventry_env.reference.betts_shuttle import PUBLISHED, heating_rate, shuttle_guess, solve_shuttle


@pytest.mark.slow
@pytest.mark.parametrize("limit", [None, 70.0])
def test_matches_published_optimum_within_0_1_percent(limit):
    res = solve_shuttle(limit, mesh_tolerance=1e-6)
    assert res.converged and res.mesh_error <= 1e-6
    assert res.published == PUBLISHED["no_heating_limit" if limit is None else "heating_limit_70"]
    assert res.tf_rel_error < 1e-3, (res.tf_s, res.published)
    assert res.latitude_rel_error < 1e-3, (res.latitude_deg, res.published)


def test_heating_limit_is_active_in_the_limited_case():
    """The limit matters: the unlimited optimum's guess path exceeds 70 BTU/ft^2/s somewhere."""
    g = shuttle_guess()
    q_btu = heating_rate(g.x.T, g.u.T) / 11356.526682226975
    assert q_btu.max() > 70.0


def test_bad_heating_limit_is_rejected():
    from rventry_env.reference.betts_shuttle import shuttle_problem

    with pytest.raises(ValueError, match="heating limit"):
        shuttle_problem(-5.0)


@pytest.mark.slow
def test_default_tolerance_matches_published_optimum_without_heating_limit():
    """At the default mesh tolerance (1e-7) the refined passes start warm from a coarse point; a
    warm pass that IPOPT cannot finish is solved again cold rather than returned as the answer."""
    res = solve_shuttle(None)
    assert res.converged and res.mesh_error <= 1e-7, (res.nlp_iterations, res.mesh_error)
    assert res.tf_rel_error < 1e-4, (res.tf_s, res.published)
    assert res.latitude_rel_error < 1e-4, (res.latitude_deg, res.published)
