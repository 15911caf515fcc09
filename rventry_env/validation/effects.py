"""Candidate effects: what the current model may lack, each expressed through the physics parts.

Every effect is a handful of named parameters and the rule that adds it to an
:class:`~rventry_env.physics.EntryModel`:

========================  ==============================  ===========================================
effect                    parameters                      physics part
========================  ==============================  ===========================================
``j2_gravity``            ``j2``                          :class:`~rventry_env.physics.J2Gravity`
``density_profile``       ``dlnrho_<h>km`` per knot       :class:`~rventry_env.physics.DensityCorrection`
``lift_coefficient``      ``cl_scale``                    :class:`~rventry_env.physics.ScaledAerodynamics`
``drag_coefficient``      ``cd_scale``                    :class:`~rventry_env.physics.ScaledAerodynamics`
``wind``                  ``wind_east_mps, wind_north_mps``  :class:`~rventry_env.physics.HorizontalWind`
========================  ==============================  ===========================================

``cl_scale`` multiplies the *declared* lift (the sidecar's aerodynamics): a
model started drag-only has cl_scale = 0, so "lift missing altogether" is the
same effect as "lift 20 % low", only further from the start.

Parameter values may be NumPy arrays (one per member of a batched replay): the
physics parts broadcast them against the batch of states.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rventry_env.physics import DensityCorrection, EntryModel, HorizontalWind, J2Gravity, ScaledAerodynamics
from rventry_env.validation.replay_setup import ReplaySetup

EFFECT_NAMES = ("j2_gravity", "density_profile", "lift_coefficient", "drag_coefficient", "wind")


@dataclass(frozen=True)
class Effect:
    """One candidate effect.

    :param name: one of :data:`EFFECT_NAMES`.
    :param param_names: its parameters.
    :param start: their values in the current model (the effect absent).
    :param scale: typical magnitude of a change (scaling and finite-difference steps).
    :param lower: lower bounds.
    :param upper: upper bounds.
    """

    name: str
    param_names: tuple
    start: tuple
    scale: tuple
    lower: tuple
    upper: tuple


KNOT_COUNTS = (2, 3, 4, 6, 8)
MIN_KNOT_SPACING = 2e3  # m: finer than this a density correction is not resolved by a trajectory


def density_knots(altitudes: np.ndarray, n_knots: int = 2) -> tuple:
    """``n_knots`` evenly spaced knots (m) over the altitudes a record visits.

    Two knots make a log-linear correction (density scale and scale height); more
    let it bend. The loop picks the number by BIC (see :func:`knot_counts`).
    """
    h = altitudes[np.isfinite(altitudes)]
    lo, hi = float(np.min(h)), float(np.max(h))
    if hi - lo < MIN_KNOT_SPACING:  # a level flight: spread the knots so they stay distinct
        mid = 0.5 * (lo + hi)
        lo, hi = mid - MIN_KNOT_SPACING / 2, mid + MIN_KNOT_SPACING / 2
    # rounded to 100 m so the parameter names stay readable
    return tuple(float(k) for k in np.round(np.linspace(lo, hi, n_knots), -2))


def knot_counts(altitudes: np.ndarray) -> tuple:
    """Knot counts worth trying: those of :data:`KNOT_COUNTS` not finer than :data:`MIN_KNOT_SPACING`."""
    h = altitudes[np.isfinite(altitudes)]
    span = float(np.max(h) - np.min(h))
    return tuple(n for n in KNOT_COUNTS if n == 2 or span / (n - 1) >= MIN_KNOT_SPACING)


def candidate_effects(setup: ReplaySetup, knots: tuple) -> dict[str, Effect]:
    """The five candidate effects for a record.

    :param setup: the current model and declared facts.
    :param knots: density-correction knots (m), from :func:`density_knots`.
    """
    nk = len(knots)
    return {
        "j2_gravity": Effect("j2_gravity", ("j2",), (0.0,), (1e-3,), (-0.05,), (0.05,)),
        "density_profile": Effect(
            "density_profile",
            tuple(f"dlnrho_{k / 1e3:.1f}km" for k in knots),
            (0.0,) * nk, (0.1,) * nk, (-3.0,) * nk, (3.0,) * nk,
        ),  # fmt: skip
        "lift_coefficient": Effect(
            "lift_coefficient", ("cl_scale",), (setup.start_lift_scale,), (0.1,), (-1.0,), (4.0,)
        ),
        "drag_coefficient": Effect("drag_coefficient", ("cd_scale",), (1.0,), (0.05,), (0.2,), (5.0,)),
        "wind": Effect(
            "wind", ("wind_east_mps", "wind_north_mps"), (0.0, 0.0), (10.0, 10.0), (-400.0,) * 2, (400.0,) * 2
        ),
    }


def build_model(setup: ReplaySetup, knots: tuple, values: dict) -> EntryModel:
    """The current model with every effect whose parameters appear in ``values``.

    :param setup: the current model and declared facts.
    :param knots: density-correction knots (m).
    :param values: parameter name -> value (float or per-member array).
    """
    m = setup.model
    parts = {}
    if "j2" in values:
        parts["gravity"] = J2Gravity(mu=m.planet.mu, j2=values["j2"], radius=m.planet.radius)
    dens = [k for k in values if k.startswith("dlnrho_")]
    if dens:
        parts["atmosphere"] = DensityCorrection(m.atmosphere, tuple(knots), tuple(values[k] for k in dens))
    if "cl_scale" in values or "cd_scale" in values:
        aero = ScaledAerodynamics(
            setup.lift_reference,
            cl_scale=values.get("cl_scale", setup.start_lift_scale),
            cd_scale=values.get("cd_scale", 1.0),
        )
        parts["vehicle"] = dataclasses.replace(m.vehicle, aerodynamics=aero)
    if "wind_east_mps" in values:
        parts["wind"] = HorizontalWind(east=values["wind_east_mps"], north=values["wind_north_mps"])
    return m.replace(**parts)


__all__ = [
    "EFFECT_NAMES",
    "KNOT_COUNTS",
    "Effect",
    "density_knots",
    "knot_counts",
    "candidate_effects",
    "build_model",
]
