"""The ladder of rungs as a user meets it: each rung is one ``gym.make`` call, the easy rungs start
where they say, and the README's training quick start lands on the easiest rung."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401  (registers RvEntry-v0)
from rventry_env.evaluation.rungs import RUNGS, rung

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", list(RUNGS))
def test_every_rung_is_one_gym_make_call_and_starts_where_it_says(name):
    r = rung(name)
    env = gym.make("RvEntry-v0", **r.env_kwargs())
    _, info = env.reset(seed=3)
    u = env.unwrapped
    t0 = info.get("time_s", u._t)
    assert u.dispersion.name == r.dispersion
    if r.before_impact_s is None:  # the task's own initial state, as evaluation flies it
        assert t0 == 0.0
    else:  # on the reference, between the rung's times before its impact
        s = r.starts()
        end = float(s.times[-1])
        lo, hi = r.before_impact_s
        assert end - hi - 1.0 <= t0 <= end - lo + 1.0, (t0, end)
    _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    assert not (terminated or truncated) and info["time_s"] == pytest.approx(t0 + u.task.dt)  # the clock runs on


def test_an_unknown_rung_names_the_ladder():
    with pytest.raises(ValueError, match="no rung 'later'; the ladder: late, half, nominal"):
        rung("later")


def _quick_start() -> tuple[str, str]:
    """The README's training quick start: its Python block and its evaluation command."""
    text = (ROOT / "README.md").read_text()
    section = text.split("<!-- train-snippet: start", 1)[1].split("<!-- train-snippet: end", 1)[0]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    command = re.search(r"```bash\n(.*?)```", section, re.S).group(1).split("#")[0].split()
    return code, command


def test_the_quick_start_trains_and_evaluates_one_folder_on_the_rung_it_names():
    code, command = _quick_start()
    assert len(code.strip().split("\n")) <= 15
    folder = re.search(r'model.save\("(.+)/model.zip"\)', code).group(1)
    assert command[:2] == ["rventry", "evaluate"] and command[command.index("--agent") + 1] == folder
    assert 'rung("late")' in code and command[command.index("--rung") + 1] == "late"
    assert int(command[command.index("--seed") + 1]) >= 1000  # past every seed make_vec_env gave training


@pytest.mark.slow
def test_the_readme_training_quick_start_lands_on_the_easiest_rung(tmp_path):
    """The README's quick start as written: basic success >= 0.8 on 100 new late starts."""
    code, command = _quick_start()
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=3000)
    assert done.returncode == 0, done.stderr[-3000:]
    rventry = str(Path(sys.executable).parent / "rventry")
    done = subprocess.run([rventry, *command[1:], "--json", "report.json"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=1200)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["rung"] == "late" and report["n_episodes"] == 100
    assert report["summary"]["success_rate"] >= 0.8, report["summary"]["success_rate"]


@pytest.mark.parametrize("name", ["late", "nominal"])
def test_evaluate_flies_a_rung_from_where_it_starts(name, tmp_path):
    """``rventry evaluate --rung``: a rung with start states starts there (its clock is the
    reference's), one without at the task's initial state; the report names the rung."""
    from rventry_env.cli import main
    from rventry_env.evaluation.cli import run_agent

    out = tmp_path / "r.json"
    assert main(["evaluate", "--agent", "reference", "--rung", name, "--episodes", "2", "--seed", "1000", "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["rung"] == name and report["dispersion_set"] == rung(name).dispersion
    batch, _ = run_agent("reference", 2, rung(name).dispersion, 1000, history=True, rung=name)
    t0 = np.asarray(batch.history_t)[0]  # each episode's first time
    if name == "late":
        end = float(rung(name).starts().times[-1])
        assert np.all((end - 61.0 <= t0) & (t0 <= end - 29.0)), t0
    else:
        assert np.all(t0 == 0.0), t0
