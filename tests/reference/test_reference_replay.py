"""Open-loop replay of the reference controls through the NumPy entry dynamics."""

import dataclasses

import numpy as np
import pytest

from rventry_env.physics.model import EntryModel
from rventry_env.reference import load_reference
from rventry_env.reference.open_loop import entry_rhs_numpy, replay_controls


@pytest.fixture(scope="module")
def replay():
    return replay_controls(entry_rhs_numpy(), load_reference(), rtol=1e-11)


@pytest.mark.slow
def test_replay_reproduces_the_reference_impact_point(replay):
    assert replay.position_error_at_impact_m <= 100.0
    assert replay.max_position_error_m <= 100.0
    # the replayed vehicle is at the ground at tf, not above or below it by much
    assert abs(replay.altitude_at_tf_m) <= 100.0
    np.testing.assert_allclose(replay.x[0], load_reference().x[0])


@pytest.mark.slow
def test_replay_detects_a_different_vehicle():
    """The check can fail: a 5 % heavier vehicle flies the same controls somewhere else."""
    model = EntryModel()
    heavy = model.replace(vehicle=dataclasses.replace(model.vehicle, mass=1.05 * model.vehicle.mass))
    res = replay_controls(entry_rhs_numpy(heavy), load_reference(), rtol=1e-8)
    assert res.position_error_at_impact_m > 1000.0


def test_replay_rejects_bad_tolerance():
    with pytest.raises(ValueError, match="rtol"):
        replay_controls(entry_rhs_numpy(), load_reference(), rtol=0.0)
