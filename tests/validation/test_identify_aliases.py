"""What the record can and cannot tell: aliases, physical plausibility and model adequacy.

Records come from the independent Cartesian truth model (``simulate_record``) with effects the
identification is not told: a mass error, the U.S. Standard Atmosphere 1976 in place of the
exponential one, a Mach-dependent drag, and a clock offset of the record (its time-offset effect).
"""

import json

import numpy as np
import pytest

from rventry_env.validation import identify_record
from rventry_env.validation.search.aliases import admissible, alias_groups, sparsest_equivalent
from rventry_env.validation.search.effects import Structure
from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record


def _run(tmp_path, specs, noise=(20.0, 0.2), duration=200.0, rate=1.0, seed=0, **kw):
    path = simulate_record(tmp_path / "rec.csv", parse_effects(specs), noise=noise, duration=duration, rate=rate,
                           seed=seed)  # fmt: skip
    return identify_record(path, **kw).report


def _explained_by(rep, allowed):
    """Every named effect is in the allowed set or in a listed alias group."""
    listed = {e for g in rep["aliases"] for e in g["effects"]}
    return set(rep["effects"]) <= set(allowed) | listed


# ------------------------------------------------------------------ structure (no flights)

ST = Structure((), density_knots=(40e3, 50e3, 60e3), mach_knots=(10.0, 20.0))


def test_mass_density_level_and_both_coefficients_are_one_direction():
    assert admissible(("mass",), ST, 1.0) and admissible(("lift_coefficient", "drag_coefficient"), ST, 1.0)
    assert not admissible(("mass", "density_profile"), ST, 1.0)  # the profile's level is the mass
    assert not admissible(("mass", "lift_coefficient", "drag_coefficient"), ST, 1.0)
    # a drag-only capsule: C_D and the mass are the same thing
    assert not admissible(("mass", "drag_coefficient"), ST, 0.0)
    assert admissible(("mass", "drag_coefficient"), ST, 1.0)


def test_a_time_offset_is_a_direction_of_its_own():
    """The record's time offset moves the controls' timing, which no force moves: admissible with every
    other effect, never an alias of one."""
    st = Structure((), density_knots=(40e3, 50e3, 60e3), mach_knots=(10.0, 20.0))
    for other in ("wind", "density_profile", "lift_coefficient", "drag_coefficient", "mass", "mach_drag"):
        assert admissible(("time_offset", other), st, 1.0)
        assert sparsest_equivalent((other, "time_offset"), "time_offset", st, 1.0) == (other, "time_offset")
    assert alias_groups({"time_offset_s": 0.5}, ("time_offset",), st, 1.0) == []


def test_adding_an_alias_adds_nothing_and_a_redundant_set_is_thinned():
    assert sparsest_equivalent(("density_profile", "mass"), "mass", ST, 1.0) is None
    # density + C_L + C_D spans what density + C_D spans: the sparsest set with the new effect
    assert sparsest_equivalent(("lift_coefficient", "drag_coefficient", "density_profile"), "density_profile",
                               ST, 1.0) == ("lift_coefficient", "density_profile")  # fmt: skip


def test_alias_members_fly_the_same_accelerations():
    """Each member's parameters give the same rho C_D S / m and rho C_L S / m as the answer."""
    st = Structure(("density_profile", "lift_coefficient"), density_knots=(40e3, 60e3))
    values = {"dlnrho_40.0km": -0.1, "dlnrho_60.0km": 0.05, "cl_scale": 0.96}
    groups = alias_groups(values, st.effects, st, 1.0)
    assert len(groups) == 1
    members = {tuple(m["effects"]): m["parameters"] for m in groups[0]["members"]}
    drag = members[("density_profile", "drag_coefficient")]
    # density + C_L x 0.96 == density x 0.96 + C_D x 1/0.96
    assert drag["cd_scale"] == pytest.approx(1 / 0.96)
    for k in ("dlnrho_40.0km", "dlnrho_60.0km"):
        assert np.exp(drag[k]) * drag["cd_scale"] == pytest.approx(np.exp(values[k]))  # drag acceleration
        assert np.exp(drag[k]) == pytest.approx(np.exp(values[k]) * 0.96)  # lift acceleration (C_L unchanged)


# ------------------------------------------------------------------ flights through the truth model


@pytest.mark.slow
def test_a_mass_error_is_named_with_its_aliases(tmp_path):
    rep = _run(tmp_path, ["mass=1.06"], seed=4)
    assert rep["effects"] == ["mass"], rep["steps"]
    assert rep["parameters"]["mass_scale"] == pytest.approx(1.06, rel=0.005)
    group = rep["aliases"][0]
    assert {"mass", "density_profile", "lift_coefficient", "drag_coefficient"} <= set(group["effects"])
    assert group["drag_acceleration_scale"] == pytest.approx(1 / 1.06, rel=0.005)
    both = next(m for m in group["members"] if m["effects"] == ["lift_coefficient", "drag_coefficient"])
    assert both["tied"] and both["parameters"]["cd_scale"] == pytest.approx(1 / 1.06, rel=0.005)
    assert both["parameters"]["cl_scale"] == pytest.approx(both["parameters"]["cd_scale"])
    assert not rep["unexplained"]


@pytest.mark.slow
@pytest.mark.parametrize("rate", [10.0, 1.0])
@pytest.mark.parametrize("specs", [["us76_density"], ["us76_density", "lift_coefficient=0.96"]],
                         ids=["us76", "us76+cl0.96"])  # fmt: skip
def test_us76_atmosphere_is_a_density_profile_never_j2(tmp_path, specs, rate):
    rep = _run(tmp_path, specs, rate=rate, duration=200.0, seed=int(rate) + len(specs))
    assert "j2_gravity" not in rep["effects"]
    assert "density_profile" in rep["effects"]
    true_set = {"density_profile"} | ({"lift_coefficient"} if len(specs) > 1 else set())
    assert _explained_by(rep, true_set), (rep["effects"], rep["aliases"])
    assert not rep["unexplained"], rep["adequacy"]["statement"]
    if len(specs) > 1:
        # the lift change, or its alias C_D x 1/0.96 with the density level x 0.96
        assert rep["identifiable"]["lift_to_drag_scale"] == pytest.approx(0.96, rel=0.01)


@pytest.mark.slow
def test_a_mach_dependent_drag_is_named(tmp_path):
    rep = _run(tmp_path, ["mach_drag=0.15"], duration=300.0, seed=3)
    assert "mach_drag" in rep["effects"], rep["steps"]
    assert set(rep["effects"]) <= {"mach_drag", "drag_coefficient"}  # a Mach law's level is a C_D scale
    assert not rep["unexplained"]


@pytest.mark.slow
@pytest.mark.parametrize("offset,seed", [(0.5, 5), (-0.5, 3)], ids=["early", "late"])
def test_a_clock_offset_is_the_records_time_offset_not_a_wind(tmp_path, offset, seed):
    """State rows tagged early (or late) against the controls: the record's time offset, found with its
    uncertainty, and nothing invented in the world for it (no wind, no density profile, no trace)."""
    rep = _run(tmp_path, [f"time_offset={offset}"], duration=300.0, seed=seed)
    assert rep["effects"] == ["time_offset"], rep["steps"]
    assert not rep["unexplained"], rep["adequacy"]["statement"]
    found = rep["record_effects"]["time_offset"]
    assert 0 < found["stderr_s"] < 0.02
    assert abs(found["value_s"] - offset) <= 2 * found["stderr_s"], found
    assert rep["parameters"] == {"time_offset_s": found["value_s"]}
    assert rep["parameter_stderr"] == {"time_offset_s": found["stderr_s"]}
    # the identified model is the current one: the offset is how the record reads the flight
    assert rep["model"]["wind"] is None and rep["model"]["atmosphere"]["type"] == "ExponentialAtmosphere"
    assert rep["trace"] is None and rep["attribution"] == []
    assert "clock offset of the record" in rep["statement"]
    assert rep["after"]["position_rms_m"] < 1.25 * np.sqrt(3) * 20.0
    assert rep["whiteness"]["after"]["ljung_box_p"] > 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("specs,tails", [([], "normal"), ([], "student-t3"), (["drag_coefficient=1.1"], "normal")],
                         ids=["none", "none-t3", "cd1.1"])  # fmt: skip
def test_a_record_on_one_clock_gets_no_time_offset(tmp_path, specs, tails):
    """No false alarm: a record whose states and controls share their time tags is given no time offset,
    and the offset fitted alone on a clean record is zero within its uncertainty."""
    path = simulate_record(tmp_path / "rec.csv", parse_effects(specs), noise=(20.0, 0.2), duration=300.0, rate=1.0,
                           seed=11, noise_tails=tails)  # fmt: skip
    rep = identify_record(path).report
    assert "time_offset" not in rep["effects"] and rep["record_effects"] == {}, rep["steps"]
    assert rep["effects"] == [s.split("=")[0] for s in specs] and not rep["unexplained"]
    if not specs:
        alone = rep["candidates"]["time_offset"]
        assert abs(alone["parameters"]["time_offset_s"]) <= 3 * alone["stderr"]["time_offset_s"], alone


@pytest.mark.slow
def test_declared_noise_sets_the_adequacy_test(tmp_path):
    path = simulate_record(tmp_path / "rec.csv", parse_effects(["drag_coefficient=1.1"]), noise=(20.0, 0.2),
                           duration=200.0, rate=0.5, seed=8)  # fmt: skip
    right = identify_record(path, h_max=2.0, noise=(20.0, 0.2)).report
    assert right["adequacy"]["noise_source"] == "declared" and not right["unexplained"]
    assert right["effects"] == ["drag_coefficient"]
    # a noise declared 3 times too small: the residual is not that noise, and the report says so
    small = identify_record(path, h_max=2.0, noise=(6.0, 0.06)).report
    assert small["unexplained"] is True and small["effect"] != "none"
    assert not small["adequacy"]["size"]["position"]["consistent"]
    assert "declared noise" in small["statement"]
    # the sidecar can declare it too
    (tmp_path / "rec.json").write_text(json.dumps({"noise": {"position_m": 20.0, "velocity_mps": 0.2}}))
    side = identify_record(path, h_max=2.0).report
    assert side["noise"]["declared"] == {"position": 20.0, "velocity": 0.2}


@pytest.mark.slow
def test_a_wrong_j2_is_never_accepted(tmp_path):
    """J2 is tested at its known value; a record that would prefer another value gets it marked implausible."""
    rep = _run(tmp_path, ["j2_gravity=-1e-3"], noise=(3.0, 0.03), rate=0.5, seed=6, h_max=2.0)
    assert "j2_gravity" not in rep["effects"]
    j2_row = next(r for r in rep["ranking"] if r["effect"] == "j2_gravity")
    assert not j2_row["credible"]
    assert rep["unexplained"] is True  # and the wrong-signed J2 the record holds is not explained away


def _member_prediction(ident, member):
    """The replay of an alias member, from the accepted fit's entry state."""
    from rventry_env.validation.search.effects import build_model

    final = ident.final
    st = final.structure
    values = {k: v for k, v in final.parameters().items()
              if k not in ("mass_scale", "cd_scale", "cl_scale") and not k.startswith("dlnrho_")}  # fmt: skip
    params = dict(member["parameters"])
    level = params.pop("density_level_factor", None)
    if level is not None:
        params.update({f"dlnrho_{k / 1e3:.1f}km": np.log(level) for k in st.density_knots})
    values.update(params)
    model = build_model(ident.setup, Structure(tuple(member["effects"]), st.density_knots, st.mach_knots), values)
    n0 = final.extra["n_initial"]
    return ident.replay.predict(model, final.values[None, :n0])[..., 0]


@pytest.mark.parametrize("spec, answer", [("drag_coefficient=1.05", "drag_coefficient"), ("mass=0.95", "mass")])
def test_every_listed_alias_member_flies_the_accepted_trajectory(tmp_path, spec, answer):
    path = simulate_record(tmp_path / "rec.csv", parse_effects([spec]), noise=(20.0, 0.2), duration=200.0, rate=0.5,
                           seed=3)  # fmt: skip
    ident = identify_record(path)
    rep = ident.report
    assert rep["effects"] == [answer], rep["steps"]
    members = rep["aliases"][0]["members"]
    accepted = _member_prediction(ident, {"effects": rep["effects"], "parameters": rep["parameters"]})
    scale = np.nanmax(np.abs(accepted[:, :3]))
    for m in members:
        pred = _member_prediction(ident, m)
        assert np.nanmax(np.abs(pred - accepted)[:, :3]) < 1e-9 * scale, m  # positions, to round-off
        assert np.nanmax(np.abs(pred - accepted)[:, 3:]) < 1e-6, m  # velocities, m/s
    # the mass member of C_D x 1.05 is the mass x 1/1.05 (not x 1.05); of a light vehicle, the mass itself
    mass = next(m for m in members if "mass" in m["effects"])
    truth = 1 / 1.05 if answer == "drag_coefficient" else 0.95
    assert mass["parameters"]["mass_scale"] == pytest.approx(truth, rel=0.01)


@pytest.mark.slow
def test_a_true_pair_is_found_when_no_single_candidate_is_credible(tmp_path):
    """mass x 0.95 + J2: each alone ends on its entry-state bound; the pair fits to the noise."""
    rep = _run(tmp_path, ["mass=0.95", "j2_gravity"], noise=(5.0, 0.05), rate=0.5, seed=1)
    assert sorted(rep["effects"]) == ["j2_gravity", "mass"], rep["steps"]
    assert rep["parameters"]["mass_scale"] == pytest.approx(0.95, rel=0.002)
    assert any(s["step"] == "pairs" and s["accepted"] for s in rep["steps"])
    assert not rep["unexplained"], rep["statement"]


def test_forward_selection_stops_at_its_replay_budget(tmp_path, monkeypatch):
    from rventry_env.validation.search import phases

    monkeypatch.setattr(phases, "SEARCH_REPLAY_BUDGET", 0)
    rep = _run(tmp_path, ["drag_coefficient=1.1", "wind=120"], noise=(10.0, 0.1), rate=0.5)
    stopped = [s for s in rep["steps"] if s["step"] == "stopped"]
    assert len(stopped) == 1 and "budget" in stopped[0]["note"] and stopped[0]["from"]
    assert not [s for s in rep["steps"] if isinstance(s["step"], int) and s["step"] > 1]  # no step after it


def test_density_knots_go_as_fine_as_the_record_resolves():
    from rventry_env.validation.search.effects import knot_counts

    dense = np.linspace(60e3, 40e3, 3001)
    assert max(knot_counts(dense)) == 21  # 20 km: knots 1 km apart, the finest the record resolves
    assert 16 in knot_counts(dense) and 24 not in knot_counts(dense)  # 24 would be 0.87 km apart
    assert max(knot_counts(dense[::60])) == 5  # 51 samples: at most 5 knots, 10 samples each
    assert knot_counts(np.full(100, 50e3)) == (2,)  # a level flight resolves no shape
