"""The model-validation loop: replay measured flight data, name the missing effect, add it.

One room (physics knows nothing of this package); inside it, sub-rooms in the order a record
goes through them:

* :mod:`~rventry_env.validation.record` reads and validates a flight record;
  :mod:`~rventry_env.validation.apollo4` ships the Apollo 4 flight record;
* :mod:`~rventry_env.validation.replay` flies it with the rv-Euler entry model, with exact
  sensitivities;
* :mod:`~rventry_env.validation.intake` rejects gross outliers, estimates the noise, and checks
  the sidecar's entry state against the first samples;
* :mod:`~rventry_env.validation.search` fits the candidate effects, selects and names them
  (with their aliases), and tests what remains against the noise;
* :mod:`~rventry_env.validation.trace` traces what no candidate explains to a force channel;
* :mod:`~rventry_env.validation.report` builds the report, the plots and the model file;
* :mod:`~rventry_env.validation.synthetic` makes synthetic records through an independent
  Cartesian truth model;
* :mod:`~rventry_env.validation.identify` runs the phases in order; :mod:`~rventry_env.validation.cli`
  is ``rventry identify`` and ``rventry simulate-record``.

Typical use::

    from rventry_env.validation import identify_record, load_model
    ident = identify_record("flight.csv")
    model = ident.model                      # an EntryModel with the effect added
    # gym.make("RvEntry-v0", model=model)

Everything heavy (SciPy) is imported by the modules, not here.
"""

from __future__ import annotations

from pathlib import Path


def identify_record(path: str | Path, **kwargs):
    """Load a record and run :func:`~rventry_env.validation.identify.identify` on it.

    :param path: the record CSV (its sidecar is read from beside it).
    :param kwargs: passed to :func:`~rventry_env.validation.identify.identify`
        (``vehicle``, ``start``, ``candidates``, ``threshold``, ``h_max``, ``max_effects``, ``progress``,
        ``noise``).
    :return: an :class:`~rventry_env.validation.identify.Identification`; ``.model`` is the
        identified :class:`~rventry_env.physics.EntryModel`, ``.report`` the JSON report.
    """
    from rventry_env.validation.identify import identify
    from rventry_env.validation.record import load_record

    return identify(load_record(path), **kwargs)


def identified_model(source):
    """The identified :class:`~rventry_env.physics.EntryModel` from an identification, a report or a file.

    :param source: an :class:`~rventry_env.validation.identify.Identification`, a report dict,
        or the path of a report JSON (``rventry identify --json``) or model JSON (``--model-out``).
    """
    from rventry_env.validation.report.model_io import load_model, model_from_dict

    if hasattr(source, "model") and hasattr(source, "report"):
        return source.model
    if isinstance(source, dict):
        return model_from_dict(source)
    return load_model(source)


def save_model(model, path):
    """Write an :class:`~rventry_env.physics.EntryModel` to JSON (:mod:`~rventry_env.validation.report.model_io`)."""
    from rventry_env.validation.report.model_io import save_model as _save

    return _save(model, path)


def load_model(path):
    """Read an :class:`~rventry_env.physics.EntryModel` from a model or report JSON."""
    from rventry_env.validation.report.model_io import load_model as _load

    return _load(path)


__all__ = ["identified_model", "identify_record", "load_model", "save_model"]
