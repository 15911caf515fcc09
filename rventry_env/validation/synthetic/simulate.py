"""Synthetic flight records: the CAV-H flown through the truth model with undeclared effects.

``rventry simulate-record --effect NAME[=VALUE] ... --noise POS_M,VEL_MPS --out RECORD.csv``

The vehicle flies a scripted glide (angle of attack and conventional bank as
smooth functions of time) through :mod:`rventry_env.validation.synthetic.truth`, which
contains the requested effects. The record is written in the format of
docs/conventions.md *without* a sidecar, so the identification is told nothing:
it sees a CAV-H flight under the default Earth and atmosphere. The effects and the noise are
written to a separate ``<record>.truth.json`` for checking, never read by
``rventry identify``.

Effect values (defaults in brackets):

* ``j2_gravity=J2`` the second zonal harmonic [1.08262668e-3];
* ``density_profile=A`` ln(rho_true / rho_exp) = A sin(2 pi (h - 30 km) / 80 km) [0.2];
* ``lift_coefficient=S`` C_L multiplied by S [0.9];
* ``drag_coefficient=S`` C_D multiplied by S [1.1];
* ``wind=E[,N]`` a horizontal wind, east and north (m/s) [50];
* ``mass=S`` the vehicle's true mass is S times the declared 907.2 kg [1.06];
* ``us76_density`` the U.S. Standard Atmosphere 1976 in place of the exponential one;
* ``mach_drag=A`` C_D multiplied by exp(A (1 - exp((M - 22) / 5))): 1 at Mach 22, the
  start of the scripted glide, and growing toward lower Mach [0.15];
* ``time_offset=DT`` the observations' time tags are DT seconds early: the row of time t
  holds the state at t + DT (the controls keep their own time) [0.5];
* ``lift_band=S,LO,HI`` / ``drag_band=S,LO,HI`` C_L (C_D) multiplied by S between LO and HI km
  altitude, with 1 km edges [0.8,50,53 / 1.15,50,53: the bottom of the scripted glide];
* ``mach_lift=S,M`` C_L multiplied by S below Mach M (1-Mach edge; the truth's speed of sound is
  300 m/s) [0.85,21];
* ``wind_shear=W[,H]`` an eastward wind W tanh((h - H) / 2 km) that reverses at H km [60,54];
* ``side_force=Y`` a force out of the vertical plane, Y times the drag [0.02];
* ``density_wave=A,WAVELENGTH_KM`` ln(rho_true / rho_exp) = A sin(2 pi (h - 30 km) / WAVELENGTH):
  the ``density_profile`` sinusoid with a wavelength of a few kilometres [0.08,6];
* ``mass_loss=F,T0,T1`` the mass falls by the fraction F linearly from T0 to T1 s (ablation)
  [0.05,100,300];
* ``bank_bias=DEG`` the record's bank column reads DEG more than the bank flown [2];
* ``alpha_bias=DEG`` the record's angle of attack reads DEG more than the angle flown (a trim
  offset) [-1].

``mach_drag`` is outside the identification's candidate set in shape (a smooth Mach law against a
piecewise-linear correction); ``time_offset`` is the record effect of the same name (a clock offset
between the record's states and its controls); the band, Mach-lift, shear, side-force,
mass-loss and control-bias effects are outside it altogether, for the residual trace
(:mod:`rventry_env.validation.trace`); the density wave is in the set's shape only where the
profile's knots resolve it.

A reduced record's sidecar declares the true entry state unless ``entry_offset`` moves it (the
sidecar's altitude and speed that much above the truth: a sidecar that disagrees with its record).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from rventry_env.util.files import write_json
from rventry_env.validation.record import write_record
from rventry_env.validation.synthetic import truth

GENERATED_BY = "rventry simulate-record"
DEFAULT_VALUES = {
    "j2_gravity": "1.08262668e-3",
    "density_profile": "0.2",
    "lift_coefficient": "0.9",
    "drag_coefficient": "1.1",
    "wind": "50",
    "mass": "1.06",
    "us76_density": "",
    "mach_drag": "0.15",
    "time_offset": "0.5",
    # outside the candidate set: for the residual trace
    "lift_band": "0.8,50,53",
    "drag_band": "1.15,50,53",
    "mach_lift": "0.85,21",
    "wind_shear": "60,54",
    "side_force": "0.02",
    "density_wave": "0.08,6",
    "mass_loss": "0.05,100,300",
    "bank_bias": "2",
    "alpha_bias": "-1",
}
RECORD_EFFECTS = ("time_offset", "bank_bias", "alpha_bias")  # in how the record reads the flight, not in the world
SIMULATED_EFFECTS = tuple(DEFAULT_VALUES)


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
        if name not in SIMULATED_EFFECTS:
            raise ValueError(f"--effect: unknown effect {name!r}; choose from {', '.join(SIMULATED_EFFECTS)}")
        if name in out:
            raise ValueError(f"--effect: effect {name!r} given twice")
        out[name] = value.strip() or DEFAULT_VALUES[name]
    return out


def _with_effect(w: truth.TruthWorld, name: str, values: list[float]) -> truth.TruthWorld:
    """``w`` with the world effect ``name`` at ``values`` (checked: their number and range); the record
    effects (a time offset, a bank or angle-of-attack bias) are only checked here."""
    if name == "wind":
        if len(values) > 2:
            raise ValueError("--effect wind takes EAST or EAST,NORTH (m/s)")
        return replace(w, wind_east=values[0], wind_north=values[1] if len(values) > 1 else 0.0)
    if name in ("lift_band", "drag_band"):
        if len(values) != 3 or values[0] <= 0 or not values[1] < values[2]:
            raise ValueError(f"--effect {name} takes SCALE,LOW_KM,HIGH_KM (scale > 0, low < high)")
        return replace(w, band_channel=name.split("_")[0], band_scale=values[0], band_low=values[1] * 1e3,
                       band_high=values[2] * 1e3)  # fmt: skip
    if name == "mach_lift":
        if len(values) != 2 or values[1] <= 0:
            raise ValueError("--effect mach_lift takes SCALE,MACH (C_L x SCALE below MACH > 0)")
        return replace(w, mach_lift_scale=values[0], mach_lift_below=values[1])
    if name == "density_wave":
        if len(values) != 2 or values[1] <= 0:
            raise ValueError("--effect density_wave takes AMPLITUDE,WAVELENGTH_KM (wavelength > 0)")
        return replace(w, density_amplitude=values[0], density_wavelength=values[1] * 1e3)
    if name == "mass_loss":
        if len(values) != 3 or not (0 <= values[0] < 1) or not values[1] < values[2]:
            raise ValueError("--effect mass_loss takes FRACTION,T0_S,T1_S (0 <= fraction < 1, T0 < T1)")
        return replace(w, mass_loss=values[0], mass_loss_start=values[1], mass_loss_end=values[2])
    if name == "wind_shear":
        if len(values) > 2:
            raise ValueError("--effect wind_shear takes PEAK_MPS[,REVERSAL_KM]")
        return replace(w, wind_shear=values[0], shear_altitude=(values[1] * 1e3 if len(values) > 1 else w.shear_altitude))
    if len(values) != 1:
        raise ValueError(f"--effect {name} takes one value")
    v = values[0]
    if name == "j2_gravity":
        w = replace(w, j2=v)
    elif name == "density_profile":
        w = replace(w, density_amplitude=v)
    elif name == "lift_coefficient":
        w = replace(w, cl_scale=v)
    elif name in ("drag_coefficient", "mass"):
        if v <= 0:
            raise ValueError(f"--effect {name}: the scale must be positive, got {v:g}")
        w = replace(w, cd_scale=v) if name == "drag_coefficient" else replace(w, mass=w.mass * v)
    elif name == "mach_drag":
        w = replace(w, mach_drag_amplitude=v)
    elif name == "side_force":
        w = replace(w, side_force=v)
    elif name == "time_offset":
        if abs(v) > 10.0:
            raise ValueError(f"--effect time_offset: at most 10 s, got {v:g}")
    elif name in ("bank_bias", "alpha_bias"):
        if abs(v) > 30.0:
            raise ValueError(f"--effect {name}: at most 30 deg, got {v:g}")
    return w


def truth_world(effects: dict[str, str]) -> truth.TruthWorld:
    """The truth model containing ``effects`` (name -> value text); :data:`RECORD_EFFECTS` are not world effects."""
    w = truth.TruthWorld()
    for name, text in effects.items():
        if name == "us76_density":
            if text.strip():
                raise ValueError("--effect us76_density takes no value")
            w = replace(w, atmosphere="us76")
            continue
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise ValueError(f"--effect {name}: cannot read {text!r} as number(s)") from None
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"--effect {name}: values must be finite, got {text!r}")
        w = _with_effect(w, name, values)
    return w


def _sample_times(rate: float, duration: float, noise) -> np.ndarray:
    """The record's sample times, after checking the rate, the duration and the noise."""
    if rate <= 0 or duration <= 0:
        raise ValueError("rate and duration must be positive")
    if not (math.isfinite(rate) and math.isfinite(duration)):
        raise ValueError("rate and duration must be finite")
    if len(noise) != 2 or not all(math.isfinite(x) and x >= 0 for x in noise):
        raise ValueError(f"--noise: two finite numbers >= 0 (position m, velocity m/s), got {noise!r}")
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    if len(t) < 5:
        raise ValueError(f"--duration {duration:g} s at --rate {rate:g} Hz gives {len(t)} sample(s); at least 5")
    if len(t) > 200_000:
        raise ValueError(f"--duration {duration:g} s at --rate {rate:g} Hz gives {len(t)} samples; at most 200000")
    return t


def _fly_truth(world, sc: "Scenario", t: np.ndarray, dt_tag: float, effects: dict[str, str]) -> tuple:
    """(r, v, altitude) of the truth flight at the record's times, a time-tag offset applied."""
    r0, v0 = truth.ecef_from_spherical(
        world.radius + sc.altitude, math.radians(sc.longitude_deg), math.radians(sc.latitude_deg),
        sc.speed, math.radians(sc.flight_path_deg), math.radians(sc.azimuth_deg),
    )  # fmt: skip
    # a time-tag offset: the row of time t holds the state at t + dt_tag (started that much later)
    t_true = t + dt_tag

    def fly(times):
        try:
            return truth.fly(world, r0, v0, sc.controls, times)
        except (OverflowError, RuntimeError) as exc:  # an effect so strong the flight leaves floating point
            given = ", ".join(f"{k}={v}" for k, v in effects.items()) or "none"
            raise ValueError(f"--effect {given}: the truth flight cannot be flown with these effects ({exc}); "
                             "choose values nearer the defaults") from None  # fmt: skip

    if dt_tag:
        t_fly = np.concatenate([[0.0], t_true]) if t_true[0] > 0 else t_true
        r, v = fly(t_fly)
        if t_true[0] > 0:
            r, v = r[1:], v[1:]
    else:
        r, v = fly(t)
    h = np.linalg.norm(r, axis=1) - world.radius
    if np.any(h < 0):
        t_ground = t[np.argmax(h < 0)]
        raise ValueError(f"the truth flight reaches the ground at t = {t_ground:.0f} s; shorten it")
    return r, v, h


def _reduced_sidecar(sc: "Scenario", world, entry_offset=None) -> dict:
    """The sidecar of a reduced record: the declared vehicle and the entry state (off the truth's by
    ``entry_offset``, metres and m/s, where given)."""
    dh, dv = entry_offset or (0.0, 0.0)
    return {
        "generated_by": GENERATED_BY,
        # the declared vehicle: a mass effect stays undeclared
        "vehicle": {"name": "CAV-H", "mass_kg": truth.TruthWorld().mass, "reference_area_m2": world.area,
                    "aerodynamics": {"type": "cav-h"}},
        "entry_state": {"t_s": 0.0, "altitude_m": sc.altitude + dh, "speed_rel_mps": sc.speed + dv,
                        "flight_path_angle_deg": sc.flight_path_deg, "longitude_deg": sc.longitude_deg,
                        "latitude_deg": sc.latitude_deg, "azimuth_deg": sc.azimuth_deg},
    }  # fmt: skip


def _truth_meta(effects, noise, observe: str, noise_tails: str, start_scatter, entry_offset, seed: int, sc,
                world) -> dict:  # fmt: skip
    """What the record was made from, for checking an identification against it (``.truth.json``)."""
    return {
        "effects": effects,
        "noise": {"position_m" if observe == "ecef" else "altitude_m": noise[0],
                  "velocity_mps" if observe == "ecef" else "speed_mps": noise[1]},
        "noise_tails": noise_tails,
        "start_scatter": None if start_scatter is None else {"seconds": start_scatter[0], "metres": start_scatter[1]},
        "entry_offset": None if entry_offset is None else {"altitude_m": entry_offset[0], "speed_mps": entry_offset[1]},
        "seed": seed,
        "scenario": asdict(sc),
        "truth_world": asdict(world),
        "note": "for checking only: rventry identify never reads this file",
    }  # fmt: skip


def _record_bias(effects: dict[str, str], name: str) -> float:
    """The bias (rad) a control column reads with, from a ``bank_bias``/``alpha_bias`` effect (0 without)."""
    return math.radians(float(effects[name])) if name in effects else 0.0


def _check_noise_shape(noise_tails: str, start_scatter, entry_offset, observe: str) -> None:
    if noise_tails not in ("normal", "student-t3"):
        raise ValueError(f"noise_tails must be 'normal' or 'student-t3', got {noise_tails!r}")
    if start_scatter is not None and not (len(start_scatter) == 2 and all(math.isfinite(x) and x >= 0
                                                                         for x in start_scatter)):  # fmt: skip
        raise ValueError(f"start_scatter: two finite numbers >= 0 (seconds, metres), got {start_scatter!r}")
    if entry_offset is not None and not (len(entry_offset) == 2 and all(math.isfinite(x) for x in entry_offset)):
        raise ValueError(f"entry_offset: two finite numbers (metres, m/s), got {entry_offset!r}")
    if entry_offset is not None and observe != "reduced":
        raise ValueError("entry_offset: only a reduced record has a sidecar entry state")


def _output_path(out: str | Path) -> Path:
    """The record's path, its folder made, and a sidecar this command wrote beside an earlier record
    of that name removed."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    stale = out.with_suffix(".json")
    if stale.is_file() and GENERATED_BY in stale.read_text():
        stale.unlink()  # a sidecar this command wrote for an earlier record of that name
    return out


def _measured_columns(observe: str, t: np.ndarray, r: np.ndarray, v: np.ndarray, h: np.ndarray, noise,
                      noise_tails: str, start_scatter, rng: np.random.Generator) -> dict:  # fmt: skip
    """The observation columns of the record: the true positions and velocities (``"ecef"``) or
    altitude and speed (``"reduced"``) with the measurement noise drawn from ``rng`` (normal or
    heavy-tailed), and the start's scatter on the positions or altitudes."""

    def draw(sd: float, shape) -> np.ndarray:
        if noise_tails == "normal":
            return rng.normal(0.0, sd, shape)
        return sd * rng.standard_t(3, shape) / math.sqrt(3.0)  # variance of t(3) is 3

    def scatter(shape) -> np.ndarray:
        out = np.zeros(shape)
        if start_scatter is not None and start_scatter[1] > 0:
            early = t <= start_scatter[0]
            out[early] = rng.normal(0.0, start_scatter[1], out[early].shape)
        return out

    if observe == "ecef":
        r_m = r + draw(noise[0], r.shape) + scatter(r.shape)
        v_m = v + draw(noise[1], v.shape)
        cols = {n: c for n, c in zip(("x_m", "y_m", "z_m"), r_m.T)}
        cols.update({n: c for n, c in zip(("vx_mps", "vy_mps", "vz_mps"), v_m.T)})
    elif observe == "reduced":
        cols = {
            "altitude_m": h + draw(noise[0], h.shape) + scatter(h.shape),
            "speed_rel_mps": np.linalg.norm(v, axis=1) + draw(noise[1], h.shape),
        }
    else:
        raise ValueError("observe must be 'ecef' or 'reduced'")
    return cols


def simulate_record(
    out: str | Path,
    effects: dict[str, str] | None = None,
    noise: tuple[float, float] = (20.0, 0.2),
    duration: float = 400.0,
    rate: float = 1.0,
    seed: int = 0,
    scenario: Scenario | None = None,
    observe: str = "ecef",
    noise_tails: str = "normal",
    start_scatter: tuple[float, float] | None = None,
    entry_offset: tuple[float, float] | None = None,
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
    :param noise_tails: ``"normal"``, or ``"student-t3"``: Student's t with 3 degrees of freedom
        scaled to the same standard deviation (heavy tails).
    :param start_scatter: ``(seconds, metres)``: the samples of the first ``seconds`` scatter by
        a further ``metres`` (one standard deviation, normal) in every position or altitude
        component, like a record digitised from a figure whose start is crowded.
    :param entry_offset: ``(metres, m/s)``: a reduced record's sidecar declares the entry altitude
        and speed this much above the truth (a sidecar that disagrees with its record, e.g. an
        altitude on another reference).
    :return: the record path.
    """
    effects = effects or {}
    sc = scenario or Scenario()
    world = truth_world(effects)
    t = _sample_times(rate, duration, noise)
    dt_tag = float(effects.get("time_offset", "0") or 0.0) if "time_offset" in effects else 0.0
    r, v, h = _fly_truth(world, sc, t, dt_tag, effects)
    _check_noise_shape(noise_tails, start_scatter, entry_offset, observe)
    rng = np.random.default_rng(seed)
    ctrl = np.array([sc.controls(ti) for ti in t])
    out = _output_path(out)
    cols = _measured_columns(observe, t, r, v, h, noise, noise_tails, start_scatter, rng)
    if observe == "reduced":
        write_json(out.with_suffix(".json"), _reduced_sidecar(sc, world, entry_offset), indent=2)
    cols["alpha_rad"] = ctrl[:, 0] + _record_bias(effects, "alpha_bias")
    cols["bank_rad"] = ctrl[:, 1] + _record_bias(effects, "bank_bias")
    write_record(out, t, cols)
    meta = _truth_meta(effects, noise, observe, noise_tails, start_scatter, entry_offset, seed, sc, world)
    write_json(out.with_name(out.stem + ".truth.json"), meta, indent=2)
    return out


__all__ = ["DEFAULT_VALUES", "RECORD_EFFECTS", "SIMULATED_EFFECTS", "Scenario", "parse_effects", "simulate_record",
           "truth_world"]
