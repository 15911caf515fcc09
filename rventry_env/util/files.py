"""Outputs written whole or not at all, and checked before the work that produces them.

Every file a command writes (reports, models, records, references, plots) goes
through :func:`atomic_write`: the content is written to a temporary file in the
destination's folder, flushed to disk, then renamed over the destination. A
failure part-way (a full disk, a killed process) leaves the old file as it was
and no partial file behind. :func:`check_writable` is called before a long run,
so an unwritable destination is reported at once rather than after the run.
:func:`dumps_json` refuses NaN and infinity: a report holds numbers or ``null``.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import math
import os
import stat
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator


class OutputError(ValueError):
    """A destination cannot be written (named in the message)."""


# the files staged by the innermost output_set() in progress (None: each write replaces its file at once)
_STAGED: contextvars.ContextVar[list | None] = contextvars.ContextVar("rventry_output_set", default=None)


@contextlib.contextmanager
def output_set() -> Iterator[None]:
    """A command's outputs as one set: all replaced, or none.

    Inside the block every :func:`atomic_write` (so :func:`write_json` and :func:`save_figure`)
    writes its whole content to a temporary file beside its destination and leaves the
    destination alone. When the block raises (a full disk, a plot that fails, an interrupt)
    every staged file is removed and every previous output stays as it was. When it ends
    normally every staged file is moved into place, the old files kept aside until the last one
    is in; if a move fails (a destination turned into a folder, say) every old file is put back
    and :class:`OutputError` is raised. A block inside another joins the outer set.
    """
    if _STAGED.get() is not None:
        yield
        return
    staged: list[tuple[Path, Path]] = []
    token = _STAGED.set(staged)
    try:
        yield
    except BaseException:
        _discard(staged)
        raise
    else:
        _commit(staged)
    finally:
        _STAGED.reset(token)


def _discard(staged: list[tuple[Path, Path]]) -> None:
    for tmp, _ in staged:
        with contextlib.suppress(OSError):
            tmp.unlink()


def _commit(staged: list[tuple[Path, Path]]) -> None:
    """Move every staged file over its destination; on any failure put every old file back and raise."""
    moved: list[tuple[Path | None, Path]] = []  # (backup of the old file or None, destination)
    dest = None
    try:
        for tmp, dest in staged:
            backup = None
            if dest.exists():
                fd, name = tempfile.mkstemp(prefix=temp_prefix(dest, ".old"), suffix=".old", dir=dest.parent)
                os.close(fd)
                backup = Path(name)
                try:
                    os.replace(dest, backup)
                except OSError:
                    backup.unlink(missing_ok=True)
                    raise
            moved.append((backup, dest))
            os.replace(tmp, dest)
    except OSError as exc:
        for backup, old in reversed(moved):
            with contextlib.suppress(OSError):
                if backup is not None:
                    os.replace(backup, old)
                else:
                    old.unlink(missing_ok=True)
        _discard(staged)
        raise OutputError(f"could not write {dest}: {exc.strerror or exc}; no output was replaced") from None
    for backup, _ in moved:
        if backup is not None:
            with contextlib.suppress(OSError):
                backup.unlink()


@contextlib.contextmanager
def atomic_path(path: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """A temporary path beside ``path``; on normal exit it replaces ``path`` atomically
    (inside an :func:`output_set`, at the end of the set, with the set's other files).

    :param path: the destination.
    :param suffix: the temporary file's suffix (default: the destination's, so that
        writers that look at the extension, such as ``numpy.savez`` or matplotlib, behave).
    """
    path = Path(path)
    _check_names(path)
    if _kind(path) == "folder":
        raise OutputError(f"{path} is a directory, not a file")
    folder = path.parent
    _check_no_file_in_the_way(folder, path)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder {folder} for {path.name}: {exc.strerror or exc}") from None
    suffix = path.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=temp_prefix(path, suffix), suffix=suffix, dir=folder)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as f:
            os.fsync(f.fileno())
        # mkstemp makes the file private (0600); give it the mode a plain open() would
        os.chmod(tmp_path, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~_umask())
        staged = _STAGED.get()
        if staged is None:
            os.replace(tmp_path, path)
        else:  # an output_set() renames it with the others at its end
            staged.append((tmp_path, path))
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, data: str | bytes | Callable[[Path], Any]) -> Path:
    """Write ``data`` to ``path`` whole or not at all.

    :param data: text, bytes, or a callable that writes the content to the path it is given.
    :return: ``path``.
    """
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            if callable(data):
                data(tmp)
            elif isinstance(data, str):
                tmp.write_text(data)
            else:
                tmp.write_bytes(data)
    except OSError as exc:
        raise OutputError(f"could not write {path}: {exc.strerror or exc}; the old file, if any, is untouched") from None
    return path


def json_safe(obj: Any) -> Any:
    """``obj`` with NumPy scalars and arrays turned into Python values and non-finite floats into ``None``."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return json_safe(obj.tolist())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def dumps_json(obj: Any, indent: int | None = 1) -> str:
    """Strict JSON text: NumPy values converted, NaN and infinity written as ``null``."""
    return json.dumps(json_safe(obj), indent=indent, allow_nan=False) + "\n"


def write_json(path: str | Path, obj: Any, indent: int | None = 1) -> Path:
    """:func:`dumps_json` written with :func:`atomic_write`."""
    return atomic_write(path, dumps_json(obj, indent))


def save_figure(fig, path: str | Path, dpi: int = 110, tight: bool = True) -> Path:
    """Save a matplotlib figure as PNG, whole or not at all, and close it.

    :param tight: apply ``tight_layout`` first.
    """
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        if tight:
            fig.tight_layout()
        atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png"))
    finally:
        plt.close(fig)
    return path


def plain_log_labels(ax) -> None:
    """Label a log y axis with plain numbers (2, 20, 200; not 2x10^0). Within one decade the minor
    ticks carry numbers too, or the axis would have one label or none. Call after the data are drawn."""
    from matplotlib.ticker import FuncFormatter

    lo, hi = ax.get_ylim()
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if hi < 10 * lo else ""))


def check_writable(*paths: str | Path | None, folders: tuple = ()) -> None:
    """Raise :class:`OutputError` now if a file or folder destination cannot be written later.

    Nothing is created: a missing folder is made when its first file is written, so a command
    refused after this check (a bad option, an unknown agent) leaves no empty folder behind. A
    missing folder is checked through the nearest folder above it that exists.

    :param paths: output files (``None`` entries are skipped).
    :param folders: output folders.
    """
    for p in paths:
        if p is None:
            continue
        p = Path(p)
        _check_names(p)
        if _kind(p) == "folder":
            raise OutputError(f"{p} is a directory; give a file name")
        _probe(p.parent, p)
    for d in folders:
        if d is None:
            continue
        d = Path(d)
        _check_names(d)
        if _kind(d) == "file":
            raise OutputError(f"{d} exists and is not a folder")
        _probe(d, d)


# the longest name (bytes) and path where the file system does not say (POSIX's usual values)
_NAME_MAX, _PATH_MAX = 255, 4096
# what a temporary name adds to its prefix: mkstemp's 8 random characters and a margin
_TEMP_EXTRA = 8 + 4


def _limits(path: Path) -> tuple[int, int]:
    """The longest file name and path (bytes) on the file system holding ``path``'s nearest existing folder."""
    folder = _existing_folder(path)
    out = []
    for name, default in (("PC_NAME_MAX", _NAME_MAX), ("PC_PATH_MAX", _PATH_MAX)):
        try:
            out.append(int(os.pathconf(folder, name)) if folder is not None else default)
        except (OSError, ValueError, AttributeError, TypeError):  # not POSIX, or no limit given
            out.append(default)
    return out[0], out[1]


def _existing_folder(path: Path) -> Path | None:
    """The nearest existing folder at or above ``path`` (None if none can be found)."""
    for part in (path, *path.parents):
        if _kind(part, strict=False) == "folder":
            return part
    return None


def _shorten(text: str, part_max: int = 40, whole_max: int = 200) -> str:
    """``text`` (a path or a name) for a message: each long name shortened to its ends, then the whole."""
    parts = [p if len(p) <= part_max else f"{p[:20]}...{p[-12:]}" for p in text.split(os.sep)]
    out = os.sep.join(parts)
    return out if len(out) <= whole_max else f"{out[: whole_max // 2]}...{out[-whole_max // 3 :]}"


def _check_names(path: Path) -> None:
    """Raise :class:`OutputError` naming it if a name in ``path``, or ``path`` itself, is longer
    than the file system allows (rather than an ``OSError`` from deep inside a write)."""
    name_max, path_max = _limits(path)
    for part in path.parts:
        n = len(os.fsencode(part))
        if n > name_max:
            what = "the file name" if part == path.name else f"the folder name {_shorten(part)}"
            raise OutputError(f"cannot write {_shorten(str(path))}: {what} is {n} bytes long; the file system "
                              f"allows at most {name_max}")  # fmt: skip
    n = len(os.fsencode(str(path)))
    extra = 2 + _TEMP_EXTRA + len(os.fsencode(path.suffix))  # the temporary file's name is this much longer
    if n + extra >= path_max:
        raise OutputError(f"cannot write {_shorten(str(path))}: the path is {n} bytes long; the file system allows "
                          f"at most {path_max - 1 - extra} for it (with room for a temporary name beside it)")


def temp_prefix(path: Path, suffix: str = "") -> str:
    """The prefix of the temporary file a write of ``path`` stages beside it: ``.<name>.``, the
    name cut short where the temporary name (prefix, mkstemp's random characters, ``suffix``)
    would exceed the longest name the file system allows, so any name that fits can be written."""
    name_max, _ = _limits(path)
    room = name_max - 2 - _TEMP_EXTRA - len(os.fsencode(suffix))
    name = path.name
    while name and len(os.fsencode(name)) > room:
        name = name[:-1]
    return f".{name}."


def _kind(path: Path, strict: bool = True) -> str:
    """``"folder"``, ``"file"`` (anything else that exists) or ``"missing"``. A path that cannot be
    looked up (a name too long, a NUL character) is refused naming it, or, unless ``strict``,
    reported ``"missing"``."""
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):  # a file above it: reported by _check_no_file_in_the_way
        return "missing"
    except (OSError, ValueError) as exc:
        if not strict:
            return "missing"
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise OutputError(f"cannot write {_shorten(str(path))!r}: {why}") from None
    return "folder" if stat.S_ISDIR(st.st_mode) else "file"


def _check_no_file_in_the_way(folder: Path, target: Path) -> None:
    """Raise :class:`OutputError` naming it if a regular file stands where a folder of ``folder`` must be."""
    for part in (folder, *folder.parents):
        kind = _kind(part)
        if kind == "file":
            raise OutputError(f"cannot write {target}: {part} is a file, not a folder")
        if kind == "folder":
            return


def _probe(folder: Path, target: Path) -> None:
    """Check that ``target`` can be written under ``folder`` (made if missing), creating nothing:
    a temporary file is made and removed in the nearest existing folder."""
    _check_no_file_in_the_way(folder, target)
    existing = _existing_folder(folder)
    if existing is None:
        raise OutputError(f"cannot write {target}: no folder above it exists")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".rventry-write-check.", dir=existing)
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from None


__all__ = ["OutputError", "output_set", "atomic_path", "atomic_write", "json_safe", "dumps_json", "write_json", "save_figure", "check_writable", "temp_prefix"]
