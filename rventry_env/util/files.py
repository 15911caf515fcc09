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
                fd, name = tempfile.mkstemp(prefix=f".{dest.name}.old.", dir=dest.parent)
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
    if path.is_dir():
        raise OutputError(f"{path} is a directory, not a file")
    folder = path.parent
    _check_no_file_in_the_way(folder, path)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder {folder} for {path.name}: {exc.strerror or exc}") from None
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix if suffix is None else suffix, dir=folder)
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

    :param paths: output files (``None`` entries are skipped).
    :param folders: output folders (created if missing).
    """
    for p in paths:
        if p is None:
            continue
        p = Path(p)
        if p.is_dir():
            raise OutputError(f"{p} is a directory; give a file name")
        _probe(p.parent, p)
    for d in folders:
        if d is None:
            continue
        d = Path(d)
        if d.exists() and not d.is_dir():
            raise OutputError(f"{d} exists and is not a folder")
        _probe(d, d)


def _check_no_file_in_the_way(folder: Path, target: Path) -> None:
    """Raise :class:`OutputError` naming it if a regular file stands where a folder of ``folder`` must be."""
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                raise OutputError(f"cannot write {target}: {part} is a file, not a folder")
            return


def _probe(folder: Path, target: Path) -> None:
    _check_no_file_in_the_way(folder, target)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".rventry-write-check.", dir=folder)
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from None


__all__ = ["OutputError", "output_set", "atomic_path", "atomic_write", "json_safe", "dumps_json", "write_json", "save_figure", "check_writable"]
