"""An identification's outputs as one set: every file replaced, or none.

``rventry identify --json R --model-out M --plots P`` writes a report, a model and plots that
describe one run. Written one after another, a failure on the last would leave a new model
beside an old report. They are written inside one :func:`~rventry_env.util.files.output_set`.
"""

from __future__ import annotations

from pathlib import Path

from rventry_env.util.files import output_set, write_json


def write_outputs(ident, report_path: str | Path, model_path: str | Path | None = None, plots: str | Path | None = None) -> None:
    """Write the report, the model and the plots of an identification as one set: all replaced, or none.

    Each file is rendered beside its destination first; only when every one is written are
    they moved into place (:func:`~rventry_env.util.files.output_set`), so a failure on the
    report never leaves a new model or new plots beside an old report.
    """
    from rventry_env.validation.report.model_io import save_model
    from rventry_env.validation.report.plots import write_plots  # matplotlib: only when writing

    rep = ident.report
    with output_set():
        if plots:
            rep["plots"] = [str(p) for p in write_plots(ident, plots)]
        if model_path:
            save_model(ident.model, model_path)
            rep["model_file"] = str(model_path)
        write_json(report_path, rep, indent=2)


__all__ = ["write_outputs"]
