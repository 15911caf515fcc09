"""One command's outputs as one set: every file replaced, or none.

``rventry identify --json R --model-out M --plots P`` writes a report, a model and plots that
describe one run. Written one after another, a failure on the last would leave a new model
beside an old report. :class:`OutputSet` stages every file beside its destination first (each
written whole, :mod:`rventry_env.util.files`); only when all are staged does :meth:`commit`
move them into place, keeping the old files aside until the last one is in, and putting them
back if any move fails.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from rventry_env.util.files import OutputError, _umask, atomic_write, dumps_json, temp_prefix


class OutputSet:
    """Files staged beside their destinations, replaced together by :meth:`commit`.

    Use as a context manager: leaving the block with an exception (or without a commit)
    removes every staged file and leaves the destinations as they were.
    """

    def __init__(self):
        self._staged: list[tuple[Path, Path]] = []

    def stage(self, dest: str | Path) -> Path:
        """A temporary path beside ``dest`` (same suffix) to write ``dest``'s new content to."""
        dest = Path(dest)
        if dest.is_dir():
            raise OutputError(f"{dest} is a directory, not a file")
        try:
            dest.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=temp_prefix(dest, dest.suffix), suffix=dest.suffix, dir=dest.parent)
        except OSError as exc:
            raise OutputError(f"cannot write {dest}: {exc.strerror or exc}") from None
        os.close(fd)
        self._staged.append((Path(tmp), dest))
        return Path(tmp)

    def commit(self) -> list[Path]:
        """Move every staged file into place; on any failure put every old file back and raise."""
        moved: list[tuple[Path | None, Path]] = []  # (backup of the old file or None, destination)
        try:
            for tmp, dest in self._staged:
                with open(tmp, "rb+") as f:
                    os.fsync(f.fileno())
                os.chmod(tmp, dest.stat().st_mode & 0o777 if dest.exists() else 0o666 & ~_umask())
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
            for backup, dest in reversed(moved):
                with contextlib.suppress(OSError):
                    if backup is not None:
                        os.replace(backup, dest)
                    else:
                        dest.unlink(missing_ok=True)
            self.discard()
            raise OutputError(f"could not write {dest}: {exc.strerror or exc}; no output was replaced") from None
        for backup, _ in moved:
            if backup is not None:
                with contextlib.suppress(OSError):
                    backup.unlink()
        done = [dest for _, dest in self._staged]
        self._staged = []
        return done

    def discard(self) -> None:
        """Remove every staged file (the destinations are untouched)."""
        for tmp, _ in self._staged:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
        self._staged = []

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()


def write_outputs(ident, report_path: str | Path, model_path: str | Path | None = None, plots: str | Path | None = None) -> None:
    """Write the report, the model and the plots of an identification as one set: all replaced, or none.

    Each file is rendered beside its destination first; only when every one is written are
    they moved into place (:class:`OutputSet`), so a
    failure on the report never leaves a new model or new plots beside an old report.
    """
    from rventry_env.validation.report.model_io import save_model
    from rventry_env.validation.report.plots import write_plots  # matplotlib: only when writing

    rep = ident.report
    with OutputSet() as outputs:
        if plots:
            rep["plots"] = [str(p) for p in write_plots(ident, plots, stage=outputs.stage)]
        if model_path:
            save_model(ident.model, outputs.stage(model_path))
            rep["model_file"] = str(model_path)
        atomic_write(outputs.stage(report_path), dumps_json(rep, indent=2))
        outputs.commit()


__all__ = ["OutputSet", "write_outputs"]
