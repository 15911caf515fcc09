"""PPO from the imitation student: the actor starts as the student, trains, saves, reloads and flies."""

from __future__ import annotations

import hashlib
import json
import tomllib

import numpy as np
import pytest

from rventry_agents.imitation import network_bytes
from rventry_agents.train import FINETUNE_CONFIG, load_config, train_sb3
from rventry_env.evaluation.agents import load_agent
from rventry_env.evaluation.rollout import rollout

START = load_config(FINETUNE_CONFIG).policy.start  # the shipped config's student


def _small(total: int, warmup: int) -> dict:
    cfg = tomllib.loads(FINETUNE_CONFIG.read_text())
    cfg["env"]["num_envs"] = 8
    cfg["ppo"].update(n_steps=64, batch_size=256, n_epochs=1)
    cfg["policy"]["critic_warmup_steps"] = warmup
    cfg["train"].update(total_timesteps=total, eval_every=10**9, eval_episodes=2, checkpoint_every=10**9,
                        torch_threads=1)  # fmt: skip
    return cfg


@pytest.fixture(scope="module")
def frozen(tmp_path_factory):
    """A run that is all critic warm-up: the actor never moves from the student."""
    return train_sb3("ppo", _small(512, 512), out=tmp_path_factory.mktemp("frozen"), progress_bar=False)


@pytest.mark.slow
def test_step_zero_flies_exactly_like_the_student(frozen):
    student = rollout(load_agent(START), seeds=[11, 12], dispersion="wide")
    ppo = rollout(load_agent(str(frozen / "final_model.zip")), seeds=[11, 12], dispersion="wide")
    for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "cost", "max_load_factor_g"):
        np.testing.assert_array_equal(getattr(ppo, key), getattr(student, key))
    meta = json.loads((frozen / "metadata.json").read_text())
    start_sha = hashlib.sha256(network_bytes(load_agent(START).network)).hexdigest()  # the student's weights, named
    assert meta["provenance"] == {"algorithm": "PPO (stable-baselines3)", "start": START, "start_sha256": start_sha,
                                  "critic_warmup_steps": 512,
                                  "timesteps": 512, "selected_at_timesteps": meta["best_evaluation"]["timesteps"]}  # fmt: skip
    assert meta["best_evaluation"]["timesteps"] in (0, 512)


@pytest.mark.slow
def test_a_short_fine_tuning_trains_saves_reloads_and_flies_deterministically(tmp_path):
    out = train_sb3("ppo", _small(2048, 512), out=tmp_path / "run", progress_bar=False)
    law = load_agent(str(out / "final_model.zip"))
    a = rollout(law, seeds=[3, 4], dispersion="standard")
    b = rollout(load_agent(str(out / "final_model.zip")), seeds=[3, 4], dispersion="standard")
    np.testing.assert_array_equal(a.miss_km, b.miss_km)
    student = rollout(load_agent(START), seeds=[3, 4], dispersion="standard")
    assert not np.array_equal(a.cost, student.cost)  # the actor moved after the warm-up
    assert a.provenance["start"] == START and a.provenance["algorithm"].startswith("PPO")
    assert [sorted(s) for s in a.law_stats] == [["load_relief_steps"]] * 2  # the student's load relief flies too
    spec = json.loads((out / "policy.json").read_text())["student"]
    assert spec["start"] == START and spec["start_sha256"] == a.provenance["start_sha256"]
    # the actor the warm-up froze is flown once, at step 0, and the clock runs through both phases
    evals, meta = (json.loads((out / name).read_text()) for name in ("evaluations.json", "metadata.json"))
    assert [e["timesteps"] for e in evals] == [0, 2048]
    assert 0 <= meta["wall_time_s"] - evals[-1]["wall_s"] < evals[0]["wall_s"]


def test_fine_tuning_refuses_a_start_that_is_not_a_student(tmp_path):
    cfg = _small(512, 0)
    cfg["policy"]["start"] = "lqr"
    with pytest.raises(ValueError, match="starts from an imitation student .* not 'lqr'"):
        train_sb3("ppo", cfg, out=tmp_path / "run", progress_bar=False)
    assert not (tmp_path / "run").exists()  # refused before anything was written


@pytest.mark.slow
def test_a_q_floor_in_the_config_is_flown_in_training_and_by_the_trained_policy(tmp_path):
    cfg = _small(512, 512)
    cfg["policy"]["q_floor_margin"] = 0.08
    out = train_sb3("ppo", cfg, out=tmp_path / "run", progress_bar=False)
    spec = json.loads((out / "policy.json").read_text())["student"]
    assert spec["q_floor_margin"] == 0.08
    # the actor never left the student (all warm-up): the policy is the student flying the floor
    law = load_agent(str(out / "final_model.zip"))
    assert law.provenance["q_floor_margin"] == 0.08
    b = rollout(law, seeds=[11], dispersion="wide")
    assert sorted(b.law_stats[0]) == ["load_relief_steps", "q_floor_steps"]


def test_fine_tuning_refuses_a_bad_q_floor_margin_before_writing(tmp_path):
    cfg = _small(512, 0)
    cfg["policy"]["q_floor_margin"] = -0.05
    with pytest.raises(ValueError, match="margin"):
        train_sb3("ppo", cfg, out=tmp_path / "run", progress_bar=False)
    assert not (tmp_path / "run").exists()


def test_the_fine_tuning_env_hands_the_law_the_navigation_state_as_evaluation_does():
    """On `flight` the vehicle's navigation errs; PPO must train on what the law flies by in
    evaluation (rollout hands it info["navigation_state"]), never on the truth."""
    from rventry_agents.finetune import StudentVecEnv
    from rventry_agents.train import make_task, make_vec_env

    cfg = load_config(_small(512, 0))
    assert cfg.env.dispersion == "flight"
    task = make_task(cfg, None)
    mode = cfg.policy.build(task)  # loads the student
    law = mode.student
    seen = []
    observe = law.tracker.estimator.observe
    law.tracker.estimator.observe = lambda m: (seen.append(m.navigation_state.copy()), observe(m))[1]
    venv = make_vec_env(cfg, task, mode=mode)
    student = venv
    while not isinstance(student, StudentVecEnv):
        student = student.venv
    venv.seed(5)
    venv.reset()
    for _ in range(30):
        venv.step(np.zeros((venv.num_envs, 3), np.float32))
    inner = student.venv
    np.testing.assert_array_equal(seen[-1], inner.last_infos["navigation_state"])
    altitude_error = np.abs(seen[-1][:, 0] - inner.venv.state[:, 0])
    assert np.all(altitude_error > 1.0)  # the navigation is off the truth, and the law saw the navigation


def test_the_privileged_features_are_the_draw_itself():
    """Zero without a draw; on the standard set (constant scale factors, exact navigation) the log
    factors are the draw's own scales, and on `flight` the navigation error is nav minus truth."""
    from rventry_agents.finetune import PRIVILEGED, privileged_features
    from rventry_agents.sb3_vec import RvEntrySB3VecEnv
    from rventry_env.task import Dispersion

    def flown(n, dispersion, steps):
        venv = RvEntrySB3VecEnv(n, dispersion=Dispersion.parse(dispersion))
        venv.seed(3)
        venv.reset()
        for _ in range(steps):
            venv.step(np.tile([0.0, 0.02], (n, 1)))
        return venv, privileged_features(venv)

    _, f = flown(3, "none", 5)
    assert f.shape == (3, len(PRIVILEGED)) and f.dtype == np.float32
    np.testing.assert_allclose(f, 0.0, atol=1e-6)
    venv, f = flown(6, "standard", 20)
    inner = venv.venv
    assert np.ptp(inner._density) > 0  # a real draw
    np.testing.assert_allclose(f[:, :3], 0.0, atol=1e-6)
    np.testing.assert_allclose(f[:, 3], np.log(inner._density), atol=1e-6)
    np.testing.assert_allclose(f[:, 4], np.log(inner._density), atol=1e-6)  # no wind: q scales with density
    np.testing.assert_allclose(f[:, 5], np.log(inner._density * inner._lift), atol=1e-6)
    np.testing.assert_allclose(f[:, 6], np.log(inner._density * inner._drag), atol=1e-6)
    venv, f = flown(4, "flight", 30)
    nav, true = venv.navigation_state, venv.true_state
    np.testing.assert_allclose(f[:, 0], (nav[:, 0] - true[:, 0]) / 1000.0, rtol=1e-5)
    assert np.all(f[:, 1] >= np.abs(f[:, 0]) - 1e-6)  # the position error is at least the altitude's
    assert np.all(np.abs(f[:, 3]) > 0)  # the flight set's atmosphere is never the nominal one


@pytest.mark.slow
def test_a_privileged_critic_sees_the_draw_and_the_actor_flies_as_the_student(tmp_path):
    from rventry_agents.finetune import PRIVILEGED

    cfg = _small(512, 512)
    cfg["policy"]["privileged_critic"] = True
    out = train_sb3("ppo", cfg, out=tmp_path / "run", progress_bar=False)
    law = load_agent(str(out / "final_model.zip"))
    policy = law.model.policy
    n = policy.n_actor_inputs
    assert policy.mlp_extractor.policy_net[0].in_features == n
    assert policy.mlp_extractor.value_net[0].in_features == n + len(PRIVILEGED)
    student = rollout(load_agent(START), seeds=[11], dispersion="wide")
    ppo = rollout(law, seeds=[11], dispersion="wide")  # the actor, all warm-up, is the student
    for key in ("miss_km", "cost", "max_load_factor_g"):
        np.testing.assert_array_equal(getattr(ppo, key), getattr(student, key))


@pytest.mark.parametrize("policy, message", [({"privileged_critic": "yes"}, "must be true or false"),
                                             ({"mode": "direct", "privileged_critic": True},
                                              r"\[policy\] .*unknown key 'privileged_critic'; it belongs to mode = 'student', not 'direct'")])  # fmt: skip
def test_a_bad_privileged_critic_setting_is_refused_before_writing(tmp_path, policy, message):
    cfg = _small(512, 0)
    cfg["policy"].update(policy)
    with pytest.raises(ValueError, match=message):
        train_sb3("ppo", cfg, out=tmp_path / "run", progress_bar=False)
    assert not (tmp_path / "run").exists()
