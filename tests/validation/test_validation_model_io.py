"""The identified model as a value: JSON round trip, report loading, and the Gymnasium env flying it."""

import json

import numpy as np
import pytest

from rventry_env.physics import (
    CAVHAerodynamics,
    ConstantAerodynamics,
    DensityCorrection,
    EntryModel,
    ExponentialAtmosphere,
    HorizontalWind,
    J2Gravity,
    ScaledAerodynamics,
    Vehicle,
)
from rventry_env.validation import identified_model, load_model, save_model
from rventry_env.validation.record import FlightRecord
from rventry_env.validation.replay.replay_setup import replay_setup
from rventry_env.validation.report.model_io import model_from_dict, model_to_dict
from rventry_env.validation.search.effects import Structure, build_model, structure_parameters

FULL = EntryModel(
    gravity=J2Gravity(j2=1.1e-3),
    atmosphere=DensityCorrection(ExponentialAtmosphere(), (40e3, 50e3, 60e3), (0.1, -0.05, 0.2)),
    vehicle=Vehicle(aerodynamics=ScaledAerodynamics(CAVHAerodynamics(), 0.9, 1.1)),
    wind=HorizontalWind(30.0, -10.0),
)


def test_round_trip(tmp_path):
    path = save_model(FULL, tmp_path / "m.json")
    assert load_model(path) == FULL
    aero = ScaledAerodynamics(ConstantAerodynamics(1.2891, 0.368), 1.04)
    capsule = EntryModel(vehicle=Vehicle(5424.6, 12.0171, aero))
    assert model_from_dict(json.loads(json.dumps(model_to_dict(capsule)))) == capsule
    report = {"effect": "wind", "model": model_to_dict(FULL)}
    assert identified_model(report) == FULL
    (tmp_path / "report.json").write_text(json.dumps(report))
    assert identified_model(tmp_path / "report.json") == FULL


def test_loading_rejects_unknown_parts():
    d = model_to_dict(FULL)
    d["wind"]["type"] = "os.system"
    with pytest.raises(ValueError, match="unknown model part type"):
        model_from_dict(d)


def test_effects_compose_through_the_physics_parts():
    rec = FlightRecord(t=np.arange(5.0), kind="ecef", observations=np.zeros((5, 6)), observation_names=())
    setup = replay_setup(rec)
    st = Structure(("j2_gravity", "density_profile", "drag_coefficient", "wind", "mass", "mach_drag"),
                   density_knots=(40e3, 60e3), mach_knots=(10.0, 25.0))  # fmt: skip
    values = {p.name: p.start for p in structure_parameters(setup, st)}
    assert build_model(setup, st, values).wind == HorizontalWind(0.0, 0.0)
    values.update(cd_scale=1.2, wind_east_mps=5.0, mass_scale=1.05)
    m = build_model(setup, st, values)
    assert m.gravity.j2 == pytest.approx(1.08262668e-3)  # the known value, not a fitted one
    assert m.vehicle.aerodynamics.cd_scale == 1.2 and m.wind.east == 5.0
    assert m.vehicle.mass == pytest.approx(907.2 * 1.05)
    assert m.atmosphere.knots == (40e3, 60e3) and m.vehicle.aerodynamics.cl_scale == 1.0
    assert m.vehicle.aerodynamics.base.mach_knots == (10.0, 25.0)
    # the model with every effect round-trips through JSON, the Mach-drag part included
    assert model_from_dict(json.loads(json.dumps(model_to_dict(m)))) == m


def test_env_flies_the_identified_model():
    """gym.make flies exactly the identified model: its trajectory is that model's, checked against an
    independent tight-tolerance integration, and far from the clean model's."""
    gym = pytest.importorskip("gymnasium")
    from scipy.integrate import solve_ivp

    import rventry_env  # noqa: F401  (registers RvEntry-v0)
    from rventry_env.core.conversions import cartesian_from_rv_euler
    from rventry_env.physics import entry_rhs

    env = gym.make("RvEntry-v0", model=FULL)
    env.reset(seed=0)
    x0 = env.unwrapped.state
    action = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    for _ in range(20):
        env.step(action)

    def fly(model):
        sol = solve_ivp(lambda t, x: np.array(entry_rhs(list(x), (0.0, 0.0), model)), (0.0, 20.0), x0,
                        method="DOP853", rtol=1e-12, atol=1e-9)  # fmt: skip
        return cartesian_from_rv_euler(sol.y[:10, -1])[0]

    flown = cartesian_from_rv_euler(env.unwrapped.state[:10])[0]
    assert np.linalg.norm(flown - fly(FULL)) < 0.05  # RK4 at 1 s against DOP853: centimetres
    assert np.linalg.norm(flown - fly(EntryModel())) > 50.0  # the identified effects move the vehicle


def _old_outputs(tmp_path):
    report, model = tmp_path / "r.json", tmp_path / "m.json"
    report.write_text('{"old": "report"}')
    model.write_text('{"old": "model"}')
    return report, model


def test_outputs_are_one_set_a_failed_report_replaces_nothing(tmp_path):
    from types import SimpleNamespace

    from rventry_env.validation.report.outputs import write_outputs

    report, model = _old_outputs(tmp_path)
    bad = SimpleNamespace(model=FULL, report={"effect": "wind", "unserialisable": object()})
    with pytest.raises(TypeError):
        write_outputs(bad, report, model)
    assert report.read_text() == '{"old": "report"}' and model.read_text() == '{"old": "model"}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "r.json"]  # no staged file left behind
    good = SimpleNamespace(model=FULL, report={"effect": "wind"})
    write_outputs(good, report, model)
    assert json.loads(report.read_text())["model_file"] == str(model)
    assert load_model(model) == FULL


def test_output_set_puts_every_old_file_back_when_a_move_fails(tmp_path):
    from rventry_env.util.files import OutputError, atomic_write, output_set

    report, model = _old_outputs(tmp_path)
    blocked = tmp_path / "plots" / "residuals.png"
    blocked.parent.mkdir()
    with pytest.raises(OutputError, match="no output was replaced"):
        with output_set():
            atomic_write(model, "new model")
            atomic_write(report, "new report")
            atomic_write(blocked, "new plot")
            blocked.mkdir()  # the last destination turns into a folder: its move fails after the others
    assert report.read_text() == '{"old": "report"}' and model.read_text() == '{"old": "model"}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "plots", "r.json"]
    assert [p.name for p in blocked.parent.iterdir()] == ["residuals.png"] and blocked.is_dir()
