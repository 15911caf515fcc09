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


def test_the_shipped_ppo_flies_the_q_floor_chosen_on_selection_seeds_and_says_so():
    """``ppo`` flies the margin its policy.json records (chosen on seeds away from the evaluation's),
    reports it in its provenance and counts its steps; without the floor it is the policy as trained."""
    import json

    from rventry_agents.sb3_policy import SHIPPED_PPO_AGENTS, load_shipped

    spec = json.loads((SHIPPED_PPO_AGENTS["ppo"] / "policy.json").read_text())["student"]
    sel = spec["q_floor_selection"]
    assert spec["q_floor_margin"] == sel["chosen"] and sel["seeds"][0] >= 100000  # not the evaluation's seeds 0-199
    score = {k: sum(v.values()) for k, v in sel["success"].items()}
    assert score[f"{sel['chosen']:g}"] == max(score.values())
    ppo = load_shipped("ppo")
    assert ppo.provenance["q_floor_margin"] == spec["q_floor_margin"] and ppo._act.q_floor.margin == spec["q_floor_margin"]
    b = rollout(ppo, seeds=[3], dispersion="wide", max_episode_steps=400)
    assert set(b.law_stats[0]) == {"load_relief_steps", "q_floor_steps"}
    bare = load_shipped("ppo").with_q_floor(None)
    assert bare._act.q_floor is None and bare._act.relief is not None
    assert set(rollout(bare, seeds=[3], dispersion="wide", max_episode_steps=50).law_stats[0]) == {"load_relief_steps"}


def test_the_q_floor_comes_before_the_load_relief_and_each_law_refuses_a_bad_margin():
    from rventry_agents.dagger import student_law
    from rventry_env.guidance.replanning import ReplanningSettings

    assert student_law({"q_floor_margin": 0.05}, EntryTask())["q_floor_margin"] == 0.05
    with pytest.raises(ValueError, match="q floor margin must be a finite number >= 0"):
        student_law({"q_floor_margin": -0.05}, EntryTask())
    with pytest.raises(ValueError, match="q_floor_margin must be None"):
        ReplanningSettings(q_floor_margin=float("nan"))
    # the learned law's chain: the q floor takes the bank (and alpha), then the load relief caps alpha
    from rventry_agents.sb3_policy import load_shipped

    law = load_shipped("ppo")._act
    calls = []
    for name in ("q_floor", "relief"):
        inner = getattr(law, name)
        setattr(law, name, lambda r, *a, _n=name, _f=inner, **k: calls.append(_n) or _f(r, *a, **k))
        getattr(law, name).reset = inner.reset
    x = load_reference().state(np.array([240.0]))
    law.limit(np.zeros((1, 2)), x, np.stack(entry_forces(tuple(x.T), EntryModel()).aero_b, axis=1))
    assert calls == ["q_floor", "relief"]


def test_a_dagger_config_that_names_a_q_floor_is_refused(tmp_path):
    from rventry_agents.dagger import DEFAULT_CONFIG, train_dagger

    cfg = tmp_path / "c.toml"
    cfg.write_text(DEFAULT_CONFIG.read_text().replace("[student]", "[student]\nq_floor_margin = 0.05", 1))
    with pytest.raises(ValueError, match=r"\[student\] q_floor_margin: the DAgger rounds fly no q floor"):
        train_dagger(cfg, tmp_path / "out", workers=1, progress_bar=False)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_choose_q_floor_measures_a_student_by_name_and_records_only_in_a_run(tmp_path, monkeypatch):
    import sys

    from script_modules import load_script

    script = load_script("studies/choose_q_floor")
    out = tmp_path / "q.json"
    monkeypatch.setattr(sys, "argv", ["choose_q_floor.py", "dagger-flight", "--write", "--json", str(out)])
    with pytest.raises(SystemExit, match="'dagger-flight' is not one"):
        script.main()
    monkeypatch.setattr(sys, "argv", ["choose_q_floor.py", "lqr", "--margins", "0.08", "--sets", "standard",
                                      "--episodes", "1", "--json", str(out)])  # fmt: skip
    with pytest.raises(ValueError, match="imitation student"):
        script.main()
    assert not out.exists()
    monkeypatch.setattr(sys, "argv", ["choose_q_floor.py", "dagger-flight", "--margins", "0.08", "--sets", "wide",
                                      "--episodes", "2", "--seed", "11", "--json", str(out)])  # fmt: skip
    script.main()
    import json

    rec = json.loads(out.read_text())
    assert rec["run"] == "dagger-flight" and set(rec["success"]) == {"none", "0.08"}
