"""Bad invocations of ``orbit``, ``reference``, ``evaluate``, ``compare`` and ``train``: a seeded corpus.

Every case must exit with code 2, print no traceback, name the offending option or file in
its message, and leave an existing report untouched.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest


from rventry_env.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _corpus(tmp: Path) -> list[tuple[list[str], str]]:
    """(arguments, text the error message must contain)."""
    a_file = tmp / "a_file"
    a_file.write_text("not a folder")
    garbage = tmp / "garbage.npz"
    garbage.write_bytes(os.urandom(64))
    bad_toml = tmp / "bad.toml"
    bad_toml.write_text("[env\nnum_envs = ")
    report = str(tmp / "r.json")
    bare = tmp / "bare" / "model.zip"  # a saved SB3 model without its observation statistics
    bare.parent.mkdir()
    bare.write_bytes((ROOT / "rventry_agents/data/baselines/ppo/model.zip").read_bytes())
    return [
        (["orbit", "--n", "0"], "--n"),
        (["orbit", "--n", "ten"], "--n"),
        (["orbit", "--n", "10", "--json", str(a_file / "x.json")], "a_file"),
        (["reference", "solve", "--first-mesh", "0", "4", "--quiet"], "--first-mesh"),
        (["reference", "solve", "--q-margin", "0.7", "--quiet"], "--q-margin"),
        (["reference", "solve", "--mesh-tolerance", "nan", "--quiet"], "--mesh-tolerance"),
        (["reference", "solve", "--out", str(tmp / "x.txt"), "--quiet"], "--out"),
        (["reference", "solve", "--out", str(a_file / "x.npz"), "--quiet"], "a_file"),
        (["reference", "export", "--csv", str(tmp / "x.csv"), "--dt", "1e-7"], "--dt"),
        (["reference", "export", "--csv", str(tmp / "x.csv"), "--dt", "-1"], "--dt"),
        (["reference", "show", "--file", str(tmp)], "is a directory"),
        (["reference", "show", "--file", str(garbage)], "garbage.npz"),
        (["reference", "show", "--file", str(tmp / "missing.npz")], "missing.npz"),
        (["evaluate", "--agent", "reference", "--episodes", "0", "--json", report], "--episodes"),
        (["evaluate", "--agent", "reference", "--episodes", "-3", "--json", report], "--episodes"),
        (["evaluate", "--agent", "reference", "--seed", "-1", "--json", report], "--seed"),
        (["evaluate", "--agent", "reference", "--seed", "1.5", "--json", report], "--seed"),
        (["evaluate", "--agent", "lqr-typo", "--json", report], "unknown agent 'lqr-typo'"),
        (["evaluate", "--agent", str(tmp / "none.zip"), "--json", report], "none.zip"),
        (["evaluate", "--agent", str(garbage), "--json", report], "garbage.npz"),
        (["evaluate", "--agent", "reference", "--dispersion", "huge", "--json", report], "--dispersion"),
        (["evaluate", "--agent", "reference", "--dispersed", "--dispersion", "wide", "--json", report], "--dispersed"),
        (["evaluate", "--agent", "reference", "--json", str(tmp)], "is a directory"),
        (["evaluate", "--agent", "reference", "--json", str(a_file / "r.json")], "a_file"),
        (["evaluate", "--agent", "reference", "--json", report, "--plots", str(a_file)], "a_file"),
        (["evaluate", "--agent", "reference", "--json", str(a_file / "sub" / "r.json")], "a_file is a file, not a folder"),
        (["evaluate", "--agent", "", "--json", report], "argument --agent: must name an agent"),
        (["evaluate", "--agent", str(bare), "--json", report], '"normalized": false'),
        (["evaluate", "--agent", str(bare), "--json", report], "vecnormalize.pkl"),
        (["identify", str(tmp / "rec.csv"), "--json", report, "--threshold", "-1e9"],
         "argument --threshold: must be a finite number >= 0, got '-1e9'"),
        (["compare", "--episodes", "0", "--json", report], "--episodes"),
        (["evaluate", "--agent", "reference", "--episodes", "100000000", "--json", report], "--episodes 100000000 needs"),
        (["evaluate", "--agent", "reference", "--episodes", "10000000", "--json", report, "--plots", str(tmp / "p")],
         "or without --plots"),
        (["compare", "--episodes", "10000000", "--json", report], "run it in parts"),
        (["compare", "--episodes", "2", "--json", report, "--plots", str(a_file)], "a_file"),
        (["train", "ppo", "--timesteps", "0", "--out", str(tmp / "run")], "--timesteps"),
        (["train", "ppo", "--seed", "-2", "--out", str(tmp / "run")], "--seed"),
        (["train", "ppo", "--config", str(tmp / "missing.toml"), "--out", str(tmp / "run")], "missing.toml"),
        (["train", "ppo", "--config", str(bad_toml), "--out", str(tmp / "run")], "bad.toml"),
        (["train", "ship", str(tmp / "no_run")], "no_run"),
    ]


def test_every_bad_invocation_exits_2_naming_the_problem(tmp_path, capsys):
    existing = tmp_path / "r.json"
    existing.write_text('{"kept": true}')
    failures = []
    for args, needle in _corpus(tmp_path):
        try:
            code = main(args)
        except SystemExit as exc:  # argparse's own errors
            code = exc.code
        err = capsys.readouterr().err
        if code != 2 or needle not in err or "Traceback" in err:
            failures.append(f"{' '.join(args)}: exit {code}, stderr {err.strip()[-300:]!r}")
    assert failures == []
    assert json.loads(existing.read_text()) == {"kept": True}


def _limit_file_size():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))


def test_a_failed_report_write_leaves_the_old_report_whole(tmp_path):
    """A full disk (simulated with a file-size limit): exit 2, a message, the old report intact, no stray file."""
    report = tmp_path / "eval.json"
    old = json.dumps({"old": "report", "pad": "x" * 100})
    report.write_text(old)
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "reference", "--episodes", "3",
           "--dispersion", "standard", "--json", str(report)]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, preexec_fn=_limit_file_size,
                         env={**os.environ, "MPLCONFIGDIR": str(tmp_path / "mpl")})  # fmt: skip
    assert res.returncode == 2, res.stderr
    assert "could not write" in res.stderr and "eval.json" in res.stderr and "Traceback" not in res.stderr
    assert report.read_text() == old
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("mpl")) == ["eval.json"]


def test_a_failed_plot_leaves_the_previous_report_and_plots_as_one_set(tmp_path):
    """evaluate --json OUT --plots DIR: the report fits under the file-size limit, a plot does not. Nothing
    of the new run replaces anything: the previous report and plots stay together, no stray file."""
    report, plots = tmp_path / "eval.json", tmp_path / "plots"
    plots.mkdir()
    old = {"eval.json": '{"old": "report"}', "plots/trajectories_reference.png": "old plot",
           "plots/outcomes_reference.png": "old plot"}  # fmt: skip
    for name, text in old.items():
        (tmp_path / name).write_text(text)
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "reference", "--episodes", "1",
           "--json", str(report), "--plots", str(plots)]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, preexec_fn=_limit_file_size,
                         env={**os.environ, "MPLCONFIGDIR": str(tmp_path / "mpl")})  # fmt: skip
    assert res.returncode == 2 and "could not write" in res.stderr and ".png" in res.stderr, res.stderr
    assert "Traceback" not in res.stderr
    assert {name: (tmp_path / name).read_text() for name in old} == old
    assert sorted(p.name for p in plots.iterdir()) == ["outcomes_reference.png", "trajectories_reference.png"]
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("mpl")) == ["eval.json", "plots"]


def _workers_of(pid: int) -> list[int]:
    """The spawned pool workers of process ``pid`` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid and b"spawn_main" in cmdline:
            found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _wait_for(condition, limit_s: float = 120.0, what: str = ""):
    """Poll ``condition`` until it holds (a bound on a wait, not a timing assertion)."""
    import time

    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"still waiting after {limit_s} s: {what}")


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_worker_or_parent_leaves_no_orphan_and_no_mixed_output_set(tmp_path):
    """kill -9 of a pool worker: the command stops with a message, the other worker ends, nothing is
    written. kill -9 of the command itself: every worker ends with it. The previous report and plots
    stay as they were either way."""
    report, plots = tmp_path / "eval.json", tmp_path / "plots"
    plots.mkdir()
    old = {"eval.json": '{"old": "report"}', "plots/trajectories_mpc.png": "old plot"}
    for name, text in old.items():
        (tmp_path / name).write_text(text)
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "mpc", "--episodes", "6", "--workers", "2",
           "--dispersion", "standard", "--json", str(report), "--plots", str(plots)]  # fmt: skip
    env = {**os.environ, "MPLCONFIGDIR": str(tmp_path / "mpl")}
    for victim in ("worker", "parent"):
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        workers = _wait_for(lambda: len(_workers_of(proc.pid)) == 2 and _workers_of(proc.pid), what="two workers")
        os.kill(workers[0] if victim == "worker" else proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=300)
        if victim == "worker":
            assert proc.returncode == 1 and "a worker process ended before its task did" in err, err
            assert "Traceback" not in err
        _wait_for(lambda: not any(_alive(w) for w in workers), what=f"the workers to end after the {victim} was killed")
        assert {name: (tmp_path / name).read_text() for name in old} == old
        assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("mpl")) == ["eval.json", "plots"]
        assert sorted(p.name for p in plots.iterdir()) == ["trajectories_mpc.png"]
