"""The vehicle: mass, reference area and its aerodynamic coefficient model."""

from __future__ import annotations

from dataclasses import dataclass, field

from rventry_env.physics.aerodynamics import Aerodynamics, CAVHAerodynamics


@dataclass(frozen=True)
class Vehicle:
    """A point-mass vehicle.

    :param mass: mass (kg).
    :param reference_area: aerodynamic reference area S (m^2).
    :param aerodynamics: the (C_L, C_D) model.
    :param name: a label for reports.
    """

    mass: float = 907.2
    reference_area: float = 0.4839
    aerodynamics: Aerodynamics = field(default_factory=CAVHAerodynamics)
    name: str = "CAV-H"


def cav_h() -> Vehicle:
    """The CAV-H defaults of docs/conventions.md (907.2 kg, 0.4839 m^2, analytic aero fit)."""
    return Vehicle()
