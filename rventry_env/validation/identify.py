"""The model-validation loop: replay a record, trace the residual to a missing effect, add it.

1. Replay the record with the current model, fitting only the initial state within its noise
   (output-error least squares with exact sensitivities): the *baseline*.
2. For every candidate effect, fit its parameters together with the initial state, and rank
   the candidates by BIC. Only *credible* fits compete for acceptance: none of their
   parameters on a physical bound, the initial state within its noise bound, J2 agreeing with
   its known value.
3. Accept the best one if it beats the baseline by more than :data:`BIC_THRESHOLD`.
4. Forward selection: with the accepted effects in the model, try each remaining one on top,
   and keep adding while the best addition again beats the current model. An addition that
   only repeats a direction the model already moves is an alias and is not fitted; one that
   makes another effect redundant replaces it by the sparsest equivalent set
   (:mod:`~rventry_env.validation.aliases`).
5. Test the final residual against the noise (:mod:`~rventry_env.validation.adequacy`): if it
   is not noise, the report says ``"unexplained": true`` and never answers ``none``.

The identified model is an :class:`~rventry_env.physics.EntryModel` built from the physics
parts (:func:`~rventry_env.validation.effects.build_model`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics import ConstantAerodynamics, EntryModel
from rventry_env.validation.adequacy import adequacy
from rventry_env.validation.aliases import (
    admissible,
    alias_groups,
    directions,
    identifiable,
    same_span,
    sparsest_equivalent,
)
from rventry_env.validation.consistency import check_entry_state
from rventry_env.validation.controls import control_schedule
from rventry_env.validation.diagnostics import error_metrics, measured_density_correction, run_diagnostics
from rventry_env.validation.effects import (
    EARTH_J2,
    EFFECT_NAMES,
    PHYSICAL_BOUNDS,
    density_knots,
    knot_counts,
    mach_knot_counts,
    mach_knots,
)
from rventry_env.validation.fit import FitResult
from rventry_env.validation.model_io import model_to_dict
from rventry_env.validation.noise import GROUPS, PROVISIONAL_SIGMA, init_bounds, is_noise, record_noise
from rventry_env.validation.outliers import reject_outliers
from rventry_env.validation.record import FlightRecord, RecordError
from rventry_env.validation.record_replay import Replay
from rventry_env.validation.replay_setup import ReplaySetup, replay_setup
from rventry_env.validation.selection import BIC_THRESHOLD, FitContext, compare_fits
from rventry_env.validation.statistics import whiteness

SCREEN_KEEP = 2  # additions fitted in full per forward-selection step, after linearized screening
PROFILES = ("density_profile", "mach_drag")  # effects whose knot count is chosen by BIC


@dataclass
class Identification:
    """The outcome of :func:`identify`.

    :param report: the JSON report (see ``docs/validation.md``).
    :param model: the identified :class:`EntryModel` (the current model if no effect was added).
    :param baseline: the baseline fit.
    :param final: the fit of the identified model.
    :param candidates: first-step fits by effect name.
    :param steps: forward-selection steps (dicts of the fits tried at each step).
    :param replay: the replay used.
    :param setup: the declared facts.
    """

    report: dict
    model: EntryModel
    baseline: FitResult
    final: FitResult
    candidates: dict
    steps: list
    replay: Replay
    setup: ReplaySetup
    extra: dict = field(default_factory=dict)


def _progress(enabled: bool):
    """Progress lines on stderr with the elapsed time; never wrapped (a log file reads line by line)."""
    from rich.console import Console
    from rich.markup import escape

    console = Console(stderr=True, highlight=False, soft_wrap=True)
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if enabled:
            console.print(f"[dim]identify {time.perf_counter() - t0:6.1f} s[/dim]  {escape(msg)}")

    return say


def _whiteness(fit: FitResult, sigma: np.ndarray) -> dict:
    return whiteness(fit.residual / sigma[None, :])


def _fit_summary(fit: FitResult, kind: str, sigma: np.ndarray) -> dict:
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
        "whiteness": _whiteness(fit, sigma),
        "replays": fit.nfev,
    }
    if "j2_check" in fit.extra:
        out["j2_check"] = fit.extra["j2_check"]
    return out


def _mach_of_record(record: FlightRecord, setup: ReplaySetup, rows: np.ndarray) -> np.ndarray:
    h = record.altitude()[rows]
    v = record.speed()[rows]
    ok = np.isfinite(h) & np.isfinite(v)
    a = np.asarray(setup.model.atmosphere.speed_of_sound(h[ok], NUMPY), float)
    return v[ok] / a


def identify(
    record: FlightRecord,
    vehicle: dict | None = None,
    start: str | None = None,
    candidates: tuple | None = None,
    threshold: float = BIC_THRESHOLD,
    h_max: float = 1.0,
    max_effects: int = 3,
    progress: bool = False,
    noise: tuple | None = None,
) -> Identification:
    """Run the validation loop on a record.

    :param record: a validated record (:func:`~rventry_env.validation.record.load_record`).
    :param vehicle: a vehicle description overriding the sidecar's.
    :param start: ``"declared"`` or ``"drag-only"`` (default: the sidecar's, else declared).
    :param candidates: the effects to consider (default: all; ``measured_density`` only for a
        record with a density column).
    :param threshold: BIC margin an effect must beat the current model by (>= 0).
    :param h_max: longest RK4 step of the replay (s, > 0).
    :param max_effects: most effects to add (0: replay, rank and test only).
    :param progress: print progress to stderr.
    :param noise: declared measurement noise (position or altitude m, velocity or speed m/s),
        overriding the sidecar's.
    """
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"threshold must be a finite number >= 0, got {threshold!r}")
    if not (isinstance(h_max, (int, float)) and math.isfinite(h_max) and 0 < h_max <= 10):
        raise ValueError(f"h_max must be a number of seconds in (0, 10], got {h_max!r}")
    if isinstance(max_effects, bool) or not isinstance(max_effects, int) or max_effects < 0:
        raise ValueError(f"max_effects must be an integer >= 0, got {max_effects!r}")
    if noise is not None and not (len(noise) == 2 and all(math.isfinite(x) and x > 0 for x in noise)):
        raise ValueError(f"noise must be two positive numbers (position m, velocity m/s), got {noise!r}")
    say = _progress(progress)
    t_start = time.perf_counter()
    has_density = record.density is not None and np.count_nonzero(np.isfinite(record.density)) >= 3
    if candidates is None:
        candidates = tuple(c for c in EFFECT_NAMES if c != "measured_density" or has_density)
    candidates = tuple(dict.fromkeys(candidates))
    unknown = [c for c in candidates if c not in EFFECT_NAMES]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {', '.join(unknown)}; choose from {', '.join(EFFECT_NAMES)}")
    if "measured_density" in candidates and not has_density:
        raise ValueError("candidate measured_density needs a record with a density_kgpm3 column (3 values or more)")
    setup = replay_setup(record, vehicle, start, noise)
    needs_alpha = not isinstance(setup.lift_reference, ConstantAerodynamics)
    controls = control_schedule(record, setup.lift_to_drag, needs_alpha)
    replay = Replay(record, setup, controls, h_max=h_max)
    kind = record.kind
    groups = np.zeros(replay.y.shape[1], dtype=int)
    for gi, (_, _, cols) in enumerate(GROUPS[kind]):
        groups[list(cols)] = gi
    group_names = [g[0] for g in GROUPS[kind]]

    # gross outliers, where the sampling resolves the signal; then the noise without them
    noise_diff, noise_kind = record_noise(replay, kind)
    screened = {g: (u, cols) for g, u, cols in GROUPS[kind] if is_noise(noise_kind.get(g, ""))}
    rejected = reject_outliers(replay, screened) if screened else []
    if rejected:
        say(f"{len(rejected)} outlier(s) rejected: rows {', '.join(str(r['row']) for r in rejected[:10])}")
        noise_diff, noise_kind = record_noise(replay, kind)
    if not np.any(np.isfinite(replay.y)):
        raise RecordError("no observation left after rejecting outliers")

    declared = setup.declared_noise
    sigma_g, weights_from = {}, {}
    for g in group_names:
        if declared is not None:
            sigma_g[g], weights_from[g] = declared[g], "declared"
        elif np.isfinite(noise_diff[g]):
            sigma_g[g], weights_from[g] = noise_diff[g], "record differences"
        else:
            sigma_g[g], weights_from[g] = PROVISIONAL_SIGMA[g], "provisional"
    entry_check = check_entry_state(replay, setup, sigma_g if declared is not None else noise_diff)
    for w in entry_check.get("warnings", []):
        say("warning: " + w)
    bound = init_bounds(replay, kind, declared if declared is not None else noise_diff)

    def sig_vector() -> np.ndarray:
        return np.array([sigma_g[group_names[g]] for g in groups])

    # density knots over the altitudes flown, Mach knots over the Mach numbers (from the record)
    rows = replay.rows
    altitudes = record.altitude()[rows]
    knots_by_count = {n: density_knots(altitudes, n) for n in knot_counts(altitudes)}
    mach = _mach_of_record(record, setup, rows)
    mach_by_count = {n: mach_knots(mach, n) for n in mach_knot_counts(mach)}
    if has_density:
        alt = record.altitude()
        ok = np.isfinite(alt) & np.isfinite(record.density)
        setup = dataclasses.replace(
            setup, measured_atmosphere=measured_density_correction(alt[ok], record.density[ok], setup.model)
        )
        replay.setup = setup

    ctx = FitContext(replay, setup, groups, sig_vector(), bound, knots_by_count, mach_by_count, threshold)
    say(f"{record.path.name if record.path else 'record'}: {kind}, {len(replay.rows)} samples, "
        f"{replay.grid.n_steps} RK4 steps; baseline fit")  # fmt: skip
    base_structure = ctx.structure(())
    base = ctx.fit(base_structure, None)
    if any(v == "provisional" for v in weights_from.values()):
        # no noise known: weight each group by its own baseline scatter, and refit
        for gi, g in enumerate(group_names):
            if weights_from[g] == "provisional" and base.n_by_group[gi]:
                sigma_g[g] = math.sqrt(base.rss_by_group[gi] / base.n_by_group[gi]) or PROVISIONAL_SIGMA[g]
                weights_from[g] = "baseline residual"
        ctx.sigma = sig_vector()
        base = ctx.fit(base_structure, base)
    sigma = ctx.sigma
    c0 = setup.start_lift_scale

    def fit_set(effects: tuple, new: str, like, previous: FitResult, rival) -> tuple[FitResult, list | None]:
        if new in PROFILES:
            return ctx.fit_profile(effects, new, like, previous, rival)
        return ctx.fit(ctx.structure(effects, like), previous), None

    # step 1: every candidate alone (an alias of an earlier one is not fitted twice)
    first: dict[str, FitResult] = {}
    knot_trials = {}
    aliases_skipped = []
    singles = []
    for name in sorted(candidates, key=lambda c: c in PROFILES):  # profiles last: they need a rival
        st = ctx.structure((name,))
        v = directions((name,), st, c0)
        twin = next((s for s in singles if v.shape[1] == 1 and same_span(directions((s,), st, c0), v)), None)
        if twin is not None:
            aliases_skipped.append({"step": 1, "effect": name, "alias_of": [twin]})
            continue
        singles.append(name)
    for name in singles:
        say(f"candidate {name}")
        rival = min((f.bic for f in first.values()), default=None)
        first[name], trials = fit_set((name,), name, None, base, rival)
        if trials is not None:
            knot_trials[f"step 1 {name}"] = trials
    cmp1 = compare_fits(base, list(first.values()), sigma, threshold, list(first))
    steps = [{"step": 1, "from": [], **_step_summary(cmp1)}]
    step_fits = [first]
    current, chosen = base, ()
    # the search continues from the last accepted fit, or from a *provisional* one: the best fit
    # of a step whose only flaw is an entry state on its noise bound is never accepted, but an
    # effect the record needs together with it may bring the entry state back within its noise
    search = base
    if max_effects == 0:
        steps[0]["accepted"] = None
        steps[0]["note"] = "max_effects = 0: nothing is added"
        search = None
    elif cmp1["accepted"] is not None:
        current = search = cmp1["accepted"]
        chosen = tuple(current.effects)
        say(f"accepted {' + '.join(chosen)}")
    elif cmp1["provisional"] is not None:
        search = cmp1["provisional"]
        steps[0]["provisional"] = list(search.effects)
        say(f"no credible candidate beats the current model; continuing from {' + '.join(search.effects)} "
            "(its entry state is on its bound)")  # fmt: skip
    else:
        search = None
        say("no credible candidate beats the current model")
    # forward selection
    while search is not None and search.effects and (
        len(search.effects) < min(max_effects, len(candidates)) or any(p in search.effects for p in PROFILES)
    ):
        base_effects = tuple(search.effects)
        sets = {}
        for c in candidates:
            if c in base_effects or len(base_effects) >= min(max_effects, len(candidates)):
                continue
            t_full = base_effects + (c,)
            st = ctx.structure(t_full, search.structure)
            sub = sparsest_equivalent(t_full, c, st, c0)
            if sub is None:
                aliases_skipped.append({"step": len(base_effects) + 1, "effect": c, "alias_of": list(base_effects)})
                continue
            if not admissible(sub, st, c0):
                continue
            sets.setdefault(sub, c)
        has_finer = any(
            p in base_effects and len(search.structure.density_knots if p == "density_profile"
                                      else search.structure.mach_knots) < max(ctx.knots_by_count if p == "density_profile"
                                                                               else ctx.mach_by_count)
            for p in PROFILES)  # fmt: skip
        if not sets and not has_finer:
            break
        # screen each set by one Gauss-Newton step from the search fit (exact Jacobian)
        lin = {}
        for sub, c in sets.items():
            prob = ctx.problem(ctx.structure(sub, search.structure))
            n = len(prob.names)
            lin[sub] = prob.linearized(ctx.start_from(prob, search), {"all": list(range(n))})["all"]["chi2"]
            ctx.nfev += 1
        screened_sets = sorted(sets, key=lin.get)
        tried = {}
        rival = None
        for sub in sorted(screened_sets[:SCREEN_KEEP], key=lambda s: sets[s] in PROFILES):
            c = sets[sub]
            label = "+".join(sub) if set(base_effects) - set(sub) else c
            say(f"step {len(base_effects) + 1}: {' + '.join(sub)}")
            fit, trials = fit_set(sub, c, search.structure, search, rival)
            if trials is not None:
                knot_trials[f"step {len(base_effects) + 1} {c}"] = trials
            tried[label] = fit
            rival = min(f.bic for f in tried.values())
        # a profile already in the model may need more knots rather than another effect
        for prof in (p for p in PROFILES if p in base_effects):
            fit = ctx.refine(search, prof)
            if fit is not None:
                n_kn = len(fit.structure.density_knots if prof == "density_profile" else fit.structure.mach_knots)
                say(f"step {len(base_effects) + 1}: {prof} with {n_kn} knots")
                tried[f"{prof} ({n_kn} knots)"] = fit
        step_fits.append(tried)
        cmp = compare_fits(current, list(tried.values()), sigma, threshold, list(tried))
        steps.append({
            "step": len(base_effects) + 1,
            "from": list(base_effects),
            "screened": [{"effects": list(s), "linearized_chi2": lin[s]} for s in screened_sets],
            **_step_summary(cmp),
        })  # fmt: skip
        if cmp["accepted"] is not None:
            current = search = cmp["accepted"]
            chosen = tuple(current.effects)
            say(f"accepted {' + '.join(chosen)}")
        elif cmp["provisional"] is not None and cmp["provisional"].structure.key() != search.structure.key():
            search = cmp["provisional"]
            steps[-1]["provisional"] = list(search.effects)
            say(f"continuing from {' + '.join(search.effects)} (its entry state is on its bound)")
        else:
            break

    # backward elimination: an effect that no longer earns its place next to the others goes
    # (forward selection is greedy, and a provisional first step may have picked a near-tie)
    while len(chosen) > 1:
        trials = {}
        for e in chosen:
            rest = tuple(x for x in chosen if x != e)
            st = ctx.structure(rest, current.structure)
            if not admissible(rest, st, c0):
                continue
            say(f"backward: {' + '.join(rest)} (without {e})")
            trials[e] = ctx.fit(st, current)
        step_fits.append(trials)
        if not trials:
            break
        cmp = compare_fits(current, list(trials.values()), sigma, 0.0, [f"without {e}" for e in trials])
        n_eff = cmp["n_eff"]
        b_cur = cmp["bic_current"]
        removable = [(row["bic"], row) for row in cmp["table"]
                     if row["credible"] and row["bic"] < b_cur + threshold]  # fmt: skip
        steps.append({"step": "backward", "from": list(chosen), "effective_samples": n_eff, "bic_current": b_cur,
                      "tried": cmp["table"], "removed": None})  # fmt: skip
        if not removable:
            break
        _, row = min(removable, key=lambda r: r[0])
        e = row["effect"][len("without "):]
        steps[-1]["removed"] = e
        current = trials[e]
        chosen = tuple(current.effects)
        say(f"removed {e}: the others explain the record as well")

    # what remains
    source = "declared" if declared is not None else (
        "estimated" if all(w == "record differences" for w in weights_from.values()) else "baseline residual")
    adeq = adequacy(current, sigma_g, source, group_names, groups, sigma,
                    {g: noise_kind.get(g) for g in group_names})  # fmt: skip
    values = current.parameters()
    aliases = alias_groups(values, chosen, current.structure, c0) if chosen else []
    canon = _canonical_member(aliases, chosen, current)
    if canon is not None:
        # an exact alias of the same size that comes first in the candidate order: name that one
        # (the same fit, so every record names the same member of a group)
        effects_c, params_c = canon
        st = ctx.structure(tuple(effects_c), current.structure)
        prob = ctx.problem(st)
        theta0 = ctx.start_from(prob, current)
        for i, nme in enumerate(prob.names):
            if nme in params_c:
                theta0[i] = params_c[nme]
        refit = ctx.fit(st, None, max_nfev=20, theta0=theta0)
        if refit.credible and refit.bic <= current.bic + 1e-6 * abs(current.bic) + 1e-6:
            current, chosen = refit, tuple(refit.effects)
            values = current.parameters()
            aliases = alias_groups(values, chosen, current.structure, c0)
    elapsed = time.perf_counter() - t_start
    n0 = current.extra["n_initial"]
    table = steps[0]["tried"]
    params_out = dict(values)
    stderr_out = {k: float(s) for k, s in zip(current.names[n0:], current.stderr[n0:])}
    if "j2_gravity" in chosen:
        params_out["j2"] = EARTH_J2
        chk = current.extra.get("j2_check", {})
        stderr_out["j2"] = chk.get("stderr")
    effect = chosen[0] if chosen else ("unexplained" if adeq["unexplained"] else "none")
    report = {
        "effect": effect,
        "effects": list(chosen),
        "unexplained": adeq["unexplained"],
        "statement": _statement(chosen, adeq, aliases),
        "parameters": params_out,
        "parameter_stderr": stderr_out,
        "fixed_parameters": {"j2": EARTH_J2} if "j2_gravity" in chosen else {},
        "identifiable": identifiable(values, chosen, c0) if chosen else None,
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
        "aliases_not_fitted": aliases_skipped,
        "steps": steps,
        "before": error_metrics(base.residual, kind),
        "after": error_metrics(current.residual, kind),
        "whiteness": {"before": _whiteness(base, sigma), "after": _whiteness(current, sigma)},
        "noise": {
            "declared": declared,
            "difference_estimate": {g: (noise_diff[g] if np.isfinite(noise_diff[g]) else None)
                                    for g in group_names},
            "difference_estimate_is": noise_kind,
            "weights": {g: sigma_g[g] for g in group_names},
            "weights_from": weights_from,
            "after_fit_rms": {g: (math.sqrt(current.rss_by_group[i] / current.n_by_group[i])
                                  if current.n_by_group[i] else None) for i, g in enumerate(group_names)},
        },  # fmt: skip
        "rejected_outliers": rejected,
        "entry_state_check": entry_check or None,
        "record": {
            "path": str(record.path) if record.path else None,
            "kind": kind,
            "samples": len(replay.rows),
            "values": int(np.count_nonzero(np.isfinite(replay.y))),
            "t_start_s": replay.t0,
            "t_end_s": float(replay.t_obs[-1]),
            "rk4_steps": int(replay.grid.n_steps),
            "notes": list(record.notes) + list(controls.notes) + list(replay.notes),
        },
        "start_model": setup.start,
        "density_knots_m": list(current.structure.density_knots) if "density_profile" in chosen else None,
        "mach_knots": list(current.structure.mach_knots) if "mach_drag" in chosen else None,
        "knot_trials": knot_trials,
        "candidates": {n: _fit_summary(f, kind, sigma) for n, f in first.items()},
        "model": model_to_dict(current.model),
        "elapsed_s": elapsed,
        "replays": ctx.nfev,
    }
    report.update(run_diagnostics(record, ctx, base, current, chosen, kind, first))
    report["elapsed_s"] = time.perf_counter() - t_start
    _check_finite(report)
    say(f"done in {report['elapsed_s']:.1f} s: effect {report['effect']}"
        + ("; unexplained residual remains" if adeq["unexplained"] else ""))  # fmt: skip
    return Identification(report, current.model, base, current, first, step_fits, replay, setup)


def _canonical_member(aliases: list, chosen: tuple, fit: FitResult):
    """The exact alias of ``chosen`` with as many effects that comes first in :data:`EFFECT_NAMES`, if another."""
    if not aliases:
        return None
    key = sorted(EFFECT_NAMES.index(e) for e in chosen)
    best = None
    for m in aliases[0]["members"]:
        if m["tied"] or len(m["effects"]) != len(chosen) or "density_level_factor" in m["parameters"]:
            continue
        k = sorted(EFFECT_NAMES.index(e) for e in m["effects"])
        if k < key and (best is None or k < best[0]):
            best = (k, m)
    if best is None:
        return None
    return best[1]["effects"], best[1]["parameters"]


def _statement(chosen, adeq: dict, aliases: list) -> str:
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


def _step_summary(cmp: dict) -> dict:
    return {
        "bic_current": cmp["bic_current"],
        "effective_samples": cmp["n_eff"],
        "lag1_of_best": cmp["lag1_of_best"],
        "tried": cmp["table"],
        "accepted": cmp["accepted_label"],
    }


def _check_finite(report: dict) -> None:
    """Fail loudly if a headline figure is not a finite number (never write NaN as a result)."""
    for key in ("before", "after"):
        for k, v in report[key].items():
            if v is None or not math.isfinite(v):
                raise RecordError(f"the replay produced no finite {k.replace('_', ' ')} ({key}); "
                                  "check the record's units and the entry state")  # fmt: skip
    for k, v in report["parameters"].items():
        if not math.isfinite(v):
            raise RecordError(f"the fit produced a non-finite parameter {k}")


__all__ = ["BIC_THRESHOLD", "Identification", "identify"]
