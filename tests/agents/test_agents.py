"""Learning agents: the training pipeline, the shipped policy, loading saved policies, the evaluation JSON schema."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from rventry_env.task import Dispersion, EntryTask
from rventry_agents.sb3_policy import SHIPPED_BASELINES, SHIPPED_PPO_RESIDUAL, SB3Policy
from rventry_env.evaluation.agents import load_agent as load_policy
from rventry_env.evaluation.rollout import rollout

SMOKE_TASK = EntryTask()


def _smoke_config():
    """The shipped config, shrunk to a smoke test (every other key still comes from rventry_agents/ppo.toml)."""
    from rventry_agents.train import load_config

    return load_config().merged({
        "env": {"num_envs": 8, "max_episode_steps": 60}, "ppo": {"n_steps": 64, "batch_size": 256, "n_epochs": 2},
        "policy": {"net_arch_pi": [32], "net_arch_vf": [32]},
        "train": {"eval_every": 1024, "eval_episodes": 4, "checkpoint_every": 1024, "torch_threads": 1},
    })  # fmt: skip


@pytest.mark.slow
def test_training_pipeline_trains_saves_and_reloads(tmp_path):
    from rventry_agents.train import train_ppo

    out = train_ppo(_smoke_config(), timesteps=2048, seed=3, out=tmp_path / "run", task=SMOKE_TASK,
                    progress_bar=False)  # fmt: skip
    for name in ("model.zip", "vecnormalize.pkl", "final_model.zip", "evaluations.json", "metadata.json",
                 "learning_curve.png"):  # fmt: skip
        assert (out / name).exists(), name
    assert list((out / "checkpoints").glob("*.zip"))
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["seed"] == 3 and meta["timesteps"] == 2048 and meta["wall_time_s"] > 0
    evals = json.loads((out / "evaluations.json").read_text())
    assert evals and all(0.0 <= e["success_rate"] <= 1.0 for e in evals)
    policy = SB3Policy(out)
    assert policy.spec["mode"] == "residual" and len(policy.spec["authority_rad"]) == 2
    a = rollout(policy, 2, seed=5, task=SMOKE_TASK, dispersion="standard", max_episode_steps=40)
    b = rollout(SB3Policy(out), 2, seed=5, task=SMOKE_TASK, dispersion="standard", max_episode_steps=40)
    np.testing.assert_array_equal(a.miss_km, b.miss_km)
    # shipping keeps the behaviour and drops the optimizer state
    from rventry_agents.ship import ship

    from stable_baselines3.common.save_util import load_from_zip_file

    shipped = ship(out, tmp_path / "shipped")
    _, params, _ = load_from_zip_file(shipped / "model.zip")
    assert params["policy.optimizer"]["state"] == {}
    c = rollout(SB3Policy(shipped), 2, seed=5, task=SMOKE_TASK, dispersion="standard", max_episode_steps=40)
    np.testing.assert_array_equal(a.miss_km, c.miss_km)
    with pytest.raises(FileNotFoundError, match="not a finished training run"):
        ship(tmp_path / "nothing", tmp_path / "x")
    # a run's model without its observation statistics is refused, never flown on raw observations
    (shipped / "vecnormalize.pkl").unlink()
    with pytest.raises(FileNotFoundError, match=r"no observation statistics beside it \(vecnormalize.pkl\)"):
        SB3Policy(shipped)


def test_residual_policy_mean_is_exactly_zero_on_the_reference():
    """Whatever the weights, a vehicle on the reference gets no correction (rventry_agents/zero_policy.py)."""
    import torch
    from gymnasium import spaces

    from rventry_agents.zero_policy import ZeroOnReferencePolicy

    obs_space = spaces.Box(-10, 10, (51,), np.float32)
    policy = ZeroOnReferencePolicy(obs_space, spaces.Box(-1, 1, (2,), np.float32), lambda _: 1e-4,
                                   n_raw_features=26, use_sde=True)  # fmt: skip
    with torch.no_grad():
        for p in policy.parameters():
            p.normal_(0.0, 1.0)
    rng = np.random.default_rng(0)
    obs = rng.uniform(-1, 1, (64, 51)).astype(np.float32)
    obs[:32, 26:] = 0.0  # the first half sits on the reference
    actions, _ = policy.predict(obs, deterministic=True)
    np.testing.assert_array_equal(actions[:32], 0.0)
    assert np.all(np.abs(actions[32:]).max(axis=1) > 1e-3)  # off the reference it does act


def test_loading_something_that_is_not_a_policy_fails_clearly(tmp_path):
    with pytest.raises(FileNotFoundError, match="no saved policy"):
        load_policy(str(tmp_path / "nothing.zip"))
    with pytest.raises(ValueError, match="unknown agent 'lqrr'.*reference, lqr"):
        load_policy("lqrr")
    bogus = tmp_path / "bogus.zip"
    bogus.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a saved stable-baselines3 model"):
        load_policy(str(bogus))


@pytest.mark.slow
def test_any_saved_sb3_algorithm_loads(tmp_path):
    """`rventry evaluate --agent PATH` takes any SB3 policy, not only PPO: here an untrained SAC."""
    from stable_baselines3 import SAC

    from rventry_env.envs.rv_entry import RvEntryEnv

    SAC("MlpPolicy", RvEntryEnv(), learning_starts=10, buffer_size=100, device="cpu").save(tmp_path / "sac.zip")
    # trained on raw observations, so it says so: a model without its statistics is otherwise refused
    (tmp_path / "policy.json").write_text(json.dumps({"mode": "direct", "normalized": False}))
    policy = load_policy(str(tmp_path / "sac.zip"))
    assert type(policy.model).__name__ == "SAC"
    batch = rollout(policy, 2, seed=1, max_episode_steps=5)
    assert batch.miss_km.shape == (2,)


def _baseline_smoke_config(algorithm: str):
    """A plain baseline's shipped config, shrunk to a smoke test."""
    from rventry_agents.train import BASELINES, load_config

    small = {"learning_starts": 200, "buffer_size": 10_000, "batch_size": 64} if algorithm == "sac" else \
        {"n_steps": 64, "batch_size": 256, "n_epochs": 2}  # fmt: skip
    return load_config(BASELINES / f"{algorithm}.toml", algorithm).merged({
        "env": {"num_envs": 8, "max_episode_steps": 60}, algorithm: small,
        "train": {"eval_every": 1024, "eval_episodes": 4, "checkpoint_every": 1024, "torch_threads": 1},
    })  # fmt: skip


@pytest.mark.parametrize("algorithm", ["ppo", "recurrent_ppo", "sac"])
def test_plain_baseline_configs_fly_directly_from_scratch(algorithm):
    """Each plain baseline is its algorithm alone: direct rate actions, no residual, no shaping, the
    environment's own reward, and at least 10M steps."""
    from rventry_agents.train import BASELINES, load_config

    from rventry_env.envs.reward import RewardWeights

    cfg = load_config(BASELINES / f"{algorithm}.toml", algorithm)
    assert cfg.policy.mode == "direct" and cfg.reward == RewardWeights()
    assert cfg.shaping.range_weight == 0.0
    assert cfg.train.total_timesteps >= 10_000_000
    assert cfg.train.eval_seed != 0  # selection never uses the evaluation's seeds


def test_a_config_without_the_algorithms_section_or_with_a_residual_off_ppo_is_refused(tmp_path):
    from rventry_agents.train import load_config, train_sb3

    with pytest.raises(ValueError, match=r"missing section \[sac\]"):
        load_config(load_config(), "sac")
    with pytest.raises(ValueError, match="unknown algorithm 'dqn'"):
        load_config(None, "dqn")
    cfg = _baseline_smoke_config("sac").to_dict()
    cfg["policy"] = {"mode": "residual", "alpha_authority_deg": 1.0, "sigma_authority_deg": 5.0}
    with pytest.raises(ValueError, match="residual' is built for ppo, not sac"):
        train_sb3("sac", cfg, timesteps=64, out=tmp_path / "run", progress_bar=False)
    assert not (tmp_path / "run").exists()  # refused before anything is written


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ["ppo", "recurrent_ppo", "sac"])
def test_plain_baseline_trains_saves_reloads_and_evaluates_deterministically(tmp_path, algorithm):
    from rventry_agents.ship import ship
    from rventry_agents.train import train_sb3

    out = train_sb3(algorithm, _baseline_smoke_config(algorithm), timesteps=2048, seed=3, out=tmp_path / "run",
                    task=SMOKE_TASK, progress_bar=False)  # fmt: skip
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["algorithm"] == algorithm and meta["timesteps"] == 2048
    assert json.loads((out / "policy.json").read_text())["algorithm"] == algorithm
    assert list((out / "checkpoints").glob(f"{algorithm}_*_steps.zip"))
    policy = SB3Policy(out)
    assert type(policy.model).__name__ == {"ppo": "PPO", "recurrent_ppo": "RecurrentPPO", "sac": "SAC"}[algorithm]
    assert policy.spec["mode"] == "direct" and policy.obs_mean is not None  # running observation statistics
    a = rollout(policy, 3, seed=5, task=SMOKE_TASK, dispersion="standard", max_episode_steps=40)
    b = rollout(SB3Policy(out), 3, seed=5, task=SMOKE_TASK, dispersion="standard", max_episode_steps=40)
    np.testing.assert_array_equal(a.miss_km, b.miss_km)
    c = rollout(SB3Policy(ship(out, tmp_path / "shipped")), 3, seed=5, task=SMOKE_TASK, dispersion="standard",
                max_episode_steps=40)  # fmt: skip
    np.testing.assert_array_equal(a.miss_km, c.miss_km)
    assert not (tmp_path / "shipped" / "resume").exists()
    # an interrupted run goes on from its latest evaluation, with its history and wall time
    history = json.loads((out / "evaluations.json").read_text())
    with pytest.raises(ValueError, match="has done 2,048 of 2,048 steps"):
        train_sb3(algorithm, _baseline_smoke_config(algorithm), timesteps=2048, seed=3, out=out, task=SMOKE_TASK,
                  progress_bar=False, resume=True)  # fmt: skip
    changed = _baseline_smoke_config(algorithm).merged({"train": {"eval_episodes": 5}})
    with pytest.raises(ValueError, match=r"config differs .*\['train'\]"):
        train_sb3(algorithm, changed, timesteps=4096, seed=3, out=out, task=SMOKE_TASK, progress_bar=False, resume=True)
    train_sb3(algorithm, _baseline_smoke_config(algorithm), timesteps=4096, seed=3, out=out, task=SMOKE_TASK,
              progress_bar=False, resume=True)  # fmt: skip
    more = json.loads((out / "evaluations.json").read_text())
    assert more[: len(history)] == history and more[-1]["timesteps"] >= 4096
    assert more[-1]["wall_s"] > history[-1]["wall_s"]
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["timesteps"] == 4096 and meta["resumed_at_timesteps"] == [history[-1]["timesteps"]]
    assert json.loads((out / "resume" / "state.json").read_text())["timesteps"] == more[-1]["timesteps"]
    with pytest.raises(ValueError, match="no resume/ point"):
        train_sb3(algorithm, _baseline_smoke_config(algorithm), timesteps=4096, out=tmp_path / "fresh",
                  task=SMOKE_TASK, progress_bar=False, resume=True)  # fmt: skip


@pytest.mark.slow
def test_a_recurrent_policy_carries_its_memory_per_vehicle_and_reset_clears_it():
    from sb3_contrib import RecurrentPPO

    from rventry_agents.sb3_policy import Predictor
    from rventry_env.envs.rv_entry import RvEntryEnv

    model = RecurrentPPO("MlpLstmPolicy", RvEntryEnv(), n_steps=8, batch_size=8, device="cpu", seed=0,
                         policy_kwargs={"log_std_init": -1.0})  # fmt: skip
    obs = np.tile(RvEntryEnv().reset(seed=0)[0], (2, 1))
    predict = Predictor(model)
    first = predict(obs)
    second = predict(obs)
    assert not np.allclose(first, second)  # the same observation, a different memory
    predict.reset(2)
    np.testing.assert_array_equal(predict(obs), first)


@pytest.mark.slow
def test_shipped_policies_are_present_and_deterministic_for_a_seed():
    # `learned` is the learned policy that lands the most of `flight`: today `ppo-scratch-flight`, by its other name
    learned, scratch = load_policy("learned"), load_policy("ppo-scratch-flight")
    assert learned.provenance["algorithm"] == "PPO (rejax), from scratch" and learned.provenance["start"] == "scratch"
    assert learned.provenance["rung"] == "flight"
    for (w, b), (v, c) in zip(learned.layers + [learned.head], scratch.layers + [scratch.head], strict=True):
        np.testing.assert_array_equal(w, v)  # the same weights under both names
        np.testing.assert_array_equal(b, c)
    student = load_policy("dagger-flight")
    assert type(student).__name__ == "LearnedGuidance" and student.relief is not None  # a student, load-relieved
    assert student.provenance["algorithm"] == "DAgger (supervised imitation of mpc-flight)"
    a = rollout(student, 4, seed=21, dispersion="flight")
    dagger = load_policy("dagger")
    assert dagger.provenance["algorithm"] == "DAgger (supervised imitation of mpc)"
    c = rollout(dagger, 4, seed=21, dispersion=Dispersion.standard())
    assert (c.failure == "").all() and c.is_success.all()  # it lands every one of these
    # `ppo` is the PPO-trained policy: PPO fine-tuning of the flight-set student, which it started from
    ppo = load_policy("ppo")
    assert type(ppo).__name__ == "SB3Policy" and ppo.spec["mode"] == "student"
    assert ppo.provenance["algorithm"] == "PPO (stable-baselines3)" and ppo.provenance["start"] == "dagger-flight"
    assert 0 < ppo.provenance["selected_at_timesteps"] <= ppo.provenance["timesteps"]
    d = rollout(ppo, 4, seed=21, dispersion="flight")
    assert not np.array_equal(d.cost, a.cost)  # PPO moved the student's network
    assert d.is_success.sum() >= 2
    # the PPO residual on TV-LQR keeps its own name
    assert (SHIPPED_PPO_RESIDUAL / "model.zip").exists() and (SHIPPED_PPO_RESIDUAL / "vecnormalize.pkl").exists()
    residual = load_policy("ppo-residual")
    assert residual.spec["mode"] == "residual"
    e = rollout(residual, 4, seed=21, dispersion=Dispersion.standard())
    assert (e.failure == "").all()


@pytest.mark.slow
@pytest.mark.parametrize("agent", ["reference", "learned", "ppo"])
def test_evaluate_cli_writes_the_documented_schema(tmp_path, agent):
    out = tmp_path / "eval.json"
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", agent, "--episodes", "3",
           "--dispersed", "--seed", "4", "--json", str(out), "--plots", str(tmp_path / "plots")]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    doc = json.loads(out.read_text())
    for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "cost_ratio", "success_rate"):
        assert isinstance(doc["summary"][key], float), key
    assert doc["summary"]["success_thresholds"]["miss_km"] == 5.0
    assert len(doc["episodes"]) == 3
    for rec in doc["episodes"]:
        for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg", "cost", "cost_ratio",
                    "max_load_factor_g", "min_dynamic_pressure_pa", "constraint_violation", "success"):  # fmt: skip
            assert key in rec, key
    assert (tmp_path / "plots" / f"trajectories_{agent}.png").stat().st_size > 10_000
    if agent == "learned":  # the report says which shipped policy the name flew, as its training recorded it
        from rventry_agents.jax_policy import SHIPPED
        from rventry_agents.learned import LEARNED

        shipped = json.loads((SHIPPED[LEARNED] / "metadata.json").read_text())["provenance"]
        assert doc["provenance"] == shipped and doc["provenance"]["start"] == "scratch"
    if agent == "ppo":  # what its load relief did, per episode and in the summary
        assert all(rec["load_relief_steps"] >= 0 for rec in doc["episodes"])
        assert doc["summary"]["load_relief"]["capped_steps"] == sum(rec["load_relief_steps"] for rec in doc["episodes"])


def test_evaluate_cli_rejects_bad_arguments(tmp_path):
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "reference", "--episodes", "0",
           "--json", str(tmp_path / "x.json")]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 2 and "positive integer" in res.stderr


def test_a_saved_model_without_its_statistics_is_refused_unless_declared_raw(tmp_path):
    """A model.zip alone is refused (raw observations would fly a different policy), naming the two ways out."""
    import shutil

    shutil.copy(SHIPPED_BASELINES / "ppo" / "model.zip", tmp_path / "model.zip")
    with pytest.raises(ValueError, match=r"vecnormalize.pkl.*\"normalized\": false"):
        load_policy(str(tmp_path / "model.zip"))
    (tmp_path / "policy.json").write_text(json.dumps({"mode": "direct", "normalized": False}))
    policy = SB3Policy(tmp_path / "model.zip")
    assert policy.normalize_path is None and policy.obs_mean is None


def test_ship_puts_each_kind_of_run_in_its_own_place_by_default(tmp_path):
    """Shipping a fine-tuning run must not overwrite the PPO residual, nor a baseline either."""
    from rventry_agents.dagger import SHIPPED_DAGGER
    from rventry_agents.sb3_policy import SHIPPED_PPO_FINETUNE
    from rventry_agents.ship import default_destination

    def run(name, spec=None, student=False):
        d = tmp_path / name
        d.mkdir()
        if spec is not None:
            (d / "policy.json").write_text(json.dumps(spec))
        if student:
            (d / "student.json").write_text("{}")
        return d

    shipped = {name: json.loads((folder / "policy.json").read_text()) for name, folder in
               (("ft", SHIPPED_PPO_FINETUNE), ("res", SHIPPED_PPO_RESIDUAL))}  # fmt: skip
    assert shipped["ft"]["mode"] == "student" and shipped["res"]["mode"] == "residual"
    assert default_destination(run("ft", shipped["ft"])) == SHIPPED_PPO_FINETUNE
    assert default_destination(run("res", shipped["res"])) == SHIPPED_PPO_RESIDUAL
    assert default_destination(run("sac", {"algorithm": "sac", "mode": "direct"})) == SHIPPED_BASELINES / "sac"
    assert default_destination(run("dagger", student=True)) == SHIPPED_DAGGER
    with pytest.raises(ValueError, match=r"no shipped place for mode 'direct', algorithm 'a2c'; give --dest"):
        default_destination(run("a2c", {"algorithm": "a2c", "mode": "direct"}))
