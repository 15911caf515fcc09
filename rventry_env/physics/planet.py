"""The central body: size, gravitational parameter and rotation (defaults of docs/conventions.md)."""

from __future__ import annotations

from dataclasses import dataclass

from rventry_env.physics.checks import check_number


@dataclass(frozen=True)
class Planet:
    """A spherical, uniformly rotating planet.

    :param radius: reference radius R_e (m); altitude is h = r - R_e.
    :param mu: gravitational parameter (m^3/s^2).
    :param omega: rotation rate about e3 (rad/s), constant (alpha_E = 0).
    :param g0: standard gravity, used only to express load factors in g (m/s^2).
    """

    radius: float = 6378137.0
    mu: float = 3.986004418e14
    omega: float = 7.292115e-5
    g0: float = 9.80665

    def __post_init__(self):
        check_number(self, "radius", low=1e3, high=1e9)  # an asteroid to beyond Jupiter
        check_number(self, "mu", low=0.0, low_open=True, high=1e21)  # the Sun's is 1.3e20
        check_number(self, "omega", low=-1e-2, high=1e-2)  # a day of ten minutes
        check_number(self, "g0", low=1e-3, high=1e3)


EARTH = Planet()
