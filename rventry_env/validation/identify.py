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

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rventry_env.physics import ConstantAerodynamics, EntryModel
from rventry_env.validation.controls import control_schedule
from rventry_env.validation.diagnostics import (
    log_density_ratio,
    measured_density_correction,
    window_errors,
    with_atmosphere,
)
from rventry_env.validation.effects import (
    EFFECT_NAMES,
    build_model,
    candidate_effects,
    density_knots,
    knot_counts,
)
from rventry_env.validation.fit import FitResult, OutputErrorProblem
from rventry_env.validation.model_io import model_to_dict
from rventry_env.validation.record import FlightRecord, RecordError
from rventry_env.validation.replay import Replay
from rventry_env.validation.setup import ReplaySetup, replay_setup
from rventry_env.validation.statistics import bic_effective, difference_noise, effective_size, whiteness

BIC_THRESHOLD = 10.0
INIT_BOUND_SIGMAS = 5.0  # the initial state may move this many noise levels from what was measured
CATCH_UP = 10.0  # density knot refinement stops when it trails the best rival by this many last gains
SCREEN_KEEP = 2  # additions fitted in full per forward-selection step, after linearized screening

GROUPS = {
    "ecef": (("position", "m", (0, 1, 2)), ("velocity", "mps", (3, 4, 5))),
    "reduced": (("altitude", "m", (0,)), ("speed", "mps", (1,))),
}
# provisional weights when the record does not allow a difference estimate of its noise
PROVISIONAL_SIGMA = {"position": 100.0, "velocity": 1.0, "altitude": 100.0, "speed": 1.0}


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
    """A tiny progress line on stderr (rich is overkill for ~15 fits, tqdm needs a known total)."""
    import sys

    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if enabled:
            print(f"[identify {time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def error_metrics(fit: FitResult, kind: str) -> dict:
    """rms and max position (or altitude) error, rms velocity (or speed) error."""
    e = fit.residual
    if kind == "ecef":
        pos = np.linalg.norm(e[:, :3], axis=1)
        vel = np.linalg.norm(e[:, 3:], axis=1)
        pos, vel = pos[np.isfinite(pos)], vel[np.isfinite(vel)]
        return {
            "position_rms_m": float(np.sqrt(np.mean(pos**2))),
            "position_max_m": float(np.max(pos)),
            "velocity_rms_mps": float(np.sqrt(np.mean(vel**2))),
            "velocity_max_mps": float(np.max(vel)),
        }
    alt = e[:, 0][np.isfinite(e[:, 0])]
    spd = e[:, 1][np.isfinite(e[:, 1])]
    return {
        "altitude_rms_m": float(np.sqrt(np.mean(alt**2))),
        "altitude_max_m": float(np.max(np.abs(alt))),
        "speed_rms_mps": float(np.sqrt(np.mean(spd**2))),
        "speed_max_mps": float(np.max(np.abs(spd))),
    }


def _whiteness(fit: FitResult, sigma: np.ndarray) -> dict:
    return whiteness(fit.residual / sigma[None, :])


def _noise(replay: Replay, kind: str) -> tuple[dict, dict]:
    """Per-group noise from the record's differences (NaN where the sampling does not allow it).

    Also says whether the differences are noise-dominated: white noise gives the
    same estimate from 3rd and 4th differences, a signal sampled too coarsely
    (a sparse trajectory table) gives estimates that fall with the order. Then
    the estimate is only an upper bound of the noise, and is reported as such.
    """
    out, kind_of = {}, {}
    for name, _, cols in GROUPS[kind]:
        est, ratios = [], []
        for c in cols:
            e4 = difference_noise(replay.t_obs, replay.y[:, c])
            if np.isfinite(e4):
                est.append(e4)
                ratios.append(difference_noise(replay.t_obs, replay.y[:, c], order=3) / e4)
        out[name] = float(np.median(est)) if est else math.nan
        if est:
            r = float(np.median(ratios))
            kind_of[name] = "noise" if 0.8 < r < 1.25 else f"upper bound (3rd/4th difference estimates {r:.2f})"
    return out, kind_of


def _fit_summary(fit: FitResult, kind: str, sigma: np.ndarray) -> dict:
    return {
        "effects": list(fit.effects),
        "bic": fit.bic,
        "parameters": fit.parameters(),
        "stderr": {k: float(s) for k, s in zip(fit.names[fit.extra["n_initial"]:],
                                               fit.stderr[fit.extra["n_initial"]:])},  # fmt: skip
        "errors": error_metrics(fit, kind),
        "whiteness": _whiteness(fit, sigma),
        "replays": fit.nfev,
    }


def effects_of(prob: OutputErrorProblem, effect: str) -> list[int]:
    """Indices of ``effect``'s parameters in ``prob``."""
    out, i = [], prob.n_init
    for e in prob.effects:
        if e.name == effect:
            out.extend(range(i, i + len(e.param_names)))
        i += len(e.param_names)
    return out


def init_bounds(replay: Replay, kind: str, noise: dict) -> np.ndarray | None:
    """Half-widths within which the initial state may move: :data:`INIT_BOUND_SIGMAS` noise levels.

    "Fitted within its noise": without a bound, a model that lacks an effect
    would bend the initial state far from what the first samples measured to
    hide the effect (on Apollo 4 a drag-only capsule moves the entry point 9 km
    down and 940 m/s faster). A reduced record does not measure the flight-path
    angle; its bound is what the altitude noise allows over the first three
    samples, sqrt(2) sigma_h / (v0 dt).
    """
    k = INIT_BOUND_SIGMAS
    if kind == "ecef":
        sp, sv = noise["position"], noise["velocity"]
        if not (np.isfinite(sp) and np.isfinite(sv)):
            return None
        return np.array([k * sp] * 3 + [k * sv] * 3)
    sh, sv = noise["altitude"], noise["speed"]
    if not (np.isfinite(sh) and np.isfinite(sv)):
        return None
    dt = float(replay.t_obs[min(2, len(replay.t_obs) - 1)] - replay.t0)
    v0 = replay.init.reference[3]
    return np.array([k * sh, k * sv, k * math.sqrt(2.0) * sh / (v0 * max(dt, 1e-3))])


@dataclass
class _Context:
    """Everything the fits of one record share."""

    replay: Replay
    setup: ReplaySetup
    groups: np.ndarray
    sigma: np.ndarray
    init_bound: np.ndarray | None
    knots_by_count: dict
    threshold: float = BIC_THRESHOLD

    def problem(self, effect_list: list, knots: tuple) -> OutputErrorProblem:
        eff = candidate_effects(self.setup, knots)
        return OutputErrorProblem(
            self.replay, self.setup, knots, [eff[e] for e in effect_list], self.sigma, self.groups,
            init_bound=self.init_bound,
        )  # fmt: skip

    @staticmethod
    def start_from(prob: OutputErrorProblem, previous: FitResult) -> np.ndarray:
        """Start values: the previous fit's where it has them, the current model's elsewhere."""
        theta0 = prob.start.copy()
        prev = dict(zip(previous.names, previous.values))
        for i, n in enumerate(prob.names):
            if n in prev:
                theta0[i] = prev[n]
        return theta0

    def fit(self, effect_list: list, previous: FitResult, knots: tuple) -> FitResult:
        prob = self.problem(effect_list, knots)
        return prob.solve(self.start_from(prob, previous))

    def fit_density(self, effect_list: list, previous: FitResult, rival_bic: float | None = None) -> tuple:
        """Fit with a density correction, its knot count chosen by BIC.

        Finer knots are kept only while they beat the coarser fit by the same BIC
        margin an effect needs (a wrong effect keeps improving a little with every
        knot and would otherwise run to the finest). Refinement also stops when the
        correction trails ``rival_bic`` (the best other candidate) by more than
        :data:`CATCH_UP` times its last gain: with diminishing gains per knot it cannot
        catch up, and the finest fits of a wrong effect are the slowest of the loop.
        Each finer fit starts from the coarser one, its log factors interpolated.
        """
        best, trials, gain = None, [], None
        for n, kn in self.knots_by_count.items():
            if best is not None and rival_bic is not None and gain is not None:
                if best.bic - rival_bic > CATCH_UP * gain:
                    trials.append({"knots": n, "skipped": "cannot catch up with the best other candidate"})
                    break
            prob = self.problem(effect_list, kn)
            theta0 = self.start_from(prob, previous if best is None else best)
            if best is not None:
                old = [i for i, name in enumerate(best.names) if name.startswith("dlnrho_")]
                new = [i for i, name in enumerate(prob.names) if name.startswith("dlnrho_")]
                theta0[new] = np.interp(kn, best.extra["knots"], best.values[old])
            f = prob.solve(theta0, max_nfev=60 if best is None else 30)
            trials.append({"knots": n, "bic": f.bic})
            if best is not None:
                gain = best.bic - f.bic
                if f.bic > best.bic - self.threshold:
                    break
            best = f
        return best, trials


def _compare(current: FitResult, fits: list[FitResult], sigma: np.ndarray, threshold: float) -> dict:
    """Rank fits against the current model with BIC counted on the effective sample size.

    The effective size comes from the whiteness of the best fit's residual (the
    lowest plain BIC): what even the best explanation leaves correlated is not
    independent evidence. The best fit whose effect parameters are not on a bound
    is accepted if it beats the current model by more than ``threshold``.
    """
    best_raw = min(fits, key=lambda f: f.bic)
    lag1 = whiteness(best_raw.residual / sigma[None, :])["lag1_autocorrelation"]
    n_tot = sum(current.n_by_group)
    n_eff = effective_size(n_tot, lag1)

    def b(f: FitResult) -> float:
        return bic_effective(f.rss_by_group, f.n_by_group, f.n_params, n_eff)

    b_cur = b(current)
    order = sorted(fits, key=b)
    b_best = b(order[0])
    table = [{
        "effect": f.effects[-1],
        "bic": b(f),
        "delta_bic": b(f) - b_best,
        "improvement_over_current": b_cur - b(f),
        "bic_white": f.bic,
        "at_bound": f.extra["at_bound"],
    } for f in order]  # fmt: skip
    credible = [f for f in order if not f.extra["at_bound"]]
    accepted = credible[0] if credible and b_cur - b(credible[0]) > threshold else None
    return {"n_eff": n_eff, "lag1_of_best": lag1, "bic_current": b_cur, "table": table, "accepted": accepted}


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

    noise_diff, noise_kind = _noise(replay, kind)
    sigma_g = {g: (noise_diff[g] if np.isfinite(noise_diff[g]) else PROVISIONAL_SIGMA[g]) for g in group_names}
    bound = init_bounds(replay, kind, noise_diff)

    def sig_vector() -> np.ndarray:
        return np.array([sigma_g[group_names[g]] for g in groups])

    ctx = _Context(replay, setup, groups, sig_vector(), bound, knots_by_count, threshold)
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
    cmp1 = _compare(base, list(first.values()), sigma, threshold)
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
        lin = full.linearized_chi2(ctx.start_from(full, current), {c: keep + effects_of(full, c) for c in remaining})
        screened = sorted(remaining, key=lin.get)
        tried = {}
        for name in sorted(screened[:SCREEN_KEEP], key=lambda c: c == "density_profile"):
            say(f"step {len(chosen) + 1}: {' + '.join(chosen)} + {name}")
            if name == "density_profile":
                rival = min((f.bic for f in tried.values()), default=None)
                tried[name], knot_trials[f"step {len(chosen) + 1}"] = ctx.fit_density(chosen + [name], current, rival)
            else:
                tried[name] = ctx.fit(chosen + [name], current, knots)
        step_fits.append(tried)
        cmp = _compare(current, list(tried.values()), sigma, threshold)
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
        "before": error_metrics(base, kind),
        "after": error_metrics(current, kind),
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
    report.update(_diagnostics(record, ctx, base, current, chosen, kind, say))
    report["elapsed_s"] = time.perf_counter() - t_start
    say(f"done in {report['elapsed_s']:.1f} s: effect {report['effect']}")
    return Identification(report, current.model, base, current, first, step_fits, replay, setup)


def fixed_state_errors(replay: Replay, model: EntryModel, kind: str) -> dict:
    """Errors of a replay from the declared (or first measured) initial state, nothing fitted."""
    pred = replay.predict(model, np.zeros((1, replay.init.size)))[..., 0]
    resid = pred - replay.y

    class _R:  # error_metrics reads .residual only
        residual = resid

    return error_metrics(_R, kind)


def _diagnostics(record, ctx: _Context, base: FitResult, current: FitResult, chosen: list, kind: str, say) -> dict:
    """Checks on what remains (see :mod:`rventry_env.validation.diagnostics`)."""
    replay, setup = ctx.replay, ctx.setup
    t = replay.t_obs
    out = {"windows": {"before": window_errors(t, base.residual, kind),
                       "after": window_errors(t, current.residual, kind)}}  # fmt: skip
    if kind == "reduced":
        # like-for-like with replays that keep the declared entry state (e.g. published reconstructions)
        declared = build_model(setup, (), {"cl_scale": 1.0}) if setup.start == "drag-only" else setup.model
        out["declared_entry_state"] = {
            "current_model": fixed_state_errors(replay, setup.model, kind),
            "declared_vehicle": fixed_state_errors(replay, declared, kind),
            "identified_model": fixed_state_errors(replay, current.model, kind),
        }
    if record.density is None:
        return out
    alt = record.altitude()
    ok = np.isfinite(alt) & np.isfinite(record.density) & (record.density > 0)
    if ok.sum() < 3:
        return out
    h, rho = alt[ok], record.density[ok]
    say("density check: replay with the record's density")
    lr_cur = log_density_ratio(h, rho, setup.model)
    lr_id = log_density_ratio(h, rho, current.model)
    corr = measured_density_correction(h, rho, setup.model)
    ctx_md = dataclasses.replace(ctx, setup=with_atmosphere(setup, corr))
    effects_md = [e for e in chosen if e != "density_profile"]
    fit_md = ctx_md.fit(effects_md, current, current.extra["knots"])
    out["density_check"] = {
        "altitude_m": h.tolist(),
        "current": {"log_ratio": lr_cur.tolist(), "rms_log_ratio": float(np.sqrt(np.mean(lr_cur**2)))},
        "identified": {"log_ratio": lr_id.tolist(), "rms_log_ratio": float(np.sqrt(np.mean(lr_id**2)))},
        "measured_correction": {"knots_m": list(corr.knots), "log_factors": list(corr.log_factors)},
        "replay_with_measured_density": {
            "effects": effects_md,
            "parameters": fit_md.parameters(),
            "errors": error_metrics(fit_md, kind),
            "windows": window_errors(t, fit_md.residual, kind),
        },
    }
    return out


def _step_summary(cmp: dict) -> dict:
    acc = cmp["accepted"]
    return {
        "bic_current": cmp["bic_current"],
        "effective_samples": cmp["n_eff"],
        "lag1_of_best": cmp["lag1_of_best"],
        "tried": cmp["table"],
        "accepted": acc.effects[-1] if acc is not None else None,
    }


__all__ = ["BIC_THRESHOLD", "Identification", "identify", "error_metrics", "init_bounds", "build_model"]
