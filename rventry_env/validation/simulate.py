"""Synthetic flight records: the CAV-H flown through the truth model with undeclared effects.

``rventry simulate-record --effect NAME[=VALUE] ... --noise POS_M,VEL_MPS --out RECORD.csv``

The vehicle flies a scripted glide (angle of attack and conventional bank as
smooth functions of time) through :mod:`rventry_env.validation.truth`, which
contains the requested effects. The record is written in the PROBLEM.md format
*without* a sidecar, so the identification is told nothing: it sees a CAV-H
flight under the default Earth and atmosphere. The effects and the noise are
written to a separate ``<record>.truth.json`` for checking, never read by
``rventry identify``.

Effect values (defaults in brackets):

* ``j2_gravity=J2`` the second zonal harmonic [1.08262668e-3];
* ``density_profile=A`` ln(rho_true / rho_exp) = A sin(2 pi (h - 30 km) / 80 km) [0.2];
* ``lift_coefficient=S`` C_L multiplied by S [0.9];
* ``drag_coefficient=S`` C_D multiplied by S [1.1];
* ``wind=E[,N]`` a horizontal wind, east and north (m/s) [50].
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from rventry_env.validation import truth
from rventry_env.validation.effects import EFFECT_NAMES
from rventry_env.validation.record import write_record

GENERATED_BY = "rventry simulate-record"
DEFAULT_VALUES = {
    "j2_gravity": "1.08262668e-3",
    "density_profile": "0.2",
    "lift_coefficient": "0.9",
    "drag_coefficient": "1.1",
    "wind": "50",
}


@dataclass(frozen=True)
class Scenario:
    """A scripted CAV-H glide (angles in degrees at this interface only).

    :param altitude: initial altitude (m).
    :param speed: initial Earth-relative speed (m/s).
    :param flight_path_deg: initial flight-path angle.
    :param longitude_deg: initial longitude.
    :param latitude_deg: initial geocentric latitude.
    :param azimuth_deg: initial heading from north toward east.
    :param alpha_deg: mean angle of attack.
    :param alpha_amp_deg: amplitude of its sinusoidal modulation.
    :param alpha_period: its period (s).
    :param bank_amp_deg: amplitude of the sinusoidal conventional bank.
    :param bank_period: its period (s).
    """

    altitude: float = 60e3
    speed: float = 6500.0
    flight_path_deg: float = -0.5
    longitude_deg: float = 0.0
    latitude_deg: float = 10.0
    azimuth_deg: float = 60.0
    alpha_deg: float = 12.0
    alpha_amp_deg: float = 2.0
    alpha_period: float = 150.0
    bank_amp_deg: float = 40.0
    bank_period: float = 200.0

    def controls(self, t: float) -> tuple[float, float]:
        """(alpha, conventional bank mu) in rad at time ``t``."""
        alpha = self.alpha_deg + self.alpha_amp_deg * math.sin(2 * math.pi * t / self.alpha_period)
        bank = self.bank_amp_deg * math.sin(2 * math.pi * t / self.bank_period)
        return math.radians(alpha), math.radians(bank)


def parse_effects(specs: list[str]) -> dict[str, str]:
    """``["wind=40,-10", "j2_gravity"]`` -> {"wind": "40,-10", "j2_gravity": "1.08e-3"}."""
    out = {}
    for spec in specs:
        name, _, value = spec.partition("=")
        name = name.strip()
        if name not in EFFECT_NAMES:
            raise ValueError(f"unknown effect {name!r}; choose from {', '.join(EFFECT_NAMES)}")
        if name in out:
            raise ValueError(f"effect {name!r} given twice")
        out[name] = value.strip() or DEFAULT_VALUES[name]
    return out


def truth_world(effects: dict[str, str]) -> truth.TruthWorld:
    """The truth model containing ``effects`` (name -> value text)."""
    w = truth.TruthWorld()
    for name, text in effects.items():
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise ValueError(f"effect {name}: cannot read {text!r} as number(s)") from None
        if name == "wind":
            if len(values) > 2:
                raise ValueError("wind takes EAST or EAST,NORTH (m/s)")
            w = replace(w, wind_east=values[0], wind_north=values[1] if len(values) > 1 else 0.0)
            continue
        if len(values) != 1:
            raise ValueError(f"effect {name} takes one value")
        v = values[0]
        if name == "j2_gravity":
            w = replace(w, j2=v)
        elif name == "density_profile":
            w = replace(w, density_amplitude=v)
        elif name == "lift_coefficient":
            w = replace(w, cl_scale=v)
        elif name == "drag_coefficient":
            if v <= 0:
                raise ValueError("drag_coefficient scale must be positive")
            w = replace(w, cd_scale=v)
    return w


def simulate_record(
    out: str | Path,
    effects: dict[str, str] | None = None,
    noise: tuple[float, float] = (20.0, 0.2),
    duration: float = 400.0,
    rate: float = 1.0,
    seed: int = 0,
    scenario: Scenario | None = None,
    observe: str = "ecef",
) -> Path:
    """Fly the truth model and write a record.

    :param out: output CSV path.
    :param effects: effect name -> value text (see the module docstring).
    :param noise: measurement noise standard deviations (position m, velocity m/s),
        applied per component; for ``observe="reduced"`` to altitude and speed.
    :param duration: flight time recorded (s).
    :param rate: samples per second.
    :param seed: noise seed.
    :param scenario: initial state and scripted controls.
    :param observe: ``"ecef"`` (full state) or ``"reduced"`` (altitude, speed, and a
        sidecar with the entry state).
    :return: the record path.
    """
    effects = effects or {}
    sc = scenario or Scenario()
    world = truth_world(effects)
    if rate <= 0 or duration <= 0:
        raise ValueError("rate and duration must be positive")
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    r0, v0 = truth.ecef_from_spherical(
        world.radius + sc.altitude, math.radians(sc.longitude_deg), math.radians(sc.latitude_deg),
        sc.speed, math.radians(sc.flight_path_deg), math.radians(sc.azimuth_deg),
    )  # fmt: skip
    r, v = truth.fly(world, r0, v0, sc.controls, t)
    h = np.linalg.norm(r, axis=1) - world.radius
    if np.any(h < 0):
        t_ground = t[np.argmax(h < 0)]
        raise ValueError(f"the truth flight reaches the ground at t = {t_ground:.0f} s; shorten it")
    rng = np.random.default_rng(seed)
    ctrl = np.array([sc.controls(ti) for ti in t])
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    stale = out.with_suffix(".json")
    if stale.is_file() and GENERATED_BY in stale.read_text():
        stale.unlink()  # a sidecar this command wrote for an earlier record of that name
    if observe == "ecef":
        r_m = r + rng.normal(0.0, noise[0], r.shape)
        v_m = v + rng.normal(0.0, noise[1], v.shape)
        cols = {n: c for n, c in zip(("x_m", "y_m", "z_m"), r_m.T)}
        cols.update({n: c for n, c in zip(("vx_mps", "vy_mps", "vz_mps"), v_m.T)})
    elif observe == "reduced":
        cols = {
            "altitude_m": h + rng.normal(0.0, noise[0], h.shape),
            "speed_rel_mps": np.linalg.norm(v, axis=1) + rng.normal(0.0, noise[1], h.shape),
        }
        sidecar = {
            "generated_by": GENERATED_BY,
            "vehicle": {"name": "CAV-H", "mass_kg": world.mass, "reference_area_m2": world.area,
                        "aerodynamics": {"type": "cav-h"}},
            "entry_state": {"t_s": 0.0, "altitude_m": sc.altitude, "speed_rel_mps": sc.speed,
                            "flight_path_angle_deg": sc.flight_path_deg, "longitude_deg": sc.longitude_deg,
                            "latitude_deg": sc.latitude_deg, "azimuth_deg": sc.azimuth_deg},
        }  # fmt: skip
        out.with_suffix(".json").write_text(json.dumps(sidecar, indent=2) + "\n")
    else:
        raise ValueError("observe must be 'ecef' or 'reduced'")
    cols["alpha_rad"] = ctrl[:, 0]
    cols["bank_rad"] = ctrl[:, 1]
    write_record(out, t, cols)
    meta = {
        "effects": effects,
        "noise": {"position_m" if observe == "ecef" else "altitude_m": noise[0],
                  "velocity_mps" if observe == "ecef" else "speed_mps": noise[1]},
        "seed": seed,
        "scenario": asdict(sc),
        "truth_world": asdict(world),
        "note": "for checking only: rventry identify never reads this file",
    }  # fmt: skip
    out.with_name(out.stem + ".truth.json").write_text(json.dumps(meta, indent=2) + "\n")
    return out


__all__ = ["DEFAULT_VALUES", "Scenario", "parse_effects", "truth_world", "simulate_record"]
