"""Inputs a user can hand the environments and the physics parts: a seeded corpus.

Every input is either refused at once with a ValueError (or TypeError) naming the field, or
flown with finite observations and rewards. NumPy warnings are errors here: an input that is
accepted must not produce NaN or an overflow on the way.
"""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import rventry_env  # noqa: F401  (registers RvEntry-v0)
from rventry_env.core import conversions as cv
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.task import EntryProblem, EntryTask
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.physics import (
    CAVHAerodynamics,
    ConstantAerodynamics,
    EntryModel,
    ExponentialAtmosphere,
    HorizontalWind,
    J2Gravity,
    Planet,
    PointMassGravity,
    ScaledAerodynamics,
    Vehicle,
)

TASK = EntryTask(problem=EntryProblem(initial_alpha=math.radians(11.86), initial_sigma=math.radians(100.0)))
NAN = float("nan")

# (a thunk building a part the way a user would, the text the refusal must contain)
BAD_PARTS = [
    (lambda: Vehicle(mass=NAN), "Vehicle.mass must be finite"),
    (lambda: Vehicle(mass=0.0), "Vehicle.mass must be >="),
    (lambda: Vehicle(mass=-1.0), "Vehicle.mass must be >="),
    (lambda: Vehicle(mass="x"), "Vehicle.mass must be a number"),
    (lambda: Vehicle(mass=1e-300), "Vehicle.mass must be >="),
    (lambda: Vehicle(mass=True), "Vehicle.mass must be a number"),
    (lambda: Vehicle(reference_area=NAN), "Vehicle.reference_area must be finite"),
    (lambda: Vehicle(reference_area=0.0), "Vehicle.reference_area must be >="),
    (lambda: Vehicle(reference_area=-0.48), "Vehicle.reference_area must be >="),
    (lambda: Vehicle(aerodynamics=None), "Vehicle.aerodynamics must be a force-model part"),
    (lambda: ExponentialAtmosphere(scale_height=0.0), "ExponentialAtmosphere.scale_height must be >= 1"),
    (lambda: ExponentialAtmosphere(rho0=NAN), "ExponentialAtmosphere.rho0 must be finite"),
    (lambda: Planet(g0=0.0), "Planet.g0 must be >= 0.001"),
    (lambda: Planet(radius=-1.0), "Planet.radius must be >= 1000"),
    (lambda: PointMassGravity(mu=NAN), "PointMassGravity.mu must be finite"),
    (lambda: J2Gravity(j2="big"), "J2Gravity.j2 must be a number"),
    (lambda: CAVHAerodynamics(cd0=math.inf), "CAVHAerodynamics.cd0 must be finite"),
    (lambda: ConstantAerodynamics(cd=-1.0), "ConstantAerodynamics.cd must be >= 0"),
    (lambda: ScaledAerodynamics(CAVHAerodynamics(), cd_scale=np.array([1.0, -0.5])), "cd_scale must be >= 0"),
    (lambda: HorizontalWind(east=NAN), "HorizontalWind.east must be finite"),
    (lambda: EntryModel(vehicle=None), "EntryModel.vehicle must be a Vehicle"),
    (lambda: EntryModel(atmosphere=None), "EntryModel.atmosphere must be a force-model part"),
    (lambda: EntryModel(wind="gusty"), "EntryModel.wind must be a force-model part"),
]


@pytest.mark.parametrize("build, message", BAD_PARTS)
def test_a_physics_part_that_cannot_be_flown_is_refused_at_construction(build, message):
    with pytest.raises(ValueError, match=message):
        gym.make("RvEntry-v0", task=TASK, model=build())  # the part raises as it is built


def test_the_defaults_and_symbolic_parameters_still_build():
    import casadi as ca

    m = ca.SX.sym("m")
    assert Vehicle(mass=907.2 * m).mass is not None  # the identification's fitted parameters are symbols
    assert HorizontalWind(east=ca.SX.sym("e")).north == 0.0
    model = EntryModel(gravity=PointMassGravity(mu=0.0))  # no gravity is allowed (a test case of its own)
    assert model.gravity.mu == 0.0


def _pole_and_vertical_states():
    radius = 6378137.0 + 37e3
    pole = cv.rv_euler_from_cartesian(np.array([0.0, 0.0, radius]), np.array([7138.0, 0.0, 0.0]))
    vertical = cv.rv_euler_from_cartesian(np.array([radius, 0.0, 0.0]), np.array([-3000.0, 0.0, 0.0]))
    return {name: np.concatenate([x, [0.2, 0.0]]) for name, x in (("pole", pole), ("vertical", vertical))}


@pytest.mark.parametrize("where", ["pole", "vertical"])
@pytest.mark.parametrize("make", [lambda: RvEntryEnv(task=TASK), lambda: RvEntryVectorEnv(2, task=TASK)],
                         ids=["single", "vector"])  # fmt: skip
def test_a_dispersion_at_the_pole_or_in_vertical_flight_is_flown_or_refused_naming_it(where, make):
    x = _pole_and_vertical_states()[where]
    env = make()
    with pytest.raises(ValueError, match=r"dispersion of the flight-path angle or heading \(Dispersion.flight_path_deg"):
        env.reset(seed=0, options={"state": x, "dispersion": "standard"})
    # altitude, speed and the model's factors need no angle: flown cleanly, as without a dispersion
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs, _ = env.reset(seed=0, options={"state": x, "dispersion": {"altitude_m": 500.0, "speed_mps": 20.0,
                                                                        "density": 0.05}})  # fmt: skip
        single = isinstance(env, RvEntryEnv)
        state = env.state if single else env.state[0]
        assert abs(state[0] - x[0]) <= 500.0 and abs(state[5] - x[5]) <= 20.0 and state[0] != x[0]
        for _ in range(3):
            obs, reward, *_ = env.step(np.zeros(2) if single else np.zeros((2, 2)))
            assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))


def _extreme_states():
    """(name, state, text of the refusal or None where it must fly): one component pushed to an extreme."""
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    base = env.state
    out = []
    names = ("r", "eA1", "eA2", "eA3", "etaA", "v", "eB1", "eB2", "eB3", "etaB", "alpha", "sigma")
    for i, name in enumerate(names):
        for value in (1e300, -1e300, 1e-300, 0.0, 1e6, -1e6):
            x = base.copy()
            x[i] = value
            out.append((f"{name}={value:g}", x))
    return out


@pytest.mark.parametrize("name, state", _extreme_states(), ids=[n for n, _ in _extreme_states()])
def test_an_extreme_reset_state_is_refused_naming_it_or_flies_finite(name, state):
    env = RvEntryEnv(task=TASK)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            obs, _ = env.reset(seed=0, options={"state": state})
        except ValueError as exc:
            assert any(w in str(exc) for w in ("radius", "altitude", "speed", "Euler parameters", "alpha")), exc
            return
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(np.ones(2))
            assert np.all(np.isfinite(obs)) and math.isfinite(reward), name
            if terminated or truncated:
                break


def test_alpha_1e300_is_refused_naming_alpha():
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    x = env.state
    x[10] = 1e300
    with pytest.raises(ValueError, match=r"initial alpha must lie in \[0, 25\] deg"):
        env.reset(seed=0, options={"state": x})
    with pytest.raises(ValueError, match="initial alpha"):
        RvEntryVectorEnv(2, task=TASK).reset(seed=0, options={"state": x})


@pytest.mark.parametrize("options", [["state"], "state", ("dispersion", "standard")])
def test_reset_options_that_are_not_a_dict_are_named(options):
    for env in (RvEntryEnv(task=TASK), RvEntryVectorEnv(2, task=TASK)):
        with pytest.raises(TypeError, match=r"reset\(options=...\) must be a dict"):
            env.reset(seed=0, options=options)


def test_complex_actions_are_refused_in_both_envs():
    env = RvEntryEnv(task=TASK)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning: a refusal
        with pytest.raises(ValueError, match="action must be real numbers, got dtype complex128"):
            env.step(np.array([0.1 + 1j, 0.0]))
        venv = RvEntryVectorEnv(2, task=TASK)
        venv.reset(seed=0)
        with pytest.raises(ValueError, match="actions must be real numbers"):
            venv.step(np.zeros((2, 2), complex))
        with pytest.raises(ValueError, match="must be real numbers"):
            env.step([None, 0.0])


def test_an_ended_copys_action_is_ignored_but_a_flying_copys_nan_is_refused():
    """DISABLED autoreset (the evaluation's): a copy whose episode ended is not flown, so its action,
    NaN included, is ignored; NEXT_STEP: the copy that restarts ignores its action too."""
    venv = RvEntryVectorEnv(2, task=TASK, max_episode_steps=2, autoreset_mode=AutoresetMode.DISABLED)
    venv.reset(seed=0, options={"state": np.stack([venv._nominal, venv._nominal])})
    venv.step(np.zeros((2, 2)))
    _, _, _, truncated, _ = venv.step(np.zeros((2, 2)))
    assert truncated.all()
    obs, reward, terminated, truncated, _ = venv.step(np.full((2, 2), np.nan))
    assert not (terminated | truncated).any() and np.all(reward == 0) and np.all(np.isfinite(obs))

    venv = RvEntryVectorEnv(2, task=TASK, max_episode_steps=2, autoreset_mode=AutoresetMode.NEXT_STEP)
    venv.reset(seed=0)
    venv.step(np.zeros((2, 2)))
    venv.step(np.zeros((2, 2)))  # both ended: the next step restarts them and ignores the actions
    obs, *_ = venv.step(np.full((2, 2), np.nan))
    assert np.all(np.isfinite(obs))
    with pytest.raises(ValueError, match=r"actions contain NaN or inf \(copies \[1\]\)"):
        venv.step(np.array([[0.0, 0.0], [np.nan, 0.0]]))


def test_lqr_est_stays_finite_under_wind_and_counts_its_refused_updates():
    """A 200 m/s wind the model does not know: the lift seen along the commanded direction turns
    negative; the estimator refuses those updates (counted) and every episode ends with a finite
    outcome, where its log-scales went NaN and the batch aborted before."""
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.evaluation.rollout import rollout

    law = load_agent("lqr-est")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        batch = rollout(law, 8, model=EntryModel(wind=HorizontalWind(east=200.0, north=200.0)),
                        dispersion="standard")  # fmt: skip
    assert np.all(np.isfinite(batch.miss_km)) and np.all(np.isfinite(batch.cost))
    rejected = [s["estimator_rejected_updates"] for s in batch.law_stats]
    assert sum(rejected) > 0
    assert np.all(np.isfinite(law.estimator.log_scales()))
    lo, hi = law.estimator.settings.scale_bounds
    assert np.all((law.estimator.k >= lo) & (law.estimator.k <= hi))
    # no wind: nothing is refused
    still = rollout(law, 8, dispersion="standard")
    assert all(s["estimator_rejected_updates"] == 0 for s in still.law_stats)
