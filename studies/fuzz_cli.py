"""Malformed ``rventry`` invocations: each must exit 2 with a message naming what is wrong, no traceback.

A corpus of command lines, each a cheap valid invocation of one command with one argument made
bad: numbers out of range, not numbers, NaN, infinity, 5000-digit integers; unknown choices;
output paths that are folders, that run through a file, or whose names are longer than the file
system allows; input files that are missing, empty, folders or random bytes; unknown options,
missing required ones, extra positionals. Every command is covered: ``orbit``, ``reference``
(``solve``, ``show``, ``export``), ``evaluate``, ``compare``, ``oracle``, ``identify``,
``simulate-record``, ``glossary`` and ``train`` (``ppo`` and its modes, ``jax-ppo``, ``ppo-scratch``,
``dagger``, ``ship``).

Each case runs in this process (``rventry_env.cli.main``) under a time limit: a case that is
not refused within it has been accepted and runs, and is counted so. A case passes when the
command exits 2, its message names the argument (the option, or the file), it prints no
traceback, the report written before it is untouched, and it leaves no new file or folder (cases
run in the fixtures' folder, so a default output path written is seen too).

    python studies/fuzz_cli.py                      # the whole corpus, a table of the figures
    python studies/fuzz_cli.py --json out/fuzz_cli.json --limit 60
    python studies/fuzz_cli.py --only "train ppo-scratch" --only glossary
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[1]
OLD_REPORT = '{"kept": true}\n'


class Case(NamedTuple):
    """One malformed invocation: its arguments, the text its message must contain, the command."""

    argv: tuple
    needle: str
    command: str

    @property
    def agents(self) -> bool:
        """Whether the learning agents' package reads what is wrong (``train``, a saved policy's files)."""
        return self.command.startswith("train") or any("/policies/" in a for a in self.argv)


class Fixtures:
    """The files the corpus points at, in one temporary folder."""

    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.a_file = tmp / "a_file"
        self.a_file.write_text("not a folder")
        self.a_dir = tmp / "a_dir"
        self.a_dir.mkdir()
        self.garbage = tmp / "garbage.npz"
        self.garbage.write_bytes(bytes(range(256)) * 3)
        self.empty = tmp / "empty.csv"
        self.empty.write_text("")
        self.text = tmp / "notes.csv"
        self.text.write_text("this,is\nnot,a record\n")
        self.bad_toml = tmp / "bad.toml"
        self.bad_toml.write_text("[env\nnum_envs = ")
        self.report = tmp / "r.json"
        self.report.write_text(OLD_REPORT)
        self.json = str(tmp / "new.json")
        self.long_name = str(tmp / ("n" * 300 + ".json"))
        self.long_folder = str(tmp / ("f" * 300) / "x.json")
        self.long_path = str(tmp / ("d/" * 2100) / "x.json")
        self.missing = str(tmp / "missing.npz")
        self.policies = self._saved_policies(tmp / "policies")

    @staticmethod
    def _saved_policies(folder: Path) -> list[tuple[str, str]]:
        """(path for --agent, needle): the shipped PPO and DAgger policies with one file spoiled."""
        import pickle
        import shutil

        data = ROOT / "rventry_agents" / "data"
        out = []

        def spoil(kind: str, name: str, file: str, content: bytes, needle: str):
            d = folder / f"{kind}_{name}"
            shutil.copytree(data / kind, d)
            (d / file).write_bytes(content)
            out.append((str(d / "model.zip") if kind == "ppo_residual" else str(d), needle))

        if not (data / "ppo_residual").is_dir():  # the learning agents' data are not installed
            return out
        spoil("ppo_residual", "empty_pkl", "vecnormalize.pkl", b"", "vecnormalize.pkl")
        spoil("ppo_residual", "random_pkl", "vecnormalize.pkl", bytes(range(256)), "vecnormalize.pkl")
        spoil("ppo_residual", "int_pkl", "vecnormalize.pkl", pickle.dumps(3), "vecnormalize.pkl")
        spoil("ppo_residual", "list_policy", "policy.json", b"[]", "policy.json")
        spoil("ppo_residual", "bad_policy", "policy.json", b"{", "policy.json")
        spoil("ppo_residual", "no_dt", "metadata.json", b'{"config": {"env": {"substeps": 1}}}', "metadata.json")
        spoil("dagger", "junk_pt", "student.pt", bytes(range(256)), "student.pt")
        spoil("dagger", "empty_pt", "student.pt", b"", "student.pt")
        spoil("dagger", "list_json", "student.json", b"[]", "student.json")
        spoil("dagger", "no_hidden", "student.json", b'{"members": 1}', "student.json")
        return out


def _bad_ints(positive: bool) -> list[str]:
    out = ["-1", "1.5", "abc", "", "nan", "1e3", "0x10", "9" * 5000]
    return (["0"] + out) if positive else out


BAD_FLOATS = ["nan", "inf", "-inf", "abc", "", "1e400", "--"]


def _outputs(f: Fixtures, kind: str, suffix: str = ".json") -> list[tuple[str, str]]:
    """(value, needle) for an output destination: a file (``kind="file"``, named ``*<suffix>``) or a folder."""
    cases = [
        (str(f.a_file / f"x{suffix}"), "a_file"),
        (str(f.a_file / "sub" / f"x{suffix}"), "a_file is a file, not a folder"),
        (f.long_name.replace(".json", suffix), "n" * 20),
        (f.long_folder.replace(".json", suffix), "f" * 20),
        (f.long_path.replace(".json", suffix), "d/d/d/d/d/"),
        (f"/proc/rventry-fuzz/x{suffix}", "rventry-fuzz"),
    ]
    if kind == "file":
        cases.append((str(f.a_dir), "a_dir"))
    else:
        cases.append((str(f.a_file), "a_file"))
    return cases


def _inputs(f: Fixtures) -> list[tuple[str, str]]:
    return [(f.missing, "missing.npz"), (str(f.a_dir), "a_dir"), (str(f.garbage), "garbage.npz"),
            (str(f.empty), "empty.csv")]  # fmt: skip


def corpus(f: Fixtures) -> list[Case]:
    """The malformed invocations, built on ``f``'s files."""
    cases: list[Case] = []

    def add(command, base, option, values, needle=None, positional=False):
        for value, need in values:
            argv = list(base)
            if positional:
                argv[option] = value
            elif option in argv:
                i = argv.index(option)
                argv[i + 1] = value
            else:
                argv += [option, value]
            cases.append(Case(tuple(argv), need if needle is None else needle, command))

    def numbers(command, base, option, values):
        add(command, base, option, [(v, option) for v in values])

    # orbit
    orbit = ["orbit", "--n", "10", "--quiet", "--json", f.json]
    numbers("orbit", orbit, "--n", _bad_ints(True))
    add("orbit", orbit, "--json", _outputs(f, "file"))
    add("orbit", orbit, "--plots", _outputs(f, "folder"))

    # reference
    solve = ["reference", "solve", "--quiet", "--out", str(f.tmp / "ref.npz")]
    numbers("reference solve", solve, "--mesh-tolerance", BAD_FLOATS + ["0", "-1e-3"])
    numbers("reference solve", solve, "--q-margin", BAD_FLOATS + ["0.7", "-0.1"])
    numbers("reference solve", solve, "--load-margin", BAD_FLOATS + ["1.5", "-0.1"])
    numbers("reference solve", solve, "--end-fraction", BAD_FLOATS + ["1.0", "-0.5"])
    numbers("reference solve", solve, "--max-mesh-iterations", _bad_ints(True))
    add("reference solve", solve, "--first-mesh", [("0", "--first-mesh")])
    cases.append(Case(tuple(solve + ["--first-mesh", "0", "4"]), "--first-mesh", "reference solve"))
    cases.append(Case(tuple(solve + ["--first-mesh", "39", "abc"]), "--first-mesh", "reference solve"))
    add("reference solve", solve, "--norm-mode", [("bogus", "--norm-mode")])
    add("reference solve", solve, "--ship", [("bogus", "--ship")])
    add("reference solve", solve, "--out", [(str(f.tmp / "x.txt"), "--out")] + _outputs(f, "file", ".npz"))
    show = ["reference", "show"]
    add("reference show", show, "--file", _inputs(f))
    add("reference show", show, "--json", _outputs(f, "file"))
    export = ["reference", "export", "--csv", str(f.tmp / "ref.csv")]
    numbers("reference export", export, "--dt", BAD_FLOATS + ["1e-7", "-1", "0"])
    add("reference export", export, "--csv", _outputs(f, "file"))
    add("reference export", export, "--file", _inputs(f))

    # evaluate
    ev = ["evaluate", "--agent", "reference", "--json", f.json]
    numbers("evaluate", ev, "--episodes", _bad_ints(True) + ["1" + "0" * 30])
    numbers("evaluate", ev, "--seed", _bad_ints(False)[:-1])
    numbers("evaluate", ev, "--workers", _bad_ints(True))
    add("evaluate", ev, "--agent", [("bogus", "unknown agent 'bogus'"), ("", "--agent"), (f.missing, "missing.npz"),
                                     (str(f.garbage), "garbage.npz"), (str(f.a_dir), "a_dir")])  # fmt: skip
    add("evaluate", ev, "--agent", f.policies)  # a saved policy with a file spoiled
    add("evaluate", ev, "--dispersion", [("huge", "--dispersion"), ("", "--dispersion")])
    cases.append(Case(tuple(ev + ["--dispersed", "--dispersion", "wide"]), "--dispersed", "evaluate"))
    add("evaluate", ev, "--targets", [("everywhere", "--targets")])
    add("evaluate", ev, "--json", _outputs(f, "file"))
    add("evaluate", ev, "--plots", _outputs(f, "folder"))
    cases.append(Case(tuple(ev + ["--episodes", "100000000", "--plots", str(f.tmp / "p")]), "--episodes", "evaluate"))

    # compare (accepted, it would fly every law: each case must be refused at once)
    cmp_ = ["compare", "--episodes", "1", "--mpc-episodes", "1", "--json", f.json, "--plots", str(f.tmp / "cp")]
    numbers("compare", cmp_, "--episodes", _bad_ints(True) + ["1" + "0" * 30])
    numbers("compare", cmp_, "--mpc-episodes", _bad_ints(True))
    numbers("compare", cmp_, "--seed", ["-1", "1.5", "abc"])
    add("compare", cmp_, "--agent", [("bogus", "unknown agent 'bogus'"), (f.missing, "missing.npz")])
    add("compare", cmp_, "--dispersion", [("huge", "--dispersion")])
    add("compare", cmp_, "--json", _outputs(f, "file")[:4])
    add("compare", cmp_, "--plots", _outputs(f, "folder")[:4])

    # oracle
    orc = ["oracle", "--dispersion", "none", "--episodes", "1", "--json", f.json]
    numbers("oracle", orc, "--episodes", _bad_ints(True) + ["1000000000000", "1" + "0" * 30])
    numbers("oracle", orc, "--seed", ["-1", "1.5", "abc"])
    numbers("oracle", orc, "--workers", ["0", "-2", "x"])
    add("oracle", orc, "--dispersion", [("huge", "--dispersion")])
    cases.append(Case(("oracle", "--episodes", "1", "--json", f.json), "--dispersion", "oracle"))
    add("oracle", orc, "--json", _outputs(f, "file"))

    # identify (on the shipped record)
    ident = ["identify", "apollo4", "--json", f.json, "--quiet"]
    add("identify", ident, 1, [(v, n) for v, n in _inputs(f)] + [(str(f.text), "notes.csv"), ("apollo5", "apollo5")],
        positional=True)  # fmt: skip
    numbers("identify", ident, "--threshold", BAD_FLOATS + ["-1e9"])
    numbers("identify", ident, "--max-effects", ["-1", "1.5", "abc"])
    numbers("identify", ident, "--h-max", BAD_FLOATS + ["0", "11"])
    numbers("identify", ident, "--noise", ["20", "20,0.2,1", "nan,0.2", "-1,0.2", "a,b", "0,0.2"])
    add("identify", ident, "--start", [("sideways", "--start")])
    add("identify", ident, "--candidates", [("gremlins", "gremlins")])
    add("identify", ident, "--vehicle", [(f.missing, "missing.npz"), (str(f.a_dir), "a_dir"),
                                         (str(f.garbage), "garbage.npz")])  # fmt: skip
    add("identify", ident, "--json", _outputs(f, "file"))
    add("identify", ident, "--model-out", _outputs(f, "file")[:4])
    add("identify", ident, "--plots", _outputs(f, "folder")[:4])

    # simulate-record
    sim = ["simulate-record", "--out", str(f.tmp / "sim.csv"), "--duration", "20"]
    add("simulate-record", sim, "--effect", [("gremlins", "gremlins"), ("wind=abc", "wind"), ("wind=1,2,3", "wind"),
                                            ("mass=-1", "mass"), ("density_profile=1e308", "density_profile"),
                                            ("density_profile=nan", "density_profile"),
                                            ("time_offset=1e9", "time_offset"), ("mach_drag=1e308", "mach_drag"),
                                            ("us76_density=3", "us76_density"),
                                            ("lift_coefficient=1e308", "lift_coefficient")])  # fmt: skip
    cases.append(Case(tuple(sim + ["--effect", "mass=2", "--effect", "mass=3"]), "mass", "simulate-record"))
    numbers("simulate-record", sim, "--duration", BAD_FLOATS + ["0", "3601", "-5"])
    numbers("simulate-record", sim, "--rate", BAD_FLOATS + ["0", "101"])
    numbers("simulate-record", sim, "--seed", ["-1", "1.5", "abc"])
    numbers("simulate-record", sim, "--noise", ["-1", "nan", "1,2,3", "a"])
    numbers("simulate-record", sim, "--start-scatter", ["1", "1,nan", "-1,5", "1,2,3"])
    add("simulate-record", sim, "--observe", [("gps", "--observe")])
    add("simulate-record", sim, "--noise-tails", [("cauchy", "--noise-tails")])
    add("simulate-record", sim, "--out", _outputs(f, "file"))

    # train (accepted, it would train: each case must be refused at once)
    ppo = ["train", "ppo", "--out", str(f.tmp / "run"), "--no-progress"]
    numbers("train ppo", ppo, "--timesteps", _bad_ints(True))
    numbers("train ppo", ppo, "--seed", ["-2", "1.5"])
    add("train ppo", ppo, "--config", [(f.missing, "missing.npz"), (str(f.bad_toml), "bad.toml"),
                                       (str(f.a_dir), "a_dir")])  # fmt: skip
    add("train ppo", ppo, "--out", [(str(f.a_file), "a_file")])
    dag = ["train", "dagger", "--out", str(f.tmp / "drun"), "--no-progress"]
    numbers("train dagger", dag, "--workers", ["0", "x"])
    numbers("train dagger", dag, "--seed", ["-1", "abc"])
    add("train dagger", dag, "--config", [(f.missing, "missing.npz"), (str(f.bad_toml), "bad.toml")])
    add("train dagger", dag, "--out", [(str(f.a_file), "a_file")])
    for algo in ("ppo-residual", "ppo-finetune", "ppo-plain", "recurrent-ppo-plain", "sac-plain"):
        mode = ["train", algo, "--out", str(f.tmp / f"run_{algo}"), "--no-progress"]
        numbers(f"train {algo}", mode, "--timesteps", ["0", "-1", "abc"])
        add(f"train {algo}", mode, "--config", [(f.missing, "missing.npz"), (str(f.bad_toml), "bad.toml")])
        add(f"train {algo}", mode, "--out", [(str(f.a_file), "a_file")])
    for algo in ("jax-ppo", "ppo-scratch"):  # the [jax] extra's trainers
        jx = ["train", algo, "--out", str(f.tmp / f"run_{algo}")]
        numbers(f"train {algo}", jx, "--timesteps", ["0", "-1", "1.5", "9" * 5000])
        numbers(f"train {algo}", jx, "--seed", ["-1", "abc"])
        numbers(f"train {algo}", jx, "--max-wall-s", ["0", *BAD_FLOATS])
        add(f"train {algo}", jx, "--config", [(f.missing, "missing.npz"), (str(f.bad_toml), "bad.toml"),
                                              (str(f.a_dir), "a_dir")])  # fmt: skip
        add(f"train {algo}", jx, "--out", [(str(f.a_file), "a_file")])
    cases.append(Case(("train", "ppo-scratch", "--out", str(f.tmp / "no_scratch_run"), "--resume"), "no_scratch_run",
                      "train ppo-scratch"))  # fmt: skip
    cases.append(Case(("glossary", "no-such-word"), "no-such-word", "glossary"))
    cases.append(Case(("train", "ship", str(f.tmp / "no_run")), "no_run", "train ship"))
    cases.append(Case(("train", "ship", str(f.a_file)), "a_file", "train ship"))

    # the command line itself
    cases += [
        Case(("bogus-command",), "bogus-command", "rventry"),
        Case(("evaluate", "--json", f.json), "--agent", "evaluate"),
        Case(("evaluate", "--agent", "reference", "--json", f.json, "--bogus-option", "1"), "--bogus-option", "evaluate"),
        Case(("evaluate", "--agent", "reference", "--json", f.json, "extra"), "extra", "evaluate"),
        Case(("evaluate", "--agent"), "--agent", "evaluate"),
        Case(("identify", "--json", f.json), "record", "identify"),
        Case(("simulate-record",), "--out", "simulate-record"),
        Case(("reference", "export"), "--csv", "reference export"),
        Case(("orbit", "--n"), "--n", "orbit"),
    ]
    return cases


class _TimeUp(BaseException):
    """The case ran past its time limit: it was accepted."""


def _snapshot(tmp: Path) -> set[str]:
    return {str(p.relative_to(tmp)) for p in tmp.rglob("*") if not p.name.startswith("mpl")}


def warm_up() -> None:
    """Import what the commands load (CasADi, matplotlib, the agents' torch and stable-baselines3)
    before any case runs: the time limit then applies to the command, and a case stopped at its
    limit never leaves a library half imported for the next ones."""
    import importlib
    from importlib.metadata import entry_points

    for name in ("casadi", "matplotlib.pyplot", "scipy.integrate", "torch", "stable_baselines3", "sb3_contrib"):
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    for group in ("rventry.agents", "rventry.agent_files", "rventry.commands"):
        for ep in entry_points(group=group):
            with contextlib.suppress(Exception):
                ep.load()


def run_case(case: Case, f: Fixtures, limit_s: float = 120.0) -> tuple[str, str]:
    """Run one case in this process: (verdict, detail). ``"ok"`` is a clean refusal."""
    from rventry_env.cli import main

    before = _snapshot(f.tmp)
    err, out = io.StringIO(), io.StringIO()

    def time_up(*_):
        raise _TimeUp()

    old = signal.signal(signal.SIGALRM, time_up)
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    verdict, detail = None, ""
    try:
        # in the fixtures' folder: a default output path (out/..., runs/...) left behind is seen
        with contextlib.chdir(f.tmp), contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                code = main(list(case.argv))
            except SystemExit as exc:
                code = exc.code
    except _TimeUp:
        verdict, detail = "accepted (ran on)", f"still running after {limit_s:g} s"
    except Exception as exc:  # noqa: BLE001 - a traceback is what is counted
        verdict, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    if verdict is None:
        if "Traceback" in text:
            verdict, detail = "traceback", text.strip().splitlines()[-1][:200]
        elif code != 2:
            verdict, detail = f"exit {code}", text.strip()[-200:]
        elif case.needle not in text:
            verdict, detail = "message does not name it", text.strip()[-200:]
    if f.report.read_text() != OLD_REPORT:
        verdict, detail = verdict or "report touched", detail
        f.report.write_text(OLD_REPORT)
    created = _snapshot(f.tmp) - before
    if created:
        verdict, detail = verdict or "left files behind", detail or ", ".join(sorted(created))[:200]
        for name in sorted(created, key=len, reverse=True):
            p = f.tmp / name
            with contextlib.suppress(OSError):
                p.rmdir() if p.is_dir() else p.unlink()
    return verdict or "ok", detail


def _short(argv: tuple) -> str:
    return " ".join(a if len(a) <= 40 else a[:18] + "..." + a[-12:] for a in argv)


def main(argv=None) -> int:
    from rventry_env.util.args import positive_float, positive_int
    from rventry_env.util.provenance import start_run, write_record

    start_run(None if argv is None else ["python", __file__, *argv])
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--limit", type=positive_float, default=120.0, help="seconds a case may run before it counts as "
                   "accepted [120]")  # fmt: skip
    p.add_argument("--only", action="append", metavar="COMMAND",
                   help="run the cases of this command only (say 'evaluate'; repeat it for several)")  # fmt: skip
    p.add_argument("--first", type=positive_int, help="run the first N cases only")
    p.add_argument("--json", help="write the figures and every failure here")
    args = p.parse_args(argv)
    os.environ.setdefault("MPLCONFIGDIR", tempfile.mkdtemp(prefix="mpl"))
    results = []
    warm_up()
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="rventry-fuzz-") as tmp:
        f = Fixtures(Path(tmp))
        cases = [c for c in corpus(f) if args.only is None or c.command in args.only][: args.first]
        for i, case in enumerate(cases):
            verdict, detail = run_case(case, f, args.limit)
            results.append((case, verdict, detail))
            if (i + 1) % 50 == 0 or i + 1 == len(cases):
                print(f"{i + 1}/{len(cases)} cases", file=sys.stderr, flush=True)
    by_command: dict[str, Counter] = {}
    for case, verdict, _ in results:
        by_command.setdefault(case.command, Counter())[verdict == "ok"] += 1
    ok = sum(v == "ok" for _, v, _ in results)
    print(f"malformed invocations refused cleanly (exit 2, the argument named, no traceback, nothing written): "
          f"{ok} / {len(results)}  ({time.time() - t0:.0f} s)")  # fmt: skip
    agents = [v == "ok" for c, v, _ in results if c.agents]
    print(f"  the library's commands: {ok - sum(agents)} / {len(results) - len(agents)}; what the learning agents read "
          f"(train, a saved policy's files): {sum(agents)} / {len(agents)}")  # fmt: skip
    for command, c in sorted(by_command.items()):
        print(f"  {command:18s} {c[True]:4d} / {c[True] + c[False]}")
    failures = [(c, v, d) for c, v, d in results if v != "ok"]
    if failures:
        print("failures:")
        for case, verdict, detail in failures:
            print(f"  [{verdict}] rventry {_short(case.argv)}\n      {detail}")
    print(f"verdicts: {dict(Counter(v for _, v, _ in results))}")
    if args.json:
        write_record(args.json, {"cases": len(results), "refused_cleanly": ok,
                               "by_command": {k: {"ok": c[True], "cases": c[True] + c[False]}
                                              for k, c in by_command.items()},
                               "failures": [{"argv": list(c.argv), "verdict": v, "detail": d}
                                            for c, v, d in failures]})  # fmt: skip
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
