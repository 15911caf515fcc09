"""The model a record is replayed with: vehicle, planet and atmosphere from the sidecar.

A record without a sidecar is a CAV-H flight under PROBLEM.md's Earth and
atmosphere. A sidecar (or ``--vehicle`` file) may declare another vehicle; a
capsule is declared by its constant drag coefficient and lift-to-drag ratio:

.. code-block:: json

    {"vehicle": {"name": "Apollo CM", "mass_kg": 5424.6, "reference_area_m2": 12.0171,
                 "aerodynamics": {"type": "constant", "drag_coefficient": 1.2891,
                                  "lift_to_drag": 0.368}},
     "start_model": "drag-only",
     "entry_state": {"t_s": -0.54, "altitude_m": 123479.4, "speed_rel_mps": 10733.84,
                     "flight_path_angle_deg": -7.129, "longitude_deg": 153.932,
                     "latitude_deg": 18.467, "azimuth_deg": 62.65}}

``start_model`` says which model the loop starts from: ``"declared"`` (the
vehicle as declared) or ``"drag-only"`` (its lift removed, so that lift becomes a
candidate effect). The declared aerodynamics stay the *reference* of the
``lift_coefficient`` effect and, for a capsule, the L/D that turns a vertical
L/D history into a bank angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rventry_env.physics import (
    CAVHAerodynamics,
    ConstantAerodynamics,
    EntryModel,
    ExponentialAtmosphere,
    Planet,
    PointMassGravity,
    ScaledAerodynamics,
    Vehicle,
)
from rventry_env.validation.record import FlightRecord, RecordError

START_MODELS = ("declared", "drag-only")


@dataclass(frozen=True)
class EntryState:
    """A declared entry state (spherical, SI and radians) at time ``t``."""

    t: float
    altitude: float
    speed: float
    flight_path: float
    longitude: float
    latitude: float
    azimuth: float


@dataclass(frozen=True)
class ReplaySetup:
    """What the replay starts from.

    :param model: the current model (the loop's starting point).
    :param lift_reference: the declared aerodynamics; ``lift_coefficient`` scales its C_L.
    :param start_lift_scale: C_L scale of the current model relative to ``lift_reference``
        (1 declared, 0 drag-only).
    :param lift_to_drag: the declared constant L/D of a capsule (None for a lifting body).
    :param entry_state: the sidecar's entry state, if any.
    :param start: ``"declared"`` or ``"drag-only"``.
    """

    model: EntryModel
    lift_reference: object
    start_lift_scale: float
    lift_to_drag: float | None
    entry_state: EntryState | None
    start: str


def _number(d: dict, key: str, where: str, default=None) -> float:
    if key not in d:
        if default is None:
            raise RecordError(f"{where}: missing {key!r}")
        return default
    try:
        value = float(d[key])
    except (TypeError, ValueError):
        raise RecordError(f"{where}: {key!r} must be a number, got {d[key]!r}") from None
    if not math.isfinite(value):
        raise RecordError(f"{where}: {key!r} must be finite")
    return value


def vehicle_from_dict(d: dict, where: str = "vehicle") -> Vehicle:
    """A :class:`Vehicle` from its JSON description (CAV-H defaults for missing keys)."""
    base = Vehicle()
    aero_d = d.get("aerodynamics", {"type": "cav-h"})
    kind = str(aero_d.get("type", "cav-h")).lower()
    if kind in ("cav-h", "cavh"):
        aero = CAVHAerodynamics()
    elif kind == "constant":
        cd = _number(aero_d, "drag_coefficient", f"{where}.aerodynamics")
        ld = _number(aero_d, "lift_to_drag", f"{where}.aerodynamics", 0.0)
        if cd <= 0:
            raise RecordError(f"{where}.aerodynamics: drag_coefficient must be positive")
        aero = ConstantAerodynamics(cd=cd, lift_to_drag=ld)
    else:
        raise RecordError(f"{where}.aerodynamics: unknown type {kind!r} (use 'cav-h' or 'constant')")
    mass = _number(d, "mass_kg", where, base.mass)
    area = _number(d, "reference_area_m2", where, base.reference_area)
    if mass <= 0 or area <= 0:
        raise RecordError(f"{where}: mass_kg and reference_area_m2 must be positive")
    return Vehicle(mass=mass, reference_area=area, aerodynamics=aero, name=str(d.get("name", base.name)))


def entry_state_from_dict(d: dict, where: str = "entry_state") -> EntryState:
    """An :class:`EntryState` from the sidecar (degrees at the interface)."""
    return EntryState(
        t=_number(d, "t_s", where),
        altitude=_number(d, "altitude_m", where),
        speed=_number(d, "speed_rel_mps", where),
        flight_path=math.radians(_number(d, "flight_path_angle_deg", where)),
        longitude=math.radians(_number(d, "longitude_deg", where)),
        latitude=math.radians(_number(d, "latitude_deg", where)),
        azimuth=math.radians(_number(d, "azimuth_deg", where)),
    )


def replay_setup(record: FlightRecord, vehicle: dict | None = None, start: str | None = None) -> ReplaySetup:
    """The current model and declared facts for a record.

    :param record: the validated record (its sidecar is read from ``record.sidecar``).
    :param vehicle: a vehicle description overriding the sidecar's (``--vehicle``); either
        the vehicle object or a document with a ``"vehicle"`` key.
    :param start: ``"declared"`` or ``"drag-only"``; default the sidecar's ``start_model``
        or ``"declared"``.
    """
    sc = record.sidecar or {}
    vd = None
    if vehicle is not None:
        vd = vehicle.get("vehicle", vehicle)
        start = start or vehicle.get("start_model")
    elif "vehicle" in sc:
        vd = sc["vehicle"]
    veh = vehicle_from_dict(vd) if vd is not None else Vehicle()
    start = start or sc.get("start_model", "declared")
    if start not in START_MODELS:
        raise RecordError(f"start model {start!r}: use one of {START_MODELS}")
    planet = Planet()
    atm_d = sc.get("atmosphere", {})
    atm = ExponentialAtmosphere(
        rho0=_number(atm_d, "rho0_kgpm3", "atmosphere", 1.225),
        scale_height=_number(atm_d, "scale_height_m", "atmosphere", 7200.0),
        sound_speed=_number(atm_d, "sound_speed_mps", "atmosphere", 300.0),
    )
    aero = veh.aerodynamics
    lift_to_drag = aero.lift_to_drag if isinstance(aero, ConstantAerodynamics) else None
    if start == "drag-only":
        # C_L scaled to zero: the declared aero stays the reference the lift effect scales
        veh = Vehicle(veh.mass, veh.reference_area, ScaledAerodynamics(aero, cl_scale=0.0), veh.name)
    model = EntryModel(planet=planet, gravity=PointMassGravity(mu=planet.mu), atmosphere=atm, vehicle=veh)
    es = entry_state_from_dict(sc["entry_state"]) if "entry_state" in sc else None
    if record.kind == "reduced" and es is None:
        raise RecordError(
            "a reduced record (altitude_m, speed_rel_mps) needs the entry state in its sidecar "
            "(<record>.json with an 'entry_state' object): position and heading are not in the record"
        )
    return ReplaySetup(model, aero, 0.0 if start == "drag-only" else 1.0, lift_to_drag, es, start)


__all__ = [
    "START_MODELS",
    "EntryState",
    "ReplaySetup",
    "vehicle_from_dict",
    "entry_state_from_dict",
    "replay_setup",
]
