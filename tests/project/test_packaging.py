"""The wheel carries every file the package loads, and an installed wheel finds them.

The wheel is built from the tracked files alone (a copy of what ``git ls-files`` lists),
installed into an empty folder, and imported from there in a fresh interpreter that
loads each shipped file through the public API.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("rventry_env", "rventry_agents")

LOAD_EVERYTHING = r"""
import sys
from pathlib import Path
target = Path(sys.argv[1]).resolve()
import rventry_env, rventry_agents
for mod in (rventry_env, rventry_agents):
    assert Path(mod.__file__).resolve().is_relative_to(target), mod.__file__
from rventry_env.reference import load_reference, load_guidance_reference
from rventry_env.reference.data_file import DEFAULT_PATH, GUIDANCE_PATH
assert DEFAULT_PATH.resolve().is_relative_to(target)
ref, gref = load_reference(), load_guidance_reference()
assert ref.summary()["converged"] and gref.summary()["converged"]
from rventry_env.validation.apollo4 import record_path
from rventry_env.validation.record import load_record
assert Path(record_path()).resolve().is_relative_to(target)
load_record(record_path())
from rventry_agents.train import load_config
load_config()
from rventry_agents.sb3_policy import SHIPPED_PPO_AGENTS, load_shipped as load_ppo
for name, folder in SHIPPED_PPO_AGENTS.items():  # every shipped PPO-trained policy loads from the wheel, with its record
    policy = load_ppo(name)
    assert folder.resolve().is_relative_to(target) and policy.model is not None, name
    assert policy.obs_mean is not None or policy.normalize_path is not None, name
    for file in ("learning_curve.png", "metadata.json", "evaluations.json"):
        assert (folder / file).is_file(), (name, file)
from rventry_agents.dagger import SHIPPED_DAGGER, SHIPPED_STUDENTS, load_config as load_dagger_config, load_shipped
assert SHIPPED_DAGGER.resolve().is_relative_to(target)
load_dagger_config()
for name, folder in SHIPPED_STUDENTS.items():  # every shipped student loads from the wheel, with its record
    assert folder.resolve().is_relative_to(target) and load_shipped(name).network is not None, name
    for file in ("learning_curve.png", "metadata.json", "rounds.json"):
        assert (folder / file).is_file(), (name, file)
from rventry_agents.sb3_policy import SHIPPED_BASELINES, load_baseline
from rventry_agents.train import ALGORITHMS, BASELINES
for algorithm in ALGORITHMS:
    load_config(BASELINES / f"{algorithm}.toml", algorithm)
from rventry_agents.sb3_policy import BASELINE_AGENTS
for agent, folder in BASELINE_AGENTS.items():  # every plain baseline is shipped and loads from the wheel
    assert load_baseline(agent).spec["mode"] == "direct", agent
    assert (SHIPPED_BASELINES / folder / "learning_curve.png").is_file(), agent
assert (SHIPPED_DAGGER / "distil.json").is_file()
print("loaded everything")
"""


def _tracked_files() -> list[str]:
    res = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip("not a git checkout")
    return [f for f in res.stdout.splitlines() if (ROOT / f).is_file()]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for rel in _tracked_files():
        dest = src / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, dest)
    dist = tmp_path_factory.mktemp("dist")
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q", "-w", str(dist),
           str(src)]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    (whl,) = dist.glob("rventry-*.whl")
    return whl


@pytest.mark.slow
def test_the_wheel_holds_every_shipped_data_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    data = [f for f in _tracked_files() if f.startswith(PACKAGES) and not f.endswith(".py")]
    assert data, "no data files found"
    missing = [f for f in data if f not in names]
    assert missing == []
    for needed in ("rventry_agents/data/ppo_residual/vecnormalize.pkl", "rventry_agents/data/ppo_residual/learning_curve.png",
                   "rventry_env/reference/data/entry_reference_v1.npz"):  # fmt: skip
        assert needed in names


@pytest.mark.slow
def test_an_installed_wheel_finds_every_file_it_loads(wheel, tmp_path):
    target = tmp_path / "site"
    cmd = [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q", "--target", str(target), str(wheel)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    run = subprocess.run(
        [sys.executable, "-c", LOAD_EVERYTHING, str(target)], capture_output=True, text=True, cwd=tmp_path,
        env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().endswith("loaded everything")
