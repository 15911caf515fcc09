"""What a trajectory can tell apart: identifiable directions, admissible effect sets and aliases.

A trajectory feels the air only through the aerodynamic accelerations

    D/m = rho C_D S / (2m) v^2,    L/m = rho C_L S / (2m) v^2,

so a flight record observes the *drag-acceleration scale* k_D = rho C_D S / m (a ballistic
coefficient) and the *lift scale* k_L = rho C_L S / m, or equivalently k_D and the lift-to-drag
ratio C_L / C_D, together with the *shape* of the density profile in altitude and of a drag
correction in Mach. It cannot see how a change of k_D splits between a uniform density factor,
the mass and the coefficients:

* a uniform density factor f, a mass x 1/f, and C_L and C_D both x f fly the same trajectory;
* with the level free, C_L x s flies as C_D x 1/s (C_L / C_D is what is seen), so
  "density + C_D x 1.042" is the same fit as "density + C_L x 0.96";
* without lift (a drag-only capsule), C_D x s is the same as the mass x 1/s.

Every candidate effect moves some of these identifiable directions (:func:`directions`). A set
of effects is *admissible* when its parameters move independent directions (no parameter an
alias of another in the set); the loop only fits admissible sets, and among sets that span the
same directions it names the sparsest (:func:`sparsest_equivalent`). :func:`alias_groups` lists,
for the identified set, every other explanation that fits exactly as well, with its parameter
values, so a report names one member and says what else it could be.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from rventry_env.validation.search.effects import EFFECT_NAMES, Structure

# identifiable coordinates of the uniform aerodynamic part: ln k_D and ln k_L
_D, _L = 0, 1
LEVEL_CAUSES = ("mass", "density_profile", "drag_coefficient", "lift_coefficient")
_N_FIXED = 5  # D, L, wind east, wind north, the record's time offset; shapes get their own coordinates after these


def lift_capable(start_lift_scale: float, effects) -> bool:
    """True when the flight has lift (declared, or added by ``lift_coefficient``)."""
    return start_lift_scale != 0.0 or "lift_coefficient" in effects


def directions(effects, structure: Structure, start_lift_scale: float) -> np.ndarray:
    """Identifiable directions moved by the parameters of ``effects``, one column per parameter.

    Coordinates: ln k_D, ln k_L, wind east, wind north, the record's time offset (the controls'
    timing against the states: no force moves it), then one per density-shape and Mach-shape
    degree of freedom. A density profile of K knots moves the level of both
    accelerations (its mean) and K - 1 shape directions; a Mach-dependent drag correction
    (fixed to 1 at the highest Mach) moves M - 1 Mach-shape directions only.
    """
    lift = lift_capable(start_lift_scale, effects)
    level = np.array([1.0, 1.0 if lift else 0.0])  # both accelerations by the same factor
    drag = np.array([1.0, 0.0])
    # every set under one structure gets the same coordinates, so their spans compare
    nk = max(len(structure.density_knots), 1)
    nm = max(len(structure.mach_knots), 1)
    dim = _N_FIXED + (nk - 1) + (nm - 1)
    cols = []

    def col(head=None, index=None):
        v = np.zeros(dim)
        if head is not None:
            v[:2] = head
        if index is not None:
            v[index] = 1.0
        cols.append(v)

    for e in effects:
        if e == "mass":
            col(-level)
        elif e == "drag_coefficient":
            col(drag)
        elif e == "lift_coefficient":
            col(np.array([0.0, 1.0]))
        elif e == "wind":
            col(index=2)
            col(index=3)
        elif e == "time_offset":
            col(index=4)
        elif e == "density_profile":
            col(level)
            for i in range(nk - 1):
                col(index=_N_FIXED + i)
        elif e == "mach_drag":
            for i in range(nm - 1):
                col(index=_N_FIXED + nk - 1 + i)
    return np.array(cols).T if cols else np.zeros((dim, 0))


def _rank(a: np.ndarray) -> int:
    return int(np.linalg.matrix_rank(a, tol=1e-9)) if a.size else 0


def same_span(a: np.ndarray, b: np.ndarray) -> bool:
    """True when the columns of ``a`` and ``b`` span the same space (same row count)."""
    ra, rb = _rank(a), _rank(b)
    return ra == rb == _rank(np.hstack([a, b])) if (a.size and b.size) else ra == rb == 0


def admissible(effects, structure: Structure, start_lift_scale: float) -> bool:
    """True when no parameter of the set is an alias of the others (the fit is identifiable)."""
    v = directions(effects, structure, start_lift_scale)
    return _rank(v) == v.shape[1]


def _priority(effects) -> tuple:
    return (len(effects), sorted(EFFECT_NAMES.index(e) for e in effects))


def sparsest_equivalent(effects, new: str, structure: Structure, start_lift_scale: float):
    """The sparsest admissible subset of ``effects`` that contains ``new`` and spans what ``effects`` span.

    :return: the subset (a tuple, in the order of ``effects``), or None if ``new`` adds no
        direction the others do not already move (it is an alias of them). An effect without
        free parameters (J2 at its known value, the measured density) changes the model rather
        than adding a direction, and is always kept.
    """
    effects = tuple(effects)
    full = directions(effects, structure, start_lift_scale)
    without = tuple(e for e in effects if e != new)
    if directions((new,), structure, start_lift_scale).shape[1] == 0:
        # a known constant or a measured atmosphere: no free direction, but a different model
        return effects if admissible(effects, structure, start_lift_scale) else None
    if same_span(directions(without, structure, start_lift_scale), full):
        return None
    best = None
    for n in range(1, len(effects) + 1):
        for sub in itertools.combinations(effects, n):
            if new not in sub:
                continue
            v = directions(sub, structure, start_lift_scale)
            if _rank(v) == v.shape[1] and same_span(v, full):
                if best is None or _priority(sub) < _priority(best):
                    best = sub
        if best is not None:
            return best
    return None


def identifiable(values: dict, effects, start_lift_scale: float, density_knots=(), mach_knots=()) -> dict:
    """The identifiable quantities of a fitted explanation, relative to the start model.

    ``drag_acceleration_scale`` is k_D (the uniform part, with the density profile's log mean
    over its knots), ``lift_to_drag_scale`` C_L/C_D relative to the declared ratio (None
    without lift), the density shape with its mean removed, and the Mach-drag correction.
    """
    ln_mu = math.log(values.get("mass_scale", 1.0))
    s = values.get("cd_scale", 1.0)
    c = values.get("cl_scale", start_lift_scale)
    rho = [values[k] for k in values if k.startswith("dlnrho_")] if "density_profile" in effects else []
    mach = [values[k] for k in values if k.startswith("dlncd_M")] if "mach_drag" in effects else []
    level = float(np.mean(rho)) if rho else 0.0
    mlevel = 0.0  # the Mach correction is 1 at the highest Mach: no level
    out = {
        "drag_acceleration_scale": s * math.exp(level + mlevel - ln_mu),
        "lift_acceleration_scale": c * math.exp(level - ln_mu),
        "lift_to_drag_scale": (c / (s * math.exp(mlevel))) if c else None,
    }
    if rho:
        out["density_shape"] = {k: float(values[k] - level) for k in values if k.startswith("dlnrho_")}
    if mach:
        out["mach_drag_log_factors"] = {k: float(values[k]) for k in values if k.startswith("dlncd_M")}
    return out


_REASONS = {
    "no_lift": "the vehicle flies without lift, so the record sees only the drag acceleration rho C_D S / m: "
    "C_D, the mass and a uniform density factor change it the same way",
    "level": "a trajectory sees the aerodynamic accelerations only through rho C_D S / m and C_L / C_D: a "
    "uniform density factor, the mass, and C_L and C_D scaled together change both accelerations by the "
    "same factor and fly the same trajectory",
    "lift": "a trajectory sees rho C_D S / m and C_L / C_D only: C_L x s flies like C_D x 1/s with the "
    "mass (or a uniform density factor) changed to keep rho C_D S / m",
    "drag": "a trajectory sees rho C_D S / m and C_L / C_D only: C_D x s flies like C_L x 1/s with a uniform "
    "density factor x s (or the mass x 1/s)",
    "both": "a trajectory sees rho C_D S / m and C_L / C_D only: any two of C_L, C_D, the mass and a uniform "
    "density factor that move both fit the record equally well",
}


def _member_parameters(sub, coef, c_ref: float, rho_names: list, values: dict, level: float) -> tuple[dict, list]:
    """The parameters of the alias member ``sub`` with coefficients ``coef`` (in ln k_D, ln k_L / c_ref),
    and its effects (the density profile's shape carried where the answer has one)."""
    params = {}
    for e, a in zip(sub, coef):
        if e == "mass":  # its direction is already (-1, -1): the mass factor is exp(+a)
            params["mass_scale"] = math.exp(a)
        elif e == "drag_coefficient":
            params["cd_scale"] = math.exp(a)
        elif e == "lift_coefficient":
            params["cl_scale"] = c_ref * math.exp(a)
        elif e == "density_profile":
            params["density_level_factor"] = math.exp(a)
    member_effects = list(sub)
    if rho_names:
        # the density profile's shape stays; only its level moves
        if "density_profile" not in sub:
            member_effects.append("density_profile")
            a_rho = 0.0
        else:
            a_rho = coef[list(sub).index("density_profile")]
        for nme in rho_names:
            params[nme] = values[nme] - level + a_rho
        params.pop("density_level_factor", None)
    return params, member_effects


def _alias_reason(lift: bool, r_answer: int, answer: np.ndarray) -> str:
    """Why the members fit alike: which direction of (ln k_D, ln k_L) the answer's uniform part spans."""
    if not lift:
        return _REASONS["no_lift"]
    if r_answer == 2:
        return _REASONS["both"]
    if np.allclose(answer[:, 0] / np.linalg.norm(answer[:, 0]), np.array([1, 1]) / math.sqrt(2)) or np.allclose(
        answer[:, 0] / np.linalg.norm(answer[:, 0]), -np.array([1, 1]) / math.sqrt(2)
    ):
        return _REASONS["level"]
    if abs(answer[0, 0]) < 1e-12:
        return _REASONS["lift"]
    return _REASONS["drag"]


def _alias_members(vec: dict, dims: int, answer: np.ndarray, target: np.ndarray, n_level: int, carried: list,
                   c_ref: float, rho_names: list, values: dict, level: float) -> list[dict]:  # fmt: skip
    """Every set of level causes (up to ``max(n_level, 2)``) that spans the answer's uniform part exactly,
    or (a pair) ties one extra cause to a single-cause answer, with the parameters that reproduce
    ``target``; each listed with the carried effects.
    """
    r_answer = _rank(answer)
    members = []
    max_size = max(n_level, 2)
    for n in range(1, max_size + 1):
        for sub in itertools.combinations(vec, n):
            v = np.array([vec[e][:dims] for e in sub]).T
            if _rank(v) != n:
                continue  # redundant within itself
            exact = n == r_answer and same_span(v, answer)
            tied = (not exact) and r_answer == 1 and n == 2 and _rank(np.hstack([v, answer])) == 2
            if not (exact or tied):
                continue
            coef, *_ = np.linalg.lstsq(v, target[:dims], rcond=None)
            if tied and np.any(np.abs(coef) < 1e-12 * max(1.0, float(np.max(np.abs(coef))))):
                continue  # one of the pair unchanged: it is the single member again
            if not np.allclose(v @ coef, target[:dims], atol=1e-9):
                continue
            params, member_effects = _member_parameters(sub, coef, c_ref, rho_names, values, level)
            members.append({
                "effects": [e for e in EFFECT_NAMES if e in member_effects + carried],
                "parameters": {k: float(v) for k, v in params.items()},
                "tied": bool(tied),
            })  # fmt: skip
    return members


def alias_groups(values: dict, effects, structure: Structure, start_lift_scale: float) -> list[dict]:
    """Every explanation that fits exactly as well as ``effects`` with ``values``.

    The uniform aerodynamic part (mass, density level, C_D, C_L) is redistributed over the
    other members of its alias class; shapes (the density profile's, the Mach correction's),
    wind and J2 are carried unchanged. Members with more effects than the answer are listed
    when the extra one is tied to another (e.g. C_L and C_D by the same factor).

    :return: ``[{"effects": [...], "reason": ..., "members": [{"effects", "parameters",
        "tied"}]}]``; empty when the answer has no aerodynamic-level part.
    """
    effects = tuple(effects)
    level_part = [e for e in effects if e in LEVEL_CAUSES]
    if not level_part:
        return []
    lift = lift_capable(start_lift_scale, effects)
    # the uniform part of the answer in (ln k_D, ln k_L / c_ref)
    ln_mu = math.log(values.get("mass_scale", 1.0))
    s = values.get("cd_scale", 1.0)
    c = values.get("cl_scale", start_lift_scale)
    rho_names = [f"dlnrho_{k / 1e3:.1f}km" for k in structure.density_knots] if "density_profile" in effects else []
    level = float(np.mean([values[n] for n in rho_names])) if rho_names else 0.0
    c_ref = start_lift_scale if start_lift_scale != 0.0 else c
    target = np.array([math.log(s) + level - ln_mu, (math.log(c / c_ref) if (lift and c > 0) else 0.0) + level - ln_mu])
    dims = 2 if lift else 1
    vec = {
        "mass": np.array([-1.0, -1.0]),
        "density_profile": np.array([1.0, 1.0]),
        "drag_coefficient": np.array([1.0, 0.0]),
        "lift_coefficient": np.array([0.0, 1.0]),
    }
    if not lift:
        vec = {k: v for k, v in vec.items() if k != "lift_coefficient"}
    answer = np.array([vec[e][:dims] for e in level_part]).T
    r_answer = _rank(answer)
    carried = [e for e in effects if e not in LEVEL_CAUSES]
    members = _alias_members(vec, dims, answer, target, len(level_part), carried, c_ref, rho_names, values, level)
    if len(members) <= 1:
        return []
    reason = _alias_reason(lift, r_answer, answer)
    names = sorted({e for m in members for e in m["effects"] if e in LEVEL_CAUSES}, key=EFFECT_NAMES.index)
    ident = identifiable(values, effects, start_lift_scale, structure.density_knots, structure.mach_knots)
    return [{
        "effects": names,
        "reason": reason,
        "drag_acceleration_scale": ident["drag_acceleration_scale"],
        "lift_to_drag_scale": ident["lift_to_drag_scale"],
        "members": members,
    }]  # fmt: skip


__all__ = [
    "LEVEL_CAUSES",
    "admissible",
    "alias_groups",
    "directions",
    "identifiable",
    "lift_capable",
    "same_span",
    "sparsest_equivalent",
]
