"""The model-validation loop: replay a record, trace the residual to a missing effect, add it.

1. Replay the record with the current model, fitting only the initial state
   (output-error least squares): the *baseline*.
2. For every candidate effect, fit its parameters together with the initial
   state, and rank the candidates by BIC.
3. Accept the best one if it beats the baseline by more than
   :data:`BIC_THRESHOLD` (strong evidence on the Kass-Raftery scale); otherwise the
   answer is ``none``: nothing explains the record better than its noise does.
4. Forward selection: with the accepted effects in the model, try each remaining
   one on top, and keep adding while the best addition again beats the current
   model by more than the threshold. Every step is reported.

The identified model is an :class:`~rventry_env.physics.EntryModel` built from
the physics parts (:func:`~rventry_env.validation.effects.build_model`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from rventry_env.physics import ConstantAerodynamics, EntryModel
from rventry_env.validation.controls import control_schedule
from rventry_env.validation.diagnostics import error_metrics, run_diagnostics
from rventry_env.validation.effects import EFFECT_NAMES, density_knots, knot_counts
from rventry_env.validation.fit import FitResult
from rventry_env.validation.model_io import model_to_dict
from rventry_env.validation.noise import GROUPS, PROVISIONAL_SIGMA, init_bounds, record_noise
from rventry_env.validation.record import FlightRecord
from rventry_env.validation.record_replay import Replay
from rventry_env.validation.selection import BIC_THRESHOLD, FitContext, compare_fits, effects_of
from rventry_env.validation.replay_setup import ReplaySetup, replay_setup
from rventry_env.validation.statistics import whiteness

SCREEN_KEEP = 2  # additions fitted in full per forward-selection step, after linearized screening


@dataclass
class Identification:
    """The outcome of :func:`identify`.

    :param report: the JSON report (see ``docs/validation.md``).
    :param model: the identified :class:`EntryModel` (the current model if ``effect`` is none).
    :param baseline: the baseline fit.
    :param final: the fit of the identified model.
    :param candidates: first-step fits by effect name.
    :param steps: forward-selection steps (lists of fits tried at each step).
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
    """Progress lines on stderr with the elapsed time (rich; a fit count is not known in advance)."""
    from rich.console import Console
    from rich.markup import escape

    console = Console(stderr=True, highlight=False)
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if enabled:
            console.print(f"[dim]identify {time.perf_counter() - t0:6.1f} s[/dim]  {escape(msg)}")

    return say


def _whiteness(fit: FitResult, sigma: np.ndarray) -> dict:
    return whiteness(fit.residual / sigma[None, :])


def _fit_summary(fit: FitResult, kind: str, sigma: np.ndarray) -> dict:
    return {
        "effects": list(fit.effects),
        "bic": fit.bic,
        "parameters": fit.parameters(),
        "stderr": {k: float(s) for k, s in zip(fit.names[fit.extra["n_initial"]:],
                                               fit.stderr[fit.extra["n_initial"]:])},  # fmt: skip
        "errors": error_metrics(fit.residual, kind),
        "whiteness": _whiteness(fit, sigma),
        "replays": fit.nfev,
    }


def identify(
    record: FlightRecord,
    vehicle: dict | None = None,
    start: str | None = None,
    candidates: tuple = EFFECT_NAMES,
    threshold: float = BIC_THRESHOLD,
    h_max: float = 1.0,
    max_effects: int = 3,
    progress: bool = False,
) -> Identification:
    """Run the validation loop on a record.

    :param record: a validated record (:func:`~rventry_env.validation.record.load_record`).
    :param vehicle: a vehicle description overriding the sidecar's.
    :param start: ``"declared"`` or ``"drag-only"`` (default: the sidecar's, else declared).
    :param candidates: the effects to consider.
    :param threshold: BIC margin an effect must beat the current model by.
    :param h_max: longest RK4 step of the replay (s).
    :param max_effects: most effects forward selection may add.
    :param progress: print progress to stderr.
    """
    say = _progress(progress)
    t_start = time.perf_counter()
    unknown = [c for c in candidates if c not in EFFECT_NAMES]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {unknown}; choose from {EFFECT_NAMES}")
    setup = replay_setup(record, vehicle, start)
    needs_alpha = not isinstance(setup.lift_reference, ConstantAerodynamics)
    controls = control_schedule(record, setup.lift_to_drag, needs_alpha)
    replay = Replay(record, setup, controls, h_max=h_max)
    kind = record.kind
    groups = np.zeros(replay.y.shape[1], dtype=int)
    for gi, (_, _, cols) in enumerate(GROUPS[kind]):
        groups[list(cols)] = gi
    group_names = [g[0] for g in GROUPS[kind]]

    # density knots over the altitudes the flight visits (from the record: a replay needs a model)
    altitudes = record.altitude()[replay.rows]
    knots_by_count = {n: density_knots(altitudes, n) for n in knot_counts(altitudes)}

    noise_diff, noise_kind = record_noise(replay, kind)
    sigma_g = {g: noise_diff[g] if np.isfinite(noise_diff[g]) else PROVISIONAL_SIGMA[g] for g in group_names}
    bound = init_bounds(replay, kind, noise_diff)

    def sig_vector() -> np.ndarray:
        return np.array([sigma_g[group_names[g]] for g in groups])

    ctx = FitContext(replay, setup, groups, sig_vector(), bound, knots_by_count, threshold)
    say(f"{record.path.name if record.path else 'record'}: {kind}, {len(replay.rows)} samples, "
        f"{len(replay.grid) - 1} RK4 steps; baseline fit")  # fmt: skip
    knots = knots_by_count[2]
    base = ctx.problem([], knots).solve()
    weights_from = {}
    for gi, g in enumerate(group_names):
        if np.isfinite(noise_diff[g]):
            weights_from[g] = "record differences"
        else:
            # no model-free estimate: weight each group by its own baseline scatter, and refit
            sigma_g[g] = math.sqrt(base.rss_by_group[gi] / base.n_by_group[gi])
            weights_from[g] = "baseline residual"
    if any(v == "baseline residual" for v in weights_from.values()):
        ctx.sigma = sig_vector()
        base = ctx.problem([], knots).solve(base.values)
    sigma = ctx.sigma

    # step 1: every candidate alone
    first: dict[str, FitResult] = {}
    knot_trials = {}
    # the density correction last, so its knot refinement knows the best rival
    for name in sorted(candidates, key=lambda c: c == "density_profile"):
        say(f"candidate {name}")
        if name == "density_profile":
            rival = min((f.bic for f in first.values()), default=None)
            first[name], knot_trials["step 1"] = ctx.fit_density([name], base, rival)
        else:
            first[name] = ctx.fit([name], base, knots)
    cmp1 = compare_fits(base, list(first.values()), sigma, threshold)
    steps = [{"step": 1, "from": [], **_step_summary(cmp1)}]
    step_fits = [first]
    current, chosen = base, []
    if cmp1["accepted"] is not None:
        current = cmp1["accepted"]
        chosen = [current.effects[-1]]
        knots = current.extra["knots"]
        say(f"accepted {chosen[0]}")
    else:
        say("no candidate beats the noise: none")
    # forward selection
    while chosen and len(chosen) < min(max_effects, len(candidates)):
        remaining = [c for c in candidates if c not in chosen]
        full = ctx.problem(chosen + remaining, knots)
        keep = list(range(full.n_init)) + [i for c in chosen for i in effects_of(full, c)]
        subsets = {c: keep + effects_of(full, c) for c in remaining}
        lin = full.linearized_chi2(ctx.start_from(full, current), subsets)
        screened = sorted(remaining, key=lin.get)
        tried = {}
        for name in sorted(screened[:SCREEN_KEEP], key=lambda c: c == "density_profile"):
            say(f"step {len(chosen) + 1}: {' + '.join(chosen)} + {name}")
            if name == "density_profile":
                rival = min((f.bic for f in tried.values()), default=None)
                fit, knot_trials[f"step {len(chosen) + 1}"] = ctx.fit_density(chosen + [name], current, rival)
                tried[name] = fit
            else:
                tried[name] = ctx.fit(chosen + [name], current, knots)
        step_fits.append(tried)
        cmp = compare_fits(current, list(tried.values()), sigma, threshold)
        steps.append({
            "step": len(chosen) + 1,
            "from": list(chosen),
            "screened": [{"effect": c, "linearized_chi2": lin[c]} for c in screened],
            **_step_summary(cmp),
        })  # fmt: skip
        if cmp["accepted"] is None:
            break
        current = cmp["accepted"]
        chosen.append(current.effects[-1])
        knots = current.extra["knots"]
        say(f"accepted {chosen[-1]}")

    elapsed = time.perf_counter() - t_start
    n0 = current.extra["n_initial"]
    table = steps[0]["tried"]
    report = {
        "effect": chosen[0] if chosen else "none",
        "effects": chosen,
        "parameters": current.parameters(),
        "parameter_stderr": {k: float(s) for k, s in zip(current.names[n0:], current.stderr[n0:])},
        "initial_state_offsets": {k: float(v) for k, v in zip(current.names[:n0], current.values[:n0])},
        "initial_state_bound": None if bound is None else dict(zip(current.names[:n0], map(float, bound))),
        "ranking": [{"effect": r["effect"], "bic": r["bic"], "delta_bic": r["delta_bic"]} for r in table],
        "margin_to_runner_up": table[1]["delta_bic"] if len(table) > 1 else None,
        "improvement_over_baseline": table[0]["improvement_over_current"],
        "bic_threshold": threshold,
        "steps": steps,
        "before": error_metrics(base.residual, kind),
        "after": error_metrics(current.residual, kind),
        "whiteness": {"before": _whiteness(base, sigma), "after": _whiteness(current, sigma)},
        "noise": {
            "difference_estimate": {g: (noise_diff[g] if np.isfinite(noise_diff[g]) else None)
                                    for g in group_names},
            "difference_estimate_is": noise_kind,
            "weights": {g: sigma_g[g] for g in group_names},
            "weights_from": weights_from,
            "after_fit_rms": {g: math.sqrt(current.rss_by_group[i] / current.n_by_group[i])
                              for i, g in enumerate(group_names)},
        },  # fmt: skip
        "record": {
            "path": str(record.path) if record.path else None,
            "kind": kind,
            "samples": int(len(replay.rows)),
            "values": int(np.count_nonzero(np.isfinite(replay.y))),
            "t_start_s": replay.t0,
            "t_end_s": float(replay.t_obs[-1]),
            "rk4_steps": int(len(replay.grid) - 1),
            "notes": list(record.notes) + list(controls.notes) + list(replay.notes),
        },
        "start_model": setup.start,
        "density_knots_m": list(current.extra["knots"]) if "density_profile" in chosen else None,
        "density_knot_trials": knot_trials,
        "candidates": {n: _fit_summary(f, kind, sigma) for n, f in first.items()},
        "model": model_to_dict(current.model),
        "elapsed_s": elapsed,
        "replays": sum(f.nfev for fits in step_fits for f in fits.values()) + base.nfev,
    }
    report.update(run_diagnostics(record, ctx, base, current, chosen, kind, say))
    report["elapsed_s"] = time.perf_counter() - t_start
    say(f"done in {report['elapsed_s']:.1f} s: effect {report['effect']}")
    return Identification(report, current.model, base, current, first, step_fits, replay, setup)


def _step_summary(cmp: dict) -> dict:
    acc = cmp["accepted"]
    return {
        "bic_current": cmp["bic_current"],
        "effective_samples": cmp["n_eff"],
        "lag1_of_best": cmp["lag1_of_best"],
        "tried": cmp["table"],
        "accepted": acc.effects[-1] if acc is not None else None,
    }


__all__ = ["BIC_THRESHOLD", "Identification", "identify"]
