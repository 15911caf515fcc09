"""Typed configurations: the schema base, every shipped config and record through its schema, and
the refusals (unknown keys, wrong types, bad values, corrupt files) named before anything is written."""

from __future__ import annotations

import inspect
import json
import math
import pickle
import shutil
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from rventry_agents.config import ConfigError, Section, setting
from rventry_agents.dagger_config import DaggerConfig
from rventry_agents.dagger_config import load_config as load_dagger_config
from rventry_agents.sb3_config import BASELINES, DEFAULT_CONFIG, FINETUNE_CONFIG, load_config

AGENTS = Path(__file__).resolve().parents[2] / "rventry_agents"
DATA = AGENTS / "data"
RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"
# every config shipped in the package, with its algorithm (None: a DAgger config); the JAX trainer's are its own
SHIPPED_CONFIGS = {
    "ppo.toml": "ppo", "ppo_finetune.toml": "ppo", "baselines/ppo.toml": "ppo",
    "baselines/recurrent_ppo.toml": "recurrent_ppo", "baselines/sac.toml": "sac",
    "dagger.toml": None, "dagger_flight.toml": None,
}  # fmt: skip
SHIPPED_RUNS = sorted(p.parent for p in DATA.rglob("metadata.json")) + sorted(p.parent for p in RESULTS.glob("*/metadata.json"))


def _load(rel: str, data: dict | None = None):
    algorithm = SHIPPED_CONFIGS[rel]
    source = AGENTS / rel if data is None else data
    return load_dagger_config(source) if algorithm is None else load_config(source, algorithm)


def test_every_shipped_toml_loads_through_its_schema_and_round_trips():
    assert sorted(p.relative_to(AGENTS).as_posix() for p in [*AGENTS.glob("*.toml"), *BASELINES.glob("*.toml")]
                  if not p.name.startswith(("jax_ppo", "ppo_scratch"))) == sorted(SHIPPED_CONFIGS)  # fmt: skip
    for rel in SHIPPED_CONFIGS:
        cfg = _load(rel)
        assert _load(rel, cfg.to_dict()) == cfg, rel
        assert json.loads(json.dumps(cfg.to_dict())) == cfg.to_dict(), rel  # a run record
    assert load_config(FINETUNE_CONFIG).policy.start == "dagger-flight"
    assert load_config(DEFAULT_CONFIG).policy.mode == "residual"


@pytest.mark.parametrize("run", SHIPPED_RUNS, ids=lambda p: p.relative_to(p.parents[1]).as_posix())
def test_every_shipped_run_folders_records_load_through_their_schemas(run):
    """The configs inside the shipped policies' folders and the result records' runs (older runs
    left defaults out), and the records a loader reads beside them."""
    from rventry_agents.records import PolicyRecord, RunRecord, StudentRecord

    meta = RunRecord.read_json(run / "metadata.json")
    if "rounds" in meta.config:
        assert isinstance(load_dagger_config(meta.config, str(run)), DaggerConfig)
    elif "chunk_timesteps" not in meta.config.get("train", {}):  # a JAX run: its trainer reads its own
        cfg = load_config(meta.config, meta.algorithm or "ppo", str(run))
        assert cfg.to_dict().keys() >= meta.config.keys()
    if (run / "policy.json").is_file():
        assert PolicyRecord.read_json(run / "policy.json").mode in ("direct", "residual", "student")
    if (run / "student.json").is_file():
        assert StudentRecord.read_json(run / "student.json").hidden == (256, 256)


def test_the_deploy_sections_old_name_is_read_from_a_file_with_a_warning_and_from_a_record_without_one(tmp_path):
    """``[deploy]`` was ``[flight]``: a config file with the old name still loads, as the same config,
    asking to rename it; a run record with it (the shipped runs' metadata.json) loads quietly; both
    names at once are refused."""
    import warnings

    text = (AGENTS / "dagger.toml").read_text()
    new = load_dagger_config(AGENTS / "dagger.toml")
    assert "\n[deploy]\n" in text
    old = tmp_path / "old.toml"
    old.write_text(text.replace("\n[deploy]\n", "\n[flight]\n"))
    with pytest.warns(FutureWarning, match=r"old.toml: the section \[flight\] is now called \[deploy\].*rename it"):
        assert load_dagger_config(old) == new
    shipped = json.loads((DATA / "dagger" / "metadata.json").read_text())["config"]
    assert "flight" in shipped and "deploy" not in shipped  # the record of a run from before the name
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cfg = load_dagger_config(shipped, "metadata.json [config]")
    assert cfg.deploy.tracking == tuple(tuple(pair) for pair in shipped["flight"]["tracking"]) and cfg.deploy.tracking
    assert "deploy" in cfg.to_dict() and "flight" not in cfg.to_dict()  # written back under the new name
    both = tmp_path / "both.toml"
    both.write_text(text + "\n[flight]\ntracking_descent_mps = 2000.0\n")
    with pytest.raises(ConfigError, match=r"both.toml: \[flight\] is the old name of \[deploy\]; give only \[deploy\]"):
        load_dagger_config(both)


def test_a_dagger_run_from_before_the_deploy_record_ships_its_flight_json_as_deploy_json(tmp_path):
    from rventry_agents.ship import ship

    run = tmp_path / "run"
    shutil.copytree(DATA / "dagger", run)
    (run / "deploy.json").rename(run / "flight.json")  # as an older run wrote it
    dest = ship(run, tmp_path / "shipped")
    assert (dest / "deploy.json").read_bytes() == (run / "flight.json").read_bytes()
    assert not (dest / "flight.json").exists()


def _misspelled(key: str) -> str:
    return key[:-1] + ("x" if key[-1] != "x" else "y")


@pytest.mark.parametrize("rel", SHIPPED_CONFIGS)
def test_a_misspelled_key_or_section_is_refused_with_its_name_in_every_shipped_config(rel, tmp_path):
    data = tomllib.loads((AGENTS / rel).read_text())
    for section, table in data.items():
        if not isinstance(table, dict):
            continue
        key = next(k for k in table if k != "mode")
        bad = {**data, section: {**{k: v for k, v in table.items() if k != key}, _misspelled(key): table[key]}}
        with pytest.raises(ConfigError, match=rf"\[{section}\] unknown key '{_misspelled(key)}'") as err:
            _load(rel, bad)
        assert f"did you mean '{key}'" in str(err.value) or "belongs to mode" in str(err.value), str(err.value)
    first = next(iter(data))
    bad = {_misspelled(first): data[first], **{k: v for k, v in data.items() if k != first}}
    with pytest.raises(ConfigError, match=rf"unknown section \[{_misspelled(first)}\].*missing section \[{first}\]"):
        _load(rel, bad)
    # in a file, the message names the file
    path = tmp_path / "bad.toml"
    path.write_text((AGENTS / rel).read_text().replace("\n[", "\nbogus_key = 1\n[", 1))
    with pytest.raises(ConfigError, match=r"bad.toml: .*unknown key 'bogus_key'"):
        load_dagger_config(path) if SHIPPED_CONFIGS[rel] is None else load_config(path, SHIPPED_CONFIGS[rel])


@pytest.mark.parametrize("section, key, value, message", [
    ("ppo", "learning_rate", math.nan, r"\[ppo\] learning_rate must be a finite number > 0, got nan"),
    ("ppo", "n_steps", 1.5, r"\[ppo\] n_steps must be a whole number, got 1.5"),
    ("ppo", "gamma", 1.5, r"\[ppo\] gamma must be a finite number > 0 and <= 1, got 1.5"),
    ("env", "num_envs", 0, r"\[env\] num_envs must be a whole number >= 1, got 0"),
    ("env", "dt", "1.0", r"\[env\] dt must be a number, got '1.0'"),
    ("env", "time_limit_is_failure", 1, r"\[env\] time_limit_is_failure must be true or false, got 1"),
    ("env", "dispersion", "windy", r"\[env\] dispersion: cannot make a Dispersion from 'windy'"),
    ("policy", "net_arch_pi", [], r"\[policy\] net_arch_pi must be a list of layer widths .*not empty"),
    ("policy", "activation", "sigmoid", r"\[policy\] activation must be one of 'tanh', 'relu', 'elu'"),
    ("policy", "alpha_authority_deg", -1.0, r"\[policy\] alpha_authority_deg must be a finite number > 0, got -1.0"),
    ("policy", "mode", "hybrid", r"\[policy\] mode must be one of 'direct', 'residual', 'student', got 'hybrid'"),
    ("reward", "failure", math.inf, r"\[reward\] failure must be a finite number, got inf"),
    ("train", "eval_episodes", True, r"\[train\] eval_episodes must be a whole number, got True"),
])  # fmt: skip
def test_a_wrong_type_or_value_is_refused_naming_the_key(section, key, value, message):
    data = tomllib.loads(DEFAULT_CONFIG.read_text())
    data.setdefault(section, {})[key] = value
    with pytest.raises(ConfigError, match=message):
        load_config(data, "ppo")


def test_a_resumed_or_direct_policy_refuses_what_is_not_its_algorithms():
    data = tomllib.loads((BASELINES / "sac.toml").read_text())
    with pytest.raises(ConfigError, match=r"\[policy\] net_arch_vf is not a network of sac"):
        load_config({**data, "policy": {**data["policy"], "net_arch_vf": [8]}}, "sac")
    with pytest.raises(ConfigError, match=r"\[policy\] lstm_hidden_size configure RecurrentPPO's LSTM, not sac"):
        load_config({**data, "policy": {**data["policy"], "lstm_hidden_size": 8}}, "sac")
    with pytest.raises(ConfigError, match=r"mode = 'student' is built for ppo, not sac"):
        load_config({**data, "policy": {"mode": "student", "start": "dagger"}}, "sac")
    with pytest.raises(ConfigError, match=r"missing section \[sac\].*unknown section \[ppo\]|unknown section \[ppo\].*missing section \[sac\]"):
        load_config(load_config(), "sac")


def test_the_algorithms_defaults_are_the_libraries_own():
    """Each default is written once: the schema's hyperparameter defaults are stable-baselines3's."""
    from dataclasses import fields

    from sb3_contrib import RecurrentPPO
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import VecNormalize

    from rventry_agents.sb3_config import NormalizeSection, PPOSection, RecurrentPPOSection, SACSection

    for section, cls in ((PPOSection, PPO), (RecurrentPPOSection, RecurrentPPO), (SACSection, SAC),
                         (NormalizeSection, VecNormalize)):  # fmt: skip
        signature = inspect.signature(cls.__init__).parameters
        for f in fields(section):
            assert f.name in signature, (section.__name__, f.name)
            assert f.default == signature[f.name].default, (section.__name__, f.name)


def test_the_dagger_config_refuses_bad_values_before_anything_is_flown_or_written(tmp_path):
    from dagger_configs import SMALL

    from rventry_agents.dagger import train_dagger

    cases = {
        "learning_rate = 1e-3": ("learning_rate = nan", r"\[fit\] learning_rate must be a finite number > 0, got nan"),
        "hidden = [16, 16]": ("hidden = []", r"\[student\] hidden must be a list of layer widths .*not empty"),
        "seed = 0\n": ("seed = 0\nbogus_key = 1\n", r"\[fit\] unknown key 'bogus_key'"),
        'agent = "lqr"': ('agent = "lqrr"', r"\[expert\] agent 'lqrr' is neither an agent"),
        '[expert]\nagent = "lqr"': ('[expert]\nagent = "mpc"\nq_marjin = 0.1', r"\[expert\] unknown key 'q_marjin'"),
        "[select]\nepisodes = 3": ("[select]\nepisodes = 3\ndispersion_set = 1", r"\[select\] unknown key 'dispersion_set'"),
    }  # fmt: skip
    cfg = tmp_path / "bad.toml"
    for good, (bad, message) in cases.items():
        assert good in SMALL
        cfg.write_text(SMALL.replace(good, bad, 1))
        with pytest.raises(ValueError, match=message):
            train_dagger(cfg, tmp_path / "never", workers=1, progress_bar=False)
        assert not (tmp_path / "never").exists(), message


# -- the base, as another trainer would use it


@dataclass(frozen=True, kw_only=True)
class _Net(Section):
    hidden: tuple[int, ...] = setting((64, 64), ge=1, nonempty=True)
    activation: str = "tanh"


@dataclass(frozen=True, kw_only=True)
class _Stage(Section):
    steps: int = setting(ge=1)
    rate: float | None = setting(None, gt=0, le=1)


@dataclass(frozen=True, kw_only=True)
class _Trainer(Section):
    net: _Net = _Net()
    stages: tuple[_Stage, ...] = setting(nonempty=True)
    extra: _Net | None = None
    horizon_s: float = setting(math.inf, gt=0, finite=False)

    def __post_init__(self):
        super().__post_init__()
        if self.stages[0].steps < 10:
            raise ConfigError("[stages][0] steps: the first stage needs at least 10")


def test_a_trainer_declares_its_schema_in_a_few_lines_and_gets_every_check():
    cfg = _Trainer.from_dict({"stages": [{"steps": 10}, {"steps": 5, "rate": 1}]})
    assert cfg.net.hidden == (64, 64) and cfg.stages[1].rate == 1.0 and isinstance(cfg.stages[1].rate, float)
    assert cfg.extra is None and cfg.horizon_s == math.inf
    assert cfg.to_dict() == {"net": {"hidden": [64, 64], "activation": "tanh"},
                             "stages": [{"steps": 10}, {"steps": 5, "rate": 1.0}], "horizon_s": math.inf}  # fmt: skip
    assert _Trainer.from_dict(cfg.to_dict()) == cfg
    assert cfg.merged({"net": {"hidden": [8]}}).net == _Net(hidden=(8,))
    refusals = {
        "trainer.toml: [stages][1] rate must be a finite number > 0 and <= 1, got 2.0": {"stages": [{"steps": 10}, {"steps": 1, "rate": 2.0}]},
        "trainer.toml: [stages][0] steps: the first stage needs at least 10": {"stages": [{"steps": 3}]},
        "trainer.toml: [net] hidden must be a list of whole numbers, each >= 1, got [8, 0]": {"net": {"hidden": [8, 0]}, "stages": [{"steps": 10}]},
        "trainer.toml: [net] unknown key 'hiden'; did you mean 'hidden'?": {"net": {"hiden": [8]}, "stages": [{"steps": 10}]},
        "trainer.toml: missing key 'stages'": {},
        "trainer.toml: [extra] activation must be a string, got 3": {"extra": {"activation": 3}, "stages": [{"steps": 10}]},
        'trainer.toml: stages must be a list of tables, got {"steps": 10}': {"stages": {"steps": 10}},
    }  # fmt: skip
    for message, data in refusals.items():
        with pytest.raises(ConfigError) as err:
            _Trainer.from_dict(data, "trainer.toml")
        assert str(err.value) == message
    with pytest.raises(ConfigError, match=r"steps must be a whole number >= 1, got 0"):
        _Stage(steps=0)  # built in Python, checked the same
    with pytest.raises(TypeError, match="immutable"):
        setting([1, 2])


def test_a_toml_file_that_is_not_toml_is_refused_naming_it(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[env\nnum_envs = 1")
    with pytest.raises(ConfigError, match="bad.toml is not valid TOML"):
        load_config(bad)
    with pytest.raises(FileNotFoundError, match="no config at"):
        load_config(tmp_path / "none.toml")
    with pytest.raises(IsADirectoryError):
        load_config(tmp_path)


# -- policy modes


def test_each_mode_round_trips_through_its_record_and_knows_where_it_ships():
    from rventry_agents.modes import SHIPPED_BASELINES, SHIPPED_PPO_RESIDUAL, DirectMode, PolicyMode, ResidualMode
    from rventry_agents.records import PolicyRecord
    from rventry_env.task import EntryTask

    residual = load_config(DEFAULT_CONFIG).policy.build(EntryTask())
    assert isinstance(residual, ResidualMode) and residual.zero_init
    assert residual.authority_rad == (math.radians(1.0), math.radians(5.0))
    again = PolicyMode.of_record(PolicyRecord.from_dict(json.loads(json.dumps({"algorithm": "ppo", **residual.record()}))))
    assert again.authority_rad == residual.authority_rad and again.destination("ppo") == SHIPPED_PPO_RESIDUAL
    direct = PolicyMode.of_record(PolicyRecord.from_dict({"algorithm": "sac", "mode": "direct"}))
    assert isinstance(direct, DirectMode) and direct.destination("sac") == SHIPPED_BASELINES / "sac"
    with pytest.raises(ValueError, match="no shipped place for mode 'direct', algorithm 'a2c'"):
        direct.destination("a2c")
    with pytest.raises(ValueError, match="a q floor belongs to a policy fine-tuned from a student, not to a 'residual'"):
        residual.with_q_floor(0.05)
    with pytest.raises(ConfigError, match="mode 'residual' needs authority_rad"):
        PolicyRecord.from_dict({"mode": "residual"})


def test_the_shipped_fine_tuned_policy_record_is_what_its_mode_writes_back():
    from rventry_agents.modes import PolicyMode
    from rventry_agents.records import PolicyRecord

    path = DATA / "ppo_finetune" / "policy.json"
    record = PolicyRecord.read_json(path)
    mode = PolicyMode.of_record(record)
    written = {"algorithm": record.algorithm, **mode.record()}
    stored = json.loads(path.read_text())
    assert written["student"] == {k: v for k, v in stored["student"].items() if v is not None}
    assert mode.with_q_floor(None).spec.q_floor_margin is None and mode.spec.q_floor_margin == 0.08


# -- the task-metric callback, alone


class _FakeModel:
    """What TaskMetricEval reads of a model: steps, episode returns, saving, a normalization."""

    def __init__(self):
        self.num_timesteps, self.ep_info_buffer, self.saved = 0, [{"r": -3.0}], []
        self.replay_buffer = None

    def save(self, path):
        self.saved.append(Path(path).name)
        Path(path).write_bytes(b"model")

    def get_vec_normalize_env(self):
        return self

    def normalize_obs(self, obs):
        return obs


def _glide():
    """A law that holds its angles."""
    from rventry_env.guidance.law import Law

    class Glide(Law):
        def __call__(self, m):
            return np.zeros((m.n, 2), np.float32)

    return Glide()


def test_the_task_metric_callback_evaluates_keeps_the_best_and_writes_a_resume_point(tmp_path):
    from stable_baselines3.common.logger import configure

    from rventry_agents.callbacks import TaskMetricEval
    from rventry_agents.sb3_config import TrainSection
    from rventry_env.task import EntryTask

    train = TrainSection(total_timesteps=100, seed=0, checkpoint_every=10, eval_every=50, eval_episodes=1,
                         eval_seed=7, eval_dispersion="none")  # fmt: skip
    model = _FakeModel()
    model.logger = configure(None, [])
    flown = []
    evaluator = TaskMetricEval(train, lambda m: flown.append(m) or _glide(), EntryTask(), 5, tmp_path, None)
    evaluator.init_callback(model)
    evaluator.on_training_start({}, {})  # the untrained policy competes too
    first = json.loads((tmp_path / "evaluations.json").read_text())
    assert len(first) == 1 and first[0]["best"] and first[0]["timesteps"] == 0 and first[0]["cost_ratio"] is None
    assert first[0]["train_ep_return"] == -3.0 and flown == [model]
    assert (tmp_path / "model.zip").is_file() and json.loads((tmp_path / "resume" / "state.json").read_text())["timesteps"] == 0
    model.num_timesteps = 49
    assert evaluator.on_step() and len(evaluator.history) == 1  # not yet
    model.num_timesteps = 50
    evaluator.on_step()
    assert len(evaluator.history) == 2 and "best" not in evaluator.history[1]  # the same flight: not better
    assert evaluator.next_eval == 100
    resumed = TaskMetricEval(train, lambda m: _glide(), EntryTask(), 5, tmp_path, None,
                             resumed={"timesteps": 50, "wall_s": 3.0, "history": evaluator.history, "resumes": []})  # fmt: skip
    assert resumed.next_eval == 100 and resumed.resumes == [50] and resumed.wall_before == 3.0


# -- resume checks read the old records through the schema


def _sb3_run(tmp_path, config: dict) -> Path:
    out = tmp_path / "run"
    (out / "resume").mkdir(parents=True)
    (out / "policy.json").write_text(json.dumps({"algorithm": "ppo", "mode": "direct", "authority_rad": [0.0, 0.0]}))
    (out / "config.json").write_text(json.dumps(config))
    (out / "resume" / "state.json").write_text(json.dumps({"timesteps": 10, "wall_s": 1.0, "resumes": []}))
    (out / "evaluations.json").write_text(json.dumps([{"timesteps": 0, "success_rate": 0.0, "miss_km": 1.0}]))
    return out


def test_a_resume_compares_the_config_a_run_started_with_through_the_schema(tmp_path):
    from rventry_agents.train import read_resume_point

    old = json.loads((DATA / "baselines" / "ppo" / "metadata.json").read_text())["config"]  # defaults left out
    assert "reward" not in old and "clip_range_vf" not in old["ppo"]
    out = _sb3_run(tmp_path, old)
    assert read_resume_point(out, "ppo", load_config(BASELINES / "ppo.toml"))["timesteps"] == 10
    changed = load_config(BASELINES / "ppo.toml").merged({"reward": {"failure": 20.0}})
    with pytest.raises(ValueError, match=r"config differs from the one it started with \(sections \['reward'\]\)"):
        read_resume_point(out, "ppo", changed)
    (out / "config.json").write_text("{")
    with pytest.raises(ConfigError, match="config.json is not valid JSON"):
        read_resume_point(out, "ppo", changed)


def test_a_dagger_resume_reads_an_older_run_json_that_left_defaults_out(tmp_path):
    from dagger_configs import SMALL

    from rventry_agents.dagger import check_resumable, prepare_run

    (tmp_path / "small.toml").write_text(SMALL)
    run = prepare_run(tmp_path / "small.toml", tmp_path / "run", workers=1, seed=None)
    run.out.mkdir()  # the folder an earlier run left (preparing a run creates nothing)
    raw = tomllib.loads(SMALL)
    (run.out / "run.json").write_text(json.dumps({"seed": None, **{k: raw[k] for k in ("student", "expert", "data", "fit", "select")}}))
    assert "weight_decay" not in raw["fit"] and "members" not in raw["student"]
    check_resumable(run, resume=True)  # the same run: its defaults are the schema's
    (run.out / "run.json").write_text(json.dumps({"seed": None, **{k: raw[k] for k in ("student", "expert", "data", "select")},
                                                  "fit": {**raw["fit"], "weight_decay": 0.1}}))  # fmt: skip
    with pytest.raises(ValueError, match=r"changed: fit.weight_decay \(0.1 -> 0.0\)"):
        check_resumable(run, resume=True)


# -- corrupt files beside a policy are refused, named, never a traceback


@pytest.fixture()
def baseline(tmp_path) -> Path:
    folder = tmp_path / "baseline"
    shutil.copytree(DATA / "baselines" / "ppo", folder)
    return folder


@pytest.mark.parametrize("name, content, message", [
    ("vecnormalize.pkl", b"", r"vecnormalize.pkl is not a VecNormalize file stable-baselines3 saved \(EOFError"),
    ("vecnormalize.pkl", bytes(range(256)) * 4, r"vecnormalize.pkl is not a VecNormalize file stable-baselines3 saved"),
    ("vecnormalize.pkl", pickle.dumps(7), r"vecnormalize.pkl holds a int, not stable-baselines3's VecNormalize"),
    ("policy.json", b"{", r"policy.json is not valid JSON"),
    ("policy.json", b"[]", r"policy.json must hold a JSON object, got list"),
    ("policy.json", b'{"mode": "bogus"}', r"policy.json: mode must be one of 'direct', 'residual', 'student'"),
    ("policy.json", b'{"mode": "student"}', r"policy.json: mode 'student' needs the student"),
    ("metadata.json", b'{"config": {"env": {}}}', r"metadata.json \[config\]: .*missing section \[normalize\]"),
    ("metadata.json", b'{"config": 3}', r"metadata.json: config must be a table, got 3"),
    ("metadata.json", b"\xff", r"metadata.json is not valid JSON"),
])  # fmt: skip
def test_a_corrupt_file_beside_a_saved_policy_is_refused_naming_it(baseline, name, content, message):
    from rventry_env.evaluation.agents import load_agent

    (baseline / name).write_bytes(content)
    with pytest.raises(ValueError, match=message):
        load_agent(str(baseline))


@pytest.mark.parametrize("name, content, message", [
    ("student.pt", b"", r"student.pt: these bytes hold no student network"),
    ("student.pt", b"junk" * 100, r"student.pt: these bytes hold no student network"),
    ("student.json", b"[]", r"student.json must hold a JSON object, got list"),
    ("student.json", b'{"members": 1}', r"student.json: missing key 'hidden'"),
    ("student.json", b'{"hidden": [256, 256], "lookahead_s": -1}', r"student.json: lookahead_s must be a finite number > 0"),
    ("metadata.json", b'{"config": {"student": {}}}', r"metadata.json \[config\]: .*missing"),
])  # fmt: skip
def test_a_corrupt_dagger_run_folder_is_refused_naming_the_file(tmp_path, name, content, message):
    from rventry_agents.dagger import load_saved

    folder = tmp_path / "dagger"
    shutil.copytree(DATA / "dagger", folder)
    (folder / name).write_bytes(content)
    with pytest.raises(ValueError, match=message):
        load_saved(str(folder))


def test_the_train_commands_refuse_a_file_as_out_and_a_config_of_another_mode(tmp_path, capsys):
    from rventry_env.cli import main

    file = tmp_path / "taken"
    file.write_text("x")
    assert main(["train", "ppo-plain", "--out", str(file), "--timesteps", "64"]) == 2
    assert f"{file} exists and is not a folder" in capsys.readouterr().err and file.read_text() == "x"
    assert main(["train", "ppo", "--out", str(file), "--timesteps", "64"]) == 2  # the older name, the same
    assert main(["train", "ppo-residual", "--config", str(BASELINES / "ppo.toml"), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "trains [policy] mode = 'direct'" in err and "use `rventry train ppo-plain`" in err
    assert not (tmp_path / "r").exists()
    bad = tmp_path / "bad.toml"
    bad.write_text((BASELINES / "ppo.toml").read_text().replace("[ppo]\n", "[ppo]\nbogus_key = 1\n"))
    assert main(["train", "ppo-plain", "--config", str(bad), "--out", str(tmp_path / "b")]) == 2
    assert "bad.toml: [ppo] unknown key 'bogus_key'" in capsys.readouterr().err and not (tmp_path / "b").exists()


def test_the_scratch_command_says_why_a_run_of_one_chunk_has_no_speed(tmp_path, capsys, monkeypatch):
    """The first chunk a process trains includes its compilation and is not timed: a process that
    trained one chunk (a resume for one chunk) measured no speed, and says so rather than printing
    nan; a process with a timed chunk prints its median rate."""
    pytest.importorskip("jax")
    from rventry_agents import scratch
    from rventry_env.cli import main

    select = {"success_rate": 0.25}
    for rate, said in ((None, "no chunk timed after the one that compiled"), (123456.7, "123,457 env-steps/s")):
        meta = {"timesteps": 4096, "wall_s": 12.0, "env_steps_per_s": rate, "best_evaluation": {"select": select}}
        monkeypatch.setattr(scratch, "train_scratch", lambda *a, meta=meta, **k: meta)
        assert main(["train", "ppo-scratch", "--out", str(tmp_path / "run")]) == 0
        out = capsys.readouterr().out
        assert f"4,096 steps in 12 s ({said}); selected policy: success 0.25 on the selection set" in out
        assert "nan" not in out


def test_each_train_command_says_what_it_trains():
    from rventry_env.cli import build_parser

    parser = build_parser()
    helps = {}
    for action in parser._subparsers._group_actions[0].choices["train"]._subparsers._group_actions[0]._choices_actions:
        helps[action.dest] = action.help
    assert "PPO residual on TV-LQR" in helps["ppo-residual"] and "ships as the agent ppo-residual" in helps["ppo-residual"]
    start = load_config(FINETUNE_CONFIG).policy.start
    assert f"({start}, by default)" in helps["ppo-finetune"] and "ships as the agent ppo)" in helps["ppo-finetune"]
    assert "from scratch" in helps["ppo-plain"] and "from scratch" in helps["sac-plain"]
    for alias, name in (("sac", "sac-plain"), ("recurrent-ppo", "recurrent-ppo-plain")):
        args = parser.parse_args(["train", alias])
        assert args.command_name == name and args.mode == "direct"


def test_a_corrupt_dagger_run_is_refused_on_resume_naming_the_file(tmp_path):
    from dagger_configs import SMALL

    from rventry_agents.dagger import RunClock, prepare_run, run_rounds

    (tmp_path / "small.toml").write_text(SMALL)
    run = prepare_run(tmp_path / "small.toml", tmp_path / "run", workers=1, seed=None)
    run.out.mkdir()  # the folder an earlier run left (preparing a run creates nothing)
    rec = {"round": 0, "episodes": 2, "beta": 1.0, "samples": 10, "wall_s": 1.0, "select_success_rate": 0.0,
           "select_miss_km_mean": 1.0, "load_relief_margin": 0.02}  # fmt: skip
    for rounds, message in (([{"round": 0}], r"rounds.json: round 0's record is malformed \(missing episodes"),
                            ({"round": 0}, r"rounds.json must hold a JSON array"),
                            ([rec], r"cannot resume: .*data_round_0.npz is unreadable")):  # fmt: skip
        (run.out / "rounds.json").write_text(json.dumps(rounds))
        (run.out / "data_round_0.npz").write_bytes(b"junk")
        with pytest.raises(ValueError, match=message):
            run_rounds(run, RunClock(), resume=True, progress_bar=False)


def test_the_jax_ppo_baseline_config_is_typed_and_refuses_a_misspelled_key():
    from rventry_agents.jax_ppo_config import DEFAULT_CONFIG as JAX_PPO, JaxPPOConfig
    from rventry_agents.jax_ppo_config import load_config as load_jax_ppo

    for path in sorted(JAX_PPO.parent.glob("jax_ppo*.toml")):  # the two-core and the GPU baselines
        shipped = load_jax_ppo(path)
        assert load_jax_ppo(shipped.to_dict()) == shipped, path.name
    cfg = load_jax_ppo()
    assert Path(JAX_PPO).name == "jax_ppo.toml" and isinstance(cfg, JaxPPOConfig)
    assert cfg.env.num_envs == 256 and cfg.ppo.hidden_layer_sizes == (256, 256) and cfg.train.eval_dispersion == "standard"
    assert load_jax_ppo(cfg.to_dict()) == cfg and json.loads(json.dumps(cfg.to_dict())) == cfg.to_dict()
    bad = cfg.to_dict()
    bad["ppo"]["num_minibatch"] = 4
    with pytest.raises(ConfigError, match=r"\[ppo\] unknown key 'num_minibatch'; did you mean 'num_minibatches'"):
        load_jax_ppo(bad)
    odd = cfg.to_dict()
    odd["ppo"]["num_minibatches"] = 3
    with pytest.raises(ConfigError, match=r"num_minibatches \(3\) must divide a rollout's 16,384 steps"):
        load_jax_ppo(odd)
