"""The search for the missing effect, one named phase per function.

1. :func:`fit_context` - knots over the altitudes and Mach numbers flown, the record's own
   atmosphere when it has a density column, and the context every fit shares;
2. :func:`fit_baseline` - the current model, only the entry state fitted;
3. :func:`first_step` - every candidate alone, ranked by BIC;
4. :func:`forward_selection` - add while one addition beats the current model;
5. :func:`backward_elimination` - drop an effect the others make redundant;
6. :func:`try_pairs` - every pair of the best single candidates, so a true pair is not lost to
   an alias accepted first;
7. :func:`name_canonical_member` - among exact aliases of the answer, name the first in the
   candidate order.

The phases share a :class:`SearchState`: the fits so far, the accepted set and the steps taken
(what the report lists). Each phase reads and extends it; none reaches into another.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.validation.search.aliases import (
    admissible,
    alias_groups,
    directions,
    same_span,
    sparsest_equivalent,
)
from rventry_env.validation.search.effects import (
    EFFECT_NAMES,
    density_knots,
    knot_counts,
    mach_knot_counts,
    mach_knots,
    measured_density_correction,
)
from rventry_env.validation.search.fit import FitResult
from rventry_env.validation.search.selection import FitContext, compare_fits

SCREEN_KEEP = 2  # additions fitted in full per forward-selection step, after linearized screening
PROFILES = ("density_profile", "mach_drag")  # effects whose knot count is chosen by BIC
MAX_PROVISIONAL_STEPS = 1  # steps in a row the search may continue from a fit whose entry state is on its bound
SEARCH_REPLAY_BUDGET = 250  # replays with sensitivities after which forward selection adds nothing more
PAIR_CANDIDATES = 3  # the best single candidates whose pairs are tried after the greedy search
PAIR_KEEP = 3  # pairs fitted in full, after a one-step screening of them all
FIXED_EFFECTS = ("j2_gravity", "measured_density")  # effects without a free parameter


def _quiet(msg: str) -> None:
    return None


@dataclass
class SearchState:
    """What the search has found so far.

    :param base: the baseline fit (the current model).
    :param current: the accepted fit (the baseline until an effect is accepted).
    :param frontier: the fit the next step starts from: the accepted one, or a *provisional* one
        (flawed only by its entry state on the bound); None when the search has stopped.
    :param first: first-step fits by effect name.
    :param steps: the report's record of every step.
    :param step_fits: the fits tried at every step.
    :param knot_trials: knot counts tried per profile fit.
    :param aliases_skipped: additions not fitted because they repeat a direction already moved.
    """

    base: FitResult
    current: FitResult
    frontier: FitResult | None = None
    first: dict = field(default_factory=dict)
    steps: list = field(default_factory=list)
    step_fits: list = field(default_factory=list)
    knot_trials: dict = field(default_factory=dict)
    aliases_skipped: list = field(default_factory=list)
    provisional_run: int = 0

    @property
    def chosen(self) -> tuple:
        """The accepted effects (empty for the baseline)."""
        return tuple(self.current.effects)

    def accept(self, fit: FitResult) -> None:
        self.current = self.frontier = fit


def mach_of_record(record, setup, rows: np.ndarray) -> np.ndarray:
    """Mach numbers of the record's samples ``rows`` (where altitude and speed are measured)."""
    h = record.altitude()[rows]
    v = record.speed()[rows]
    ok = np.isfinite(h) & np.isfinite(v)
    a = np.asarray(setup.model.atmosphere.speed_of_sound(h[ok], NUMPY), float)
    return v[ok] / a


def fit_context(record, replay, setup, screened, threshold: float) -> FitContext:
    """The context every fit of the record shares: knots, weights, entry-state bound, atmosphere.

    Density knots span the altitudes flown, Mach knots the Mach numbers (from the record). With
    a density column, the record's own density becomes the ``measured_density`` atmosphere.
    """
    rows = replay.rows
    altitudes = record.altitude()[rows]
    knots_by_count = {n: density_knots(altitudes, n) for n in knot_counts(altitudes)}
    mach = mach_of_record(record, setup, rows)
    mach_by_count = {n: mach_knots(mach, n) for n in mach_knot_counts(mach)}
    if has_density_column(record):
        alt = record.altitude()
        ok = np.isfinite(alt) & np.isfinite(record.density)
        setup = dataclasses.replace(
            setup, measured_atmosphere=measured_density_correction(alt[ok], record.density[ok], setup.model)
        )
        replay.setup = setup
    return FitContext(replay, setup, screened.groups, screened.sigma_vector(), screened.bound, knots_by_count,
                      mach_by_count, threshold)  # fmt: skip


def has_density_column(record) -> bool:
    """True when the record measures density at 3 samples or more."""
    return record.density is not None and np.count_nonzero(np.isfinite(record.density)) >= 3


def fit_baseline(ctx: FitContext, screened, reweight) -> FitResult:
    """The current model with only the entry state fitted.

    :param reweight: ``reweight(screened, fit)`` sets weights no noise was known for from the
        fit's residual; the baseline is refitted with them.
    """
    structure = ctx.structure(())
    base = ctx.fit(structure, None)
    if any(v == "provisional" for v in screened.weights_from.values()):
        reweight(screened, base)
        ctx.sigma = screened.sigma_vector()
        base = ctx.fit(structure, base)
    return base


def _fit_set(ctx: FitContext, effects: tuple, new: str, like, previous: FitResult, rival):
    if new in PROFILES:
        return ctx.fit_profile(effects, new, like, previous, rival)
    return ctx.fit(ctx.structure(effects, like), previous), None


def _step_summary(cmp: dict) -> dict:
    return {
        "bic_current": cmp["bic_current"],
        "effective_samples": cmp["n_eff"],
        "lag1_of_best": cmp["lag1_of_best"],
        "tried": cmp["table"],
        "accepted": cmp["accepted_label"],
    }


def single_candidates(ctx: FitContext, candidates: tuple, state: SearchState) -> list[str]:
    """The candidates fitted alone: one of each group of single-parameter exact aliases (profiles last)."""
    c0 = ctx.setup.start_lift_scale
    singles = []
    for name in sorted(candidates, key=lambda c: c in PROFILES):  # profiles last: they need a rival
        st = ctx.structure((name,))
        v = directions((name,), st, c0)
        twin = next((s for s in singles if v.shape[1] == 1 and same_span(directions((s,), st, c0), v)), None)
        if twin is not None:
            state.aliases_skipped.append({"step": 1, "effect": name, "alias_of": [twin]})
            continue
        singles.append(name)
    return singles


def first_step(ctx: FitContext, base: FitResult, candidates: tuple, max_effects: int, threshold: float,
               say=_quiet) -> SearchState:  # fmt: skip
    """Every candidate alone against the baseline; accept the best credible one that beats it.

    The search continues from the accepted fit, or from a *provisional* one: the best fit of a
    step whose only flaw is an entry state on its noise bound is never accepted, but an effect
    the record needs together with it may bring the entry state back within its noise.
    """
    state = SearchState(base=base, current=base)
    for name in single_candidates(ctx, candidates, state):
        say(f"candidate {name}")
        rival = min((f.bic for f in state.first.values()), default=None)
        state.first[name], trials = _fit_set(ctx, (name,), name, None, base, rival)
        if trials is not None:
            state.knot_trials[f"step 1 {name}"] = trials
    cmp1 = compare_fits(base, list(state.first.values()), ctx.sigma, threshold, list(state.first))
    state.steps.append({"step": 1, "from": [], **_step_summary(cmp1)})
    state.step_fits.append(state.first)
    state.frontier = base
    if max_effects == 0:
        state.steps[0]["accepted"] = None
        state.steps[0]["note"] = "max_effects = 0: nothing is added"
        state.frontier = None
    elif cmp1["accepted"] is not None:
        state.accept(cmp1["accepted"])
        say(f"accepted {' + '.join(state.chosen)}")
    elif cmp1["provisional"] is not None:
        state.frontier = cmp1["provisional"]
        state.provisional_run = 1
        state.steps[0]["provisional"] = list(state.frontier.effects)
        say(f"no credible candidate beats the current model; continuing from {' + '.join(state.frontier.effects)} "
            "(its entry state is on its bound)")  # fmt: skip
    else:
        state.frontier = None
        say("no credible candidate beats the current model")
    return state


def _additions(ctx: FitContext, state: SearchState, candidates: tuple, limit: int) -> dict:
    """Admissible sets one addition from the frontier (sparsest equivalent set -> the effect added)."""
    c0 = ctx.setup.start_lift_scale
    search = state.frontier
    base_effects = tuple(search.effects)
    sets = {}
    for c in candidates:
        if c in base_effects or len(base_effects) >= limit:
            continue
        t_full = base_effects + (c,)
        st = ctx.structure(t_full, search.structure)
        sub = sparsest_equivalent(t_full, c, st, c0)
        if sub is None:
            state.aliases_skipped.append({"step": len(base_effects) + 1, "effect": c, "alias_of": list(base_effects)})
            continue
        if not admissible(sub, st, c0):
            continue
        sets.setdefault(sub, c)
    return sets


def _has_finer_profile(ctx: FitContext, fit: FitResult) -> bool:
    for p in PROFILES:
        if p not in fit.effects:
            continue
        knots = fit.structure.density_knots if p == "density_profile" else fit.structure.mach_knots
        counts = ctx.knots_by_count if p == "density_profile" else ctx.mach_by_count
        if len(knots) < max(counts):
            return True
    return False


def forward_step(ctx: FitContext, state: SearchState, candidates: tuple, max_effects: int, threshold: float,
                 say=_quiet) -> bool:  # fmt: skip
    """One forward-selection step from the frontier. True if the search goes on."""
    search = state.frontier
    base_effects = tuple(search.effects)
    limit = min(max_effects, len(candidates))
    sets = _additions(ctx, state, candidates, limit)
    if not sets and not _has_finer_profile(ctx, search):
        return False
    # screen each set by one Gauss-Newton step from the frontier (exact Jacobian)
    lin = {}
    for sub in sets:
        prob = ctx.problem(ctx.structure(sub, search.structure))
        n = len(prob.names)
        lin[sub] = prob.linearized(ctx.start_from(prob, search), {"all": list(range(n))})["all"]["chi2"]
        ctx.nfev += 1
    screened_sets = sorted(sets, key=lin.get)
    tried = {}
    rival = None
    step = len(base_effects) + 1
    for sub in sorted(screened_sets[:SCREEN_KEEP], key=lambda s: sets[s] in PROFILES):
        c = sets[sub]
        label = "+".join(sub) if set(base_effects) - set(sub) else c
        say(f"step {step}: {' + '.join(sub)}")
        fit, trials = _fit_set(ctx, sub, c, search.structure, search, rival)
        if trials is not None:
            state.knot_trials[f"step {step} {c}"] = trials
        tried[label] = fit
        rival = min(f.bic for f in tried.values())
    # a profile already in the model may need more knots rather than another effect
    for prof in (p for p in PROFILES if p in base_effects):
        fit = ctx.refine(search, prof)
        if fit is not None:
            n_kn = len(fit.structure.density_knots if prof == "density_profile" else fit.structure.mach_knots)
            say(f"step {step}: {prof} with {n_kn} knots")
            tried[f"{prof} ({n_kn} knots)"] = fit
    state.step_fits.append(tried)
    cmp = compare_fits(state.current, list(tried.values()), ctx.sigma, threshold, list(tried))
    state.steps.append({
        "step": step,
        "from": list(base_effects),
        "screened": [{"effects": list(s), "linearized_chi2": lin[s]} for s in screened_sets],
        **_step_summary(cmp),
    })  # fmt: skip
    if cmp["accepted"] is not None:
        state.accept(cmp["accepted"])
        state.provisional_run = 0
        say(f"accepted {' + '.join(state.chosen)}")
        return True
    if cmp["provisional"] is not None and cmp["provisional"].structure.key() != search.structure.key():
        if state.provisional_run >= MAX_PROVISIONAL_STEPS:
            state.steps[-1]["stopped"] = (f"the best fit again needs its entry state on the bound; the search "
                                          f"continues from such a fit for at most {MAX_PROVISIONAL_STEPS} step(s)")
            return False
        state.provisional_run += 1
        state.frontier = cmp["provisional"]
        state.steps[-1]["provisional"] = list(state.frontier.effects)
        say(f"continuing from {' + '.join(state.frontier.effects)} (its entry state is on its bound)")
        return True
    return False


def forward_selection(ctx: FitContext, state: SearchState, candidates: tuple, max_effects: int, threshold: float,
                      say=_quiet) -> SearchState:  # fmt: skip
    """Add effects from the frontier while one addition beats the current model."""
    limit = min(max_effects, len(candidates))
    while state.frontier is not None and state.frontier.effects and (
        len(state.frontier.effects) < limit or any(p in state.frontier.effects for p in PROFILES)
    ):
        if ctx.nfev > SEARCH_REPLAY_BUDGET:
            state.steps.append({"step": "stopped", "from": list(state.frontier.effects),
                                "note": f"{ctx.nfev} replays: the forward search stops at its budget of "
                                        f"{SEARCH_REPLAY_BUDGET}"})  # fmt: skip
            say(f"forward search stopped at its budget ({ctx.nfev} replays)")
            break
        if not forward_step(ctx, state, candidates, max_effects, threshold, say):
            break
    return state


def _pair_structure(ctx: FitContext, pair: tuple, fits: list[FitResult]):
    """A structure for a pair with the knots its members' single fits chose."""
    dk = next((f.structure.density_knots for f in fits if "density_profile" in f.effects), None)
    mk = next((f.structure.mach_knots for f in fits if "mach_drag" in f.effects), None)
    st = ctx.structure(pair)
    return dataclasses.replace(st, density_knots=dk or st.density_knots, mach_knots=mk or st.mach_knots)


def _pair_candidates(ctx: FitContext, state: SearchState) -> dict:
    """The admissible pairs of the best unstretched first-step fits, with each other and with every
    effect without a free parameter, other than the answer itself.

    :return: label -> (the pair's structure, its better member's fit to start from).
    """
    c0 = ctx.setup.start_lift_scale
    ranked = [row["effect"] for row in state.steps[0]["tried"] if not row["at_bound"]]
    top = [e for e in ranked if e in state.first][:PAIR_CANDIDATES]
    # an effect without a free parameter (J2 at its known value, the measured density) ranks low
    # alone, since it only corrects the model next to the effect it was missing: pair it with each
    fixed = [e for e in state.first if e in FIXED_EFFECTS and e not in top]
    pairs = list(itertools.combinations(top, 2)) + [(a, b) for a in top for b in fixed]
    candidates = {}
    for pair in pairs:
        if set(pair) == set(state.chosen):
            continue
        members = [state.first[e] for e in pair]
        st = _pair_structure(ctx, pair, members)
        if not admissible(pair, st, c0):
            continue
        candidates[" + ".join(pair)] = (st, min(members, key=lambda f: f.bic))
    return candidates


def try_pairs(ctx: FitContext, state: SearchState, max_effects: int, threshold: float, say=_quiet) -> bool:
    """Fit every admissible pair of the best single candidates, so a true pair is not lost to an alias.

    The greedy search accepts the best single effect first; when that is an alias of one member
    of a true pair (a density level for a mass error), the other member may then only fit
    implausibly next to it (J2 soaking up the difference). The :data:`PAIR_CANDIDATES` best
    first-step fits that are not stretched to a physical bound are paired with each other and
    with every effect that has no free parameter (:data:`FIXED_EFFECTS`). Every admissible pair is
    screened by one Gauss-Newton step from its better member's fit (one replay); the
    :data:`PAIR_KEEP` best are fitted in full. A credible pair replaces the answer when it beats it
    by the threshold (by any margin when the answer has as many effects). Run when the greedy
    answer leaves a residual that is not noise.

    :return: True when a pair replaced the answer.
    """
    if max_effects < 2:
        return False
    candidates = _pair_candidates(ctx, state)
    # one Gauss-Newton step from the better member (exact Jacobian, one replay) screens every pair; the
    # PAIR_KEEP best are fitted in full
    screened = {}
    for label, (st, start) in candidates.items():
        prob = ctx.problem(st)
        lin = prob.linearized(ctx.start_from(prob, start), {"all": list(range(len(prob.names)))})
        screened[label] = lin["all"]["chi2"]
        ctx.nfev += 1
    fits = {}
    for label in sorted(screened, key=screened.get)[:PAIR_KEEP]:
        st, start = candidates[label]
        say(f"pair: {label}")
        fits[label] = ctx.fit(st, start)
    if not fits:
        return False
    state.step_fits.append(fits)
    cmp = compare_fits(state.current, list(fits.values()), ctx.sigma, 0.0, list(fits))
    margin = threshold if len(state.chosen) < 2 else 0.0
    best = next((row for row in cmp["table"] if row["credible"]), None)
    replace = best is not None and best["bic"] < cmp["bic_current"] - margin
    state.steps.append({"step": "pairs", "from": list(state.chosen), "effective_samples": cmp["n_eff"],
                        "bic_current": cmp["bic_current"], "tried": cmp["table"],
                        "screened": [{"effects": label, "linearized_chi2": chi2} for label, chi2 in
                                     sorted(screened.items(), key=lambda kv: kv[1])],
                        "accepted": best["effect"] if replace else None})  # fmt: skip
    if replace:
        state.current = fits[best["effect"]]
        say(f"accepted the pair {best['effect']}: it beats {' + '.join(state.steps[-1]['from']) or 'the baseline'}")
    return replace


def backward_elimination(ctx: FitContext, state: SearchState, threshold: float, say=_quiet) -> SearchState:
    """Remove an effect that no longer earns its place next to the others.

    Forward selection is greedy, and a provisional first step may have picked a near-tie.
    """
    c0 = ctx.setup.start_lift_scale
    while len(state.chosen) > 1:
        current, chosen = state.current, state.chosen
        trials = {}
        for e in chosen:
            rest = tuple(x for x in chosen if x != e)
            st = ctx.structure(rest, current.structure)
            if not admissible(rest, st, c0):
                continue
            say(f"backward: {' + '.join(rest)} (without {e})")
            trials[e] = ctx.fit(st, current)
        state.step_fits.append(trials)
        if not trials:
            break
        cmp = compare_fits(current, list(trials.values()), ctx.sigma, 0.0, [f"without {e}" for e in trials])
        b_cur = cmp["bic_current"]
        removable = [(row["bic"], row) for row in cmp["table"]
                     if row["credible"] and row["bic"] < b_cur + threshold]  # fmt: skip
        state.steps.append({"step": "backward", "from": list(chosen), "effective_samples": cmp["n_eff"],
                            "bic_current": b_cur, "tried": cmp["table"], "removed": None})  # fmt: skip
        if not removable:
            break
        _, row = min(removable, key=lambda r: r[0])
        e = row["effect"][len("without "):]
        state.steps[-1]["removed"] = e
        state.current = trials[e]
        say(f"removed {e}: the others explain the record as well")
    return state


def canonical_member(aliases: list, chosen: tuple):
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


def name_canonical_member(ctx: FitContext, state: SearchState) -> list:
    """Name the exact alias of the same size that comes first in the candidate order.

    The same fit, so every record of one flight (at 10 Hz or 1 Hz) names the same member of a
    group. Returns the alias groups of the answer.
    """
    c0 = ctx.setup.start_lift_scale
    current, chosen = state.current, state.chosen
    aliases = alias_groups(current.parameters(), chosen, current.structure, c0) if chosen else []
    canon = canonical_member(aliases, chosen)
    if canon is None:
        return aliases
    effects_c, params_c = canon
    st = ctx.structure(tuple(effects_c), current.structure)
    prob = ctx.problem(st)
    theta0 = ctx.start_from(prob, current)
    for i, nme in enumerate(prob.names):
        if nme in params_c:
            theta0[i] = params_c[nme]
    refit = ctx.fit(st, None, max_nfev=20, theta0=theta0)
    if refit.credible and refit.bic <= current.bic + 1e-6 * abs(current.bic) + 1e-6:
        state.current = refit
        aliases = alias_groups(refit.parameters(), state.chosen, refit.structure, c0)
    return aliases


__all__ = [
    "PROFILES",
    "SCREEN_KEEP",
    "SearchState",
    "backward_elimination",
    "try_pairs",
    "canonical_member",
    "first_step",
    "fit_baseline",
    "fit_context",
    "forward_selection",
    "forward_step",
    "has_density_column",
    "name_canonical_member",
]
