"""Where the target lies from the vehicle, and the vehicle's energy: plain arithmetic on components.

Written once for floats, NumPy arrays, JAX values and CasADi symbols (the ``ns`` argument gives
the few functions that differ), and used by the observation, the episode's outcome and the
shaping potentials alike.
"""

from __future__ import annotations


def target_in_a(c_ae, target_e) -> tuple:
    """The target's unit vector (E components) in A components: C_AE target."""
    return tuple(c_ae[i][0] * target_e[0] + c_ae[i][1] * target_e[1] + c_ae[i][2] * target_e[2] for i in range(3))


def surface_angle(ta, ns):
    """The angle at the planet's centre between the vehicle (a1) and the target, from ``ta`` =
    :func:`target_in_a` (rad; times the radius, the great-circle distance along the surface)."""
    return ns.arctan2(ns.sqrt(ta[1] * ta[1] + ta[2] * ta[2]), ta[0])


def specific_energy(x, mu: float, radius: float):
    """Specific mechanical energy relative to standing on the surface, v^2/2 + mu/R - mu/r (J/kg),
    of the state components ``x`` (Earth-relative speed x[5], radius x[0])."""
    return 0.5 * x[5] * x[5] + mu / radius - mu / x[0]


__all__ = ["target_in_a", "surface_angle", "specific_energy"]
