"""The footprint mission family: a target drawn per episode, told to the law, scored against it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rventry_env.envs.observation import feature_names
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.evaluation.rollout import rollout
from rventry_env.guidance.law import Law, Measurement
from rventry_env.physics import EntryModel
from rventry_env.task import EntryProblem, EntryTask, Footprint, footprint_target

R = EntryModel().planet.radius
FOOTPRINT = EntryTask(targets="footprint")


def _arc(a, b) -> float:
    """Great-circle distance (m) between unit vectors."""
    return R * math.atan2(np.linalg.norm(np.cross(a, b)), float(np.dot(a, b)))


def test_footprint_moves_the_target_along_and_across_the_nominal_track():
    p = EntryProblem()
    t = p.target_unit_vector()
    entry = np.array([1.0, 0.0, 0.0])  # the paper's entry point: 0 deg N, 0 deg E
    for down, cross in [(300e3, 0.0), (-300e3, 0.0), (0.0, 150e3), (0.0, -150e3), (-123e3, 77e3)]:
        moved = footprint_target(p, R, down, cross)
        assert np.linalg.norm(moved) == pytest.approx(1.0, abs=1e-15)
        # on the track: the range from the entry grows by the downrange shift; across: it stays
        # nearly the same (a right spherical triangle) and the target leaves the track's plane
        normal = np.cross(entry, t) / np.linalg.norm(np.cross(entry, t))
        assert R * math.asin(float(np.dot(moved, normal))) == pytest.approx(cross, abs=1e-6)
        if cross == 0.0:
            assert _arc(entry, moved) - _arc(entry, t) == pytest.approx(down, abs=1e-6)
        assert _arc(t, moved) == pytest.approx(math.hypot(down, cross), rel=2e-3)
    # +crossrange is to the left of an eastbound track: north
    assert footprint_target(p, R, 0.0, 150e3)[2] > 0


def test_a_fixed_target_draws_nothing_and_a_footprint_target_stays_inside():
    rng = np.random.default_rng(4)
    assert EntryTask().draw_target(rng, R) is None
    assert rng.uniform() == np.random.default_rng(4).uniform()  # nothing drawn
    p = EntryProblem()
    t = p.target_unit_vector()
    normal = np.cross([1.0, 0.0, 0.0], t)
    normal /= np.linalg.norm(normal)
    draws = np.array([FOOTPRINT.draw_target(rng, R) for _ in range(400)])
    cross = R * np.arcsin(draws @ normal)
    assert np.max(np.abs(cross)) <= 150e3 + 1e-6 and np.max(np.abs(cross)) > 140e3
    along = np.array([_arc([1.0, 0.0, 0.0], d) for d in draws]) - _arc([1.0, 0.0, 0.0], t)
    assert np.min(along) > -301e3 and np.max(along) < 301e3 and np.ptp(along) > 560e3


def test_the_footprint_refuses_a_negative_half_width_and_an_unknown_family():
    with pytest.raises(ValueError, match="footprint downrange_m must be a finite half-width"):
        Footprint(downrange_m=-1.0)
    with pytest.raises(ValueError, match=r"targets must be one of \('fixed', 'footprint'\), got 'moving'"):
        EntryTask(targets="moving")


def test_single_and_vector_env_draw_the_same_target_and_observe_it():
    single = RvEntryEnv(targets="footprint", dispersion="standard")
    vec = RvEntryVectorEnv(num_envs=3, targets="footprint", dispersion="standard")
    obs_v, info_v = vec.reset(seed=10)
    for i in range(3):
        obs, info = single.reset(seed=10 + i)
        np.testing.assert_array_equal(info["target_e"], info_v["target_e"][i])
        np.testing.assert_array_equal(obs, obs_v[i])
        # the range-to-go feature is the great-circle distance to the drawn target / 2800 km
        a1 = info["r_ecef_m"] / np.linalg.norm(info["r_ecef_m"])
        k = feature_names().index("range_to_go")
        assert obs[k] == pytest.approx(_arc(a1, info["target_e"]) / 2800e3, rel=1e-5)
    # the same seeds without a footprint: the same dispersion draws (the target is drawn last)
    vec_fixed = RvEntryVectorEnv(num_envs=3, dispersion="standard")
    vec_fixed.reset(seed=10)
    np.testing.assert_array_equal(vec_fixed.dispersion_draw, vec.dispersion_draw)
    np.testing.assert_array_equal(vec_fixed.state, vec.state)


def test_the_miss_is_measured_from_the_episode_target():
    env = RvEntryVectorEnv(num_envs=4, targets="footprint")
    _, info = env.reset(seed=3)
    target = info["target_e"].copy()
    done = np.zeros(4, bool)
    miss = np.zeros(4)
    impact = np.zeros((4, 3))
    while not done.all():
        _, _, term, trunc, info = env.step(np.zeros((4, 2), np.float32))
        ended = (term | trunc) & ~done
        miss[ended] = info["miss_km"][ended]
        impact[ended] = info["r_ecef_m"][ended] / np.linalg.norm(info["r_ecef_m"][ended], axis=1, keepdims=True)
        done |= ended
    for i in range(4):
        assert miss[i] * 1e3 == pytest.approx(_arc(impact[i], target[i]), rel=1e-6, abs=1.0)


class _Fixed(Law):
    def __call__(self, m: Measurement) -> np.ndarray:
        return np.zeros((m.n, 2), np.float32)


class _Told(_Fixed):
    retargets = True

    def __init__(self):
        self.told = []

    def __call__(self, m: Measurement) -> np.ndarray:
        self.told.append(m.target_e)
        return super().__call__(m)


def test_a_law_that_cannot_retarget_is_refused_and_one_that_can_is_told_the_target():
    with pytest.raises(ValueError, match="_Fixed cannot re-target: it flies the task's fixed target"):
        rollout(_Fixed(), 2, task=FOOTPRINT)
    law = _Told()
    batch = rollout(law, 2, seed=5, task=FOOTPRINT, max_episode_steps=3)
    env = RvEntryVectorEnv(num_envs=2, targets="footprint")
    _, info = env.reset(seed=[5, 6])
    np.testing.assert_array_equal(law.told[0], info["target_e"])
    lat = np.degrees(np.arcsin(info["target_e"][:, 2]))
    np.testing.assert_allclose(batch.targets["target_latitude_deg"], lat)
    assert "target_longitude_deg" in batch.records()[0]
    # on the fixed target the law is told None, and the records carry no target
    law = _Told()
    assert not rollout(law, 1, task=EntryTask(), max_episode_steps=2).targets and law.told[0] is None


def test_a_measurement_refuses_a_target_of_the_wrong_shape():
    with pytest.raises(ValueError, match=r"target_e \(2,\)"):
        Measurement(np.zeros((2, 26), np.float32), np.zeros(2), np.zeros((2, 12)), np.zeros((2, 3)), np.ones(2, bool),
                    np.zeros(2))  # fmt: skip


def test_the_jax_faces_refuse_a_footprint():
    pytest.importorskip("jax")
    from rventry_env.envs.functional import RvEntryFunctional

    with pytest.raises(ValueError, match="flies the fixed target"):
        RvEntryFunctional(task=FOOTPRINT, max_episode_steps=10)


def test_aimed_at_moves_the_problem_target_and_refuses_a_non_unit_vector():
    v = footprint_target(EntryProblem(), R, 200e3, -100e3)
    aimed = FOOTPRINT.aimed_at(v)
    np.testing.assert_allclose(aimed.problem.target_unit_vector(), v, atol=1e-15)
    assert aimed.targets == "fixed" and aimed.problem.initial_state(R).tolist() == EntryProblem().initial_state(R).tolist()
    with pytest.raises(ValueError, match="a target must be a unit vector"):
        FOOTPRINT.aimed_at([1.0, 1.0, 0.0])


@pytest.mark.slow
def test_replanning_guidance_flies_the_target_it_is_told():
    """mpc on a coarse mesh, one footprint episode 300 km long of the nominal and 150 km left of
    it: it plans to the target it is told and lands on it."""
    from rventry_env.guidance.replanning import ReplanningGuidance, ReplanningSettings

    law = ReplanningGuidance(FOOTPRINT, settings=ReplanningSettings(mesh_intervals=10, mesh_degree=4, replan_s=60.0))
    batch = rollout(law, 1, seed=0, task=FOOTPRINT)
    target = np.array([batch.targets["target_latitude_deg"][0], batch.targets["target_longitude_deg"][0]])
    nominal = np.degrees([EntryProblem().target_latitude, EntryProblem().target_longitude])
    assert np.linalg.norm(target - nominal) > 0.5  # seed 0 draws a target well away from the nominal
    assert batch.is_success[0] and batch.miss_km[0] < 0.5, (batch.miss_km, batch.failure)
