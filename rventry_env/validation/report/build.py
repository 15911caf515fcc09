"""The JSON report of an identification, assembled from what the phases found.

:func:`build_report` takes the record's flight, its intake, the search state and the adequacy
test and lays them out in the keys documented in ``docs/validation.md``; it computes nothing
the phases have not, except summaries (error metrics, whiteness) of their fits.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.intake.references import explain_entry_offset
from rventry_env.validation.record import RecordError
from rventry_env.validation.replay.record_replay import TIME_OFFSET
from rventry_env.validation.report.diagnostics import error_metrics
from rventry_env.validation.report.model_io import model_to_dict
from rventry_env.validation.search.aliases import identifiable
from rventry_env.validation.search.effects import EARTH_J2, PHYSICAL_BOUNDS
from rventry_env.validation.search.fit import FitResult
from rventry_env.validation.search.statistics import effective_size, whiteness


PRIVATE_TRACE_KEYS = ("residual_after_trace", "fit", "rival_fits")  # the trace's arrays and fit objects: for plots and phases


def residual_whiteness(fit: FitResult, sigma: np.ndarray) -> dict:
    """Whiteness of a fit's residual in noise units."""
    return whiteness(fit.residual / sigma[None, :])


def fit_summary(fit: FitResult, kind: str, sigma: np.ndarray) -> dict:
    """One candidate's fit for the report: effects, BIC, credibility, parameters, errors."""
    n0 = fit.extra["n_initial"]
    out = {
        "effects": list(fit.effects),
        "bic": fit.bic,
        "credible": fit.credible,
        "parameters": fit.parameters(),
        "stderr": {k: float(s) for k, s in zip(fit.names[n0:], fit.stderr[n0:])},
        "at_bound": fit.extra["at_bound"],
        "initial_state_at_bound": fit.extra["initial_state_at_bound"],
        "implausible": fit.extra["implausible"],
        "errors": error_metrics(fit.residual, kind),
        "whiteness": residual_whiteness(fit, sigma),
        "replays": fit.nfev,
    }
    if "j2_check" in fit.extra:
        out["j2_check"] = fit.extra["j2_check"]
    return out


def statement(chosen, adeq: dict, aliases: list) -> str:
    """The report's plain-words answer: what was identified, its aliases, and what remains."""
    if chosen:
        head = f"Identified: {' + '.join(chosen)}."
    else:
        head = "No candidate effect is supported by the record."
    if aliases:
        others = [" + ".join(m["effects"]) + (" (tied)" if m["tied"] else "") for m in aliases[0]["members"]
                  if sorted(m["effects"]) != sorted(chosen)]  # fmt: skip
        if others:
            head += f" The record cannot tell it from: {'; '.join(others)} (see aliases)."
    if adeq["unexplained"] and chosen:
        head += " The named effects are the best the candidate set offers; they may stand in for the missing one."
    return head + " " + adeq["statement"]


def record_effects(params: dict, stderr: dict) -> dict:
    """The identified effects of the record itself (not of the world): its time-tag offset, with its uncertainty."""
    if TIME_OFFSET not in params:
        return {}
    value, se = params[TIME_OFFSET], stderr.get(TIME_OFFSET)
    return {"time_offset": {
        "value_s": value, "stderr_s": se,
        "statement": f"The record's state rows are tagged {value:+.4g} +/- {_fmt_se(se)} s early against its "
                     "controls (the row of time t holds the state flown at t + that offset): a clock offset of "
                     "the record, not a force; it is not in the identified model, which flies the controls at "
                     "their own times.",
    }}  # fmt: skip


def _fmt_se(se) -> str:
    return "n/a" if se is None or not math.isfinite(se) else f"{se:.2g}"


def surrogate_text(trace: dict | None) -> str:
    """The effects removed because they only stood in for the traced correction, in words ('' if none)."""
    gone = (trace or {}).get("surrogates_removed") or []
    if not gone:
        return ""
    names = ", ".join(g["effect"] for g in gone)
    return (f" Next to the traced correction the record does not support {names}: "
            f"{'it' if len(gone) == 1 else 'they'} only stood in for it and {'is' if len(gone) == 1 else 'are'} "
            "not in the identified model.")


def answer_parameters(current: FitResult, chosen) -> tuple[dict, dict]:
    """The answer's parameters and standard errors (the known J2 with its record-preferred stderr)."""
    n0 = current.extra["n_initial"]
    params = current.parameters()
    stderr = {k: float(s) for k, s in zip(current.names[n0:], current.stderr[n0:])}
    if "j2_gravity" in chosen:
        params["j2"] = EARTH_J2
        stderr["j2"] = current.extra.get("j2_check", {}).get("stderr")
    return params, stderr


def noise_section(screened, current: FitResult) -> dict:
    """What the noise was taken to be, where it came from, and the rms after the fit."""
    names = screened.group_names
    return {
        "declared": screened.declared,
        "difference_estimate": {g: (screened.estimate[g] if np.isfinite(screened.estimate[g]) else None)
                                for g in names},
        "difference_estimate_is": screened.estimate_is,
        "robust_difference_estimate": {g: (v if np.isfinite(v) else None) for g, v in screened.robust_estimate.items()},
        "weights": {g: screened.sigma[g] for g in names},
        "weights_from": screened.weights_from,
        "after_fit_rms": {g: (math.sqrt(current.rss_by_group[i] / current.n_by_group[i])
                              if current.n_by_group[i] else None) for i, g in enumerate(names)},
    }  # fmt: skip


def record_section(record, replay, controls) -> dict:
    """The record as replayed: samples, span, RK4 steps, and every note on it."""
    return {
        "path": str(record.path) if record.path else None,
        "kind": record.kind,
        "samples": len(replay.rows),
        "values": int(np.count_nonzero(np.isfinite(replay.y))),
        "t_start_s": replay.t0,
        "t_end_s": float(replay.t_obs[-1]),
        "rk4_steps": int(replay.grid.n_steps),
        "notes": list(record.notes) + list(controls.notes) + list(replay.notes),
    }


def entry_state_section(fit: FitResult, setup, screened, sigma: np.ndarray) -> dict | None:
    """The entry-state offset a reduced record's fit found from its sidecar, with its uncertainty and references.

    The standard errors are the fit's, inflated by sqrt(n / n_eff) when its residual is serially
    correlated (the AR(1) effective sample size, as in BIC): a correlated residual holds fewer
    independent values than samples.
    """
    if setup.entry_state is None or fit.extra["n_initial"] != 3:
        return None
    n0 = fit.extra["n_initial"]
    lag1 = residual_whiteness(fit, sigma)["lag1_autocorrelation"]
    n = sum(fit.n_by_group)
    inflation = math.sqrt(n / effective_size(n, lag1)) if n else 1.0
    return explain_entry_offset(fit.names[:n0], fit.values[:n0], fit.stderr[:n0], setup, inflation,
                                screened.entry_check)  # fmt: skip


def build_report(record, replay, controls, setup, screened, ctx, state, adeq: dict, aliases: list,
                 threshold: float, max_effects: int, elapsed: float, trace: dict | None = None) -> dict:  # fmt: skip
    """The identification report (see ``docs/validation.md`` for every key).

    :param trace: the residual trace (:mod:`~rventry_env.validation.trace.attribution`), when the
        residual is not noise.
    """
    current, base, chosen = state.current, state.base, state.chosen
    kind = record.kind
    sigma = ctx.sigma
    n0 = current.extra["n_initial"]
    table = state.steps[0]["tried"]
    params, stderr = answer_parameters(current, chosen)
    bound = screened.bound
    in_record = record_effects(params, stderr)
    return {
        "effect": chosen[0] if chosen else ("unexplained" if adeq["unexplained"] else "none"),
        "effects": list(chosen),
        "unexplained": adeq["unexplained"],
        "statement": (statement(chosen, adeq, aliases) + surrogate_text(trace)
                      + "".join(" " + r["statement"] for r in in_record.values())
                      + (" " + trace["statement"] if trace else "")),
        "record_effects": in_record,
        "attribution": trace["attribution"] if trace else [],
        "trace": None if trace is None else {k: v for k, v in trace.items() if k not in PRIVATE_TRACE_KEYS},
        "parameters": params,
        "parameter_stderr": stderr,
        "fixed_parameters": {"j2": EARTH_J2} if "j2_gravity" in chosen else {},
        "identifiable": identifiable(current.parameters(), chosen, setup.start_lift_scale) if chosen else None,
        "aliases": aliases,
        "adequacy": adeq,
        "initial_state_offsets": {k: float(v) for k, v in zip(current.names[:n0], current.values[:n0])},
        "initial_state_bound": None if bound is None else dict(zip(current.names[:n0], map(float, bound))),
        "initial_state_at_bound": current.extra["initial_state_at_bound"],
        "ranking": [{k: r[k] for k in ("effect", "bic", "delta_bic", "credible", "at_bound",
                                       "initial_state_at_bound", "implausible")} for r in table],  # fmt: skip
        "margin_to_runner_up": table[1]["delta_bic"] if len(table) > 1 else None,
        "improvement_over_baseline": table[0]["improvement_over_current"] if table else None,
        "bic_threshold": threshold,
        "max_effects": max_effects,
        "physical_bounds": PHYSICAL_BOUNDS,
        "aliases_not_fitted": state.aliases_skipped,
        "steps": state.steps,
        "before": error_metrics(base.residual, kind),
        "after": error_metrics(current.residual, kind),
        "whiteness": {"before": residual_whiteness(base, sigma), "after": residual_whiteness(current, sigma)},
        "noise": noise_section(screened, current),
        "rejected_outliers": screened.rejected,
        "entry_state_check": screened.entry_check or None,
        "entry_state_offset": entry_state_section(current, setup, screened, sigma),
        "record": record_section(record, replay, controls),
        "start_model": setup.start,
        "density_knots_m": list(current.structure.density_knots) if "density_profile" in chosen else None,
        "mach_knots": list(current.structure.mach_knots) if "mach_drag" in chosen else None,
        "knot_trials": state.knot_trials,
        "candidates": {n: fit_summary(f, kind, sigma) for n, f in state.first.items()},
        "model": model_to_dict(current.model),
        "elapsed_s": elapsed,
        "replays": ctx.nfev,
    }


def check_finite(report: dict) -> None:
    """Fail loudly if a headline figure is not a finite number (never write NaN as a result)."""
    for key in ("before", "after"):
        for k, v in report[key].items():
            if v is None or not math.isfinite(v):
                raise RecordError(f"the replay produced no finite {k.replace('_', ' ')} ({key}); "
                                  "check the record's units and the entry state")  # fmt: skip
    for k, v in report["parameters"].items():
        if not math.isfinite(v):
            raise RecordError(f"the fit produced a non-finite parameter {k}")


__all__ = ["build_report", "check_finite", "fit_summary", "residual_whiteness", "statement"]
