"""Where a benchmark's or a study's record was made: the commit, the machine, the packages, the command.

A figure without its machine and its code means little: a timing on a loaded 2-core machine is not
one on a quiet workstation, and a success rate belongs to the commit that flew it. Every script
under ``benchmarks/`` and ``studies/`` starts a :class:`RunRecord` before its work and writes its
JSON through :meth:`RunRecord.write`, which adds a ``"provenance"`` entry:

* ``commit``: the source tree's ``git`` commit and whether it had uncommitted changes (None
  outside a checkout);
* ``machine``: the CPU model, with its family, model and stepping numbers and the vector
  extensions it has (where the model name is a generic one, these tell two machines apart: XLA
  compiles for the extensions it finds, and float32 training parts between two of them within a
  chunk), the cores the process may use and those the machine has, the load average at the start
  and at the end (a shared machine's timings are read against it), and ``OMP_NUM_THREADS`` and
  ``XLA_FLAGS`` as the run had them (None: unset);
* ``versions``: Python and the packages the figures depend on (None where one is not installed);
* ``command``: the command line, and the start and end times (UTC).

The record is written whole or not at all (:func:`~rventry_env.util.files.write_json`).
"""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
import time
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from rventry_env.util.files import write_json

PACKAGES = ("rventry", "numpy", "scipy", "casadi", "gymnasium", "stable-baselines3", "torch", "jax", "jaxlib", "flax",
            "optax", "rejax")  # fmt: skip
# the vector extensions of /proc/cpuinfo's flags that XLA's CPU code generation reads
VECTOR_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512dq", "avx512vl", "avx512_vnni", "avx512_bf16",
                "amx_tile")  # fmt: skip
SOURCE = Path(__file__).resolve().parents[2]  # the source tree's root, where this package is a checkout


def source_commit(root: Path = SOURCE) -> dict | None:
    """``{"sha", "dirty"}`` of the git checkout at ``root``; None where it is not one (an installed wheel)."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        if sha.returncode != 0:
            return None
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                                capture_output=True, text=True, timeout=30)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return {"sha": sha.stdout.strip(), "dirty": bool(status.stdout.strip())}


def cpuinfo_fields(cpuinfo: Path = Path("/proc/cpuinfo")) -> dict[str, str] | None:
    """The fields of the first processor in Linux's ``cpuinfo`` (None where there is none)."""
    try:
        text = cpuinfo.read_text()
    except OSError:
        return None
    fields: dict[str, str] = {}
    for line in text.split("\n\n", 1)[0].splitlines():
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    return fields


def cpu_model() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo; elsewhere what the platform says)."""
    name = (cpuinfo_fields() or {}).get("model name")
    return name or platform.processor() or platform.machine()


def cpu_identity(cpuinfo: Path = Path("/proc/cpuinfo")) -> dict | None:
    """The CPU's family, model and stepping numbers and the vector extensions of :data:`VECTOR_FLAGS`
    it has, from Linux's ``cpuinfo`` (its first processor); None where there is none."""
    fields = cpuinfo_fields(cpuinfo)
    if fields is None:
        return None
    have = set(fields.get("flags", "").split())
    return {"family": fields.get("cpu family"), "model": fields.get("model"), "stepping": fields.get("stepping"),
            "vector": [f for f in VECTOR_FLAGS if f in have]}  # fmt: skip


def load_average() -> list[float] | None:
    """The 1-, 5- and 15-minute load averages (None where the system has none)."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def package_versions(names=PACKAGES) -> dict:
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


class RunRecord:
    """The provenance of one run of a script: started when built, closed by :meth:`provenance`."""

    def __init__(self, argv: list[str] | None = None):
        """:param argv: the command line (default: this process's, as ``python SCRIPT ARGS``)."""
        self.command = shlex.join(["python", *sys.argv] if argv is None else argv)
        self.started = datetime.now(timezone.utc)
        self._t0 = time.perf_counter()
        self.load_start = load_average()
        self.commit = source_commit()
        self.cpu = cpu_identity()

    def provenance(self) -> dict[str, Any]:
        """The ``"provenance"`` entry, with the load average now as the end's."""
        try:
            usable = len(os.sched_getaffinity(0))
        except AttributeError:
            usable = os.cpu_count()
        return {
            "commit": self.commit,
            "machine": {"cpu": cpu_model(), "cpu_identity": self.cpu, "cores_usable": usable, "cores": os.cpu_count(),
                        "system": platform.system(), "load_average_start": self.load_start,
                        "load_average_end": load_average(), "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
                        "xla_flags": os.environ.get("XLA_FLAGS")},
            "versions": package_versions(),
            "command": self.command,
            "started_utc": self.started.isoformat(timespec="seconds"),
            "wall_time_s": round(time.perf_counter() - self._t0, 3),
        }  # fmt: skip

    def write(self, path: str | Path, data: dict, indent: int | None = 1) -> Path:
        """Write ``data`` with its ``"provenance"`` to ``path`` as strict JSON, whole or not at all."""
        if not isinstance(data, dict):
            raise TypeError(f"a record is a JSON object (dict), got {type(data).__name__}")
        return write_json(path, {**data, "provenance": self.provenance()}, indent=indent)


_CURRENT: RunRecord | None = None


def start_run(argv: list[str] | None = None) -> RunRecord:
    """Start this script's :class:`RunRecord` (call first thing in its ``main``: the load at the start,
    the wall time and the commit are taken now)."""
    global _CURRENT
    _CURRENT = RunRecord(argv)
    return _CURRENT


def current_provenance() -> dict[str, Any]:
    """The ``"provenance"`` entry of the run :func:`start_run` started, now (for a record that gathers
    entries from several runs, each with its own)."""
    return (_CURRENT or start_run()).provenance()


def write_record(path: str | Path, data: dict, indent: int | None = 1) -> Path:
    """Write ``data`` with the provenance of the run :func:`start_run` started (started now if none was)."""
    return (_CURRENT or start_run()).write(path, data, indent=indent)


__all__ = ["RunRecord", "start_run", "current_provenance", "write_record", "source_commit", "cpu_model", "cpu_identity", "cpuinfo_fields", "load_average", "package_versions", "PACKAGES"]
