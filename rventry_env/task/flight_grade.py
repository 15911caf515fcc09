"""Flight-grade errors: what a flight Monte Carlo draws beyond constant scale factors.

:class:`FlightGradeErrors` describes the magnitudes; :func:`draw_flight_grade` draws one vehicle's
errors from its episode generator (``np_random``), always the same count of numbers for one
description, so the single and the vector environment stay in step draw for draw.

* **Atmosphere**: the departure of one NRLMSIS 2.1 atmosphere (``pymsis``; day of year, local
  time, F10.7, F10.7a and Ap drawn and always passed explicitly, so ``pymsis`` never looks them
  up or downloads them) from the climatological mean along the nominal ground track, tabulated
  on the altitude grid, times a first-order Gauss-Markov perturbation in altitude with an rms
  and a correlation length per altitude band (the small-scale perturbation model of Earth-GRAM,
  reduced to its vertical structure). Both multiply the model's own density: the paper's
  exponential atmosphere stands for the mean atmosphere a mission's guidance is built on.
* **Wind**: per horizontal component, a constant mean plus a Gauss-Markov profile in altitude.
* **Aerodynamics**: relative C_L and C_D errors smooth in Mach (Legendre P1 and P2 terms;
  :class:`~rventry_env.physics.uncertainty.MachVaryingAerodynamics`).
* **Sensors and navigation**: accelerometer bias, scale factor, misalignment and white noise,
  and the navigation error at the entry fix, which then grows like an inertial system's
  (:mod:`rventry_env.physics.sensors`).

Magnitudes and their sources: docs/uncertainty.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields

import numpy as np

# the altitude grid every profile lives on: 0 to 100 km every 1 km
GRID_START_M = 0.0
GRID_STEP_M = 1000.0
GRID_POINTS = 101
GRID_M = GRID_START_M + GRID_STEP_M * np.arange(GRID_POINTS)

# the ranges the climatology's drivers are drawn from (docs/uncertainty.md)
F107_RANGE = (70.0, 230.0)  # sfu: solar minimum to maximum, 81-day mean
AP_MEDIAN, AP_LOG_SIGMA, AP_MAX = 8.0, 0.8, 400.0
MSIS_YEAR = np.datetime64("2001-01-01T00:00")  # a non-leap year; NRLMSIS 2.1 has no trend below 100 km


def parse_bands(value, what: str) -> tuple:
    """Bands ((top altitude m, rms, correlation length m), ...) with increasing tops."""
    try:
        bands = tuple(tuple(float(c) for c in b) for b in value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be bands (top altitude m, rms, correlation length m), got {value!r}") from None
    tops = [b[0] for b in bands]
    for b in bands:
        if len(b) != 3 or not all(math.isfinite(c) for c in b) or b[1] < 0 or b[2] <= 0:
            raise ValueError(f"{what}: each band is (top altitude m, rms >= 0, correlation length m > 0), got {b}")
    if any(b <= a for a, b in zip(tops, tops[1:])):
        raise ValueError(f"{what}: band tops must increase, got {tops}")
    return bands


# the fields of FlightGradeErrors that make the vehicle's sensors and navigation err (the rest is the truth's)
SENSING_FIELDS = ("accel_bias_mps2", "accel_scale", "accel_misalignment_rad", "accel_noise_mps2", "nav_position_m",
                  "nav_velocity_mps")  # fmt: skip


@dataclass(frozen=True)
class FlightGradeErrors:
    """Magnitudes (1 sigma) of the flight-grade errors; every default is zero (off).

    :param climatology: fly an NRLMSIS 2.1 atmosphere drawn per episode instead of the
        nominal exponential one.
    :param density_bands: Gauss-Markov ln-density perturbation: bands (top altitude m,
        rms, correlation length m) from the ground up; above the last top, the last band.
    :param wind_mean_mps: rms of the constant part of each horizontal wind component.
    :param wind_bands: Gauss-Markov part of each horizontal wind component, bands as above
        (rms in m/s).
    :param lift_mach, drag_mach: rms of the P1 and P2 coefficients of the relative C_L and
        C_D errors across the Mach range (each coefficient drawn with this rms).
    :param accel_bias_mps2: accelerometer bias, per axis. :param accel_scale: scale-factor
        error, per axis (relative). :param accel_misalignment_rad: misalignment, small
        rotation per axis. :param accel_noise_mps2: white noise of one sample (one control step).
    :param nav_position_m, nav_velocity_mps: navigation error at the entry fix, per axis.
    """

    climatology: bool = False
    density_bands: tuple = ()
    wind_mean_mps: float = 0.0
    wind_bands: tuple = ()
    lift_mach: float = 0.0
    drag_mach: float = 0.0
    accel_bias_mps2: float = 0.0
    accel_scale: float = 0.0
    accel_misalignment_rad: float = 0.0
    accel_noise_mps2: float = 0.0
    nav_position_m: float = 0.0
    nav_velocity_mps: float = 0.0

    def __post_init__(self):
        if not isinstance(self.climatology, bool):
            raise ValueError(f"flight climatology must be True or False, got {self.climatology!r}")
        object.__setattr__(self, "density_bands", parse_bands(self.density_bands, "flight density_bands"))
        object.__setattr__(self, "wind_bands", parse_bands(self.wind_bands, "flight wind_bands"))
        for f in fields(self):
            if f.name in ("climatology", "density_bands", "wind_bands"):
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"flight {f.name} must be a finite rms >= 0, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        for name in ("lift_mach", "drag_mach", "accel_scale"):
            if getattr(self, name) >= 0.25:
                raise ValueError(f"flight {name} = {getattr(self, name):g} is relative and must stay below 0.25")

    @classmethod
    def parse(cls, value) -> "FlightGradeErrors | None":
        if value is None or isinstance(value, FlightGradeErrors):
            return value
        if isinstance(value, dict):
            unknown = set(value) - {f.name for f in fields(cls)}
            if unknown:
                raise ValueError(f"unknown flight error field(s) {sorted(unknown)}; known: {[f.name for f in fields(cls)]}")
            return cls(**value)
        raise ValueError(f"flight errors must be a FlightGradeErrors or a dict of its fields, got {value!r}")

    @property
    def is_zero(self) -> bool:
        return not self.climatology and not self.has_density and not self.has_wind and not self.has_aero and not self.has_sensing

    @property
    def has_density(self) -> bool:
        return self.climatology or any(b[1] > 0 for b in self.density_bands)

    @property
    def has_wind(self) -> bool:
        return self.wind_mean_mps > 0 or any(b[1] > 0 for b in self.wind_bands)

    @property
    def has_aero(self) -> bool:
        return self.lift_mach > 0 or self.drag_mach > 0

    @property
    def has_sensing(self) -> bool:
        return any(getattr(self, n) > 0 for n in SENSING_FIELDS)

    def describe(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def band_profile(bands: tuple, grid: np.ndarray = GRID_M) -> tuple[np.ndarray, np.ndarray]:
    """(rms, correlation length) at each grid altitude: the band whose top is the first at or
    above it (the last band above every top)."""
    tops = np.array([b[0] for b in bands])
    k = np.minimum(np.searchsorted(tops, grid, side="left"), len(bands) - 1)
    rms, corr = np.array([b[1] for b in bands]), np.array([b[2] for b in bands])
    return rms[k], corr[k]  # a number's band is a 0-d array


def band_spread(bands: tuple, h_from, h_to) -> np.ndarray:
    """1-sigma spread of a Gauss-Markov process in altitude (``bands``: rms and correlation length
    per band, at ``h_to``'s band) between two altitudes: s sqrt(2 (1 - exp(-|h_to - h_from| / L))),
    the standard deviation of the difference of its values there. What a value measured at
    ``h_from`` tells of the value at ``h_to``: zero spread where it was measured, the process's
    whole sqrt(2) s far away (conservative: the conditional spread is s sqrt(1 - exp(-2|dh|/L)))."""
    h_to = np.asarray(h_to, dtype=float)
    rms, corr = band_profile(bands, h_to)
    return rms * np.sqrt(2.0 * (1.0 - np.exp(-np.abs(h_to - np.asarray(h_from, dtype=float)) / corr)))


def gauss_markov(eps: np.ndarray, bands: tuple, grid: np.ndarray = GRID_M) -> np.ndarray:
    """A first-order Gauss-Markov profile on ``grid`` from standard normals ``eps`` (same length).

    z_0 = eps_0, z_k = phi_k z_(k-1) + sqrt(1 - phi_k^2) eps_k with phi_k = exp(-dh / L_k):
    unit variance at every altitude and correlation exp(-|dh| / L) within a band; the profile
    is rms(h) z. Zero where there are no bands. (The recursion is linear in eps: one product
    with a lower-triangular matrix, formed once per band set.)
    """
    if not bands:
        return np.zeros_like(grid, dtype=float)
    return _gauss_markov_matrix(bands, grid.tobytes()) @ eps


@functools.lru_cache(maxsize=32)
def _gauss_markov_matrix(bands: tuple, grid_bytes: bytes) -> np.ndarray:
    grid = np.frombuffer(grid_bytes, dtype=float)
    rms, corr = band_profile(bands, grid)
    phi = np.exp(-np.diff(grid) / corr[1:])
    k = grid.size
    m = np.zeros((k, k))
    m[0, 0] = 1.0
    for i in range(1, k):
        m[i] = phi[i - 1] * m[i - 1]
        m[i, i] = math.sqrt(1.0 - phi[i - 1] ** 2)
    m = rms[:, None] * m
    m.flags.writeable = False
    return m


def ground_track_longitude_deg(problem, grid: np.ndarray = GRID_M) -> np.ndarray:
    """Where the nominal flight is at each grid altitude: longitude (deg) on the equatorial track,
    linear from the entry point at the initial altitude to the target at the surface."""
    frac = np.clip(1.0 - grid / problem.initial_altitude, 0.0, 1.0)
    lon0 = math.degrees(problem.initial_longitude) if hasattr(problem, "initial_longitude") else 0.0
    return lon0 + frac * (math.degrees(problem.target_longitude) - lon0)


def msis_log_density(day_of_year, local_time_h, f107, f107a, ap, problem, grid: np.ndarray = GRID_M) -> np.ndarray:
    """ln(NRLMSIS 2.1 total mass density, kg/m^3) on ``grid`` along the nominal ground track.

    NRLMSIS is evaluated on the whole grid at the entry longitude and at the target's (one
    column each: it reuses its horizontal terms down a column, 40x faster than a different
    longitude per altitude), and the two are blended by where the nominal flight is at each
    altitude (:func:`ground_track_longitude_deg`). The space-weather indices are always given,
    so ``pymsis`` never reads or downloads its index files.
    """
    from pymsis import msis

    lon = ground_track_longitude_deg(problem, grid)
    lon_entry, lon_target = float(lon[-1]), math.degrees(problem.target_longitude)
    lat = math.degrees(problem.target_latitude)
    # universal time from the local solar time at the entry longitude
    ut_h = (local_time_h - lon_entry / 15.0) % 24.0
    minutes = int(round((day_of_year - 1.0) * 1440.0 + ut_h * 60.0))
    date = MSIS_YEAR + np.timedelta64(minutes, "m")
    out = msis.calculate(
        [date], [lon_entry, lon_target], [lat], grid / 1000.0,
        f107s=[f107], f107as=[f107a], aps=[[ap] * 7], version=2.1,
    )  # fmt: skip
    rho = np.asarray(out)[..., 0].reshape(2, grid.size)
    if not np.all(np.isfinite(rho) & (rho > 0)):
        raise ValueError(f"NRLMSIS returned a non-positive or non-finite density for day {day_of_year}, F10.7 {f107}")
    span = lon_target - lon_entry
    w = (lon - lon_entry) / span if span else np.zeros_like(grid)
    return (1.0 - w) * np.log(rho[0]) + w * np.log(rho[1])


# the climatological mean: day of year and local time on a uniform grid (the drivers' draw is
# uniform in both), the solar and geomagnetic indices at the middle of their drawn ranges
MEAN_DAYS, MEAN_HOURS = 24, 8


def msis_mean_log_density(problem, grid: np.ndarray = GRID_M) -> np.ndarray:
    """ln of the climatological mean NRLMSIS 2.1 density on ``grid`` along the nominal track.

    The mean of ln rho over the drawn day of year and local time (a 24 x 8 grid: both are drawn
    uniform), at F10.7 = F10.7a = the middle of their range and Ap = its median (below 100 km
    the indices barely matter). This is the atmosphere a mission's guidance is built on; a draw
    departs from it by ln rho_draw - ln rho_mean (docs/uncertainty.md). Cached per problem.
    """
    return _msis_mean(problem, grid.tobytes())


@functools.lru_cache(maxsize=8)
def _msis_mean(problem, grid_bytes: bytes) -> np.ndarray:
    grid = np.frombuffer(grid_bytes, dtype=float)
    f107 = 0.5 * (F107_RANGE[0] + F107_RANGE[1])
    rows = [msis_log_density(1.0 + 365.0 * (i + 0.5) / MEAN_DAYS, 24.0 * (j + 0.5) / MEAN_HOURS, f107, f107,
                             AP_MEDIAN, problem, grid)
            for i in range(MEAN_DAYS) for j in range(MEAN_HOURS)]  # fmt: skip
    mean = np.mean(rows, axis=0)
    mean.flags.writeable = False
    return mean


# how many standard normals / uniforms one vehicle's flight-grade draw takes (fixed per description)
def draw_flight_grade(rng: np.random.Generator, errors: FlightGradeErrors, problem) -> dict:
    """One vehicle's flight-grade errors, drawn from ``rng`` in a fixed order and count.

    Returns a dict of NumPy values: ``climate`` (day of year, local time h, F10.7, F10.7a, Ap)
    and ``log_density_climate`` (K,), the draw's NRLMSIS ln density less the climatological
    mean (:func:`msis_mean_log_density`), when the climatology is on; ``density_perturbation`` (K,)
    (ln density); ``wind_east``/``wind_north`` (K,) m/s; ``aero`` (lift P1, lift P2, drag P1,
    drag P2); ``accel_bias`` (3,), ``accel_scale`` (3,), ``accel_misalignment`` (3,);
    ``noise_key`` (uint64); ``nav_position`` (3,) and ``nav_velocity`` (3,) in E components.
    """
    out: dict = {}
    k = GRID_POINTS
    if errors.climatology:
        u = rng.uniform(size=4)
        n_ap, n_f = rng.standard_normal(2)
        doy = 1.0 + 365.0 * u[0]
        lt = 24.0 * u[1]
        f107a = F107_RANGE[0] + (F107_RANGE[1] - F107_RANGE[0]) * u[2]
        f107 = max(60.0, f107a * (1.0 + 0.1 * n_f))
        ap = min(AP_MAX, AP_MEDIAN * math.exp(AP_LOG_SIGMA * n_ap))
        out["climate"] = np.array([doy, lt, f107, f107a, ap])
        out["log_density_climate"] = msis_log_density(doy, lt, f107, f107a, ap, problem) - msis_mean_log_density(problem)
    out["density_perturbation"] = gauss_markov(rng.standard_normal(k), errors.density_bands)
    mean = rng.standard_normal(2) * errors.wind_mean_mps
    out["wind_east"] = mean[0] + gauss_markov(rng.standard_normal(k), errors.wind_bands)
    out["wind_north"] = mean[1] + gauss_markov(rng.standard_normal(k), errors.wind_bands)
    a = rng.standard_normal(4)
    out["aero"] = np.array([a[0] * errors.lift_mach, a[1] * errors.lift_mach, a[2] * errors.drag_mach, a[3] * errors.drag_mach])
    s = rng.standard_normal(9)
    out["accel_bias"] = s[0:3] * errors.accel_bias_mps2
    out["accel_scale"] = s[3:6] * errors.accel_scale
    out["accel_misalignment"] = s[6:9] * errors.accel_misalignment_rad
    out["noise_key"] = rng.integers(0, 2**63, dtype=np.uint64)
    nav = rng.standard_normal(6)
    out["nav_position"] = nav[:3] * errors.nav_position_m
    out["nav_velocity"] = nav[3:] * errors.nav_velocity_mps
    return out


__all__ = [
    "SENSING_FIELDS",
    "GRID_START_M",
    "GRID_STEP_M",
    "GRID_POINTS",
    "GRID_M",
    "FlightGradeErrors",
    "parse_bands",
    "band_profile",
    "gauss_markov",
    "ground_track_longitude_deg",
    "msis_log_density",
    "msis_mean_log_density",
    "draw_flight_grade",
]
