"""Save and load an :class:`~rventry_env.physics.EntryModel` as JSON.

A model is a tree of frozen dataclasses from :mod:`rventry_env.physics`; it is
written as ``{"type": ClassName, field: value, ...}`` (what
:meth:`EntryModel.describe` gives) and read back only through an allow-list of
those classes, so loading a file never constructs anything else.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from rventry_env import physics
from rventry_env.physics import mach_drag
from rventry_env.util.files import write_json

FORMAT = "rventry-entry-model/1"


def _part_classes() -> dict:
    out = {}
    for module in (physics, mach_drag):
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, type) and dataclasses.is_dataclass(obj):
                out[name] = obj
    return out


def model_to_dict(model: physics.EntryModel) -> dict:
    """A JSON-friendly description of ``model`` (scalar parameters only)."""
    d = model.describe()
    d["format"] = FORMAT
    return d


def _build(obj, classes: dict):
    if isinstance(obj, dict) and "type" in obj:
        cls = classes.get(obj["type"])
        if cls is None:
            raise ValueError(f"unknown model part type {obj['type']!r}")
        names = {f.name for f in dataclasses.fields(cls) if f.init}
        kwargs = {k: _build(v, classes) for k, v in obj.items() if k in names}
        return cls(**kwargs)
    if isinstance(obj, list):
        return tuple(_build(v, classes) for v in obj)
    return obj


def model_from_dict(d: dict) -> physics.EntryModel:
    """Rebuild an :class:`EntryModel` from :func:`model_to_dict` output (or a report holding it)."""
    if "model" in d and "type" not in d:
        d = d["model"]
    model = _build({k: v for k, v in d.items() if k != "format"}, _part_classes())
    if not isinstance(model, physics.EntryModel):
        raise ValueError("the document does not describe an EntryModel")
    return model


def save_model(model: physics.EntryModel, path: str | Path) -> Path:
    """Write ``model`` to a JSON file, whole or not at all (strict JSON)."""
    return write_json(Path(path), model_to_dict(model), indent=2)


def load_model(path: str | Path) -> physics.EntryModel:
    """Read a model written by :func:`save_model`, or the ``"model"`` of an identification report."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a model JSON file")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object")
    return model_from_dict(data)


__all__ = ["FORMAT", "load_model", "model_from_dict", "model_to_dict", "save_model"]
