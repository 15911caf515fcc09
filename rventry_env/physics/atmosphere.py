"""Atmosphere models: density and speed of sound against altitude.

Every model is component arithmetic with the namespace ``ns`` supplying exp/log,
so it evaluates on NumPy arrays and CasADi symbols. Models compose: a
:class:`ScaledAtmosphere` or :class:`DensityCorrection` wraps any other model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, Sequence

import numpy as np

from rventry_env.physics.checks import check_number, check_part, check_sequence


class Atmosphere(Protocol):
    def density(self, h, ns):
        """Density (kg/m^3) at altitude h (m)."""
        ...

    def speed_of_sound(self, h, ns):
        """Speed of sound (m/s) at altitude h (m)."""
        ...


@dataclass(frozen=True)
class ExponentialAtmosphere:
    """rho = rho0 exp(-h / H_s) and a constant speed of sound (docs/conventions.md)."""

    rho0: float = 1.225
    scale_height: float = 7200.0
    sound_speed: float = 300.0

    def __post_init__(self):
        check_number(self, "rho0", low=0.0, high=1e3)  # Venus's surface: 65 kg/m^3
        check_number(self, "scale_height", low=1.0, high=1e6)
        check_number(self, "sound_speed", low=1.0, high=1e5)

    def density(self, h, ns):
        return self.rho0 * ns.exp(-h / self.scale_height)

    def speed_of_sound(self, h, ns):
        return self.sound_speed + 0 * h


@dataclass(frozen=True)
class ScaledAtmosphere:
    """Any atmosphere with its density multiplied by ``scale`` (scalar or per-vehicle array)."""

    base: Atmosphere
    scale: object = 1.0

    def __post_init__(self):
        check_part(self, "base", "density", "speed_of_sound")
        check_number(self, "scale", low=0.0, high=1e3)

    def density(self, h, ns):
        return self.scale * self.base.density(h, ns)

    def speed_of_sound(self, h, ns):
        return self.base.speed_of_sound(h, ns)


def piecewise_linear(h, knots: Sequence[float], values: Sequence[float], ns):
    """Continuous piecewise-linear function through (knots, values), constant outside.

    Written with hat functions built from fmin/fmax so it is plain component
    arithmetic (differentiable almost everywhere for CasADi).
    """
    knots = [float(k) for k in knots]
    if len(knots) != len(values) or len(knots) < 1:
        raise ValueError("knots and values must have the same, non-zero length")
    if any(b <= a for a, b in zip(knots, knots[1:])):
        raise ValueError("knots must be strictly increasing")
    out = values[0] + 0 * h
    for k in range(1, len(knots)):
        # ramp from 0 at knots[k-1] to 1 at knots[k]
        ramp = ns.fmin(ns.fmax((h - knots[k - 1]) / (knots[k] - knots[k - 1]), 0.0), 1.0)
        out = out + (values[k] - values[k - 1]) * ramp
    return out


@dataclass(frozen=True)
class DensityCorrection:
    """An altitude-dependent density error: rho = rho_base(h) exp(c(h)).

    c(h) is piecewise linear through ``log_factors`` at ``knots`` (m), constant
    beyond the end knots. This is the ``density_profile`` effect of the
    model-validation loop.
    """

    base: Atmosphere
    knots: tuple = (0.0, 40e3, 80e3, 120e3)
    log_factors: tuple = (0.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        check_part(self, "base", "density", "speed_of_sound")
        check_sequence(self, "knots")
        check_sequence(self, "log_factors")

    def density(self, h, ns):
        return self.base.density(h, ns) * ns.exp(piecewise_linear(h, self.knots, self.log_factors, ns))

    def speed_of_sound(self, h, ns):
        return self.base.speed_of_sound(h, ns)


@dataclass(frozen=True)
class TabulatedAtmosphere:
    """Density tabulated against altitude, interpolated linearly in log(density).

    Beyond the table the end segments' log-slopes extend the profile. Array namespaces
    only (NumPy, JAX: ``ns.interp``); use an analytic model for collocation. The table
    is held as two arrays (``_altitudes``, ``_log_rho``), which the JAX environment
    carries in its params.
    """

    TABLE_FIELDS = ("altitudes", "densities")  # held as the arrays below: data, not structure

    altitudes: tuple
    densities: tuple
    sound_speed: float = 300.0
    _altitudes: np.ndarray = field(init=False, repr=False, compare=False)
    _log_rho: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        h = np.asarray(self.altitudes, dtype=float)
        rho = np.asarray(self.densities, dtype=float)
        if h.ndim != 1 or h.shape != rho.shape or h.size < 2:
            raise ValueError("altitudes and densities must be 1-D of the same length >= 2")
        if np.any(np.diff(h) <= 0):
            raise ValueError("altitudes must be strictly increasing")
        if np.any(~np.isfinite(rho)) or np.any(rho <= 0):
            raise ValueError("densities must be positive and finite")
        check_number(self, "sound_speed", low=1.0, high=1e5)
        object.__setattr__(self, "_altitudes", h)
        object.__setattr__(self, "_log_rho", np.log(rho))

    def density(self, h, ns):
        if not getattr(ns, "array", False):
            raise TypeError("TabulatedAtmosphere evaluates on NumPy or JAX arrays only")
        hs, lr = self._altitudes, self._log_rho
        out = ns.interp(h, hs, lr)
        lo_slope = (lr[1] - lr[0]) / (hs[1] - hs[0])
        hi_slope = (lr[-1] - lr[-2]) / (hs[-1] - hs[-2])
        out = ns.where(h < hs[0], lr[0] + lo_slope * (h - hs[0]), out)
        out = ns.where(h > hs[-1], lr[-1] + hi_slope * (h - hs[-1]), out)
        return ns.exp(out)

    def speed_of_sound(self, h, ns):
        return self.sound_speed + 0 * h
