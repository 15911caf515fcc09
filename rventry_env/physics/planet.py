"""The central body: size, gravitational parameter and rotation (defaults of docs/conventions.md)."""

from __future__ import annotations

from dataclasses import dataclass

from rventry_env.physics.checks import check_number, check_numbers


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
        check_numbers(self, ("radius", "mu", "g0"), low=0.0, low_open=True)
        check_number(self, "omega")


EARTH = Planet()
