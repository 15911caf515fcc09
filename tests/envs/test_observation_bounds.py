"""When the environment clips an observation into its Box, exactly as documented.

Without navigation errors no flown episode leaves the Box. With them (the ``flight`` set) the
altitude feature is the navigated altitude, which near impact can lie more than 400 m below
the ground (the feature's low bound, -0.01): then, and only then, the env clips, the altitude
feature alone, and sets ``info["observation_clipped"]``.
"""

from __future__ import annotations

import numpy as np
import pytest

from script_modules import load_script

bench = load_script("studies/observation_bounds")


def _fly(law: str, dispersion: str, seeds: list[int]) -> list[tuple]:
    """Every flown step: (raw features (N, 26), info, which copies flew)."""
    from gymnasium.vector import AutoresetMode

    from rventry_env.envs.vector import RvEntryVectorEnv
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.guidance.law import Measurement

    n = len(seeds)
    steps = []
    with bench.raw_features() as raw:
        venv = RvEntryVectorEnv(num_envs=n, dispersion=dispersion, autoreset_mode=AutoresetMode.DISABLED)
        policy = bench.ZeroRates() if law == "zero" else load_agent(law, venv.task)
        obs, info = venv.reset(seed=seeds)
        policy.reset(n)
        done, t = np.zeros(n, bool), np.zeros(n)
        while not done.all():
            m = Measurement(obs, t.copy(), info["navigation_state"].copy(), info["sensed_accel_b"].copy(), ~done)
            obs, _, term, trunc, info = venv.step(np.asarray(policy(m), np.float32))
            t = info["time_s"]
            steps.append((raw[-1], obs, info, ~done, venv))
            done |= term | trunc
    return steps


def _check_the_rule(steps) -> int:
    """Assert the documented rule on every flown step; return the clipped steps."""
    from rventry_env.envs.observation import ALTITUDE_SCALE, feature_index

    h = feature_index("altitude")
    clipped_steps = 0
    for raw, obs, info, flew, venv in steps:
        lo, hi = venv.single_observation_space.low, venv.single_observation_space.high
        outside = ((raw < lo) | (raw > hi)) & flew[:, None]
        clipped = info["observation_clipped"] & flew
        np.testing.assert_array_equal(outside.any(axis=1), clipped)
        assert not outside[:, np.arange(raw.shape[1]) != h].any(), "only the altitude feature leaves the Box"
        assert not (raw[:, h] > hi[h])[flew].any()
        if clipped.any():
            clipped_steps += int(clipped.sum())
            nav_h = info["navigation_state"][clipped, 0] - venv.model.planet.radius
            assert np.all(np.float32(nav_h / ALTITUDE_SCALE) < lo[h])  # the navigated altitude is below -400 m
            assert np.all(info["altitude_m"][clipped] >= -1e-6)  # the vehicle itself is above ground, or at impact
            assert np.all(obs[clipped, h] == lo[h])  # clipped to the bound
    return clipped_steps


def test_only_the_navigated_altitude_below_400_m_is_clipped_on_the_flight_set():
    steps = _fly("zero", "flight", list(range(60)))
    assert _check_the_rule(steps) > 0  # the case arises in these seeds


@pytest.mark.slow
@pytest.mark.parametrize("law", ["reference", "lqr-est"])
def test_the_rule_holds_for_guided_flight_on_the_flight_set(law):
    assert _check_the_rule(_fly(law, "flight", list(range(200)))) > 0


@pytest.mark.slow
@pytest.mark.parametrize("dispersion", ["none", "standard", "wide", "peer", "peer-0.1"])
def test_without_navigation_errors_no_flown_step_is_clipped(dispersion):
    for law in ("reference", "zero"):
        assert _check_the_rule(_fly(law, dispersion, list(range(100)))) == 0
