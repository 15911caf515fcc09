"""The vehicle: mass, reference area and its aerodynamic coefficient model."""

from __future__ import annotations

from dataclasses import dataclass, field

from rventry_env.physics.aerodynamics import Aerodynamics, CAVHAerodynamics
from rventry_env.physics.checks import check_number, check_part

# the masses and areas a vehicle may have: a gram to a million tonnes, a square millimetre to a
# square kilometre. Wide enough for any vehicle, narrow enough that every force and acceleration
# stays finite in float64 (a mass of 1e-300 kg gives an infinite acceleration, then NaN)
MASS_RANGE_KG = (1e-3, 1e9)
AREA_RANGE_M2 = (1e-6, 1e6)


@dataclass(frozen=True)
class Vehicle:
    """A point-mass vehicle.

    :param mass: mass (kg), within :data:`MASS_RANGE_KG`.
    :param reference_area: aerodynamic reference area S (m^2), within :data:`AREA_RANGE_M2`.
    :param aerodynamics: the (C_L, C_D) model.
    :param name: a label for reports.
    """

    mass: float = 907.2
    reference_area: float = 0.4839
    aerodynamics: Aerodynamics = field(default_factory=CAVHAerodynamics)
    name: str = "CAV-H"

    def __post_init__(self):
        check_number(self, "mass", low=MASS_RANGE_KG[0], high=MASS_RANGE_KG[1])
        check_number(self, "reference_area", low=AREA_RANGE_M2[0], high=AREA_RANGE_M2[1])
        check_part(self, "aerodynamics", "coefficients")
        if not isinstance(self.name, str):
            raise ValueError(f"Vehicle.name must be a string, got {self.name!r}")


def cav_h() -> Vehicle:
    """The CAV-H defaults of docs/conventions.md (907.2 kg, 0.4839 m^2, analytic aero fit)."""
    return Vehicle()
