"""Aerodynamic coefficient models: (C_L, C_D) from angle of attack (rad) and Mach number."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from rventry_env.physics.checks import check_number, check_numbers, check_part

# the largest coefficient, or coefficient scale, a part may have (any real one is a few units):
# far beyond any vehicle, and small enough that every force stays finite in float64
COEFFICIENT_MAX = 1e3


class Aerodynamics(Protocol):
    def coefficients(self, alpha, mach, ns) -> tuple:
        """(C_L, C_D) at angle of attack ``alpha`` (rad) and Mach number ``mach``."""
        ...


@dataclass(frozen=True)
class CAVHAerodynamics:
    """The CAV-H analytic fit (docs/conventions.md; Phillips 2003), with ``a`` in degrees.

    C_L = cl0 + cl_alpha a + cl_mach exp(-cl_decay M)
    C_D = cd0 + cd_alpha2 a^2 + cd_mach exp(-cd_decay M)
    """

    cl0: float = -0.2317
    cl_alpha: float = 0.0513
    cl_mach: float = 0.2945
    cl_decay: float = 0.1028
    cd0: float = 0.024
    cd_alpha2: float = 7.24e-4
    cd_mach: float = 0.406
    cd_decay: float = 0.323

    def __post_init__(self):
        check_numbers(self, ("cl0", "cl_alpha", "cl_mach", "cd0", "cd_alpha2", "cd_mach"), low=-COEFFICIENT_MAX,
                      high=COEFFICIENT_MAX)  # fmt: skip
        check_numbers(self, ("cl_decay", "cd_decay"), low=0.0, high=COEFFICIENT_MAX)  # exp(-decay M) stays <= 1

    def coefficients(self, alpha, mach, ns):
        a = alpha * (180.0 / math.pi)
        cl = self.cl0 + self.cl_alpha * a + self.cl_mach * ns.exp(-self.cl_decay * mach)
        cd = self.cd0 + self.cd_alpha2 * a * a + self.cd_mach * ns.exp(-self.cd_decay * mach)
        return cl, cd


@dataclass(frozen=True)
class ConstantAerodynamics:
    """Trimmed capsule: constant C_D and C_L = lift_to_drag * C_D, whatever alpha."""

    cd: float
    lift_to_drag: float = 0.0

    def __post_init__(self):
        check_number(self, "cd", low=0.0, high=COEFFICIENT_MAX)
        check_number(self, "lift_to_drag", low=-COEFFICIENT_MAX, high=COEFFICIENT_MAX)

    def coefficients(self, alpha, mach, ns):
        zero = 0 * alpha
        return self.lift_to_drag * self.cd + zero, self.cd + zero


@dataclass(frozen=True)
class ScaledAerodynamics:
    """Any coefficient model with C_L and C_D multiplied by scale factors.

    The scales may be per-vehicle arrays (dispersions in the vector environment)
    or fitted values (the ``lift_coefficient`` / ``drag_coefficient`` effects).
    """

    base: Aerodynamics
    cl_scale: object = 1.0
    cd_scale: object = 1.0

    def __post_init__(self):
        check_part(self, "base", "coefficients")
        check_number(self, "cl_scale", low=-COEFFICIENT_MAX, high=COEFFICIENT_MAX)
        check_number(self, "cd_scale", low=0.0, high=COEFFICIENT_MAX)

    def coefficients(self, alpha, mach, ns):
        cl, cd = self.base.coefficients(alpha, mach, ns)
        return self.cl_scale * cl, self.cd_scale * cd
