"""Fitting and ranking candidate effects: the shared fit context and the BIC comparison."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rventry_env.validation.effects import candidate_effects
from rventry_env.validation.fit import FitResult, OutputErrorProblem
from rventry_env.validation.record_replay import Replay
from rventry_env.validation.replay_setup import ReplaySetup
from rventry_env.validation.statistics import bic_effective, effective_size, whiteness

BIC_THRESHOLD = 10.0  # "very strong" evidence on the Kass-Raftery scale
CATCH_UP = 10.0  # density knot refinement stops when it trails the best rival by this many last gains


def effects_of(prob: OutputErrorProblem, effect: str) -> list[int]:
    """Indices of ``effect``'s parameters in ``prob``."""
    out, i = [], prob.n_init
    for e in prob.effects:
        if e.name == effect:
            out.extend(range(i, i + len(e.param_names)))
        i += len(e.param_names)
    return out


@dataclass
class FitContext:
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


def compare_fits(current: FitResult, fits: list[FitResult], sigma: np.ndarray, threshold: float) -> dict:
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


__all__ = ["BIC_THRESHOLD", "CATCH_UP", "FitContext", "compare_fits", "effects_of"]
