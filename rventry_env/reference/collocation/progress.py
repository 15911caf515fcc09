"""Progress of the hp mesh iterations: a record per pass and reporters for it.

The solver calls ``progress(record)`` once per mesh pass; anything callable fits.
:class:`RichMeshTable` prints one aligned row per pass (the header once), which
is what the command line uses; :class:`RecordingProgress` keeps the records for
tests and benchmarks.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable


@dataclass(frozen=True)
class MeshIterationRecord:
    """What happened in one mesh pass.

    :param iteration: 0-based mesh pass.
    :param n_intervals: mesh intervals.
    :param n_nodes: state nodes (collocation points + 1).
    :param max_error: largest relative error estimate over the intervals.
    :param status: IPOPT return status.
    :param success: whether IPOPT reported success.
    :param nlp_iterations: IPOPT iterations.
    :param solve_time_s: wall time of this pass (transcription, solve, error estimate).
    :param cost: objective value (unscaled).
    :param tf: final time.
    """

    iteration: int
    n_intervals: int
    n_nodes: int
    max_error: float
    status: str
    success: bool
    nlp_iterations: int
    solve_time_s: float
    cost: float
    tf: float
    label: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


Progress = Callable[[MeshIterationRecord], None]


class RichMeshTable:
    """Print one row per mesh pass with rich (header on the first row).

    :param title: printed above the header.
    :param console: a ``rich.console.Console`` (default: a new one on stderr).
    """

    columns = ("pass", "intervals", "nodes", "max rel. error", "NLP status", "iter", "time s", "cost", "tf s")

    def __init__(self, title: str = "", console=None):
        from rich.console import Console

        self.console = console if console is not None else Console(stderr=True, highlight=False)
        self.title = title
        self._started = False

    def __call__(self, rec: MeshIterationRecord) -> None:
        if not self._started:
            if self.title:
                self.console.print(f"[bold]{self.title}[/bold]")
            self.console.print(self._fmt(self.columns), style="bold", soft_wrap=True)
            self._started = True
        row = (
            f"{rec.iteration}{rec.label}",
            str(rec.n_intervals),
            str(rec.n_nodes),
            f"{rec.max_error:.2e}",
            rec.status,
            str(rec.nlp_iterations),
            f"{rec.solve_time_s:.2f}",
            f"{rec.cost:.6g}",
            f"{rec.tf:.3f}",
        )
        # a failed NLP shows in red; markup is off so odd status text prints verbatim
        self.console.print(self._fmt(row), style=None if rec.success else "red", markup=False, soft_wrap=True)

    @staticmethod
    def _fmt(cells) -> str:
        widths = (6, 9, 6, 14, 26, 5, 7, 12, 10)
        # the status column is text: left-aligned; numbers right-aligned
        cols = [str(c).ljust(w) if i == 4 else str(c).rjust(w) for i, (c, w) in enumerate(zip(cells, widths))]
        return " ".join(cols)


class RecordingProgress:
    """Keep every record (and forward to another reporter if given)."""

    def __init__(self, forward: Progress | None = None):
        self.records: list[MeshIterationRecord] = []
        self.forward = forward

    def __call__(self, rec: MeshIterationRecord) -> None:
        self.records.append(rec)
        if self.forward is not None:
            self.forward(rec)


__all__ = ["MeshIterationRecord", "Progress", "RichMeshTable", "RecordingProgress"]
