"""How fast Ctrl-C stops ``rventry evaluate --agent mpc --workers 2``, and what it leaves.

Each trial starts the command in a session of its own, waits until both workers run and have
flown for a while, then sends SIGINT to the whole process group, as a terminal's Ctrl-C does. It
prints, per trial: when the command said "interrupted" (it stopped its work: queued episodes
cancelled, running ones ended), when the process exited, when its children were gone, and the
files it wrote (none is right). For comparison it also times the exit of a process that only loads
the re-planning law and ends: the interpreter's own teardown, which no command can shorten.

    nice -n 19 python benchmarks/interrupt.py --trials 2 [--json PATH]
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (Linux: /proc)."""
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                if int((p / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(p.name))
            except (OSError, ValueError, IndexError):
                pass
    return out


def trial(tmp: Path, episodes: int, wait_s: float) -> dict:
    cmd = [sys.executable, "-m", "rventry_env.cli", "evaluate", "--agent", "mpc", "--episodes", str(episodes),
           "--workers", "2", "--dispersion", "standard", "--json", str(tmp / "eval.json"), "--plots", str(tmp / "plots")]
    env = {**os.environ, "MPLCONFIGDIR": str(tmp / "mpl")}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)  # fmt: skip
    workers: list[int] = []
    while len(workers) < 2 and proc.poll() is None:
        workers = children(proc.pid)
        time.sleep(0.2)
    time.sleep(wait_s)
    lines: list[tuple[float, str]] = []
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)

    def read():
        for line in proc.stderr:
            lines.append((time.monotonic() - t0, line.strip()))

    reader = threading.Thread(target=read)
    reader.start()
    proc.wait(timeout=300)
    exited = time.monotonic() - t0
    reader.join()
    while any(Path(f"/proc/{p}").exists() for p in workers):
        time.sleep(0.05)
    said = next((t for t, line in lines if "interrupted" in line), None)
    return {"interrupted_s": said, "exit_s": exited, "children_gone_s": time.monotonic() - t0,
            "exit_code": proc.returncode, "written": sorted(p.name for p in tmp.iterdir() if p.name != "mpl")}  # fmt: skip


def teardown_s() -> float:
    """Seconds a process that has loaded the re-planning law takes to exit after its last line."""
    code = "from rventry_env.evaluation.agents import load_agent\nload_agent('mpc')\nprint('ready', flush=True)\n"
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    proc.stdout.readline()
    t0 = time.monotonic()
    proc.wait()
    return time.monotonic() - t0


def main(argv=None) -> int:
    from rventry_env.util.args import positive_int
    from rventry_env.util.files import check_writable
    from rventry_env.util.provenance import start_run, write_record

    start_run(None if argv is None else ["python", __file__, *argv])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=positive_int, default=2)
    ap.add_argument("--episodes", type=positive_int, default=8, help="episodes of the evaluation [8]")
    ap.add_argument("--wait", type=float, default=8.0, help="seconds the workers fly before the Ctrl-C [8]")
    ap.add_argument("--json", help="write the trials' figures here")
    args = ap.parse_args(argv)
    check_writable(args.json)
    print(f"load average at the start: {os.getloadavg()[0]:.1f}")
    trials = []
    for i in range(args.trials):
        tmp = Path(tempfile.mkdtemp(prefix="rventry-interrupt-"))
        try:
            r = trial(tmp, args.episodes, args.wait)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        said = "-" if r["interrupted_s"] is None else f"{r['interrupted_s']:.2f} s"
        print(f"trial {i}: 'interrupted' after {said}, exit {r['exit_code']} after {r['exit_s']:.2f} s, children gone "
              f"after {r['children_gone_s']:.2f} s, files written: {r['written'] or 'none'}")  # fmt: skip
        trials.append(r)
    teardown = teardown_s()
    print(f"a process that loads the mpc law exits {teardown:.2f} s after its last line (its teardown alone)")
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    if args.json:
        write_record(args.json, {"episodes": args.episodes, "wait_s": args.wait, "trials": trials,
                                 "teardown_s": teardown})  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
