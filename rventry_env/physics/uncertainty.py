"""Truth-model parts for flight-grade uncertainty: altitude profiles of density and wind, and
aerodynamic errors that vary with Mach.

Each part holds its per-vehicle parameters as arrays with the vehicle on the first axis (a
batch of N vehicles flies N different profiles in one array operation; see
:func:`rventry_env.envs.propagation.take_model`), or as one row / plain numbers for one
vehicle. Profiles live on a uniform altitude grid (``start``, ``step``) and are interpolated
linearly by :func:`uniform_table`, which evaluates on Python floats (``MATH``), NumPy arrays
and JAX arrays (one row for all, or one row per vehicle) and CasADi symbols, so the single environment, the
vector environment and the collocation transcription share one profile part. On CasADi the
profile is a cubic B-spline interpolant through the same knots: the linear one has a kink at
every knot, and IPOPT's Newton steps stalled on them (the oracle's first draw ran out of
iterations); between knots the two differ by the profile's curvature, well below its rms.

Where these magnitudes come from and how they are drawn: docs/uncertainty.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics.aerodynamics import Aerodynamics
from rventry_env.physics.atmosphere import Atmosphere


def _check_grid(start, step, values, what: str) -> None:
    if not (math.isfinite(start) and math.isfinite(step) and step > 0):
        raise ValueError(f"{what}: the grid needs a finite start and a positive step, got {start!r}, {step!r}")
    v = np.asarray(values)
    if v.ndim not in (1, 2) or v.shape[-1] < 2:
        raise ValueError(f"{what}: a profile is (K,) or (N, K) values with K >= 2, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{what}: the profile contains NaN or inf")


def uniform_table(x, start: float, step: float, values, ns):
    """Linear interpolation of ``values`` on the grid ``start + k step``, constant beyond its ends
    (on CasADi symbols: a cubic B-spline through the same knots, see the module docstring).

    :param x: where to evaluate: a float (``ns`` MATH), an array (NUMPY) or a CasADi symbol.
    :param values: (K,) one profile, or (N, K) one per vehicle (NUMPY only; ``x`` then has
        shape (N,)).
    """
    k_max = np.shape(values)[-1] - 1
    if ns.symbolic:
        # held at the end values beyond the grid (a B-spline itself falls to zero out there)
        return _casadi_table(start, step, values)(ns.fmin(ns.fmax(x, start), start + step * k_max))
    if not ns.array:  # one float: the array path's arithmetic, operation for operation: the same bits
        u = min(max((x - start) * (1.0 / step), 0.0), float(k_max))
        i = min(int(u), k_max - 1)
        lo = float(values[i])
        return lo + (float(values[i + 1]) - lo) * (u - i)
    return table_gather(values, *table_index(x, start, step, k_max, ns), ns)


def table_index(x, start: float, step: float, k_max: int, ns=NUMPY):
    """(i, w): the grid interval of each ``x`` (array namespaces) and the weight of its upper end."""
    u = ns.fmin(ns.fmax((x - start) * (1.0 / step), 0.0), float(k_max))
    i = ns.fmin(ns.index(u), k_max - 1)
    return i, u - i


_ROW_OFFSETS: dict = {}


def table_gather(values, i, w, ns=NUMPY):
    """Linear interpolation in ``values`` (K,) or (N, K) at the intervals ``i`` with weights ``w``."""
    lo, hi = _gather_pair(values, i, ns)
    return lo + (hi - lo) * w


def _gather_pair(values, i, ns):
    """values[.., i] and values[.., i + 1]: one profile, or each vehicle's row of a table."""
    if not ns.concrete:  # traced
        if np.ndim(values) == 1:
            return values[i], values[i + 1]
        return ns.take_rows(values, i), ns.take_rows(values, i + 1)
    v = np.asarray(values)
    if v.ndim == 1:
        return v[i], v[i + 1]
    # a Fortran-ordered table keeps each altitude's values for all vehicles together: vehicles
    # flying at similar altitudes then read neighbouring memory (2-3x faster at N = 8192)
    n, k = v.shape
    fortran = v.flags.f_contiguous and not v.flags.c_contiguous
    key = (n, k, fortran)
    offsets = _ROW_OFFSETS.get(key)
    if offsets is None:
        offsets = _ROW_OFFSETS[key] = np.arange(n, dtype=np.intp) * (1 if fortran else k)
    flat = v.reshape(-1, order="F" if fortran else "C")
    base = i * n + offsets if fortran else offsets + i
    lo = np.take(flat, base)
    base += n if fortran else 1
    return lo, np.take(flat, base)


_CASADI_TABLES: dict = {}


def _casadi_table(start, step, values):
    v = np.asarray(values, dtype=float)
    if v.ndim != 1:
        raise ValueError(f"a CasADi profile is one vehicle's (K,) values, got shape {v.shape}")
    key = (float(start), float(step), v.tobytes())
    fn = _CASADI_TABLES.get(key)
    if fn is None:
        import casadi as ca

        grid = (start + step * np.arange(v.size)).tolist()
        # flat beyond the ends, like the NumPy and float paths: repeated end values
        grid = [grid[0] - 2 * step, grid[0] - step] + grid + [grid[-1] + step, grid[-1] + 2 * step]
        vals = [v[0], v[0]] + v.tolist() + [v[-1], v[-1]]
        fn = ca.interpolant(f"profile_{len(_CASADI_TABLES)}", "bspline", [grid], vals)
        if len(_CASADI_TABLES) > 256:
            _CASADI_TABLES.clear()
        _CASADI_TABLES[key] = fn
    return fn


@dataclass(frozen=True)
class ProfileAtmosphere:
    """Any atmosphere with its density multiplied by exp(c(h)), c a profile in altitude.

    c holds both a climatological departure from the base (NRLMSIS against the exponential
    model) and a Gauss-Markov perturbation; per vehicle when ``log_factors`` is (N, K).

    :param base: the atmosphere corrected (its speed of sound is kept).
    :param start: altitude of the first grid point (m). :param step: grid spacing (m).
    :param log_factors: ln(density / base density) at the grid points, (K,) or (N, K).
    """

    base: Atmosphere
    start: float = 0.0
    step: float = 1000.0
    log_factors: object = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self):
        _check_grid(self.start, self.step, self.log_factors, "ProfileAtmosphere")

    def density(self, h, ns):
        return self.base.density(h, ns) * ns.exp(uniform_table(h, self.start, self.step, self.log_factors, ns))

    def speed_of_sound(self, h, ns):
        return self.base.speed_of_sound(h, ns)


@dataclass(frozen=True)
class ProfileWind:
    """A horizontal wind whose east and north components (m/s) are profiles in altitude.

    Same A-component formula as :class:`~rventry_env.physics.wind.HorizontalWind`; undefined
    at the poles.
    """

    start: float = 0.0
    step: float = 1000.0
    east: object = field(default_factory=lambda: np.zeros(2))
    north: object = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self):
        _check_grid(self.start, self.step, self.east, "ProfileWind east")
        _check_grid(self.start, self.step, self.north, "ProfileWind north")
        if np.shape(self.east) != np.shape(self.north):
            raise ValueError(f"ProfileWind: east {np.shape(self.east)} and north {np.shape(self.north)} differ in shape")

    def velocity_a(self, h, e3_a, ns):
        _, c2, c3 = e3_a
        if getattr(ns, "array", False):  # one look-up of the interval serves both components
            at = table_index(h, self.start, self.step, np.shape(self.east)[-1] - 1, ns)
            east, north = table_gather(self.east, *at, ns), table_gather(self.north, *at, ns)
        else:
            east = uniform_table(h, self.start, self.step, self.east, ns)
            north = uniform_table(h, self.start, self.step, self.north, ns)
        cos_lat = ns.sqrt(c2 * c2 + c3 * c3)
        return 0.0 * h, (east * c3 + north * c2) / cos_lat, (north * c3 - east * c2) / cos_lat


def mach_legendre(mach, mach_low, mach_high, ns):
    """(P1(s), P2(s)) at s = (2 M - mach_low - mach_high) / (mach_high - mach_low), s held at
    +/-1 outside the range: the Mach shape of :class:`MachVaryingAerodynamics`' errors."""
    s = ns.fmin(ns.fmax((2.0 * mach - mach_low - mach_high) / (mach_high - mach_low), -1.0), 1.0)
    return s, 1.5 * s * s - 0.5


def mach_spread(rms: float, mach_from, mach_to, mach_low: float, mach_high: float, ns=NUMPY):
    """1-sigma spread of a relative error a1 P1 + a2 P2 in Mach (:func:`mach_legendre`; each coefficient
    of rms ``rms``) between two Mach numbers: rms |(dP1, dP2)|. What the error measured at
    ``mach_from`` tells of the error at ``mach_to``."""
    p1, p2 = mach_legendre(mach_to, mach_low, mach_high, ns)
    q1, q2 = mach_legendre(mach_from, mach_low, mach_high, ns)
    return rms * ns.sqrt((p1 - q1) ** 2 + (p2 - q2) ** 2)


@dataclass(frozen=True)
class MachVaryingAerodynamics:
    """C_L and C_D of ``base`` multiplied by 1 + a1 P1(s) + a2 P2(s), smooth in Mach.

    s = (2 M - mach_low - mach_high) / (mach_high - mach_low), held at +/-1 outside the
    range; P1 and P2 are the Legendre polynomials, so a1 tilts the error across the Mach range
    and a2 bends it, each with zero mean over the range. The coefficients are numbers or
    per-vehicle arrays (N,).
    """

    base: Aerodynamics
    lift_p1: object = 0.0
    lift_p2: object = 0.0
    drag_p1: object = 0.0
    drag_p2: object = 0.0
    mach_low: float = 3.0
    mach_high: float = 25.0

    def __post_init__(self):
        if not (math.isfinite(self.mach_low) and math.isfinite(self.mach_high) and self.mach_high > self.mach_low):
            raise ValueError(f"MachVaryingAerodynamics: need mach_low < mach_high, got {self.mach_low}, {self.mach_high}")
        for name in ("lift_p1", "lift_p2", "drag_p1", "drag_p2"):
            if not np.all(np.isfinite(np.asarray(getattr(self, name), dtype=float))):
                raise ValueError(f"MachVaryingAerodynamics: {name} contains NaN or inf")

    def coefficients(self, alpha, mach, ns):
        cl, cd = self.base.coefficients(alpha, mach, ns)
        s, p2 = mach_legendre(mach, self.mach_low, self.mach_high, ns)
        return cl * (1.0 + self.lift_p1 * s + self.lift_p2 * p2), cd * (1.0 + self.drag_p1 * s + self.drag_p2 * p2)


__all__ = ["uniform_table", "ProfileAtmosphere", "ProfileWind", "MachVaryingAerodynamics", "mach_legendre"]
