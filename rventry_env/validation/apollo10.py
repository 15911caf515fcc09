"""Apollo 10 (AS-505) entry: the second shipped flight record, digitised from a report figure.

The record ``data/apollo10/apollo10.csv`` holds the altitude and the inertial speed the vehicle
flew (NASA TN D-6725, figure 13, the "Actual" curves) and the roll angle the guidance held
(figure 12), merged on one time axis; ``apollo10.json`` is its sidecar: the command module and the
entry state of the report's table II, converted to an Earth-relative state by a published
reconstruction. :func:`convert` regenerates both from the digitised files; the attribution is in
``data/apollo10/README.md``.

What makes the record hard, and why it is shipped:

* it is read from a figure: its reading error is about 1 km in altitude and 100 m/s in speed,
  and near entry the samples scatter by about a kilometre;
* its sidecar disagrees with its first samples by about 4 km in altitude (the robust line through
  the first 30 s), the size of the altitude reference at 23.7 deg S (geodetic against the model's
  sphere, 3.5 km): a finding of the identification, not an error;
* its speed is inertial (``speed_inertial_mps``), as the report plots it.

Sources: NASA TN D-6725 (table I: trim coefficients; table II: entry state; figures 12 and 13),
digitised and converted to SI by the Tacode project (MIT licence).
"""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from rventry_env.validation.record import write_record

RECORD_NAME = "apollo10.csv"

SIDECAR = {
    "description": "Apollo 10 (AS-505) lunar-return entry, 1969-05-26. t_s from entry interface "
    "(400 000 ft; 191:48:52 GET).",
    "sources": [
        "altitude and inertial speed flown: NASA TN D-6725 (1972) figure 13, 'Actual' curves, digitised",
        "roll angle held: NASA TN D-6725 figure 12, digitised",
        "entry state: NASA TN D-6725 table II (best-estimated trajectory), converted to an Earth-relative state",
        "digitisation, conversion and SI units: Tacode, github.com/ytakahashi3123/Tacode (MIT licence)",
    ],
    "vehicle": {
        "name": "Apollo CM (AS-505)",
        "mass_kg": 5500.0,
        "reference_area_m2": 12.0171,
        "aerodynamics": {"type": "constant", "drag_coefficient": 1.2891, "lift_to_drag": 0.30076},
        "notes": "C_D and C_L = 0.38773 (L/D 0.30076): TN D-6725 table I, trim values for M > 29.5; area "
        "pi/4 x 3.9116^2 (TN D-3890); mass not in the references: the figure commonly quoted for a "
        "lunar-return command module",
    },
    "start_model": "declared",
    "entry_state": {
        "t_s": 0.0,
        "altitude_m": 123883.0,
        "speed_rel_mps": 10657.67,
        "flight_path_angle_deg": -6.827,
        "longitude_deg": 174.244,
        "latitude_deg": -23.652,
        "azimuth_deg": 71.182,
        "notes": "TN D-6725 table II: 11067.06 m/s inertial, -6.616 deg, 71.928 deg at 174.244 E, 23.652 S, "
        "123.883 km; the Earth's rotation (434.54 m/s eastward there) subtracted and the velocity rotated "
        "into the geocentric horizon by Tacode's conversion. The report does not say on which reference "
        "its altitude and flight-path angle are read",
    },
}

# published 3-DOF replay of this flight from the same entry state and roll history (Tacode's
# Apollo 10 validation, NRLMSISE-00 atmosphere, mass 5500 kg): altitude difference over the 311
# digitised points
PUBLISHED_RMS_ALTITUDE_M = 3.19e3
READING_ERROR = {"altitude_m": 1000.0, "speed_mps": 100.0}  # the digitisation's line width


def read_digitised(path: str | Path) -> np.ndarray:
    """The numeric rows of a digitised Tacode reference file (its ``zone`` and ``f=point`` data), ``(n, columns)``."""
    rows = []
    for line in Path(path).read_text().splitlines():
        fields = line.split()
        if not fields or line.lstrip().startswith(("#", "Variables", "zone")):
            continue
        rows.append([float(x) for x in fields])
    if not rows:
        raise ValueError(f"{path}: no data rows")
    return np.array(rows)


def convert(src: str | Path, out: str | Path) -> Path:
    """Write the Apollo 10 record and sidecar from the digitised files.

    :param src: folder with ``apollo10_flight.dat`` (time s, altitude km, inertial speed m/s) and
        ``apollo10_roll.dat`` (time s, roll angle deg, 0 = lift up).
    :param out: output folder.
    :return: the record path.
    """
    src, out = Path(src), Path(out)
    flight = read_digitised(src / "apollo10_flight.dat")
    roll = read_digitised(src / "apollo10_roll.dat")
    # both files print times to 8 significant digits: merge them on times rounded to the microsecond
    keys = sorted({round(t, 6) for t in flight[:, 0]} | {round(t, 6) for t in roll[:, 0]})
    idx = {k: i for i, k in enumerate(keys)}
    n = len(keys)
    cols = {c: np.full(n, math.nan) for c in ("altitude_m", "speed_inertial_mps", "bank_rad")}
    for t, h_km, v in flight[:, :3]:
        j = idx[round(t, 6)]
        cols["altitude_m"][j] = h_km * 1e3
        cols["speed_inertial_mps"][j] = v
    for t, bank in roll[:, :2]:
        cols["bank_rad"][idx[round(t, 6)]] = math.radians(bank)
    out.mkdir(parents=True, exist_ok=True)
    path = write_record(out / RECORD_NAME, np.array(keys), cols)
    (out / "apollo10.json").write_text(json.dumps(SIDECAR, indent=2) + "\n")
    return path


def record_path() -> Path:
    """The shipped Apollo 10 record (its sidecar ``apollo10.json`` lies beside it)."""
    return Path(str(resources.files("rventry_env.validation") / "data" / "apollo10" / RECORD_NAME))


__all__ = ["PUBLISHED_RMS_ALTITUDE_M", "READING_ERROR", "RECORD_NAME", "SIDECAR", "convert", "read_digitised",
           "record_path"]
