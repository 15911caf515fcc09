"""Force-model parts (gravity, atmosphere, aerodynamics, vehicle, wind) and entry dynamics.

Pure numerics: nothing here knows about Gymnasium, CasADi problem set-up or I/O.
"""

from rventry_env.physics.aerodynamics import CAVHAerodynamics, ConstantAerodynamics, ScaledAerodynamics
from rventry_env.physics.atmosphere import (
    DensityCorrection,
    ExponentialAtmosphere,
    ScaledAtmosphere,
    TabulatedAtmosphere,
)
from rventry_env.physics.entry import CONTROL_NAMES, ENTRY_STATE_NAMES, IDX, N_STATE, EntryForces, entry_forces, entry_rhs
from rventry_env.physics.gravity import J2Gravity, PointMassGravity
from rventry_env.physics.mach_drag import MachDragCorrection
from rventry_env.physics.model import EntryModel, scaled_model, with_aero_scales
from rventry_env.physics.planet import EARTH, Planet
from rventry_env.physics.vehicle import Vehicle, cav_h
from rventry_env.physics.wind import HorizontalWind

__all__ = [
    "CAVHAerodynamics",
    "ConstantAerodynamics",
    "ScaledAerodynamics",
    "DensityCorrection",
    "ExponentialAtmosphere",
    "ScaledAtmosphere",
    "TabulatedAtmosphere",
    "CONTROL_NAMES",
    "ENTRY_STATE_NAMES",
    "IDX",
    "N_STATE",
    "EntryForces",
    "entry_forces",
    "entry_rhs",
    "J2Gravity",
    "PointMassGravity",
    "EntryModel",
    "MachDragCorrection",
    "scaled_model",
    "with_aero_scales",
    "EARTH",
    "Planet",
    "Vehicle",
    "cav_h",
    "HorizontalWind",
]
