"""Every record a benchmark or a study writes names its commit, its machine, its packages and its command."""

from __future__ import annotations

import ast
import json
import os
from pathlib import Path

import pytest

from rventry_env.util.provenance import VECTOR_FLAGS, RunRecord, cpu_identity, write_record

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted([*(ROOT / "benchmarks").glob("*.py"), *(ROOT / "studies").glob("*.py")])


def test_a_record_names_its_commit_machine_versions_and_command(tmp_path):
    run = RunRecord(["python", "benchmarks/env_speed.py", "--quick"])
    path = run.write(tmp_path / "r.json", {"figure": 1.5})
    doc = json.loads(path.read_text())
    assert doc["figure"] == 1.5
    p = doc["provenance"]
    assert p["command"] == "python benchmarks/env_speed.py --quick"
    if (ROOT / ".git").exists():  # a checkout (a worktree's .git is a file)
        assert len(p["commit"]["sha"]) == 40 and isinstance(p["commit"]["dirty"], bool)
    m = p["machine"]
    assert m["cpu"] and m["cores"] >= 1 and 1 <= m["cores_usable"] <= m["cores"]
    assert len(m["load_average_start"]) == 3 and len(m["load_average_end"]) == 3
    assert m["omp_num_threads"] == os.environ.get("OMP_NUM_THREADS") and m["xla_flags"] == os.environ.get("XLA_FLAGS")
    if Path("/proc/cpuinfo").is_file():
        assert m["cpu_identity"]["family"] and set(m["cpu_identity"]["vector"]) <= set(VECTOR_FLAGS)
    assert p["versions"]["numpy"] and p["versions"]["python"] and "jax" in p["versions"]
    assert p["wall_time_s"] >= 0
    with pytest.raises(TypeError, match="a record is a JSON object"):
        run.write(tmp_path / "bad.json", [1, 2])
    assert not (tmp_path / "bad.json").exists()


def test_the_cpu_identity_reads_the_first_processor_and_its_vector_extensions(tmp_path):
    """Two machines that share a generic model name are told apart by their numbers and extensions."""
    info = tmp_path / "cpuinfo"
    first = "processor\t: 0\ncpu family\t: 25\nmodel\t\t: 17\nmodel name\t: AMD EPYC\nstepping\t: 1\n"
    info.write_text(first + "flags\t\t: fpu sse4_2 avx2 fma avx512f avx512bw\n\n"
                    "processor\t: 1\ncpu family\t: 23\nmodel\t\t: 49\nflags\t\t: fpu avx\n")  # fmt: skip
    assert cpu_identity(info) == {"family": "25", "model": "17", "stepping": "1",
                                  "vector": ["sse4_2", "avx2", "fma", "avx512f", "avx512bw"]}  # fmt: skip
    info.write_text(first.replace("25", "23") + "flags\t\t: fpu sse4_2 avx avx2 fma\n")
    assert cpu_identity(info) == {"family": "23", "model": "17", "stepping": "1", "vector": ["sse4_2", "avx", "avx2", "fma"]}
    assert cpu_identity(tmp_path / "absent") is None


def test_write_record_writes_strict_json_and_leaves_no_partial_file(tmp_path):
    with pytest.raises(TypeError):
        write_record(tmp_path / "r.json", {"x": object()})
    assert not (tmp_path / "r.json").exists()
    path = write_record(tmp_path / "r.json", {"x": float("nan")})
    assert json.loads(path.read_text())["x"] is None  # strict JSON: null, never NaN
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_script_records_its_provenance_and_edits_no_import_path(script):
    """Each script starts its run record in main and writes its JSON through it; none edits sys.path
    or writes JSON by hand."""
    tree = ast.parse(script.read_text())
    calls = {(n.func.attr if isinstance(n.func, ast.Attribute) else getattr(n.func, "id", None))
             for n in ast.walk(tree) if isinstance(n, ast.Call)}  # fmt: skip
    assert {"start_run", "write_record"} <= calls, script.name
    text = script.read_text()
    assert "sys.path" not in text and "json.dump(" not in text, script.name


def test_no_scripts_folder_is_left_and_the_split_is_documented():
    assert not (ROOT / "scripts").exists()
    assert len(SCRIPTS) == 25
    doc = (ROOT / "docs" / "howto" / "development.md").read_text()
    assert "benchmarks/" in doc and "studies/" in doc
