"""The vector env's steppers: the episodes each flies, the features each refuses, and the interface."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from rventry_env.envs.steppers import ArrayStepper, FloatStepper, Stepper, Unsupported
from rventry_env.envs.vector import RvEntryVectorEnv

from stepper_rollouts import CASES, FIXTURE, rollout

NUMPY_CASES = [name for name, case in CASES.items() if case[0] == "numpy"]
JAX_CASES = [name for name, case in CASES.items() if case[0] == "jax"]


# the Earth-fixed position and the navigation state go through numpy's vectorised trigonometric
# functions, whose last bits depend on the processor's SIMD instructions (the fixture's processor
# and an AVX-512 one differ there by 2-72 units in the last place, under 2e-15 of each value): those
# two are held to 1e-13 of what was recorded, every other array to the bit
PROCESSOR_DEPENDENT = ("r_ecef_m", "navigation_state")


def _assert_recorded(name: str) -> None:
    recorded = np.load(FIXTURE)
    flown = rollout(*CASES[name])
    assert {f"{name}/{k}" for k in flown} == {k for k in recorded.files if k.startswith(name + "/")}
    for k, v in flown.items():
        want = recorded[f"{name}/{k}"]
        assert v.dtype == want.dtype and v.shape == want.shape, (k, v.dtype, want.dtype, v.shape, want.shape)
        if k in PROCESSOR_DEPENDENT:
            np.testing.assert_allclose(v, want, rtol=1e-13, atol=0, equal_nan=True, err_msg=f"{name} {k}")
            continue
        same = np.array_equal(v, want) if v.dtype.kind in "bUiu" else np.array_equal(v, want, equal_nan=True)
        assert same, (name, k, np.argwhere(v != want)[:5])


@pytest.mark.parametrize("name", NUMPY_CASES)
def test_the_numpy_steppers_fly_the_recorded_episodes_bit_for_bit(name):
    """Observations, rewards, endings, positions, clocks, costs, navigation and outcomes of short seeded
    rollouts (autoresets in every mode, footprint targets, a diverging coarse step) equal, bit for bit,
    what the vector env flew before its step was handed to stepper objects."""
    _assert_recorded(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", JAX_CASES)
def test_the_jax_stepper_flies_the_recorded_episodes_bit_for_bit(name):
    pytest.importorskip("jax")
    _assert_recorded(name)


def test_the_backend_chooses_the_stepper():
    assert type(RvEntryVectorEnv(2).stepper) is FloatStepper
    assert type(RvEntryVectorEnv(8).stepper) is ArrayStepper
    venv = gym.make_vec("RvEntry-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.unwrapped.stepper.name == "floats" and venv.unwrapped.backend == "numpy"
    with pytest.raises(ValueError, match="backend must be one of"):
        RvEntryVectorEnv(2, backend="torch")
    with pytest.raises(ValueError, match="backend='numpy' computes in float64"):
        RvEntryVectorEnv(2, dtype="float32")


def test_every_stepper_gives_true_forces_render_and_episode_steps_or_refuses_them_by_name():
    for n in (1, 8):  # floats, arrays: everything
        venv = RvEntryVectorEnv(n, render_mode="rgb_array", targets="footprint")
        venv.reset(seed=3)
        venv.step(np.zeros((n, 2), np.float32))
        assert venv.true_forces.aero_accel.shape == (n,)
        assert np.array_equal(venv.episode_steps, np.ones(n, np.int64))
        assert venv.render()[0].ndim == 3
    base = Stepper(RvEntryVectorEnv(1).stepper.setup)
    with pytest.raises(Unsupported, match="the 'stepper' stepper does not support true_forces"):
        base.true_forces
    with pytest.raises(ValueError, match="the 'stepper' stepper does not support render"):
        base.track()


def test_the_jax_stepper_refuses_what_it_cannot_fly_with_its_name():
    pytest.importorskip("jax")
    from rventry_env.envs.jax_vector import RvEntryJaxVectorEnv

    with pytest.raises(ValueError, match="the 'jax' stepper does not support render_mode='rgb_array'"):
        RvEntryVectorEnv(2, backend="jax", render_mode="rgb_array")
    with pytest.raises(ValueError, match="the 'jax' stepper does not support targets='footprint'.*fixed target"):
        RvEntryJaxVectorEnv(2, targets="footprint")
    with pytest.raises(ValueError, match="dtype must be one of"):
        RvEntryJaxVectorEnv(2, dtype="float16")
    venv = RvEntryJaxVectorEnv(2, max_episode_steps=5)
    assert type(venv) is RvEntryVectorEnv and venv.stepper.name == "jax"
    venv.reset(seed=0)
    with pytest.raises(NotImplementedError, match="the 'jax' stepper does not support true_forces"):
        venv.true_forces
    for _ in range(3):
        venv.step(np.zeros((2, 2), np.float32))
    assert np.array_equal(venv.episode_steps, [3, 3])
