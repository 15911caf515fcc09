"""The model a record is replayed with: vehicle, planet, atmosphere, entry state and noise from the sidecar.

A record without a sidecar is a CAV-H flight under the Earth and atmosphere of
``docs/conventions.md``. A sidecar (or ``--vehicle`` file) may declare another vehicle; a
capsule is declared by its constant drag coefficient and lift-to-drag ratio:

.. code-block:: json

    {"vehicle": {"name": "Apollo CM", "mass_kg": 5424.6, "reference_area_m2": 12.0171,
                 "aerodynamics": {"type": "constant", "drag_coefficient": 1.2891,
                                  "lift_to_drag": 0.368}},
     "start_model": "drag-only",
     "entry_state": {"t_s": -0.54, "altitude_m": 123479.4, "speed_rel_mps": 10733.84,
                     "flight_path_angle_deg": -7.129, "longitude_deg": 153.932,
                     "latitude_deg": 18.467, "azimuth_deg": 62.65},
     "noise": {"position_m": 1000, "velocity_mps": 100}}

``start_model`` says which model the loop starts from: ``"declared"`` (the vehicle as declared)
or ``"drag-only"`` (its lift removed, so that lift becomes a candidate effect). The declared
aerodynamics stay the *reference* of the ``lift_coefficient`` effect and, for a capsule, the L/D
that turns a vertical L/D history into a bank angle. ``noise`` declares the measurement noise
(one standard deviation per component: ``position_m``/``velocity_mps``, or for a reduced record
also ``altitude_m``/``speed_mps``); without it the noise is estimated from the record.

Every key is checked: an unknown one (a typo such as ``"vehicel"``) is an error that names it,
and so is a value of the wrong type or outside its physical range.
"""

from __future__ import annotations

import difflib
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
from rventry_env.validation.record import (
    MAX_ALTITUDE,
    MAX_SPEED,
    MIN_ALTITUDE,
    FlightRecord,
    RecordError,
)

START_MODELS = ("declared", "drag-only")
TEXT_KEYS = ("name", "description", "sources", "notes", "generated_by")
SIDECAR_KEYS = ("vehicle", "start_model", "entry_state", "atmosphere", "noise") + TEXT_KEYS
VEHICLE_KEYS = ("mass_kg", "reference_area_m2", "aerodynamics") + TEXT_KEYS
AERO_KEYS = {"cav-h": ("type",) + TEXT_KEYS, "constant": ("type", "drag_coefficient", "lift_to_drag") + TEXT_KEYS}
ENTRY_KEYS = ("t_s", "altitude_m", "speed_rel_mps", "flight_path_angle_deg", "longitude_deg", "latitude_deg",
              "azimuth_deg") + TEXT_KEYS  # fmt: skip
ATMOSPHERE_KEYS = ("rho0_kgpm3", "scale_height_m", "sound_speed_mps") + TEXT_KEYS
NOISE_KEYS = ("position_m", "velocity_mps", "altitude_m", "speed_mps") + TEXT_KEYS
# a vehicle file given with --vehicle: the vehicle object itself, or a document holding one
VEHICLE_FILE_KEYS = ("vehicle", "start_model") + TEXT_KEYS


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
    :param declared_noise: observation group -> declared noise standard deviation, or None.
    :param measured_atmosphere: the atmosphere fitted to the record's density column (the
        ``measured_density`` candidate), or None.
    """

    model: EntryModel
    lift_reference: object
    start_lift_scale: float
    lift_to_drag: float | None
    entry_state: EntryState | None
    start: str
    declared_noise: dict | None = None
    measured_atmosphere: object = None


def check_keys(d, allowed, where: str) -> dict:
    """``d`` must be a JSON object whose keys are all in ``allowed``; an unknown key is named."""
    if not isinstance(d, dict):
        raise RecordError(f"{where}: expected a JSON object, got {type(d).__name__} {d!r:.60}")
    unknown = [k for k in d if k not in allowed]
    if unknown:
        hints = []
        for k in unknown:
            close = difflib.get_close_matches(str(k), allowed, n=1, cutoff=0.6)
            hints.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
        raise RecordError(
            f"{where}: unknown key(s) {', '.join(hints)}; allowed: {', '.join(a for a in allowed if a not in TEXT_KEYS)}"
        )
    return d


def _number(d: dict, key: str, where: str, default=None, low=None, high=None, positive=False) -> float:
    if key not in d:
        if default is None:
            raise RecordError(f"{where}: missing {key!r}")
        return default
    v = d[key]
    # JSON true/false are not numbers (Python would read true as 1)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise RecordError(f"{where}.{key}: must be a number, got {v!r:.60}")
    value = float(v)
    if not math.isfinite(value):
        raise RecordError(f"{where}.{key}: must be finite, got {v!r}")
    if positive and value <= 0:
        raise RecordError(f"{where}.{key}: must be positive, got {value:g}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise RecordError(f"{where}.{key}: {value:g} is outside [{low:g}, {high:g}]")
    return value


def vehicle_from_dict(d, where: str = "vehicle") -> Vehicle:
    """A :class:`Vehicle` from its JSON description (CAV-H defaults for missing keys)."""
    check_keys(d, VEHICLE_KEYS, where)
    base = Vehicle()
    aero_d = d.get("aerodynamics", {"type": "cav-h"})
    if not isinstance(aero_d, dict):
        raise RecordError(f"{where}.aerodynamics: expected a JSON object such as "
                          f"{{\"type\": \"constant\", \"drag_coefficient\": 1.3}}, got {aero_d!r:.60}")  # fmt: skip
    kind = aero_d.get("type", "cav-h")
    if not isinstance(kind, str):
        raise RecordError(f"{where}.aerodynamics.type: must be 'cav-h' or 'constant', got {kind!r:.40}")
    kind = kind.lower()
    if kind in ("cav-h", "cavh"):
        check_keys(aero_d, AERO_KEYS["cav-h"], f"{where}.aerodynamics")
        aero = CAVHAerodynamics()
    elif kind == "constant":
        check_keys(aero_d, AERO_KEYS["constant"], f"{where}.aerodynamics")
        cd = _number(aero_d, "drag_coefficient", f"{where}.aerodynamics", positive=True, high=10.0)
        ld = _number(aero_d, "lift_to_drag", f"{where}.aerodynamics", 0.0, low=0.0, high=5.0)
        aero = ConstantAerodynamics(cd=cd, lift_to_drag=ld)
    else:
        raise RecordError(f"{where}.aerodynamics.type: unknown type {kind!r} (use 'cav-h' or 'constant')")
    mass = _number(d, "mass_kg", where, base.mass, positive=True)
    area = _number(d, "reference_area_m2", where, base.reference_area, positive=True)
    name = d.get("name", base.name)
    return Vehicle(mass=mass, reference_area=area, aerodynamics=aero, name=str(name))


def entry_state_from_dict(d, where: str = "entry_state") -> EntryState:
    """An :class:`EntryState` from the sidecar (degrees at the interface), range-checked."""
    check_keys(d, ENTRY_KEYS, where)
    return EntryState(
        t=_number(d, "t_s", where),
        altitude=_number(d, "altitude_m", where, low=MIN_ALTITUDE, high=MAX_ALTITUDE),
        speed=_number(d, "speed_rel_mps", where, positive=True, high=MAX_SPEED),
        flight_path=math.radians(_number(d, "flight_path_angle_deg", where, low=-90.0, high=90.0)),
        longitude=math.radians(_number(d, "longitude_deg", where, low=-360.0, high=360.0)),
        latitude=math.radians(_number(d, "latitude_deg", where, low=-90.0, high=90.0)),
        azimuth=math.radians(_number(d, "azimuth_deg", where, low=-360.0, high=360.0)),
    )


def noise_from_dict(d, kind: str, where: str = "noise") -> dict:
    """Declared noise per observation group from a sidecar's ``noise`` object."""
    check_keys(d, NOISE_KEYS, where)
    if kind == "ecef":
        pos_keys, vel_keys = ("position_m",), ("velocity_mps",)
        names = ("position", "velocity")
    else:
        pos_keys, vel_keys = ("altitude_m", "position_m"), ("speed_mps", "velocity_mps")
        names = ("altitude", "speed")
    out = {}
    for name, keys in zip(names, (pos_keys, vel_keys)):
        given = [k for k in keys if k in d]
        if len(given) > 1:
            raise RecordError(f"{where}: give one of {', '.join(given)}, not both")
        if not given:
            raise RecordError(f"{where}: missing {' or '.join(keys)}")
        out[name] = _number(d, given[0], where, positive=True)
    return out


def replay_setup(
    record: FlightRecord,
    vehicle: dict | None = None,
    start: str | None = None,
    noise: tuple | None = None,
) -> ReplaySetup:
    """The current model and declared facts for a record.

    :param record: the validated record (its sidecar is read from ``record.sidecar``).
    :param vehicle: a vehicle description overriding the sidecar's (``--vehicle``); either
        the vehicle object or a document with a ``"vehicle"`` key.
    :param start: ``"declared"`` or ``"drag-only"``; default the sidecar's ``start_model``
        or ``"declared"``.
    :param noise: (position or altitude, velocity or speed) noise standard deviations
        overriding the sidecar's ``noise`` (``--noise``).
    :raises RecordError: naming the sidecar field at fault.
    """
    sc = record.sidecar if record.sidecar is not None else {}
    check_keys(sc, SIDECAR_KEYS, "sidecar")
    vd = None
    if vehicle is not None:
        if not isinstance(vehicle, dict):
            raise RecordError(f"--vehicle: expected a JSON object, got {type(vehicle).__name__}")
        if "vehicle" in vehicle:
            check_keys(vehicle, VEHICLE_FILE_KEYS, "--vehicle file")
            vd = vehicle["vehicle"]
            where = "--vehicle file: vehicle"
            if start is None and "start_model" in vehicle:
                start = vehicle["start_model"]
        else:
            vd, where = vehicle, "--vehicle file"
    elif "vehicle" in sc:
        vd, where = sc["vehicle"], "sidecar: vehicle"
    veh = vehicle_from_dict(vd, where) if vd is not None else Vehicle()
    if start is None:
        start = sc.get("start_model", "declared")
    if start not in START_MODELS:
        raise RecordError(f"start_model {start!r}: use one of {', '.join(START_MODELS)}")
    planet = Planet()
    atm_d = check_keys(sc.get("atmosphere", {}), ATMOSPHERE_KEYS, "sidecar: atmosphere")
    atm = ExponentialAtmosphere(
        rho0=_number(atm_d, "rho0_kgpm3", "sidecar: atmosphere", 1.225, positive=True, high=10.0),
        scale_height=_number(atm_d, "scale_height_m", "sidecar: atmosphere", 7200.0, low=1000.0, high=50000.0),
        sound_speed=_number(atm_d, "sound_speed_mps", "sidecar: atmosphere", 300.0, low=100.0, high=1000.0),
    )
    aero = veh.aerodynamics
    lift_to_drag = aero.lift_to_drag if isinstance(aero, ConstantAerodynamics) else None
    if start == "drag-only":
        # C_L scaled to zero: the declared aero stays the reference the lift effect scales
        veh = Vehicle(veh.mass, veh.reference_area, ScaledAerodynamics(aero, cl_scale=0.0), veh.name)
    model = EntryModel(planet=planet, gravity=PointMassGravity(mu=planet.mu), atmosphere=atm, vehicle=veh)
    es = entry_state_from_dict(sc["entry_state"], "sidecar: entry_state") if "entry_state" in sc else None
    if record.kind == "reduced" and es is None:
        raise RecordError(
            "a reduced record (altitude_m, speed_rel_mps) needs the entry state in its sidecar "
            "(<record>.json with an 'entry_state' object): position and heading are not in the record"
        )
    names = ("position", "velocity") if record.kind == "ecef" else ("altitude", "speed")
    declared = None
    if noise is not None:
        declared = dict(zip(names, (float(noise[0]), float(noise[1]))))
    elif "noise" in sc:
        declared = noise_from_dict(sc["noise"], record.kind, "sidecar: noise")
    start_scale = 0.0 if start == "drag-only" else 1.0
    return ReplaySetup(model, aero, start_scale, lift_to_drag, es, start, declared)


__all__ = [
    "SIDECAR_KEYS",
    "START_MODELS",
    "EntryState",
    "ReplaySetup",
    "check_keys",
    "entry_state_from_dict",
    "noise_from_dict",
    "replay_setup",
    "vehicle_from_dict",
]
