"""Fitting and ranking candidate effects: the shared fit context, plausibility, and the BIC comparison."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rventry_env.validation.replay.record_replay import Replay
from rventry_env.validation.replay.replay_setup import ReplaySetup
from rventry_env.validation.replay.sensitivity import ReplayCache
from rventry_env.validation.search.effects import EARTH_J2, Structure
from rventry_env.validation.search.fit import FitResult, OutputErrorProblem, j2_free_param
from rventry_env.validation.search.statistics import bic, bic_effective, effective_size, whiteness

BIC_THRESHOLD = 10.0  # "very strong" evidence on the Kass-Raftery scale
CATCH_UP = 10.0  # knot refinement stops when it trails the best rival by this many last gains
J2_AGREEMENT_SIGMAS = 3.0  # the J2 a record prefers must agree with the known one within this many sigma


@dataclass
class FitContext:
    """Everything the fits of one record share.

    :param knots_by_count: density-profile knots (m) by knot count.
    :param mach_by_count: Mach-drag knots by knot count.
    :param engines: compiled sensitivity replays by structure (built once, reused).
    :param replays: the last replays with sensitivities, for points asked for again (the fits' and the
        trace's; :class:`~rventry_env.validation.replay.sensitivity.ReplayCache`).
    """

    replay: Replay
    setup: ReplaySetup
    groups: np.ndarray
    sigma: np.ndarray
    init_bound: np.ndarray | None
    knots_by_count: dict
    mach_by_count: dict
    threshold: float = BIC_THRESHOLD
    engines: dict = field(default_factory=dict)
    nfev: int = 0
    replays: ReplayCache = field(default_factory=ReplayCache)

    def problem(self, structure: Structure, extra=()) -> OutputErrorProblem:
        return OutputErrorProblem(
            self.replay, self.setup, structure, self.sigma, self.groups, init_bound=self.init_bound,
            engines=self.engines, extra_params=extra, replays=self.replays,
        )  # fmt: skip

    @staticmethod
    def start_from(prob: OutputErrorProblem, previous: FitResult | None) -> np.ndarray:
        """Start values: the previous fit's where it has them, the current model's elsewhere."""
        theta0 = prob.start.copy()
        if previous is None:
            return theta0
        prev = dict(zip(previous.names, previous.values))
        for i, n in enumerate(prob.names):
            if n in prev:
                theta0[i] = prev[n]
        return theta0

    def structure(self, effects, like: Structure | None = None, density_n=None, mach_n=None) -> Structure:
        """A structure for ``effects`` with the knots of ``like`` (or the coarsest)."""
        dk = like.density_knots if (like and like.density_knots) else self.knots_by_count[min(self.knots_by_count)]
        mk = like.mach_knots if (like and like.mach_knots) else self.mach_by_count[min(self.mach_by_count)]
        if density_n is not None:
            dk = self.knots_by_count[density_n]
        if mach_n is not None:
            mk = self.mach_by_count[mach_n]
        return Structure(tuple(effects), dk, mk)

    def fit(self, structure: Structure, previous: FitResult | None, max_nfev: int = 60, theta0=None) -> FitResult:
        prob = self.problem(structure)
        f = prob.solve(self.start_from(prob, previous) if theta0 is None else theta0, max_nfev=max_nfev)
        self.nfev += f.nfev
        if "j2_gravity" in structure.effects and not f.extra["diverged"]:
            self.check_j2(f)
        return f

    def check_j2(self, fit: FitResult) -> dict:
        """The J2 the record would prefer, from one Gauss-Newton step with J2 freed at the fit.

        The model flies the known J2; if the value the record prefers disagrees with it by more
        than :data:`J2_AGREEMENT_SIGMAS` standard errors (a wrong sign, say), J2 is soaking up
        another misfit and the fit is marked implausible.
        """
        prob = self.problem(fit.structure, extra=(j2_free_param(),))
        theta = np.concatenate([fit.values, [EARTH_J2]])
        n = len(theta)
        lin = prob.linearized(theta, {"all": list(range(n))})["all"]
        self.nfev += 1
        j2, se = EARTH_J2 + float(lin["step"][-1]), float(lin["stderr"][-1])
        agrees = bool(np.isfinite(se) and abs(j2 - EARTH_J2) <= J2_AGREEMENT_SIGMAS * se)
        check = {"known": EARTH_J2, "preferred": j2, "stderr": se, "agrees": agrees}
        fit.extra["j2_check"] = check
        if not agrees:
            fit.extra["implausible"] = list(fit.extra["implausible"]) + [
                f"the record prefers J2 = {j2:.3g} +- {se:.2g}, not the known {EARTH_J2:.6g}"
            ]
        return check

    def refine(self, previous: FitResult, profile: str) -> FitResult | None:
        """``previous`` refitted with a finer knot count of one of its profiles (None if none is finer).

        The next finer count, or the finer count that one Gauss-Newton step from ``previous`` (its
        profile interpolated, exact Jacobian) says fits best, when that is another: a profile that
        cannot yet follow a structure of the record competes with a new effect by the count that
        resolves it, not only by the next.
        """
        counts = self.knots_by_count if profile == "density_profile" else self.mach_by_count
        st0 = previous.structure
        kn_old = st0.density_knots if profile == "density_profile" else st0.mach_knots
        finer = [n for n in counts if n > len(kn_old)]
        if not finer:
            return None
        screened = {n: self._screen_count(previous.effects, profile, st0, previous, n) for n in finer}
        n = min(screened, key=screened.get) if len(finer) > 1 else finer[0]
        return self._fit_count(previous.effects, profile, st0, previous, n, False)

    def _screen_count(self, effects, profile: str, like, best: FitResult, n: int) -> float:
        """The BIC one Gauss-Newton step from ``best`` reaches with the profile at ``n`` knots (one replay)."""
        prefix = "dlnrho_" if profile == "density_profile" else "dlncd_M"
        st = self.structure(effects, like, **({"density_n": n} if profile == "density_profile" else {"mach_n": n}))
        prob = self.problem(st)
        theta0 = self.start_from(prob, best)
        old = [i for i, name in enumerate(best.names) if name.startswith(prefix)]
        new = [i for i, name in enumerate(prob.names) if name.startswith(prefix)]
        theta0[new] = _profile_start(profile, best.structure, st, best.values[old])
        lin = prob.linearized(theta0, {"all": list(range(len(prob.names)))})["all"]
        self.nfev += 1
        rss, nval = prob.rss_by_group(lin["residual"])
        return bic(rss, nval, len(prob.names))

    def fit_profile(self, effects: tuple, profile: str, like: Structure | None, previous: FitResult | None,
                    rival_bic: float | None = None) -> tuple[FitResult, list]:  # fmt: skip
        """Fit with a density profile or Mach-drag correction, its knot count chosen by BIC.

        Finer knots are kept only while they beat the coarser fit by the same BIC margin an
        effect needs (a wrong effect keeps improving a little with every knot and would
        otherwise run to the finest). Refinement also stops when the profile trails
        ``rival_bic`` (the best other candidate) by more than :data:`CATCH_UP` times its last
        gain. Each finer fit starts from the coarser one, its log factors interpolated.
        """
        counts = self.knots_by_count if profile == "density_profile" else self.mach_by_count
        best, trials, gain = None, [], None
        stalled = False
        for n in counts:
            if best is not None and rival_bic is not None and gain is not None:
                if best.bic - rival_bic > CATCH_UP * gain:
                    trials.append({"knots": n, "skipped": "cannot catch up with the best other candidate"})
                    break
            f = self._fit_count(effects, profile, like, previous if best is None else best, n, best is None)
            trials.append({"knots": n, "bic": f.bic, "credible": f.credible})
            if best is not None:
                gain = best.bic - f.bic
                if f.bic > best.bic - self.threshold:
                    stalled = True
                    break
            best = f
        if stalled:
            best = self._finer_than_stalled(effects, profile, like, best, trials)
        return best, trials

    def _fit_count(self, effects, profile: str, like, start: FitResult | None, n: int, first: bool) -> FitResult:
        """The profile's fit at ``n`` knots, started from ``start`` (a coarser profile's values interpolated)."""
        prefix = "dlnrho_" if profile == "density_profile" else "dlncd_M"
        st = self.structure(effects, like, **({"density_n": n} if profile == "density_profile" else {"mach_n": n}))
        prob = self.problem(st)
        theta0 = self.start_from(prob, start)
        if not first and start is not None:
            old = [i for i, name in enumerate(start.names) if name.startswith(prefix)]
            new = [i for i, name in enumerate(prob.names) if name.startswith(prefix)]
            theta0[new] = _profile_start(profile, start.structure, st, start.values[old])
        return self.fit(st, None, max_nfev=60 if first else 30, theta0=theta0)

    def _finer_than_stalled(self, effects, profile: str, like, best: FitResult, trials: list) -> FitResult:
        """A profile that stopped gaining may still resolve a finer structure: screen every finer count.

        A density wave of a few kilometres is aliased by knots coarser than half its wavelength, so
        the next finer count may gain nothing while a finer one resolves it. Each finer count the
        record resolves is screened by one Gauss-Newton step from ``best`` (its profile
        interpolated, exact Jacobian); the best of them is fitted when it promises to beat ``best``
        by the threshold, and kept when it does.
        """
        counts = self.knots_by_count if profile == "density_profile" else self.mach_by_count
        n_best = len(best.structure.density_knots if profile == "density_profile" else best.structure.mach_knots)
        tried = {t["knots"] for t in trials}
        screened = {}
        for n in counts:
            if n <= n_best or n in tried:
                continue
            screened[n] = self._screen_count(effects, profile, like, best, n)
            trials.append({"knots": n, "screened_bic": screened[n]})
        if not screened:
            return best
        n = min(screened, key=screened.get)
        if screened[n] > best.bic - self.threshold:
            return best
        f = self._fit_count(effects, profile, like, best, n, False)
        trials.append({"knots": n, "bic": f.bic, "credible": f.credible})
        return f if f.bic < best.bic - self.threshold else best


def _profile_start(profile: str, old: Structure, new: Structure, values: np.ndarray) -> np.ndarray:
    """A finer profile's start values, interpolated from a coarser fit's."""
    if profile == "density_profile":
        return np.interp(new.density_knots, old.density_knots, values)
    # the Mach correction is 0 at its highest knot, which has no parameter
    return np.interp(new.mach_knots[:-1], old.mach_knots, np.append(values, 0.0))


def _ranking_row(f: FitResult, label: str, bic: float, b_best: float, b_cur: float) -> dict:
    """One fit's row of the ranking: its effective BIC against the best and the current model's, and
    what makes it credible or not."""
    row = {
        "effect": label,
        "effects": list(f.effects),
        "bic": bic,
        "delta_bic": bic - b_best,
        "improvement_over_current": b_cur - bic,
        "bic_white": f.bic,
        "credible": f.credible,
        "at_bound": f.extra["at_bound"],
        "initial_state_at_bound": f.extra["initial_state_at_bound"],
        "implausible": f.extra["implausible"],
    }
    if "j2_check" in f.extra:
        row["j2_check"] = f.extra["j2_check"]
    return row


def compare_fits(current: FitResult, fits: list[FitResult], sigma: np.ndarray, threshold: float,
                 labels: list[str] | None = None) -> dict:  # fmt: skip
    """Rank fits against the current model with BIC counted on the effective sample size.

    The effective size comes from the whiteness of the best fit's residual (the lowest plain
    BIC): what even the best explanation leaves correlated is not independent evidence. The
    best *credible* fit (no parameter on a physical bound, the initial state within its bound,
    nothing implausible) is accepted if it beats the current model by more than ``threshold``.
    """
    labels = labels or [f.effects[-1] for f in fits]
    finite = [f for f in fits if np.isfinite(f.bic)] or fits
    best_raw = min(finite, key=lambda f: f.bic)
    lag1 = whiteness(best_raw.residual / sigma[None, :])["lag1_autocorrelation"]
    n_tot = sum(current.n_by_group)
    n_eff = effective_size(n_tot, lag1)

    def b(f: FitResult) -> float:
        if not np.isfinite(f.bic):
            return float("inf")
        return bic_effective(f.rss_by_group, f.n_by_group, f.n_params, n_eff)

    b_cur = b(current)
    order = sorted(range(len(fits)), key=lambda i: b(fits[i]))
    b_best = b(fits[order[0]])
    table = []
    for i in order:
        table.append(_ranking_row(fits[i], labels[i], b(fits[i]), b_best, b_cur))
    credible = [i for i in order if fits[i].credible]
    acc = credible[0] if credible and b_cur - b(fits[credible[0]]) > threshold else None
    prov = None
    if acc is None:
        # flawed only by an entry state on its bound, and far better than the current model
        for i in order:
            x = fits[i].extra
            if x["initial_state_at_bound"] and not (x["at_bound"] or x["implausible"]):
                prov = i if b_cur - b(fits[i]) > threshold else None
                break
    return {
        "provisional": None if prov is None else fits[prov],
        "n_eff": n_eff,
        "lag1_of_best": lag1,
        "bic_current": b_cur,
        "table": table,
        "accepted": None if acc is None else fits[acc],
        "accepted_label": None if acc is None else labels[acc],
    }


__all__ = ["BIC_THRESHOLD", "CATCH_UP", "J2_AGREEMENT_SIGMAS", "FitContext", "compare_fits"]
