"""Per-copy flight-grade draws for the environments: the truth model they define, and what the
vehicle's sensors and navigation make of the truth.

Shared by :class:`~rventry_env.envs.rv_entry.RvEntryEnv` (one copy) and
:class:`~rventry_env.envs.vector.RvEntryVectorEnv` (N copies): both keep one
:class:`VehicleErrors` of N rows, fill row i from copy i's draws, and build from it the truth
model (per-copy arrays for the batch, row 0 as plain numbers and one profile for the single
env) and, where the set has sensor or navigation errors, the navigation state and the sensed
features every observation is made of. The truth state is never changed.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.physics.model import EntryModel, scaled_model
from rventry_env.physics.sensors import accelerometer, propagate_navigation_error, white_noise
from rventry_env.physics.uncertainty import MachVaryingAerodynamics, ProfileAtmosphere, ProfileWind
from rventry_env.task import SCALAR_FIELDS, Dispersion
from rventry_env.task.flight_grade import GRID_M, GRID_POINTS, GRID_START_M, GRID_STEP_M


class Sensed(NamedTuple):
    """What the observation is built from in place of the true forces (see ``observe``)."""

    c_ba: tuple
    dynamic_pressure: object
    aero_accel: object


class VehicleErrors:
    """The flight-grade errors drawn for N vehicles (copies), and their sensors' and navigation's
    running errors."""

    def __init__(self, n: int, model: EntryModel):
        self.n = n
        self.base = model
        k = GRID_POINTS
        self.mass = np.ones(n)
        # profiles in Fortran order: see physics.uncertainty.table_gather
        self.log_factors = np.zeros((n, k), order="F")
        self.wind_east = np.zeros((n, k), order="F")
        self.wind_north = np.zeros((n, k), order="F")
        self.aero = np.zeros((n, 4))
        self.bias = np.zeros((n, 3))
        self.scale = np.zeros((n, 3))
        self.misalignment = np.zeros((n, 3))
        self.noise = np.zeros(n)
        self.key = np.zeros(n, dtype=np.uint64)
        self.step = np.zeros(n, dtype=np.int64)
        self.dr = np.zeros((3, n))  # navigation errors, E components (rows), one column per copy
        self.dv = np.zeros((3, n))
        self.senses = np.zeros(n, bool)
        self.any_model = False
        self.any_wind = False
        self.any_sensing = False

    def assign(self, i: int, dispersion: Dispersion, extras: dict | None) -> None:
        """Row ``i`` from one copy's draws (:func:`~rventry_env.task.draw_extras`); zeros for none."""
        if extras is None:
            self.mass[i] = 1.0
            for a in (self.log_factors, self.wind_east, self.wind_north, self.aero, self.bias, self.scale,
                      self.misalignment):  # fmt: skip
                a[i] = 0.0
            self.dr[:, i] = self.dv[:, i] = 0.0
            self.noise[i] = 0.0
            self.senses[i] = False
            return
        flight = dispersion.flight
        self.any_model = True
        self.mass[i] = 1.0 + extras["mass"]
        lf = extras["density_perturbation"].copy()
        if "log_density_climate" in extras:
            lf += extras["log_density_climate"]
        self.log_factors[i] = lf
        self.wind_east[i] = extras["wind_east"]
        self.wind_north[i] = extras["wind_north"]
        if flight is not None and flight.has_wind:
            if self.base.wind is not None:
                raise ValueError("a dispersion with winds needs a model without a wind of its own")
            self.any_wind = True
        self.aero[i] = extras["aero"]
        self.bias[i] = extras["accel_bias"]
        self.scale[i] = extras["accel_scale"]
        self.misalignment[i] = extras["accel_misalignment"]
        self.noise[i] = 0.0 if flight is None else flight.accel_noise_mps2
        self.key[i] = extras["noise_key"]
        self.step[i] = 0
        self.dr[:, i] = extras["nav_position"]
        self.dv[:, i] = extras["nav_velocity"]
        self.senses[i] = dispersion.has_sensing
        self.any_sensing |= bool(self.senses[i])

    def model(self, density, lift, drag, single: bool = False, row: int = 0) -> EntryModel:
        """The truth model: the base with the scale factors and, where any copy draws them, the
        profiles, the Mach-dependent aerodynamics, the mass (and the wind).

        :param single: one copy's model as plain numbers and one profile: copy ``row``'s (the
            scale factors are then that copy's numbers).
        """
        m = scaled_model(self.base, density, lift, drag)
        if not self.any_model:
            return m
        table = (lambda a: a[row]) if single else (lambda a: a)
        num = (lambda a: float(a[row])) if single else (lambda a: a)
        veh = m.vehicle
        aero = MachVaryingAerodynamics(veh.aerodynamics, num(self.aero[:, 0]), num(self.aero[:, 1]),
                                       num(self.aero[:, 2]), num(self.aero[:, 3]))  # fmt: skip
        changes = {
            "atmosphere": ProfileAtmosphere(m.atmosphere, GRID_START_M, GRID_STEP_M, table(self.log_factors)),
            "vehicle": dataclasses.replace(veh, mass=num(self.base.vehicle.mass * self.mass), aerodynamics=aero),
        }
        if self.any_wind:
            changes["wind"] = ProfileWind(GRID_START_M, GRID_STEP_M, table(self.wind_east), table(self.wind_north))
        return m.replace(**changes)

    def draw_info(self, draws9: np.ndarray, extras: list, single: bool = False) -> dict:
        """The draws of the copies, for evaluation (``info["dispersion_draw"]`` at reset)."""
        out = {f: draws9[:, j] for j, f in enumerate(SCALAR_FIELDS)}
        if any(e is not None for e in extras):
            out.update(
                mass=self.mass - 1.0, density_log_factor=self.log_factors.copy(), wind_east_mps=self.wind_east.copy(),
                wind_north_mps=self.wind_north.copy(), aero_mach=self.aero.copy(), accel_bias_mps2=self.bias.copy(),
                accel_scale=self.scale.copy(), accel_misalignment_rad=self.misalignment.copy(),
                nav_position_error_m=self.dr.T.copy(), nav_velocity_error_mps=self.dv.T.copy(),
                altitude_grid_m=GRID_M.copy(),
            )  # fmt: skip
            climate = [e.get("climate", np.full(5, np.nan)) if e is not None else np.full(5, np.nan) for e in extras]
            out["climate"] = np.array(climate)  # day of year, local time h, F10.7, F10.7a, Ap
        if single:
            out = {k: (v if k == "altitude_grid_m" else (v[0] if np.ndim(v) else v)) for k, v in out.items()}
            out = {k: (float(v) if np.ndim(v) == 0 else v) for k, v in out.items()}
        return out

    # ------------------------------------------------------------------ sensing
    def sensor_errors(self, noise: np.ndarray) -> "SensorErrors":
        """The copies' accelerometer errors, this sample's ``noise`` (N, 3) and navigation errors."""
        cols = lambda a: tuple(a[:, j] for j in range(3))  # noqa: E731
        return SensorErrors(cols(self.bias), cols(self.scale), cols(self.misalignment), cols(noise), self.senses,
                            tuple(self.dr), tuple(self.dv))  # fmt: skip

    def noise_sample(self) -> np.ndarray:
        """(N, 3): this step's accelerometer noise (the counter-based stream of each copy's key)."""
        return white_noise(self.key, self.step) * self.noise[:, None]

    def sense(self, x: tuple, forces, c_ae, g0: float, elapsed=None, active=None):
        """The navigation state (N, 12), the sensed specific force (N, 3) and the features the
        observation is built from (:class:`Sensed`, and C_AE of the navigation state); see :func:`sense`.

        :param elapsed: time flown since the last call (N,) (None at a reset: nothing flown).
        :param active: copies stepped since the last call (their noise sample advances).
        """
        n = self.n
        if elapsed is not None:
            self.step += np.ones(n, np.int64) if active is None else np.asarray(active, np.int64)
            elapsed = np.broadcast_to(np.asarray(elapsed, dtype=float), (n,))
        seen = sense(x, forces, c_ae, tuple(self.dr), tuple(self.dv), self.sensor_errors(self.noise_sample()),
                     self.base, elapsed, NUMPY)  # fmt: skip
        if elapsed is not None:
            self.dr, self.dv = np.array(seen.dr), np.array(seen.dv)
        stack = lambda cs: np.stack(np.broadcast_arrays(*cs), axis=-1)  # noqa: E731
        return stack(seen.x), stack(seen.sensed_b), seen.features, seen.c_ae


class SensorErrors(NamedTuple):
    """The accelerometer errors and navigation errors of N copies, as components (each (N,))."""

    bias: tuple  # 3 components, B axes (m/s^2)
    scale: tuple
    misalignment: tuple  # rad
    noise: tuple  # this sample's white noise (m/s^2)
    senses: object  # (N,) bool: the copies whose sensors or navigation err
    dr: tuple  # navigation position error, E components (m)
    dv: tuple  # navigation velocity error, E components (m/s)


class Seen(NamedTuple):
    """What the vehicles' sensors and navigation make of the truth (:func:`sense`)."""

    x: tuple  # the navigation state, 12 components
    sensed_b: tuple  # the sensed specific force, B components
    features: Sensed  # the observation's sensed features
    c_ae: tuple  # C_AE of the navigation state
    dr: tuple  # the navigation errors after the step
    dv: tuple


def sense(x: tuple, forces, c_ae, dr: tuple, dv: tuple, errors: SensorErrors, base: EntryModel, elapsed, ns) -> Seen:
    """The sensors' and the navigation's view of the true state ``x`` (with ``forces`` and ``c_ae`` at it).

    Component arithmetic on ``ns`` (the NumPy environments and the JAX one share it). Where
    ``elapsed`` is given (time flown since the last call, per copy), the navigation errors first
    integrate the accelerometer's error over it
    (:func:`~rventry_env.physics.sensors.propagate_navigation_error`). The navigated position and
    velocity are the true ones plus the errors (E components); the navigation frames are the true
    frames turned by the smallest rotations that carry a1 and b1 onto them, so the bank angle keeps
    its meaning (sigma is the vehicle's own). Air data come from the accelerometer:
    q = |a| m / (S |C|) with ``base``'s nominal coefficients at the navigated Mach number, and the
    load factor is the sensed one. Copies whose ``errors.senses`` is False see the truth.
    """
    z = 0.0 * errors.noise[0]  # one value per copy: broadcasts the shared parts
    col = lambda c: c + z  # noqa: E731
    senses = errors.senses
    true_b = tuple(col(c) for c in forces.aero_b)
    sensed_b = accelerometer(true_b, errors.bias, errors.scale, errors.misalignment, errors.noise)
    c_ba = forces.c_ba
    if elapsed is not None:
        err_b = tuple(sensed_b[i] - true_b[i] for i in range(3))
        err_a = tuple(err_b[0] * c_ba[0][j] + err_b[1] * c_ba[1][j] + err_b[2] * c_ba[2][j] for j in range(3))
        err_e = tuple(err_a[0] * c_ae[0][k] + err_a[1] * c_ae[1][k] + err_a[2] * c_ae[2][k] for k in range(3))
        dr, dv = propagate_navigation_error(dr, dv, err_e, ns.where(senses, elapsed, 0.0))
    r, v = x[0], x[5]
    # the errors in A (position) and in B (velocity) components
    dr_a = tuple(c_ae[j][0] * dr[0] + c_ae[j][1] * dr[1] + c_ae[j][2] * dr[2] for j in range(3))
    dv_a = tuple(c_ae[j][0] * dv[0] + c_ae[j][1] * dv[1] + c_ae[j][2] * dv[2] for j in range(3))
    dv_b = tuple(c_ba[i][0] * dv_a[0] + c_ba[i][1] * dv_a[1] + c_ba[i][2] * dv_a[2] for i in range(3))
    p = (r + dr_a[0], dr_a[1], dr_a[2])  # navigated position, A components
    r_nav = ns.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    w = (v + dv_b[0], dv_b[1], dv_b[2])  # navigated velocity, B components
    v_nav = ns.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    q_a = _turn(p, r_nav, ns)  # C_A'A
    q_b = _turn(w, v_nav, ns)  # C_B'B
    e_a = _compose(q_a, tuple(x[1:5]))  # C_A'E = C_A'A C_AE
    e_b = _compose(_compose(q_b, tuple(x[6:10])), (-q_a[0], -q_a[1], -q_a[2], q_a[3]))
    nav_x = (r_nav, *e_a, v_nav, *e_b, x[10], x[11])
    nav_x = tuple(ns.where(senses, a, b) for a, b in zip(nav_x, x))
    sensed = tuple(ns.where(senses, a, b) for a, b in zip(sensed_b, true_b))
    mach = nav_x[5] / base.atmosphere.speed_of_sound(nav_x[0] - base.planet.radius, ns)
    cl, cd = base.vehicle.aerodynamics.coefficients(nav_x[10], mach, ns)
    a_mag = ns.sqrt(sensed[0] * sensed[0] + sensed[1] * sensed[1] + sensed[2] * sensed[2])
    q_hat = a_mag * base.vehicle.mass / (base.vehicle.reference_area * ns.sqrt(cl * cl + cd * cd))
    q = ns.where(senses, q_hat, forces.dynamic_pressure)
    load = ns.where(senses, a_mag, forces.aero_accel)
    feats = Sensed(dcm(*nav_x[6:10]), q, load)
    return Seen(nav_x, sensed, feats, dcm(*nav_x[1:5]), dr, dv)


def _turn(u: tuple, norm, ns):
    """Euler parameters of the frame turned by the smallest rotation carrying its first axis onto
    the direction of ``u`` (components in the frame; ``norm`` = |u|)."""
    c = 1.0 + u[0] / norm
    s = ns.sqrt(2.0 * c)
    return (0.0 * c, -u[2] / norm / s, u[1] / norm / s, 0.5 * s)


def _compose(p: tuple, q: tuple) -> tuple:
    """Euler parameters of dcm(p) dcm(q): e = eta_p e_q + eta_q e_p - e_p x e_q, eta = eta_p eta_q - e_p . e_q."""
    e1, e2, e3, ep = p
    f1, f2, f3, eq = q
    return (
        ep * f1 + eq * e1 - (e2 * f3 - e3 * f2),
        ep * f2 + eq * e2 - (e3 * f1 - e1 * f3),
        ep * f3 + eq * e3 - (e1 * f2 - e2 * f1),
        ep * eq - (e1 * f1 + e2 * f2 + e3 * f3),
    )


__all__ = ["VehicleErrors", "Sensed", "SensorErrors", "Seen", "sense"]
