"""Generated files that know their source: a manifest per shipped policy and per results record,
and the check that says which are stale.

A shipped policy (a folder of ``rventry_agents/data``) and a results record (a file of
``docs/results``) are produced by code from a configuration, on a task. Their manifest names:

* ``config``: the SHA-256 of the configuration that produced it (a policy's ``metadata.json``
  ``config``, a record's ``command`` or ``config``; canonical JSON), with where it was read;
* ``task``: the SHA-256 of the task record, :func:`task_record`: the task (boundary conditions,
  control step, thresholds), the nominal force model, and the shipped references' files, which
  guidance laws and students track;
* ``code``: the commit that last wrote the artifact (``git log -1`` of its files) and the
  package version;
* ``files``: the SHA-256 of each of its files.

:func:`stale` compares a manifest with the tree as it is: a task record that changed (the policy
was trained, or the record flown, on another task), files changed without their manifest
(edited or regenerated without a new manifest), or files missing. ``rventry stale`` runs it on every
manifest of the source tree; ``--write`` writes the manifests of what it is given.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import subprocess
from pathlib import Path

from rventry_env.util.files import json_safe, write_json

MANIFEST = "manifest.json"
RESULTS_MANIFEST = "manifest.json"  # docs/results/manifest.json: one entry per record


def canonical_sha(obj) -> str:
    """SHA-256 of ``obj`` as canonical JSON (sorted keys, NumPy values as Python ones)."""
    text = json.dumps(json_safe(obj), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def file_sha(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def reference_files() -> dict[str, str]:
    """SHA-256 of each shipped reference file (the optimum and the guidance reference)."""
    from rventry_env.reference import data_file

    folder = Path(data_file.__file__).resolve().parent / "data"
    return {p.name: file_sha(p) for p in sorted(folder.iterdir()) if p.is_file()}


def task_record(task=None, model=None) -> dict:
    """What a policy is trained and a record is flown on: the task, the nominal force model and the
    shipped references' files."""
    from rventry_env.physics.model import EntryModel
    from rventry_env.task import EntryTask

    task = EntryTask() if task is None else task
    model = EntryModel() if model is None else model
    return {"task": json_safe(dataclasses.asdict(task)), "model": json_safe(dataclasses.asdict(model)),
            "references": reference_files()}  # fmt: skip


def _last_commit(paths: list[Path]) -> str | None:
    try:
        res = subprocess.run(["git", "log", "-1", "--format=%H", "--", *map(str, paths)], cwd=paths[0].parent,
                             capture_output=True, text=True, timeout=30)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout.strip() or None


def _files(artifact: Path) -> list[Path]:
    if artifact.is_file():
        return [artifact]
    return sorted(p for p in artifact.rglob("*") if p.is_file() and p.name != MANIFEST)


def _config(artifact: Path) -> tuple[str, object]:
    """(where, what) of the configuration that produced the artifact."""
    meta = artifact / "metadata.json" if artifact.is_dir() else artifact
    if meta.is_file() and meta.suffix == ".json":
        try:
            doc = json.loads(meta.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError):
            doc = None
        if isinstance(doc, dict):
            for key in ("config", "command", "commands"):
                if key in doc:
                    return f"{meta.name}:{key}", doc[key]
    return "unrecorded", None


def build_manifest(artifact: str | Path, root: str | Path, task=None, model=None) -> dict:
    """The manifest of a shipped policy's folder or a results record's file (paths relative to ``root``)."""
    from rventry_env import __version__

    artifact, root = Path(artifact), Path(root)
    files = _files(artifact)
    if not files:
        raise ValueError(f"{artifact}: nothing to describe (no files)")
    where, config = _config(artifact)
    record = task_record(task, model)
    base = artifact if artifact.is_dir() else artifact.parent
    return {
        "artifact": str(artifact.resolve().relative_to(Path(root).resolve())),
        "config": {"source": where, "sha256": canonical_sha(config)},
        "task": {"sha256": canonical_sha(record), "record": record},
        "code": {"commit": _last_commit(files), "version": __version__},
        "files": {str(p.relative_to(base)): file_sha(p) for p in files},
    }


def stale(manifest: dict, root: str | Path, task=None, model=None) -> list[str]:
    """Why the artifact a manifest describes is stale (empty: it is not), against the tree under ``root``
    and the task (default: this package's :class:`~rventry_env.task.EntryTask` and model)."""
    root = Path(root)
    artifact = root / manifest["artifact"]
    reasons = []
    now = task_record(task, model)
    if canonical_sha(now) != manifest["task"]["sha256"]:
        then = manifest["task"].get("record") or {}
        parts = [k for k in now if canonical_sha(now[k]) != canonical_sha(then.get(k))]
        reasons.append("task record changed (" + ", ".join(parts or ["record"]) + ")")
    base = artifact if artifact.is_dir() else artifact.parent
    for name, sha in manifest["files"].items():
        p = base / name
        if not p.is_file():
            reasons.append(f"{name} is missing")
        elif file_sha(p) != sha:
            reasons.append(f"{name} changed since its manifest")
    if artifact.is_dir():
        extra = sorted(str(p.relative_to(base)) for p in _files(artifact))
        new = [n for n in extra if n not in manifest["files"]]
        if new:
            reasons.append("files not in its manifest: " + ", ".join(new))
    return reasons


def shipped_policies(root: Path) -> list[Path]:
    """The shipped policies' folders: every folder of ``rventry_agents/data`` that holds a policy file."""
    data = root / "rventry_agents" / "data"
    policy_files = ("student.pt", "model.zip", "params.npz", "policy.npz")
    return sorted({p.parent for name in policy_files for p in data.rglob(name)}) if data.is_dir() else []


def results_records(root: Path) -> list[Path]:
    """The results records: every JSON file under ``docs/results`` but its manifest."""
    folder = root / "docs" / "results"
    return sorted(p for p in folder.rglob("*.json") if p.name != RESULTS_MANIFEST) if folder.is_dir() else []


def write_manifests(root: str | Path) -> list[Path]:
    """Write the manifest of every shipped policy (in its folder) and of every results record (in
    ``docs/results/manifest.json``), as the tree is now."""
    root = Path(root)
    written = [write_json(folder / MANIFEST, build_manifest(folder, root)) for folder in shipped_policies(root)]
    records = {str(p.relative_to(root)): build_manifest(p, root) for p in results_records(root)}
    if records:
        # the task record is the same for every record written now: keep it once
        first = next(iter(records.values()))
        shared = first["task"]["record"]
        for m in records.values():
            m["task"] = {"sha256": m["task"]["sha256"]}
        written.append(write_json(root / "docs" / "results" / RESULTS_MANIFEST,
                                  {"task_record": shared, "records": records}))  # fmt: skip
    return written


def stale_artifacts(root: str | Path, task=None, model=None) -> dict[str, list[str]]:
    """Every shipped policy and results record that is stale or has no manifest, with the reasons."""
    root = Path(root)
    out = {}
    for folder in shipped_policies(root):
        path = folder / MANIFEST
        rel = str(folder.relative_to(root))
        if not path.is_file():
            out[rel] = ["no manifest"]
            continue
        reasons = stale(json.loads(path.read_text()), root, task, model)
        if reasons:
            out[rel] = reasons
    results = root / "docs" / "results" / RESULTS_MANIFEST
    doc = json.loads(results.read_text()) if results.is_file() else {"records": {}}
    for p in results_records(root):
        rel = str(p.relative_to(root))
        m = doc["records"].get(rel)
        if m is None:
            out[rel] = ["no manifest"]
            continue
        m = {**m, "task": {**m["task"], "record": doc.get("task_record")}}
        reasons = stale(m, root, task, model)
        if reasons:
            out[rel] = reasons
    return out


def register(sub) -> None:
    p = sub.add_parser("stale", help="which shipped policies and results records are stale: trained or flown on "
                                     "another task record, or changed since their manifest")  # fmt: skip
    p.add_argument("--root", metavar="DIR", default=None,
                   help="the source tree (default: the one this package runs from)")  # fmt: skip
    p.add_argument("--write", action="store_true",
                   help="write every manifest as the tree is now (after regenerating what was stale)")  # fmt: skip
    p.set_defaults(func=_stale_command)


def _stale_command(args) -> int:
    root = Path(args.root) if args.root else Path(__file__).resolve().parents[2]
    if not root.is_dir():
        raise ValueError(f"--root {root}: not a folder")
    if args.write:
        for path in write_manifests(root):
            print(f"wrote {path}")
        return 0
    found = stale_artifacts(root)
    total = len(shipped_policies(root)) + len(results_records(root))
    for name, reasons in found.items():
        print(f"{name}: " + "; ".join(reasons))
    print(f"{len(found)} of {total} shipped policies and results records stale or without a manifest")
    return 1 if found else 0


__all__ = ["MANIFEST", "build_manifest", "stale", "stale_artifacts", "write_manifests", "task_record", "canonical_sha",
           "shipped_policies", "results_records"]
