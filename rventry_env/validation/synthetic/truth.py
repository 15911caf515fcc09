"""An independent truth model for synthetic flight records: Newton's law in ECEF Cartesian form.

This module is the one deliberate second copy of the entry physics in rventry. It
exists as a **test oracle** for the model-validation loop, so it must not share
the identification's assumptions or code:

* the state is the ECEF position and Earth-relative velocity ``(r_E, v_E)``, not
  the rv-Euler parameters, and the rotating-frame terms are written as vector
  cross products (-2 w x v - w x (w x r)) rather than the paper's apparent force;
* every force (point-mass + J2 gravity in Cartesian form, exponential density,
  the CAV-H coefficient fit, lift direction from the conventional bank angle,
  wind) is evaluated here from the formulas of docs/conventions.md, with nothing imported from
  :mod:`rventry_env.physics` or :mod:`rventry_env.core`;
* it is integrated by SciPy's adaptive DOP853 with tight tolerances, not by the
  project's fixed-step RK4;
* its density error (the ``density_profile`` effect) is a smooth sinusoid in log
  density, a shape the identification's piecewise-linear correction can only
  approximate.

Shared with the identification is only what a flight record *means*: the
conventional bank angle mu (0 = lift up, positive toward b1 x up, measured about
the Earth-relative velocity) and that lift is normal to the air-relative velocity
(docs/conventions.md). ``tests/validation/test_validation_truth.py`` cross-checks this model against
the rv-Euler entry dynamics without effects, and each effect against its
force-model part.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# default J2 of the Earth (EGM-96), the magnitude of the ``j2_gravity`` effect
EARTH_J2 = 1.08262668e-3


@dataclass(frozen=True)
class TruthWorld:
    """Planet, atmosphere, vehicle and the effects a synthetic flight contains.

    :param radius: planet radius (m); altitude is |r| - radius.
    :param mu: gravitational parameter (m^3/s^2).
    :param omega: rotation rate about e3 (rad/s).
    :param j2: second zonal harmonic (0 = point mass; the ``j2_gravity`` effect).
    :param rho0: sea-level density of the exponential atmosphere (kg/m^3).
    :param scale_height: its scale height (m).
    :param sound_speed: constant speed of sound for the Mach number (m/s).
    :param density_amplitude: the ``density_profile`` effect: ln(rho_true / rho_exp) =
        A sin(2 pi (h - density_phase_altitude) / density_wavelength).
    :param density_wavelength: wavelength of that profile in altitude (m).
    :param density_phase_altitude: its zero crossing (m).
    :param cl_scale: the ``lift_coefficient`` effect (C_L multiplied by this).
    :param cd_scale: the ``drag_coefficient`` effect (C_D multiplied by this).
    :param wind_east: the ``wind`` effect, eastward air velocity (m/s).
    :param wind_north: northward air velocity (m/s).
    :param mass: vehicle mass (kg), CAV-H by default; a value other than the declared
        907.2 kg is the ``mass`` effect.
    :param area: reference area (m^2).
    :param atmosphere: ``"exponential"`` (rho0, scale_height) or ``"us76"`` (the U.S. Standard
        Atmosphere 1976, :func:`us76_density`).
    :param mach_drag_amplitude: a Mach-dependent drag: C_D multiplied by
        exp(A (1 - exp((M - mach_drag_centre) / mach_drag_width))), 1 at the centre and
        growing (for A > 0) toward lower Mach.
    :param mach_drag_centre: the Mach number where that factor is 1.
    :param mach_drag_width: its e-folding width in Mach.
    :param band_channel: ``"lift"`` or ``"drag"``: that coefficient multiplied by ``band_scale``
        between the altitudes ``band_low`` and ``band_high`` (m), with 1 km tanh edges (an
        effect outside the candidate set).
    :param mach_lift_scale: C_L multiplied by this below Mach ``mach_lift_below`` (1-Mach tanh edge).
    :param wind_shear: an eastward wind ``wind_shear`` tanh((h - shear_altitude) / shear_width)
        (m/s): it reverses at ``shear_altitude``.
    :param side_force: a force out of the vertical plane, this fraction of the drag, toward the
        right of the velocity (v x up).
    :param mass_loss: a mass that falls with time (ablation, a jettison): the fraction of the mass
        lost, linearly from ``mass_loss_start`` to ``mass_loss_end`` (s), constant outside.
    """

    radius: float = 6378137.0
    mu: float = 3.986004418e14
    omega: float = 7.292115e-5
    j2: float = 0.0
    rho0: float = 1.225
    scale_height: float = 7200.0
    sound_speed: float = 300.0
    density_amplitude: float = 0.0
    density_wavelength: float = 80e3
    density_phase_altitude: float = 30e3
    cl_scale: float = 1.0
    cd_scale: float = 1.0
    wind_east: float = 0.0
    wind_north: float = 0.0
    mass: float = 907.2
    area: float = 0.4839
    atmosphere: str = "exponential"
    mach_drag_amplitude: float = 0.0
    mach_drag_centre: float = 22.0
    mach_drag_width: float = 5.0
    band_channel: str = ""
    band_scale: float = 1.0
    band_low: float = 0.0
    band_high: float = 0.0
    mach_lift_scale: float = 1.0
    mach_lift_below: float = 0.0
    wind_shear: float = 0.0
    shear_altitude: float = 54e3
    shear_width: float = 2e3
    side_force: float = 0.0
    mass_loss: float = 0.0
    mass_loss_start: float = 0.0
    mass_loss_end: float = 0.0


# U.S. Standard Atmosphere 1976 below 86 km: layers in geopotential altitude (m') with their
# base temperature gradients (K/m'); sea-level temperature and pressure; gas constants
_US76_LAYERS = ((0.0, -6.5e-3), (11e3, 0.0), (20e3, 1.0e-3), (32e3, 2.8e-3), (47e3, 0.0), (51e3, -2.8e-3),
                (71e3, -2.0e-3), (84852.0, None))  # fmt: skip
_US76_T0, _US76_P0 = 288.15, 101325.0
_US76_R, _US76_M0, _US76_G0, _US76_R0 = 8.31432, 28.9644e-3, 9.80665, 6356766.0
# above 86 km: the standard's tabulated densities (kg/m^3), interpolated in log density
_US76_HIGH = ((86e3, None), (90e3, 3.416e-6), (95e3, 1.393e-6), (100e3, 5.604e-7), (110e3, 9.708e-8),
              (120e3, 2.222e-8), (130e3, 8.152e-9), (150e3, 2.076e-9), (200e3, 2.541e-10),
              (300e3, 1.916e-11), (500e3, 5.215e-13), (1000e3, 3.561e-15))  # fmt: skip


def _us76_low(z: float) -> float:
    """Density below 86 km from the hydrostatic layers (molecular-scale temperature)."""
    h = _US76_R0 * z / (_US76_R0 + z)  # geopotential altitude
    k = _US76_G0 * _US76_M0 / _US76_R
    t, p = _US76_T0, _US76_P0
    for (hb, lapse), (hn, _) in zip(_US76_LAYERS[:-1], _US76_LAYERS[1:]):
        top = min(h, hn)
        if lapse == 0.0:
            p_top = p * math.exp(-k * (top - hb) / t)
            t_top = t
        else:
            t_top = t + lapse * (top - hb)
            p_top = p * (t / t_top) ** (k / lapse)
        t, p = t_top, p_top
        if h <= hn:
            break
    return p * _US76_M0 / (_US76_R * t)


def us76_density(z: float) -> float:
    """Density (kg/m^3) of the U.S. Standard Atmosphere 1976 at geometric altitude ``z`` (m).

    Below 86 km the hydrostatic layers of the standard; above, its tabulated densities,
    interpolated linearly in log density; below 0 m the sea-level layer extends.
    """
    if z < 86e3:
        return _us76_low(z)
    table = [(h, d if d is not None else _us76_low(86e3 - 1e-9)) for h, d in _US76_HIGH]
    for (h0, d0), (h1, d1) in zip(table[:-1], table[1:]):
        if z <= h1:
            return d0 * math.exp(math.log(d1 / d0) * (z - h0) / (h1 - h0))
    (h0, d0), (h1, d1) = table[-2], table[-1]
    return d1 * math.exp(math.log(d1 / d0) * (z - h1) / (h1 - h0))


def gravity_ecef(r: np.ndarray, world: TruthWorld) -> np.ndarray:
    """Gravitational acceleration in ECEF: point mass plus the standard Cartesian J2 terms.

    :param r: position (3,) in m.
    :param world: the planet.
    """
    x, y, z = r
    rn = math.sqrt(x * x + y * y + z * z)
    g = -world.mu / rn**3 * r
    if world.j2:
        k = 1.5 * world.j2 * world.mu * world.radius**2 / rn**5
        zz = 5.0 * z * z / (rn * rn)
        g = g + k * np.array([x * (zz - 1.0), y * (zz - 1.0), z * (zz - 3.0)])
    return g


def density(h: float, world: TruthWorld) -> float:
    """Truth density (kg/m^3) at altitude ``h`` (m), including the density-profile effect."""
    if world.atmosphere == "us76":
        rho = us76_density(h)
    elif world.atmosphere == "exponential":
        rho = world.rho0 * math.exp(-h / world.scale_height)
    else:
        raise ValueError(f"unknown truth atmosphere {world.atmosphere!r}")
    if world.density_amplitude:
        phase = 2.0 * math.pi * (h - world.density_phase_altitude) / world.density_wavelength
        rho *= math.exp(world.density_amplitude * math.sin(phase))
    return rho


def cav_h_coefficients(alpha: float, mach: float) -> tuple[float, float]:
    """(C_L, C_D) of the CAV-H fit in docs/conventions.md, with alpha in rad (converted to degrees)."""
    a = math.degrees(alpha)
    cl = -0.2317 + 0.0513 * a + 0.2945 * math.exp(-0.1028 * mach)
    cd = 0.024 + 7.24e-4 * a * a + 0.406 * math.exp(-0.323 * mach)
    return cl, cd


def wind_ecef(r: np.ndarray, world: TruthWorld) -> np.ndarray:
    """Horizontal wind (m/s) in ECEF from its east and north components at position ``r``."""
    if not (world.wind_east or world.wind_north or world.wind_shear):
        return np.zeros(3)
    up = r / np.linalg.norm(r)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    w_east = world.wind_east
    if world.wind_shear:
        h = np.linalg.norm(r) - world.radius
        w_east = w_east + world.wind_shear * math.tanh((h - world.shear_altitude) / world.shear_width)
    return w_east * east + world.wind_north * north


def lift_direction(r: np.ndarray, v: np.ndarray, v_air: np.ndarray, bank: float) -> np.ndarray:
    """Unit lift direction for the conventional bank angle ``bank`` (rad).

    The bank is measured about the Earth-relative velocity: mu = 0 is the part of
    the local vertical normal to v, positive rolls toward v x up. The lift is the
    part of that direction normal to the air-relative velocity.
    """
    up = r / np.linalg.norm(r)
    vh = v / np.linalg.norm(v)
    up_n = up - np.dot(up, vh) * vh
    up_n /= np.linalg.norm(up_n)
    right = np.cross(vh, up_n)
    l0 = math.cos(bank) * up_n + math.sin(bank) * right
    va = v_air / np.linalg.norm(v_air)
    lv = l0 - np.dot(l0, va) * va
    return lv / np.linalg.norm(lv)


def mass_at(t: float, world: TruthWorld) -> float:
    """The vehicle's mass (kg) at time ``t`` (s): the declared mass less the ``mass_loss`` ramp."""
    if not world.mass_loss:
        return world.mass
    a, b = world.mass_loss_start, world.mass_loss_end
    frac = 1.0 if t >= b else (0.0 if t <= a else (t - a) / (b - a))
    return world.mass * (1.0 - world.mass_loss * frac)


def acceleration(r: np.ndarray, v: np.ndarray, alpha: float, bank: float, world: TruthWorld,
                 t: float = 0.0) -> np.ndarray:  # fmt: skip
    """Earth-relative acceleration d(v_E)/dt in ECEF (m/s^2) for one state and control at time ``t``.

    Newton's law seen from the rotating frame:
    a = g + (L + D)/m - 2 w x v - w x (w x r), w = (0, 0, omega). The time matters only for a
    mass that changes (``mass_loss``).
    """
    w = np.array([0.0, 0.0, world.omega])
    h = np.linalg.norm(r) - world.radius
    v_air = v - wind_ecef(r, world)
    speed_air = np.linalg.norm(v_air)
    q = 0.5 * density(h, world) * speed_air**2
    mach = speed_air / world.sound_speed
    cl, cd = cav_h_coefficients(alpha, mach)
    if world.mach_drag_amplitude:
        shape = 1.0 - math.exp((mach - world.mach_drag_centre) / world.mach_drag_width)
        cd *= math.exp(world.mach_drag_amplitude * shape)
    if world.band_channel:
        inside = 0.5 * (math.tanh((h - world.band_low) / 1e3) - math.tanh((h - world.band_high) / 1e3))
        factor = 1.0 + (world.band_scale - 1.0) * inside
        if world.band_channel == "lift":
            cl *= factor
        elif world.band_channel == "drag":
            cd *= factor
        else:
            raise ValueError(f"band_channel must be 'lift' or 'drag', got {world.band_channel!r}")
    if world.mach_lift_below:
        below = 0.5 * (1.0 - math.tanh(mach - world.mach_lift_below))
        cl *= 1.0 + (world.mach_lift_scale - 1.0) * below
    k = q * world.area / mass_at(t, world)
    drag = -k * world.cd_scale * cd * v_air / speed_air
    lift = k * world.cl_scale * cl * lift_direction(r, v, v_air, bank)
    out = gravity_ecef(r, world) + drag + lift - 2.0 * np.cross(w, v) - np.cross(w, np.cross(w, r))
    if world.side_force:
        up_dir = lift_direction(r, v, v_air, 0.0)
        side = np.cross(v_air / speed_air, up_dir)
        out = out + world.side_force * k * world.cd_scale * cd * side
    return out


def ecef_from_spherical(
    radius: float, longitude: float, latitude: float, speed: float, flight_path: float, azimuth: float
) -> tuple[np.ndarray, np.ndarray]:
    """ECEF position and Earth-relative velocity from spherical coordinates.

    Angles in rad; the azimuth is measured from north toward east.
    """
    cl, sl, co, so = math.cos(latitude), math.sin(latitude), math.cos(longitude), math.sin(longitude)
    up = np.array([cl * co, cl * so, sl])
    east = np.array([-so, co, 0.0])
    north = np.array([-sl * co, -sl * so, cl])
    horizontal = math.cos(azimuth) * north + math.sin(azimuth) * east
    return radius * up, speed * (math.sin(flight_path) * up + math.cos(flight_path) * horizontal)


Controls = Callable[[float], tuple[float, float]]


def fly(
    world: TruthWorld,
    r0: np.ndarray,
    v0: np.ndarray,
    controls: Controls,
    t_eval: np.ndarray,
    rtol: float = 1e-11,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate a flight through the truth world and sample it.

    :param world: the truth model.
    :param r0: ECEF position at ``t_eval[0]`` (m).
    :param v0: Earth-relative ECEF velocity at ``t_eval[0]`` (m/s).
    :param controls: ``t -> (alpha, conventional bank mu)`` in rad.
    :param t_eval: increasing sample times (s).
    :param rtol: relative tolerance of DOP853 (absolute tolerances follow from it).
    :return: positions and velocities at ``t_eval``, each ``(n, 3)``.
    """
    from scipy.integrate import solve_ivp

    def rhs(t, s):
        alpha, bank = controls(t)
        return np.concatenate([s[3:], acceleration(s[:3], s[3:], alpha, bank, world, t)])

    t_eval = np.asarray(t_eval, dtype=float)
    s0 = np.concatenate([np.asarray(r0, float), np.asarray(v0, float)])
    atol = np.array([1e-4] * 3 + [1e-7] * 3) * (rtol / 1e-11)
    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), s0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"truth integration failed: {sol.message}")
    return sol.y[:3].T, sol.y[3:].T


__all__ = [
    "EARTH_J2",
    "TruthWorld",
    "acceleration",
    "cav_h_coefficients",
    "density",
    "ecef_from_spherical",
    "fly",
    "gravity_ecef",
    "lift_direction",
    "mass_at",
    "us76_density",
    "wind_ecef",
]
