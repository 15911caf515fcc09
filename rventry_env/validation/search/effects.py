"""Candidate effects: what the current model may lack, each expressed through the physics parts.

Every effect ("cause") is a handful of named parameters with documented physical bounds, and the
rule that adds it to an :class:`~rventry_env.physics.EntryModel`:

====================  ===================================  ==========================  ========================================
effect                parameters                           physical bounds             physics part
====================  ===================================  ==========================  ========================================
``j2_gravity``        none: J2 = 1.08262668e-3 (EGM-96)    the known value             :class:`~rventry_env.physics.J2Gravity`
``density_profile``   ``dlnrho_<h>km`` per knot            density x 1/3 .. 3          :class:`~rventry_env.physics.DensityCorrection`
``lift_coefficient``  ``cl_scale`` (of the declared C_L)   0 .. 2                      :class:`~rventry_env.physics.ScaledAerodynamics`
``drag_coefficient``  ``cd_scale``                         0.5 .. 2                    :class:`~rventry_env.physics.ScaledAerodynamics`
``wind``              ``wind_east_mps, wind_north_mps``    +-200 m/s each              :class:`~rventry_env.physics.HorizontalWind`
``mass``              ``mass_scale`` (of the declared)     0.5 .. 2                    :class:`~rventry_env.physics.Vehicle`
``mach_drag``         ``dlncd_M<m>`` per Mach knot but     C_D x 1/2 .. 2              :class:`~rventry_env.physics.mach_drag.MachDragCorrection`
                      the highest (where it is 0)
``measured_density``  none: the record's density column    (records with one)          :class:`~rventry_env.physics.DensityCorrection`
``time_offset``       ``time_offset_s``: the record's      +-10 s                      none: the record's controls are read
                      time tags that much early                                        that much later (an effect of the record)
====================  ===================================  ==========================  ========================================

The bounds are physical, not numerical: a fit that ends on one is not explaining the record, it
is being stretched to absorb something else, and is never accepted. J2 is a known constant, so
``j2_gravity`` has no free parameter: it is tested at its known value (and the value the record
would prefer is checked against it, :mod:`~rventry_env.validation.search.selection`).

``mach_drag`` is the *variation* of C_D with Mach: its factor is 1 at the highest Mach number
the record flies (a declared C_D is the value at the top of the flight, like Apollo's trim C_D for
M > 29.5), so a uniform change of C_D stays the ``drag_coefficient`` effect and the two are not
nested.

``time_offset`` is an effect of the record, not of the world: its state rows tagged ``time_offset_s``
early against its controls (a clock offset between the two, the row of time t holding the state
flown at t + ``time_offset_s``). The replay reads the controls that much later
(:meth:`~rventry_env.validation.replay.record_replay.Replay.shifted_controls`); the model's physics
is unchanged, so :func:`build_model` leaves it out. A record whose states and controls share one
shifted clock flies the same trajectory (the dynamics do not depend on time): what the record
shows, and the effect fits, is the offset between the two. It is bounded by
:data:`TIME_OFFSET_MAX_S`: a larger misalignment is a record on another time base, not an offset.

``cl_scale`` multiplies the *declared* lift (the sidecar's aerodynamics): a model started
drag-only has cl_scale = 0, so "lift missing altogether" is the same effect as "lift 20 % low",
only further from the start. Which of these the data can tell apart is the business of
:mod:`~rventry_env.validation.search.aliases`.

Parameter values may be NumPy arrays or CasADi symbols: the physics parts are plain component
arithmetic, so the same :func:`build_model` serves the reported model and the symbolic replay
whose exact sensitivities the fits use (:mod:`~rventry_env.validation.replay.sensitivity`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics import DensityCorrection, EntryModel, HorizontalWind, J2Gravity, ScaledAerodynamics
from rventry_env.physics.atmosphere import piecewise_linear
from rventry_env.physics.mach_drag import MachDragCorrection
from rventry_env.validation.replay.record_replay import TIME_OFFSET
from rventry_env.validation.replay.replay_setup import ReplaySetup

EFFECT_NAMES = (
    "j2_gravity",
    "density_profile",
    "lift_coefficient",
    "drag_coefficient",
    "wind",
    "mass",
    "mach_drag",
    "measured_density",
    "time_offset",
)
RECORD_EFFECTS = ("time_offset",)  # effects of how the record reads the flight, not of the world

# the Earth's second zonal harmonic (EGM-96): a known constant, not a free parameter
EARTH_J2 = 1.08262668e-3

# documented physical bounds of every candidate's parameters
DENSITY_FACTOR_MAX = 3.0  # a density profile within 1/3 .. 3 of the model atmosphere
CL_SCALE_BOUNDS = (0.0, 2.0)  # of the declared C_L: wrong-signed lift is not a correction
CD_SCALE_BOUNDS = (0.5, 2.0)
MASS_SCALE_BOUNDS = (0.5, 2.0)
WIND_MAX_MPS = 200.0  # the strongest winds measured at 40-120 km are about this
MACH_DRAG_FACTOR_MAX = 2.0
TIME_OFFSET_MAX_S = 10.0  # a record's states and controls misaligned by more are on different time bases
PHYSICAL_BOUNDS = {
    "density_factor": [1.0 / DENSITY_FACTOR_MAX, DENSITY_FACTOR_MAX],
    "cl_scale": list(CL_SCALE_BOUNDS),
    "cd_scale": list(CD_SCALE_BOUNDS),
    "mass_scale": list(MASS_SCALE_BOUNDS),
    "wind_component_mps": [-WIND_MAX_MPS, WIND_MAX_MPS],
    "mach_drag_factor": [1.0 / MACH_DRAG_FACTOR_MAX, MACH_DRAG_FACTOR_MAX],
    "time_offset_s": [-TIME_OFFSET_MAX_S, TIME_OFFSET_MAX_S],
    "j2": "fixed at the known value 1.08262668e-3 (EGM-96)",
}


@dataclass(frozen=True)
class Param:
    """One fitted parameter: start value (the effect absent), typical change, physical bounds."""

    name: str
    effect: str
    start: float
    scale: float
    lower: float
    upper: float


@dataclass(frozen=True)
class Structure:
    """A set of effects and the knots their profiles use.

    :param effects: effect names, in the order they were added.
    :param density_knots: altitudes (m) of the ``density_profile`` knots (when it is included).
    :param mach_knots: Mach numbers of the ``mach_drag`` knots (when it is included).
    """

    effects: tuple = ()
    density_knots: tuple = ()
    mach_knots: tuple = ()

    def with_effect(self, name: str, density_knots=None, mach_knots=None) -> Structure:
        return Structure(
            self.effects + (name,),
            self.density_knots if density_knots is None else tuple(density_knots),
            self.mach_knots if mach_knots is None else tuple(mach_knots),
        )

    def key(self) -> tuple:
        return (
            tuple(sorted(self.effects)),
            self.density_knots if "density_profile" in self.effects else (),
            self.mach_knots if "mach_drag" in self.effects else (),
        )


KNOT_COUNTS = (2, 3, 4, 6, 8, 12, 16, 24, 32)
MACH_KNOT_COUNTS = (2, 3, 4)
MIN_KNOT_SPACING = 1e3  # m: finer than this a density correction is not resolved by a trajectory
SAMPLES_PER_KNOT = 10  # a profile gets at most one knot per this many samples


def density_knots(altitudes: np.ndarray, n_knots: int = 2) -> tuple:
    """``n_knots`` evenly spaced knots (m) over the altitudes a record visits.

    Two knots make a log-linear correction (density level and scale height); more let it
    bend. The loop picks the number by BIC (see :func:`knot_counts`).
    """
    h = altitudes[np.isfinite(altitudes)]
    lo, hi = float(np.min(h)), float(np.max(h))
    if hi - lo < MIN_KNOT_SPACING * (n_knots - 1):  # a level flight: spread the knots so they stay distinct
        mid = 0.5 * (lo + hi)
        half = 0.5 * MIN_KNOT_SPACING * (n_knots - 1)
        lo, hi = mid - half, mid + half
    # rounded to 100 m so the parameter names stay readable
    return tuple(float(k) for k in np.round(np.linspace(lo, hi, n_knots), -2))


def knot_counts(altitudes: np.ndarray) -> tuple:
    """Knot counts worth trying, up to what the record resolves.

    Those of :data:`KNOT_COUNTS` whose spacing over the altitudes flown is at least
    :data:`MIN_KNOT_SPACING` and with at least :data:`SAMPLES_PER_KNOT` samples per knot, and the
    finest count that still meets both (a 10 km span resolves 11 knots, which the list's 8 and 12
    step over): a long dense record may bend its profile every kilometre (a density wave of a few
    kilometres), a short or sparse one stays coarse. BIC picks among them
    (:meth:`FitContext.fit_profile`).
    """
    h = altitudes[np.isfinite(altitudes)]
    span = float(np.max(h) - np.min(h))

    def resolved(n):
        return span / (n - 1) >= MIN_KNOT_SPACING and n * SAMPLES_PER_KNOT <= h.size

    counts = {n for n in KNOT_COUNTS if n == 2 or resolved(n)}
    finest = min(int(span // MIN_KNOT_SPACING) + 1, h.size // SAMPLES_PER_KNOT, max(KNOT_COUNTS))
    if finest > 2 and resolved(finest):
        counts.add(finest)
    return tuple(sorted(counts))


def mach_knots(mach: np.ndarray, n_knots: int = 2) -> tuple:
    """``n_knots`` knots spaced evenly in log Mach over the Mach numbers a record visits.

    Log spacing: drag coefficients change most at the low end of a hypersonic flight.
    """
    m = mach[np.isfinite(mach) & (mach > 0)]
    lo, hi = max(float(np.min(m)), 0.5), float(np.max(m))
    if hi < lo * 1.2:
        lo, hi = lo / 1.1, hi * 1.1
    k = np.round(np.exp(np.linspace(math.log(lo), math.log(hi), n_knots)), 2)
    return tuple(float(x) for x in k)


def mach_knot_counts(mach: np.ndarray) -> tuple:
    """Mach knot counts worth trying: more knots only over a wide Mach range."""
    m = mach[np.isfinite(mach) & (mach > 0)]
    ratio = float(np.max(m) / max(np.min(m), 0.5))
    return tuple(n for n in MACH_KNOT_COUNTS if n == 2 or ratio ** (1.0 / (n - 1)) >= 1.15)


def _density_name(k: float) -> str:
    return f"dlnrho_{k / 1e3:.1f}km"


def _mach_name(k: float) -> str:
    return f"dlncd_M{k:.2f}"


def effect_parameters(name: str, setup: ReplaySetup, structure: Structure) -> list[Param]:
    """The parameters of one effect (empty for ``j2_gravity`` and ``measured_density``)."""
    if name in ("j2_gravity", "measured_density"):
        return []
    if name == "density_profile":
        lim = math.log(DENSITY_FACTOR_MAX)
        return [Param(_density_name(k), name, 0.0, 0.05, -lim, lim) for k in structure.density_knots]
    if name == "mach_drag":
        lim = math.log(MACH_DRAG_FACTOR_MAX)
        # every knot but the highest: the correction is fixed to 1 at the top Mach number
        return [Param(_mach_name(k), name, 0.0, 0.05, -lim, lim) for k in structure.mach_knots[:-1]]
    if name == "lift_coefficient":
        return [Param("cl_scale", name, setup.start_lift_scale, 0.05, *CL_SCALE_BOUNDS)]
    if name == "drag_coefficient":
        return [Param("cd_scale", name, 1.0, 0.02, *CD_SCALE_BOUNDS)]
    if name == "mass":
        return [Param("mass_scale", name, 1.0, 0.02, *MASS_SCALE_BOUNDS)]
    if name == "wind":
        return [
            Param("wind_east_mps", name, 0.0, 10.0, -WIND_MAX_MPS, WIND_MAX_MPS),
            Param("wind_north_mps", name, 0.0, 10.0, -WIND_MAX_MPS, WIND_MAX_MPS),
        ]
    if name == "time_offset":
        return [Param(TIME_OFFSET, name, 0.0, 0.1, -TIME_OFFSET_MAX_S, TIME_OFFSET_MAX_S)]
    raise ValueError(f"unknown effect {name!r}; choose from {', '.join(EFFECT_NAMES)}")


def structure_parameters(setup: ReplaySetup, structure: Structure) -> list[Param]:
    """Every fitted parameter of a structure, effect by effect."""
    return [p for e in structure.effects for p in effect_parameters(e, setup, structure)]


def build_model(setup: ReplaySetup, structure: Structure, values: dict | None = None) -> EntryModel:
    """The current model with the effects of ``structure``.

    :param setup: the current model and declared facts.
    :param structure: the effects and their knots.
    :param values: parameter name -> value (float, array or CasADi symbol); parameters not given
        take their start values (the effect absent, or its known value). ``"j2"`` overrides
        the known J2 (only to check what value the record would prefer). A record effect
        (:data:`RECORD_EFFECTS`) changes how the record is replayed, not the model: it is not in it.
    """
    values = dict(values or {})
    for p in structure_parameters(setup, structure):
        values.setdefault(p.name, p.start)
    m = setup.model
    eff = structure.effects
    parts = {}
    if "j2_gravity" in eff:
        parts["gravity"] = J2Gravity(mu=m.planet.mu, j2=values.get("j2", EARTH_J2), radius=m.planet.radius)
    atm = m.atmosphere
    if "measured_density" in eff:
        if setup.measured_atmosphere is None:
            raise ValueError("measured_density needs a record with a density_kgpm3 column")
        atm = setup.measured_atmosphere
    if "density_profile" in eff:
        kn = structure.density_knots
        atm = DensityCorrection(atm, tuple(kn), tuple(values[_density_name(k)] for k in kn))
    if atm is not m.atmosphere:
        parts["atmosphere"] = atm
    veh = m.vehicle
    if {"lift_coefficient", "drag_coefficient", "mach_drag"} & set(eff):
        ref = setup.lift_reference
        if "mach_drag" in eff:
            kn = structure.mach_knots
            ref = MachDragCorrection(ref, tuple(kn), tuple(values[_mach_name(k)] for k in kn[:-1]) + (0.0,))
        aero = ScaledAerodynamics(
            ref,
            cl_scale=values.get("cl_scale", setup.start_lift_scale),
            cd_scale=values.get("cd_scale", 1.0),
        )
        veh = dataclasses.replace(veh, aerodynamics=aero)
    if "mass" in eff:
        veh = dataclasses.replace(veh, mass=setup.model.vehicle.mass * values["mass_scale"])
    if veh is not m.vehicle:
        parts["vehicle"] = veh
    if "wind" in eff:
        parts["wind"] = HorizontalWind(east=values["wind_east_mps"], north=values["wind_north_mps"])
    return m.replace(**parts)


def log_density_ratio(altitude: np.ndarray, density: np.ndarray, model: EntryModel) -> np.ndarray:
    """ln(rho_record / rho_model) at the record's altitudes."""
    return np.log(density / np.asarray(model.atmosphere.density(altitude, NUMPY), float))


def measured_density_correction(altitude: np.ndarray, density: np.ndarray, model: EntryModel,
                                n_knots: int = 6) -> DensityCorrection:  # fmt: skip
    """The :class:`DensityCorrection` of ``model``'s atmosphere that best matches measured densities.

    Linear least squares of ln(rho_record / rho_model) on the piecewise-linear
    (hat-function) basis of the correction, knots spread evenly over the
    measured altitudes (fewer if there are few measurements).

    :param altitude: altitudes of the measurements (m).
    :param density: measured densities (kg/m^3).
    :param model: the model whose atmosphere is corrected.
    :param n_knots: most knots.
    """
    lr = log_density_ratio(altitude, density, model)
    n = int(max(2, min(n_knots, len(altitude) // 4)))
    knots = tuple(float(k) for k in np.linspace(np.min(altitude), np.max(altitude), n))
    # hat function i: the correction with log factor 1 at knot i, 0 elsewhere
    hats = [piecewise_linear(altitude, knots, tuple(float(i == j) for j in range(n)), NUMPY)
            for i in range(n)]  # fmt: skip
    basis = np.stack(hats, axis=1)
    coef, *_ = np.linalg.lstsq(basis, lr, rcond=None)
    return DensityCorrection(model.atmosphere, knots, tuple(float(c) for c in coef))


__all__ = [
    "EARTH_J2",
    "EFFECT_NAMES",
    "KNOT_COUNTS",
    "MACH_KNOT_COUNTS",
    "MIN_KNOT_SPACING",
    "SAMPLES_PER_KNOT",
    "PHYSICAL_BOUNDS",
    "RECORD_EFFECTS",
    "TIME_OFFSET",
    "TIME_OFFSET_MAX_S",
    "Param",
    "Structure",
    "build_model",
    "density_knots",
    "effect_parameters",
    "knot_counts",
    "log_density_ratio",
    "mach_knot_counts",
    "mach_knots",
    "measured_density_correction",
    "structure_parameters",
]
