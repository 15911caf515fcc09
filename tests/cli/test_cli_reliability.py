"""The command line under hostile use: malformed arguments, impossible file names, Ctrl-C.

Every malformed invocation exits 2 with a message naming what is wrong, prints no traceback and
creates nothing; a name the file system cannot hold is refused before the work; Ctrl-C stops a
parallel evaluation at once, its queued and running episodes included, and writes nothing.
The corpus is ``studies/fuzz_cli.py``'s.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rventry_env.cli import main
from rventry_env.util.files import OutputError, check_writable, write_json
from script_modules import load_script

ROOT = Path(__file__).resolve().parents[2]
fuzz = load_script("studies/fuzz_cli")


@pytest.fixture(scope="module")
def fixtures(tmp_path_factory):
    fuzz.warm_up()
    return fuzz.Fixtures(tmp_path_factory.mktemp("fuzz"))


def _library_cases(f) -> list:
    """The corpus less what the learning agents' package reads (its own tests cover those)."""
    return [c for c in fuzz.corpus(f) if not c.agents]


def test_a_seeded_sample_of_the_corpus_is_refused_cleanly(fixtures):
    cases = _library_cases(fixtures)
    sample = cases[:: max(1, len(cases) // 60)]
    bad = [(fuzz._short(c.argv), *fuzz.run_case(c, fixtures)) for c in sample]
    assert [b for b in bad if b[1] != "ok"] == []


@pytest.mark.slow
def test_the_whole_corpus_is_refused_cleanly(fixtures):
    bad = [(fuzz._short(c.argv), *fuzz.run_case(c, fixtures)) for c in _library_cases(fixtures)]
    assert [b for b in bad if b[1] != "ok"] == []


# ----------------------------------------------------------------------------- numbers, by hypothesis
_POSITIVE_INTS = [("evaluate", "--episodes"), ("evaluate", "--workers"), ("oracle", "--episodes"), ("orbit", "--n")]
_SEEDS = [("evaluate", "--seed"), ("oracle", "--seed"), ("simulate-record", "--seed")]
# (command, option, low, high): a number outside [low, high], or not finite, is refused
_RANGES = [("simulate-record", "--duration", 1e-300, 3600.0), ("simulate-record", "--rate", 1e-300, 100.0),
           ("identify", "--h-max", 1e-300, 10.0), ("identify", "--threshold", 0.0, float("inf")),
           ("reference export", "--dt", 1e-300, float("inf"))]  # fmt: skip


def _argv(command: str, option: str, value: str, f) -> list[str]:
    base = {
        "evaluate": ["evaluate", "--agent", "reference", "--json", f.json],
        "oracle": ["oracle", "--dispersion", "none", "--episodes", "1", "--json", f.json],
        "orbit": ["orbit", "--n", "10", "--quiet", "--json", f.json],
        "simulate-record": ["simulate-record", "--out", str(f.tmp / "sim.csv"), "--duration", "20"],
        "identify": ["identify", "apollo4", "--json", f.json, "--quiet"],
        "reference export": ["reference", "export", "--csv", str(f.tmp / "ref.csv")],
    }[command]
    if option in base:
        i = base.index(option)
        return base[:i] + [f"{option}={value}"] + base[i + 2 :]
    return base + [f"{option}={value}"]  # --opt=VALUE: a value starting with '-' stays the option's


def _refused(argv, needle, f) -> None:
    verdict, detail = fuzz.run_case(fuzz.Case(tuple(argv), needle, argv[0]), f, limit_s=60.0)
    assert verdict == "ok", (argv, verdict, detail)


_WORDS = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_,. ", min_size=0, max_size=12)


@settings(max_examples=40)
@given(which=st.sampled_from(_POSITIVE_INTS), value=st.one_of(
    st.integers(max_value=0).map(str), st.floats(allow_nan=True).filter(lambda x: x != int(x) if x == x and abs(x) < 1e300
                                                                        else True).map(repr), _WORDS))  # fmt: skip
def test_a_count_that_is_not_a_positive_integer_is_refused_naming_the_option(fixtures, which, value):
    _refused(_argv(*which, value, fixtures), which[1], fixtures)


@settings(max_examples=30)
@given(which=st.sampled_from(_SEEDS), value=st.one_of(st.integers(max_value=-1).map(str), _WORDS,
                                                      st.floats(0.5, 1e6).filter(lambda x: x != int(x)).map(repr)))
def test_a_seed_that_is_not_an_integer_at_least_0_is_refused_naming_the_option(fixtures, which, value):
    _refused(_argv(*which, value, fixtures), which[1], fixtures)


@settings(max_examples=40)
@given(which=st.sampled_from(_RANGES), x=st.floats(allow_nan=True, allow_infinity=True), words=_WORDS, pick=st.booleans())
def test_a_number_outside_its_range_or_not_finite_is_refused_naming_the_option(fixtures, which, x, words, pick):
    command, option, low, high = which
    if pick and not (low <= x <= high):
        value = repr(x)
    else:
        value = words
    _refused(_argv(command, option, value, fixtures), option, fixtures)


# ----------------------------------------------------------------------------- file names
_LONG = "n" * 300


@pytest.mark.parametrize("argv", [
    ["evaluate", "--agent", "reference", "--json", "{long}.json"],
    ["evaluate", "--agent", "reference", "--json", "{tmp}/r.json", "--plots", "{long}"],
    ["compare", "--episodes", "1", "--json", "{long}.json", "--plots", "{tmp}/p"],
    ["oracle", "--dispersion", "none", "--episodes", "1", "--json", "{long}.json"],
    ["identify", "apollo4", "--quiet", "--json", "{long}.json"],
    ["identify", "apollo4", "--quiet", "--json", "{tmp}/r.json", "--model-out", "{long}.json"],
    ["simulate-record", "--out", "{long}.csv"],
    ["simulate-record", "--out", "{tmp}/" + "s" * 250 + ".csv"],  # its .truth.json beside it is too long
    ["orbit", "--n", "10", "--quiet", "--json", "{long}.json"],
    ["reference", "export", "--csv", "{long}.csv"],
    ["reference", "show", "--json", "{long}.json"],
    ["reference", "solve", "--quiet", "--out", "{long}.npz"],
])  # fmt: skip
def test_a_file_name_too_long_for_the_file_system_is_refused_before_the_run(tmp_path, capsys, argv):
    argv = [a.replace("{long}", str(tmp_path / _LONG)).replace("{tmp}", str(tmp_path)) for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    assert "bytes long; the file system allows at most" in err and ("n" * 20 in err or "s" * 20 in err), err
    assert list(tmp_path.iterdir()) == []


def test_a_name_as_long_as_the_file_system_allows_is_written_whole(tmp_path):
    """The temporary file staged beside it has a shortened name, so the longest legal name works."""
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    path = tmp_path / ("x" * (limit - 5) + ".json")
    check_writable(path)
    write_json(path, {"a": 1})
    assert path.read_text() == '{\n "a": 1\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    from rventry_env.util.files import atomic_write, output_set

    with output_set():  # replacing it in a set keeps the old file aside under a shortened name too
        atomic_write(path, "staged")
    assert path.read_text() == "staged"
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    with pytest.raises(OutputError, match=f"the file name is {limit + 1} bytes long; the file system allows at most {limit}"):
        check_writable(tmp_path / ("x" * (limit - 4) + ".json"))
    with pytest.raises(OutputError, match="the folder name"):
        check_writable(folders=(tmp_path / ("f" * (limit + 1)) / "sub",))


# ----------------------------------------------------------------------------- nothing created by a refusal
def test_checking_a_destination_creates_nothing(tmp_path):
    check_writable(tmp_path / "a" / "b" / "r.json", folders=(tmp_path / "plots" / "deep",))
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_writable(folders=(tmp_path / "f" / "plots",))


@pytest.mark.parametrize("argv", [
    ["evaluate", "--agent", "reference", "--episodes", "100000000", "--json", "{tmp}/r.json", "--plots", "{tmp}/p"],
    ["evaluate", "--agent", "bogus", "--json", "{tmp}/out/r.json", "--plots", "{tmp}/p"],
    ["compare", "--agent", "bogus", "--json", "{tmp}/out/r.json", "--plots", "{tmp}/cp"],
    ["compare", "--agent", "{tmp}/none.zip", "--json", "{tmp}/out/r.json", "--plots", "{tmp}/cp"],
    ["oracle", "--dispersion", "none", "--episodes", "1000000000000", "--json", "{tmp}/out/r.json"],
    ["identify", "{tmp}/missing.csv", "--json", "{tmp}/out/r.json", "--plots", "{tmp}/ip", "--model-out",
     "{tmp}/m/m.json"],
])  # fmt: skip
def test_a_refused_command_leaves_no_folder_behind(tmp_path, capsys, argv):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    assert "Traceback" not in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("episodes", ["1000000000000", str(10**30), str(10**400)])
def test_oracle_episodes_beyond_memory_are_refused_naming_the_option(tmp_path, capsys, episodes):
    """An oracle draw holds a few kB until the report is written: the count is bounded like evaluate's."""
    assert main(["oracle", "--dispersion", "flight", "--episodes", episodes, "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert f"--episodes {episodes} needs" in err and "per draw" in err and "run it in parts" in err, err


def test_a_simulated_effect_too_strong_to_fly_is_refused_naming_it(tmp_path, capsys):
    for effect in ("density_profile=1e308", "mach_drag=1e308"):
        code = main(["simulate-record", "--effect", effect, "--out", str(tmp_path / "s.csv"), "--duration", "20"])
        err = capsys.readouterr().err
        assert code == 2 and f"--effect {effect}: the truth flight cannot be flown" in err, err
        assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- Ctrl-C
def _workers(pid: int) -> list[int]:
    """The spawned pool workers of process ``pid`` (Linux /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
                if parent == pid and b"spawn_main" in (entry / "cmdline").read_bytes():
                    out.append(int(entry.name))
            except (OSError, ValueError, IndexError):
                pass
    return out


def _gone(pids: list[int]) -> bool:
    return not any((Path("/proc") / str(p)).exists() for p in pids)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_cancels_the_queued_tasks_and_ends_the_running_ones():
    """Six 60 s tasks on two workers: an interrupt once both run ends the map before either could
    finish, and every worker with it (the pool used to wait for every queued task)."""
    from rventry_env.evaluation.parallel import map_local

    me = os.getpid()
    seen = []
    old = signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C raises KeyboardInterrupt here

    def interrupt_when_running():
        end = time.monotonic() + 120
        while time.monotonic() < end and len(_workers(me)) < 2:
            time.sleep(0.1)
        time.sleep(1.0)
        seen.extend(_workers(me))
        os.kill(me, signal.SIGINT)

    threading.Thread(target=interrupt_when_running, daemon=True).start()
    t0 = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            map_local(time.sleep, [(60.0,)] * 6, 2, lambda i, r: None)
    finally:
        signal.signal(signal.SIGINT, old)
    assert time.monotonic() - t0 < 45.0  # a running task would have needed 60 s
    assert len(seen) == 2
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not _gone(seen):
        time.sleep(0.1)
    assert _gone(seen)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_on_a_parallel_mpc_evaluation_exits_at_once_writing_nothing(tmp_path):
    """Ctrl-C at a terminal signals the whole process group: the command exits with 130 well before
    a queued episode (about 17 s each) could run, its workers end with it, no file is written."""
    report, plots = tmp_path / "eval.json", tmp_path / "plots"
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "mpc", "--episodes", "8", "--workers", "2",
           "--dispersion", "standard", "--json", str(report), "--plots", str(plots)]  # fmt: skip
    env = {**os.environ, "MPLCONFIGDIR": str(tmp_path / "mpl")}
    # started as from a terminal's shell, Ctrl-C not ignored: a process started with SIGINT ignored keeps
    # ignoring it (POSIX; Python installs no KeyboardInterrupt then), and a test runner's worker may be one
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip
    deadline = time.monotonic() + 180
    workers = []
    while time.monotonic() < deadline and len(workers) < 2:
        workers = _workers(proc.pid)
        time.sleep(0.2)
    assert len(workers) == 2
    time.sleep(5.0)  # the workers build the law and fly their first episodes
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=20)  # a bound on the wait: the old pool waited 30 s and more per queued episode
    assert proc.returncode == 130 and "interrupted" in err and "Traceback" not in err, err
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not _gone(workers):
        time.sleep(0.1)
    assert _gone(workers)
    assert sorted(p.name for p in tmp_path.iterdir()) in ([], ["mpl"])
