"""Gravity models.

A gravity model returns the gravitational acceleration in **A components** (a1
along r) from the radius and the spin axis e3 written in A, ``e3_a = C_AE(:, 3)``
(so ``e3_a[0]`` is the sine of the geocentric latitude). Component arithmetic
only, so a model serves NumPy and CasADi alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from rventry_env.physics.checks import check_number
from rventry_env.physics.planet import EARTH


class Gravity(Protocol):
    def acceleration_a(self, r, e3_a, ns) -> tuple:
        """Gravitational acceleration (m/s^2) in A components."""
        ...


@dataclass(frozen=True)
class PointMassGravity:
    """-mu / r^2 along a1 (Eq. ``Ex2-EOM-Ftot``)."""

    mu: float = EARTH.mu

    def __post_init__(self):
        check_number(self, "mu", low=0.0, high=1e21)

    def acceleration_a(self, r, e3_a, ns):
        return -self.mu / (r * r), 0.0, 0.0


@dataclass(frozen=True)
class J2Gravity:
    """Point mass plus the J2 zonal term of an oblate planet.

    g = -mu/r^2 a1 - 3/2 J2 mu R^2 / r^4 [(1 - 5 s^2) a1 + 2 s e3], s = sin(latitude).

    :param j2: second zonal harmonic (EGM-96 value for the Earth by default).
    :param radius: the harmonic's reference radius (m).
    """

    mu: float = EARTH.mu
    j2: float = 1.08262668e-3
    radius: float = EARTH.radius

    def __post_init__(self):
        check_number(self, "mu", low=0.0, high=1e21)
        check_number(self, "j2", low=-1.0, high=1.0)  # the Earth's is 1.1e-3, Jupiter's 1.5e-2
        check_number(self, "radius", low=1e3, high=1e9)

    def acceleration_a(self, r, e3_a, ns):
        s = e3_a[0]
        k = -1.5 * self.j2 * self.mu * self.radius**2 / (r * r * r * r)
        return (
            -self.mu / (r * r) + k * (1 - 5 * s * s) + k * 2 * s * s,
            k * 2 * s * e3_a[1],
            k * 2 * s * e3_a[2],
        )
