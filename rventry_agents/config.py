"""Typed configurations: every TOML section a frozen dataclass, checked as it is read.

A trainer declares its configuration once, as nested frozen dataclasses, each default written
in its field:

.. code-block:: python

    from dataclasses import dataclass
    from rventry_agents.config import Section, setting

    @dataclass(frozen=True, kw_only=True)
    class Fit(Section):
        epochs: int = setting(ge=1)                    # required: no default
        learning_rate: float = setting(1e-3, gt=0)
        hidden: tuple[int, ...] = setting((64, 64), ge=1, nonempty=True)

    @dataclass(frozen=True, kw_only=True)
    class MyConfig(Section):
        fit: Fit                                       # a [fit] table
        rounds: tuple[Round, ...] = ()                 # [[rounds]] tables
        distil: Distil | None = None                   # an optional [distil] table

    cfg = MyConfig.load("my.toml")                     # or MyConfig.from_dict(a_dict)
    cfg.fit.epochs

Reading a file or a dict refuses, naming the file, the section and the key:

* a key or section the schema does not know (with the nearest known name);
* a key without a default that is missing;
* a value of another type: a bool is not a number, a float is not a whole number, a number is
  not a string; an int is taken as a float, a TOML list as a tuple;
* a number out of its range (``gt``, ``ge``, ``lt``, ``le``; each element of a list of numbers),
  NaN or infinite (unless ``finite=False``), an empty list where ``nonempty``;
* whatever a field's ``check`` callable or a section's own ``__post_init__`` refuses.

The checks run in ``__post_init__``, so a section built in Python is checked as one read from a
file. ``to_dict()`` gives the JSON-ready dict for run records (a None field is left out, as TOML
has no null), ``from_dict(to_dict())`` the same config back, and :meth:`Section.merged` a
checked copy with some keys changed. A field may also be any dataclass of the library (such as
:class:`~rventry_env.envs.reward.RewardWeights`): its keys are checked the same way and its own
``__post_init__`` applies.

A section with several variants (the ``[policy]`` of the stable-baselines3 trainer, one per
``mode``) overrides :meth:`Section._variant`; one whose TOML form differs from its fields (extra
keys gathered into one mapping) overrides :meth:`Section._pack` and :meth:`Section._unpack`.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import math
import numbers
import operator
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, ClassVar, Literal

ALGORITHMS = ("ppo", "recurrent_ppo", "sac")


class ConfigError(ValueError):
    """A configuration or record that cannot be used; the message names the file, section and key."""

    def __init__(self, message: str, located: bool = False):
        super().__init__(message)
        self.located = located  # the message already names the file and section


def setting(default: Any = dataclasses.MISSING, *, gt=None, ge=None, lt=None, le=None, finite: bool = True,
            nonempty: bool = False, check=None, what: str | None = None):  # fmt: skip
    """A configuration field: its default (none: the key is required) and its checks.

    :param gt, ge, lt, le: bounds on a number, or on each number of a list of them.
    :param finite: refuse NaN and infinities.
    :param nonempty: refuse an empty list.
    :param check: called with the (non-None) value; a ValueError or TypeError it raises refuses it.
    :param what: how a message describes a value of the right kind (default: from the type).
    """
    meta = {"gt": gt, "ge": ge, "lt": lt, "le": le, "finite": finite, "nonempty": nonempty, "check": check, "what": what}
    if isinstance(default, (list, dict, set)):
        raise TypeError("a setting's default must be immutable: use a tuple")
    return dataclasses.field(default=default, metadata=meta)


def widths(default: Any = dataclasses.MISSING):
    """A setting of layer widths: a non-empty list of whole numbers >= 1."""
    return setting(default, ge=1, nonempty=True, what="a list of layer widths (whole numbers >= 1)")


def _check_dispersion(value) -> None:
    from rventry_env.task import Dispersion

    Dispersion.parse(value)


def dispersion(default: Any = dataclasses.MISSING):
    """A setting of vehicle draws: a named set (``"standard"``, ``"flight"``, ...) or a table of
    :class:`~rventry_env.task.Dispersion` fields, parsed when it is read."""
    return setting(default, check=_check_dispersion, what="a named set or a table of Dispersion fields")


@functools.cache
def _hints(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _fields(cls) -> tuple[dataclasses.Field, ...]:
    return tuple(f for f in dataclasses.fields(cls) if f.init)


def _is_table(tp) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _args(tp) -> tuple:
    return typing.get_args(tp)


def _is_union(tp) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def describe(tp) -> str:
    """How a message names a value of type ``tp``."""
    if tp is bool:
        return "true or false"
    if tp is int:
        return "a whole number"
    if tp is float:
        return "a number"
    if tp is str:
        return "a string"
    if tp is type(None):
        return "absent"
    if tp is dict or typing.get_origin(tp) is dict or _is_table(tp):
        return "a table"
    if typing.get_origin(tp) is Literal:
        return "one of " + ", ".join(repr(a) for a in _args(tp))
    if _is_union(tp):
        return " or ".join(describe(a) for a in _args(tp) if a is not type(None))
    if typing.get_origin(tp) is tuple:
        args = _args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_plural(args[0])}"
        return f"a list [{', '.join(describe(a) for a in args)}]"
    return getattr(tp, "__name__", str(tp))


def _plural(tp) -> str:
    words = describe(tp)
    for one, many in (("a whole number", "whole numbers"), ("a number", "numbers"), ("a string", "strings"),
                      ("a table", "tables"), ("a list", "lists")):  # fmt: skip
        if words.startswith(one):
            return many + words[len(one) :]
    return words


class _Refused(Exception):
    """A value that does not fit its type (internal: the caller names the key)."""


def _convert(tp, value, path: tuple, where: str):
    """``value`` as type ``tp``: tables built into their dataclass, lists into tuples, ints into floats."""
    if tp is Any:
        return value
    if _is_union(tp):
        if value is None and type(None) in _args(tp):
            return None
        for alternative in _args(tp):
            if alternative is type(None):
                continue
            try:
                return _convert(alternative, value, path, where)
            except _Refused:
                continue
        raise _Refused
    if _is_table(tp):
        if not isinstance(value, dict):
            raise _Refused
        return _build(tp, value, path, where)
    if typing.get_origin(tp) is tuple:
        if not isinstance(value, (list, tuple)):
            raise _Refused
        args = _args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, (*path, i), where) for i, v in enumerate(value))
        if len(value) != len(args):
            raise _Refused
        return tuple(_convert(a, v, (*path, i), where) for i, (a, v) in enumerate(zip(args, value)))
    if _conforms(tp, value):
        if tp is float:
            return float(value)
        if tp is dict or typing.get_origin(tp) is dict:
            return dict(value)
        return value
    raise _Refused


def _conforms(tp, value) -> bool:
    """Whether ``value`` already is of type ``tp`` (an int counts as a float; a bool as neither)."""
    if tp is Any:
        return True
    if _is_union(tp):
        return any(_conforms(a, value) for a in _args(tp))
    if tp is type(None):
        return value is None
    if tp is bool:
        return isinstance(value, bool)
    if tp is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, numbers.Real) and not isinstance(value, bool)
    if tp is str:
        return isinstance(value, str)
    if tp is dict or typing.get_origin(tp) is dict:
        return isinstance(value, dict)
    if typing.get_origin(tp) is Literal:
        return any(value == a and type(value) is type(a) for a in _args(tp))
    if typing.get_origin(tp) is tuple:
        args = _args(tp)
        if not isinstance(value, tuple):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_conforms(args[0], v) for v in value)
        return len(value) == len(args) and all(_conforms(a, v) for a, v in zip(args, value))
    return isinstance(value, tp)


def _numbers(value):
    """The numbers in ``value`` (a number, or nested tuples of them)."""
    if isinstance(value, bool):
        return
    if isinstance(value, numbers.Real):
        yield value
    elif isinstance(value, tuple):
        for v in value:
            yield from _numbers(v)


def _range_words(meta: dict) -> str:
    words = [f"{op} {meta[key]:g}" for key, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")) if meta[key] is not None]
    return " and ".join(words)


def check_field(owner, f: dataclasses.Field, tp) -> None:
    """Raise :class:`ConfigError` naming ``f`` unless ``owner``'s value of it has type ``tp`` and
    passes the field's checks (:func:`setting`)."""
    value = getattr(owner, f.name)
    meta = {"gt": None, "ge": None, "lt": None, "le": None, "finite": True, "nonempty": False, "check": None,
            "what": None, **f.metadata}  # fmt: skip
    kind = meta["what"] or describe(tp)
    if not _conforms(tp, value):
        raise ConfigError(f"{f.name} must be {kind}, got {_shown(value)}")
    if value is None:
        return
    if meta["nonempty"] and isinstance(value, tuple) and not value:
        raise ConfigError(f"{f.name} must be {kind}, not empty")
    bounds = _range_words(meta)
    for x in _numbers(value):
        bad = (not math.isfinite(x) and (meta["finite"] or math.isnan(x))) or any(
            limit is not None and not ok(x, limit)
            for limit, ok in ((meta["gt"], operator.gt), (meta["ge"], operator.ge), (meta["lt"], operator.lt),
                              (meta["le"], operator.le))
        )  # fmt: skip
        if bad:
            finite = "" if isinstance(x, numbers.Integral) or not meta["finite"] else "finite "
            if isinstance(value, tuple):
                wanted = f"{kind}, each {finite}{bounds}".rstrip(", ")
            else:
                wanted = f"a {'whole number' if isinstance(x, numbers.Integral) else finite + 'number'} {bounds}"
            raise ConfigError(f"{f.name} must be {wanted.strip()}, got {_shown(value)}")
    if meta["check"] is not None:
        try:
            meta["check"](value)
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{f.name}: {exc}") from None


def _shown(value) -> str:
    """A value as the TOML or JSON it came from shows it (lists, not tuples)."""
    encoded = _encode(value)
    return repr(encoded) if not isinstance(encoded, (list, dict)) else json.dumps(encoded)


def _where(where: str, path: tuple) -> str:
    """``file: [section]`` for messages (``[rounds][1]`` for an item of a list of tables)."""
    if not path:
        return f"{where}: "
    text = "".join(f"[{p}]" if isinstance(p, int) else f"{'.' if i else ''}{p}" for i, p in enumerate(path))
    if isinstance(path[-1], int):  # an item of a list of tables: [rounds][1]
        cut = text.rindex("[")
        return f"{where}: [{text[:cut]}]{text[cut:]} "
    return f"{where}: [{text}] "


def _build(cls, data: dict, path: tuple, where: str):
    """A dataclass ``cls`` (or the variant :meth:`Section._variant` picks) from the table ``data``
    at ``path`` in the file ``where``."""
    try:
        if issubclass(cls, Section):
            cls = cls._variant(data)
            data = cls._pack(dict(data))
    except ConfigError as exc:
        _relocate(exc, where, path)
    hints = _hints(cls)
    known = {f.name: f for f in _fields(cls)}
    if getattr(cls, "IGNORE_UNKNOWN", False):
        data = {k: v for k, v in data.items() if k in known}
    unknown = [k for k in data if k not in known]
    missing = [name for name, f in known.items() if name not in data and _required(f)]
    if unknown or missing:
        raise ConfigError(_where(where, path) + _key_problems(cls, data, unknown, missing, hints), located=True)
    values = {}
    for name, value in data.items():
        try:
            values[name] = _convert(hints[name], value, (*path, name), where)
        except _Refused:
            kind = known[name].metadata.get("what") or describe(hints[name])
            raise ConfigError(f"{_where(where, path)}{name} must be {kind}, got {_shown(value)}", located=True) from None
    try:
        if not issubclass(cls, Section):  # a library dataclass: the keys as written checked first, then its own checks
            given = types.SimpleNamespace(**values)
            for f in _fields(cls):
                if f.name in values:
                    check_field(given, f, hints[f.name])
        made = cls(**values)
        if not issubclass(cls, Section):  # and its defaults, as its own checks left them
            for f in _fields(cls):
                check_field(made, f, hints[f.name])
        return made
    except ConfigError as exc:
        _relocate(exc, where, path)
    except (TypeError, ValueError) as exc:  # a library dataclass's own checks
        raise ConfigError(f"{_where(where, path)}{exc}", located=True) from None


def _relocate(exc: ConfigError, where: str, path: tuple):
    if exc.located:
        raise exc
    head, text = _where(where, path), str(exc)
    section = head.split(": ", 1)[1]  # a section's own check may name its section already
    if section and text.startswith(section):
        text = text[len(section):]
    raise ConfigError(f"{head}{text}", located=True) from None


def _required(f: dataclasses.Field) -> bool:
    return f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING


def _key_problems(cls, data: dict, unknown: list, missing: list, hints: dict) -> str:
    names = [f.name for f in _fields(cls)]
    problems = []
    for key in unknown:
        what = f"section [{key}]" if isinstance(data[key], dict) else f"key {key!r}"
        hint = cls._unknown_hint(key) if issubclass(cls, Section) else ""
        near = difflib.get_close_matches(key, names, n=1)
        hint = hint or (f"; did you mean {near[0]!r}?" if near else f"; known: {', '.join(names)}")
        problems.append(f"unknown {what}{hint}")
    for key in missing:
        tp = hints[key]
        problems.append(f"missing section [{key}]" if _is_table(tp) else f"missing key {key!r}")
    return "; ".join(problems)


def _encode(value):
    if isinstance(value, Section):
        return value.to_dict()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _encode(getattr(value, f.name)) for f in _fields(type(value)) if getattr(value, f.name) is not None}
    if isinstance(value, tuple):
        return [_encode(v) for v in value]
    if isinstance(value, dict):
        return {k: _encode(v) for k, v in value.items()}
    return value


def merge_tables(base: dict, changes: dict) -> dict:
    """``base`` with ``changes`` merged in, table by table (a nested dict, as TOML gives it)."""
    out = dict(base)
    for key, value in changes.items():
        out[key] = merge_tables(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


@dataclasses.dataclass(frozen=True)
class Section:
    """A configuration section (or a whole configuration): a frozen dataclass whose fields are
    checked on construction (see the module docstring). Subclasses are declared
    ``@dataclass(frozen=True, kw_only=True)``; one with its own ``__post_init__`` calls
    ``super().__post_init__()`` first. A record read for some of its keys (the rest written for
    people) sets ``IGNORE_UNKNOWN = True``."""

    IGNORE_UNKNOWN: ClassVar[bool] = False

    def __post_init__(self):
        hints = _hints(type(self))
        for f in _fields(type(self)):
            check_field(self, f, hints[f.name])

    # -- reading
    @classmethod
    def from_dict(cls, data, where: str = "config"):
        """The section from ``data`` (a dict, as TOML or JSON gives it); ``where`` names its
        source in messages. Raises :class:`ConfigError`."""
        if isinstance(data, cls):
            return data
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: a configuration is a table of keys, got {type(data).__name__}", located=True)
        return _build(cls, data, (), str(where))

    @classmethod
    def load(cls, path: str | Path):
        """The section from a TOML file (see :func:`read_toml`)."""
        return cls.from_dict(read_toml(path), str(path))

    @classmethod
    def read_json(cls, path: str | Path):
        """The section from a JSON record (see :func:`read_json`)."""
        return cls.from_dict(read_json(path), str(path))

    # -- writing
    def to_dict(self) -> dict:
        """A JSON-ready dict of every field (None fields left out); ``from_dict`` reads it back."""
        return self._unpack(_plain(self))

    def replace(self, **changes):
        """A checked copy with ``changes`` to this section's fields."""
        return dataclasses.replace(self, **changes)

    def merged(self, changes: dict):
        """A checked copy with ``changes`` (a nested dict, as in the TOML file) merged in."""
        return type(self).from_dict(merge_tables(self.to_dict(), changes), "the changed config")

    # -- hooks for sections with variants or a TOML form of their own
    @classmethod
    def _variant(cls, data: dict) -> type:
        """The class that reads ``data``: ``cls``, or one of its variants."""
        return cls

    @classmethod
    def _pack(cls, data: dict) -> dict:
        """The TOML table as the dataclass's keywords."""
        return data

    def _unpack(self, data: dict) -> dict:
        """The dataclass's fields as the TOML table (the inverse of :meth:`_pack`)."""
        return data

    @classmethod
    def _unknown_hint(cls, key: str) -> str:
        """More to say about the unknown ``key`` (default: the nearest known name)."""
        return ""


def _plain(section: Section) -> dict:
    return {f.name: _encode(getattr(section, f.name)) for f in _fields(type(section)) if getattr(section, f.name) is not None}


def read_toml(path: str | Path) -> dict:
    """A TOML file as a dict; a missing file, a folder or bad TOML is refused naming the path."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"the config {path} is a directory; give a TOML file")
    if not path.is_file():
        raise FileNotFoundError(f"no config at {path}")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path} is not valid TOML: {exc}", located=True) from None


def read_json(path: str | Path, kind: type = dict):
    """A JSON record written by this package, as ``kind`` (a dict: a JSON object; list: an array);
    a missing, unreadable or malformed file is refused naming the path."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no {path.name} at {path.parent}")
    try:
        value = json.loads(path.read_bytes())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path} is not valid JSON: {exc}", located=True) from None
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror or exc}", located=True) from None
    if not isinstance(value, kind):
        words = {dict: "a JSON object", list: "a JSON array"}.get(kind, kind.__name__)
        raise ConfigError(f"{path} must hold {words}, got {type(value).__name__}", located=True)
    return value


def check_algorithm(algorithm: str) -> str:
    if algorithm not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algorithm!r}; known: {', '.join(ALGORITHMS)}")
    return algorithm


def algorithm_class(algorithm: str):
    """The stable-baselines3 (or sb3-contrib) class of ``algorithm``."""
    if check_algorithm(algorithm) == "recurrent_ppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    import stable_baselines3

    return getattr(stable_baselines3, algorithm.upper())


__all__ = ["ALGORITHMS", "ConfigError", "Section", "algorithm_class", "check_algorithm", "check_field",
           "describe", "dispersion", "merge_tables", "read_json", "read_toml", "setting", "widths"]  # fmt: skip
