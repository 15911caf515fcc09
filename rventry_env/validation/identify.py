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
   (:mod:`~rventry_env.validation.search.aliases`).
5. Test the final residual against the noise (:mod:`~rventry_env.validation.search.adequacy`): if it
   is not noise, the report says ``"unexplained": true`` and never answers ``none``.

The identified model is an :class:`~rventry_env.physics.EntryModel` built from the physics
parts (:func:`~rventry_env.validation.search.effects.build_model`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from rventry_env.physics import ConstantAerodynamics, EntryModel
from rventry_env.validation.intake.screen import reweight_from_baseline, screen_record
from rventry_env.validation.record import FlightRecord
from rventry_env.validation.replay.controls import control_schedule
from rventry_env.validation.replay.record_replay import Replay
from rventry_env.validation.replay.replay_setup import ReplaySetup, replay_setup
from rventry_env.validation.report.build import build_report, check_finite
from rventry_env.validation.report.diagnostics import run_diagnostics
from rventry_env.validation.search.adequacy import adequacy
from rventry_env.validation.search.effects import EFFECT_NAMES
from rventry_env.validation.search.fit import FitResult
from rventry_env.validation.search.phases import (
    backward_elimination,
    first_step,
    fit_baseline,
    fit_context,
    forward_selection,
    has_density_column,
    name_canonical_member,
    try_pairs,
)
from rventry_env.validation.search.selection import BIC_THRESHOLD
from rventry_env.validation.trace.attribution import trace_residual
from rventry_env.validation.trace.support import drop_surrogates


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


def check_arguments(record: FlightRecord, candidates, threshold, h_max, max_effects, noise) -> tuple:
    """Check the options of :func:`identify`; return the candidate effects to consider."""
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"threshold must be a finite number >= 0, got {threshold!r}")
    if not (isinstance(h_max, (int, float)) and math.isfinite(h_max) and 0 < h_max <= 10):
        raise ValueError(f"h_max must be a number of seconds in (0, 10], got {h_max!r}")
    if isinstance(max_effects, bool) or not isinstance(max_effects, int) or max_effects < 0:
        raise ValueError(f"max_effects must be an integer >= 0, got {max_effects!r}")
    if noise is not None and not (len(noise) == 2 and all(math.isfinite(x) and x > 0 for x in noise)):
        raise ValueError(f"noise must be two positive numbers (position m, velocity m/s), got {noise!r}")
    has_density = has_density_column(record)
    if candidates is None:
        candidates = tuple(c for c in EFFECT_NAMES if c != "measured_density" or has_density)
    candidates = tuple(dict.fromkeys(candidates))
    unknown = [c for c in candidates if c not in EFFECT_NAMES]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {', '.join(unknown)}; choose from {', '.join(EFFECT_NAMES)}")
    if "measured_density" in candidates and not has_density:
        raise ValueError("candidate measured_density needs a record with a density_kgpm3 column (3 values or more)")
    return candidates


def fly_record(record: FlightRecord, vehicle, start, noise, h_max: float):
    """The declared facts, the record's control schedule, and its replay with the current model."""
    setup = replay_setup(record, vehicle, start, noise)
    needs_alpha = not isinstance(setup.lift_reference, ConstantAerodynamics)
    controls = control_schedule(record, setup.lift_to_drag, needs_alpha)
    return setup, controls, Replay(record, setup, controls, h_max=h_max)


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
    candidates = check_arguments(record, candidates, threshold, h_max, max_effects, noise)
    say = _progress(progress)
    t_start = time.perf_counter()
    setup, controls, replay = fly_record(record, vehicle, start, noise, h_max)
    screened = screen_record(replay, setup, say)
    ctx = fit_context(record, replay, setup, screened, threshold)
    say(f"{record.path.name if record.path else 'record'}: {record.kind}, {len(replay.rows)} samples, "
        f"{replay.grid.n_steps} RK4 steps; baseline fit")  # fmt: skip
    base = fit_baseline(ctx, screened, reweight_from_baseline)
    state = first_step(ctx, base, candidates, max_effects, threshold, say)
    forward_selection(ctx, state, candidates, max_effects, threshold, say)
    backward_elimination(ctx, state, threshold, say)

    def test_residual():
        return adequacy(state.current, screened.sigma, screened.noise_source, screened.group_names, screened.groups,
                        ctx.sigma, {g: screened.estimate_is.get(g) for g in screened.group_names},
                        screened.robust_noise)  # fmt: skip

    adeq = test_residual()
    if adeq["unexplained"] and try_pairs(ctx, state, max_effects, threshold, say):
        adeq = test_residual()  # a pair replaced the greedy answer
    trace = trace_residual(ctx, state.current, threshold, say) if adeq["unexplained"] else None
    if trace and drop_surrogates(ctx, state, trace, threshold, say):
        adeq = test_residual()  # an effect stood in for the traced correction: the model without it
    aliases = name_canonical_member(ctx, state)
    report = build_report(record, replay, controls, ctx.setup, screened, ctx, state, adeq, aliases, threshold,
                          max_effects, time.perf_counter() - t_start, trace)  # fmt: skip
    report.update(run_diagnostics(record, ctx, base, state.current, state.chosen, record.kind, state.first))
    report["elapsed_s"] = time.perf_counter() - t_start
    check_finite(report)
    say(f"done in {report['elapsed_s']:.1f} s: effect {report['effect']}"
        + ("; unexplained residual remains" if adeq["unexplained"] else ""))  # fmt: skip
    extra = {"trace": trace} if trace else {}
    return Identification(report, state.current.model, base, state.current, state.first, state.step_fits, replay,
                          ctx.setup, extra)  # fmt: skip


__all__ = ["BIC_THRESHOLD", "Identification", "check_arguments", "fly_record", "identify"]
