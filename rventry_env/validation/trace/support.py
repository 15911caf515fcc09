"""Which identified effects the record supports next to the trace, and which only stood in for it.

A candidate effect lowers the residual of a record that needs something outside the candidate
set, and may be accepted for that alone: a density profile bends to absorb part of a bank-angle
bias, a wind part of a density structure. That is a wrong physical claim however small the
residual. Once the residual is traced (:mod:`~rventry_env.validation.trace.attribution`), every
accepted effect must earn its place *next to the traced correction*: the correction is refitted on
the identified model without the effect (:func:`~rventry_env.validation.trace.attribution.refit_without`,
never worse than its start), and if that fit is within the BIC threshold of the fit with it, the
effect only stood in for what the trace found. It is removed from the identified model, and the
trace is reported on the model without it. The least supported effect goes first, one at a time.
"""

from __future__ import annotations

from rventry_env.validation.search.aliases import admissible
from rventry_env.validation.trace.attribution import describe_trace, refit_without


def drop_surrogates(ctx, state, trace: dict, threshold: float, say=lambda msg: None) -> list[dict]:
    """Remove the accepted effects that stand in for the traced correction; return what was removed and why.

    :param ctx: the record's fit context.
    :param state: the search state (its ``current`` fit loses the effects removed).
    :param trace: a trace with a significant attribution (its ``fit`` and description are updated).
    :param threshold: the BIC margin an effect must earn next to the correction.
    """
    if not trace or not trace.get("attribution") or "fit" not in trace:
        return []
    removed = []
    c0 = ctx.setup.start_lift_scale
    while state.chosen:
        current, chosen = state.current, state.chosen
        with_bic = trace["fit"].f["bic"]
        trials = {}
        for e in chosen:
            rest = tuple(x for x in chosen if x != e)
            st = ctx.structure(rest, current.structure)
            if rest and not admissible(rest, st, c0):
                continue
            say(f"support: {' + '.join(rest) or 'the current model'} with the traced correction (without {e})")
            reduced = ctx.fit(st, current)
            tf = refit_without(ctx, trace, reduced, threshold)
            if tf.f["outside"] or tf.f["unsupported"]:
                continue
            trials[e] = (tf.f["bic"], reduced, tf)
        rows = [{"without": e, "bic_with": with_bic, "bic_without": b, "earns": b - with_bic > threshold}
                for e, (b, _, _) in trials.items()]  # fmt: skip
        state.steps.append({"step": "support next to the trace", "from": list(chosen), "tried": rows,
                            "removed": None})  # fmt: skip
        if not trials:
            break
        e, (b, reduced, tf) = min(trials.items(), key=lambda kv: kv[1][0])
        if b - with_bic > threshold:
            break
        state.steps[-1]["removed"] = e
        state.current = reduced
        removed.append({"effect": e, "bic_with": with_bic, "bic_without": b,
                        "reason": f"next to the traced correction the record prefers the model without {e} "
                                  f"(BIC {b - with_bic:+.1f}, threshold {threshold:g}): it stood in for the "
                                  "trace"})  # fmt: skip
        say(f"removed {e}: it stood in for the traced correction")
        trace["fit"] = tf
        describe_trace(ctx, reduced, trace, threshold, trace.get("rivals", []))
        if not trace.get("attribution"):
            break
    if removed:
        trace["surrogates_removed"] = removed
    return removed


__all__ = ["drop_surrogates"]
