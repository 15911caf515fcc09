"""The q floor: its apex prediction against the env's own flight, and the bound held in thinner air."""

from __future__ import annotations

import numpy as np
import pytest

from rventry_env.evaluation.rollout import rollout
from rventry_env.guidance.q_floor import QFloor
from rventry_env.guidance.reference_replay import ReferencePolicy
from rventry_env.physics import EntryModel
from rventry_env.physics.entry import entry_forces
from rventry_env.physics.model import scaled_model
from rventry_env.reference.data_file import load_reference
from rventry_env.task import EntryTask

FIRST_APEX_STEPS = 320  # the optimum's first skip touches the q bound at 270 s


class _FlooredReplay(ReferencePolicy):
    """The optimum's controls open loop, through a q floor."""

    def __init__(self, margin: float):
        super().__init__()
        self.floor = QFloor(margin=margin)

    def reset(self, n_episodes: int) -> None:
        self.floor.reset(n_episodes)

    def __call__(self, m):
        return self.floor(super().__call__(m), m.navigation_state, m.sensed_accel_b).astype(np.float32)


def test_the_floor_holds_q_over_the_first_apex_in_thinner_air():
    """Air 8 % thinner than the model: the optimum, which rides the q bound at its first apex, dips 9 %
    under it open loop; through the floor it stays above q_min, and the floor acted."""
    truth = scaled_model(EntryModel(), density=0.92)
    bare = rollout(ReferencePolicy(), 1, model=truth, max_episode_steps=FIRST_APEX_STEPS).records()[0]
    assert bare["min_dynamic_pressure_pa"] < 0.92 * 12e3 * 1.001  # the check can fail: without the floor it does
    law = _FlooredReplay(margin=0.02)
    floored = rollout(law, 1, model=truth, max_episode_steps=FIRST_APEX_STEPS).records()[0]
    assert floored["min_dynamic_pressure_pa"] >= EntryTask().problem.q_min
    assert law.floor.steps[0] >= 1


def test_the_apex_prediction_is_the_envs_flight_with_the_angles_held():
    """From the optimum 40 s before its first apex, the predicted least q to the apex is what the
    environment's own integrator flies with the same rates for a step and the angles held (within
    0.5 %: the prediction takes 2-s RK4 steps)."""
    from rventry_env.core.backend import NUMPY
    from rventry_env.envs.propagation import Propagator

    task, model = EntryTask(), EntryModel()
    ref = load_reference()
    x = ref.state(np.array([230.0]))
    floor = QFloor(model, task)
    predicted = floor.apex_q(x, np.array([0.0]), np.array([0.0]))[0]
    prop = Propagator(task, NUMPY)
    y, q = tuple(x.T), []
    for _ in range(90):
        out = prop.step(y, entry_forces(y, model), np.zeros(1), np.zeros(1), model)
        y = out.x
        q.append(float(np.asarray(out.min_q)[0]))
    flown = min(q[: int(np.argmin(q)) + 1])
    assert 11e3 < flown < 13e3 and predicted == pytest.approx(flown, rel=5e-3)


def test_no_action_where_the_vehicle_descends_or_q_is_far_above_the_floor():
    ref = load_reference()
    task, model = EntryTask(), EntryModel()
    floor = QFloor(model, task)
    x = ref.x[(ref.t > ref.tf - 15.0)]  # the final dive: descending, q far above the floor
    sensed = np.stack(entry_forces(tuple(x.T), model).aero_b, axis=1)
    rates = np.tile([0.3, -0.4], (len(x), 1))
    np.testing.assert_array_equal(floor(rates, x, sensed), rates)
    assert not floor.active.any() and not floor.steps.any()


def test_the_sensed_acceleration_is_what_calibrates_the_prediction():
    """The same state, climbing to the first apex: sensed as the model predicts, the apex clears a
    floor 2 % above q_min; sensed 8 % weaker (thinner air), the floor takes the bank."""
    ref = load_reference()
    model = EntryModel()
    x = ref.state(np.array([240.0]))
    sensed = np.stack(entry_forces(tuple(x.T), model).aero_b, axis=1)
    rates = np.array([[0.0, 0.0]])
    floor = QFloor(model, margin=0.0)
    np.testing.assert_array_equal(floor(rates, x, sensed * 1.05), rates)
    out = floor(rates, x, sensed * 0.92)
    assert floor.active[0] and abs(out[0, 1]) == 1.0


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="q floor margin must be a finite number >= 0"):
        QFloor(margin=-0.1)
    with pytest.raises(ValueError, match="q floor watch must be a finite number >= 1"):
        QFloor(watch=0.5)
    with pytest.raises(ValueError, match="q floor horizon_s"):
        QFloor(horizon_s=float("nan"))
    floor = QFloor()
    x = load_reference().x[:3]
    with pytest.raises(ValueError, match="the q floor needs the sensed acceleration"):
        floor(np.zeros((3, 2)), x, None)
    with pytest.raises(ValueError, match=r"rates \(N, 2\), state \(N, 12\) and sensed acceleration \(N, 3\)"):
        floor(np.zeros((2, 2)), x, np.zeros((3, 3)))
