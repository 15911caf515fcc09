"""Generated files know their source: a manifest per shipped policy and per results record, and the
check that flags the stale ones."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rventry_env.cli import main
from rventry_env.evaluation.manifest import (MANIFEST, build_manifest, shipped_policies, stale, stale_artifacts,
                                             task_record, write_manifests)  # fmt: skip
from rventry_env.task import EntryTask

ROOT = Path(__file__).resolve().parents[2]


def _tree(tmp_path, *policies):
    for name in policies:
        shutil.copytree(ROOT / "rventry_agents" / "data" / name, tmp_path / "rventry_agents" / "data" / name,
                        ignore=shutil.ignore_patterns(MANIFEST))  # fmt: skip
    (tmp_path / "docs" / "results").mkdir(parents=True)
    (tmp_path / "docs" / "results" / "r.json").write_text(json.dumps({"command": "rventry evaluate --agent lqr"}))
    return tmp_path


def test_every_shipped_policy_has_a_manifest_naming_its_config_task_and_code_and_none_is_stale():
    policies = shipped_policies(ROOT)
    assert {p.name for p in policies} >= {"dagger", "dagger_flight", "ppo", "ppo_finetune", "ppo_residual", "ppo_scratch",
                                          "sac"}  # fmt: skip
    for folder in policies:
        m = json.loads((folder / MANIFEST).read_text())
        assert m["config"]["source"] == "metadata.json:config" and len(m["config"]["sha256"]) == 64, folder
        assert len(m["code"]["commit"]) == 40 and m["code"]["version"]
        assert set(m["task"]["record"]) == {"task", "model", "references"}
        assert stale(m, ROOT) == [], folder


def test_the_check_flags_a_policy_whose_task_record_changed(tmp_path):
    root = _tree(tmp_path, "dagger")
    folder = root / "rventry_agents" / "data" / "dagger"
    write_manifests(root)
    assert stale_artifacts(root) == {}
    m = json.loads((folder / MANIFEST).read_text())
    assert stale(m, root, task=EntryTask(dt=2.0)) == ["task record changed (task)"]
    assert stale_artifacts(root, task=EntryTask(substeps=2)) == {
        "rventry_agents/data/dagger": ["task record changed (task)"], "docs/results/r.json": ["task record changed (task)"]}
    # a policy replaced without its manifest, and a record added without one
    (folder / "student.json").write_text("{}")
    (root / "docs" / "results" / "new.json").write_text("{}")
    found = stale_artifacts(root)
    assert found == {"rventry_agents/data/dagger": ["student.json changed since its manifest"],
                     "docs/results/new.json": ["no manifest"]}  # fmt: skip


def test_the_stale_command_lists_the_stale_and_exits_1(tmp_path, capsys):
    root = _tree(tmp_path, "ppo_residual")
    assert main(["stale", "--root", str(root)]) == 1
    out = capsys.readouterr().out
    assert "rventry_agents/data/ppo_residual: no manifest" in out and "2 of 2 shipped policies and results records" in out
    assert main(["stale", "--root", str(root), "--write"]) == 0
    assert main(["stale", "--root", str(root)]) == 0
    assert "0 of 2" in capsys.readouterr().out


def test_the_task_record_holds_the_task_the_model_and_the_references():
    rec = task_record()
    assert rec["task"]["dt"] == EntryTask().dt and rec["model"]["vehicle"]["name"] == "CAV-H"
    assert {"entry_reference_v1.npz", "guidance_reference_v1.npz"} <= set(rec["references"])
    with pytest.raises(ValueError, match="nothing to describe"):
        build_manifest(Path("/nonexistent/dir"), ROOT)
