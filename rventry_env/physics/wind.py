"""Wind models: the velocity of the air relative to the rotating planet.

A wind model returns the wind in **A components** from altitude and the spin axis
in A (``e3_a = C_AE(:, 3)``). With e3_a = (sin lat, e3a2, e3a3), the local east is
(0, e3a3, -e3a2)/cos(lat) and north (0, e3a2, e3a3)/cos(lat) in A components.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from rventry_env.physics.checks import check_number

WIND_MAX_MPS = 1e4  # a wind faster than any vehicle it blows on, and far below overflow


class Wind(Protocol):
    def velocity_a(self, h, e3_a, ns) -> tuple:
        """Wind velocity relative to E (m/s), A components."""
        ...


@dataclass(frozen=True)
class HorizontalWind:
    """A uniform horizontal wind with east and north components (m/s).

    Undefined at the poles, where east and north are.
    """

    east: float = 0.0
    north: float = 0.0

    def __post_init__(self):
        check_number(self, "east", low=-WIND_MAX_MPS, high=WIND_MAX_MPS)
        check_number(self, "north", low=-WIND_MAX_MPS, high=WIND_MAX_MPS)

    def velocity_a(self, h, e3_a, ns):
        _, c2, c3 = e3_a
        cos_lat = ns.sqrt(c2 * c2 + c3 * c3)
        return 0.0 * h, (self.east * c3 + self.north * c2) / cos_lat, (self.north * c3 - self.east * c2) / cos_lat
