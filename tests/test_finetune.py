"""PPO from the imitation student: the actor starts as the student, trains, saves, reloads and flies."""

from __future__ import annotations

import hashlib
import json
import tomllib

import numpy as np
import pytest

from rventry_agents.imitation import network_bytes
from rventry_agents.train import FINETUNE_CONFIG, train_sb3
from rventry_env.evaluation.agents import load_agent
from rventry_env.evaluation.rollout import rollout

START = tomllib.loads(FINETUNE_CONFIG.read_text())["policy"]["start"]  # the shipped config's student


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
    from rventry_agents.finetune import StudentScales, StudentVecEnv, load_start
    from rventry_agents.train import make_task, make_vec_env

    cfg = _small(512, 0)
    assert cfg["env"]["dispersion"] == "flight"
    task = make_task(cfg, None)
    law = load_start(START, task)
    seen = []
    observe = law.tracker.estimator.observe
    law.tracker.estimator.observe = lambda m: (seen.append(m.navigation_state.copy()), observe(m))[1]
    venv = make_vec_env(cfg, task, student=(law, StudentScales.of(law.network)))
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
