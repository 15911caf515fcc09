"""A Mach-dependent drag correction: any coefficient model with C_D multiplied by a factor of Mach.

A trimmed capsule's drag coefficient is often known at one Mach number only (Apollo's C_D of
1.2891 is the trim value for M > 29.5), and a lifting body's fit may be off in part of its Mach
range. This part corrects C_D by exp(c(M)), c piecewise linear in the Mach number through
``log_factors`` at ``mach_knots`` and constant beyond the end knots; C_L is left as it is.
It is the ``mach_drag`` candidate of the model-validation loop.

Plain component arithmetic (:func:`~rventry_env.physics.atmosphere.piecewise_linear`), so it
evaluates on NumPy arrays and CasADi symbols like every other part.
"""

from __future__ import annotations

from dataclasses import dataclass

from rventry_env.physics.aerodynamics import Aerodynamics
from rventry_env.physics.atmosphere import piecewise_linear
from rventry_env.physics.checks import check_part, check_sequence


@dataclass(frozen=True)
class MachDragCorrection:
    """C_D of ``base`` multiplied by exp(c(M)), c piecewise linear in Mach; C_L unchanged.

    :param base: the coefficient model corrected.
    :param mach_knots: Mach numbers of the knots, strictly increasing.
    :param log_factors: ln(C_D factor) at each knot.
    """

    base: Aerodynamics
    mach_knots: tuple = (5.0, 30.0)
    log_factors: tuple = (0.0, 0.0)

    def __post_init__(self):
        check_part(self, "base", "coefficients")
        check_sequence(self, "mach_knots")
        check_sequence(self, "log_factors")

    def coefficients(self, alpha, mach, ns):
        cl, cd = self.base.coefficients(alpha, mach, ns)
        return cl, cd * ns.exp(piecewise_linear(mach, self.mach_knots, self.log_factors, ns))


__all__ = ["MachDragCorrection"]
