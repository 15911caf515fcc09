"""The ladder of rungs as a user meets it: each rung is one ``gym.make`` call, the easy rungs start
where they say, and the README's training quick start lands on the easiest rung."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401  (registers RvEntry-v0)
from rventry_env.evaluation.rungs import RUNGS, rung

ROOT = Path(__file__).resolve().parents[1]


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


def _quick_start() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("<!-- train-snippet: start", 1)[1].split("<!-- train-snippet: end", 1)[0]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_the_readme_training_quick_start_lands_on_the_easiest_rung(tmp_path):
    """The README's ~15 lines of plain SB3 PPO: basic success >= 0.8 on 100 new late starts."""
    code = _quick_start()
    assert len(code.strip().split("\n")) <= 20
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=3000)
    assert done.returncode == 0, done.stderr[-3000:]
    success = float(re.search(r"success (\d\.\d\d) on 100 new late starts", done.stdout).group(1))
    assert success >= 0.8, done.stdout
