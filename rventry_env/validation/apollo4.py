"""Apollo 4 (AS-501) entry: the shipped flight record, and the density comparison.

The record ``data/apollo4/apollo4.csv`` merges the three CSV files of the
project's shared data (best estimated trajectory, flight-derived vertical L/D,
bank angle) onto one time axis; ``apollo4.json`` is its sidecar (vehicle and
entry state). :func:`convert` regenerates both from the shared data; the
attribution is in ``data/apollo4/README.md``.

Sources: NASA TM X-58091 (trajectory), NASA TN D-5399 (vertical L/D, bank),
digitised and converted to SI by the Tacode project (MIT licence).
"""

from __future__ import annotations

import csv
import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from rventry_env.physics import EntryModel
from rventry_env.validation.record import write_record

RECORD_NAME = "apollo4.csv"

SIDECAR = {
    "description": "Apollo 4 (AS-501) lunar-return entry, 1967-11-09. "
    "t_s from entry interface (GET 29968.54 s).",
    "sources": [
        "trajectory: NASA TM X-58091 (1972) table I, 45-day best estimated trajectory",
        "vertical L/D and bank: NASA TN D-5399 (1969) figures 16(a) and 6(b), digitised",
        "digitisation and SI conversion: Tacode, github.com/ytakahashi3123/Tacode (MIT licence)",
    ],
    "vehicle": {
        "name": "Apollo CM (AS-501)",
        "mass_kg": 5424.6,
        "reference_area_m2": 12.0171,
        "aerodynamics": {"type": "constant", "drag_coefficient": 1.2891, "lift_to_drag": 0.368},
        "notes": "mass TN D-5399 table II; area pi/4 x 3.9116^2 (TN D-3890); C_D trim for M > 29.5 "
        "(TN D-6725 table I); L/D flight-derived (TN D-5399)",
    },
    # the published experiment starts from a capsule without lift: lift is what the loop must find
    "start_model": "drag-only",
    "entry_state": {
        "t_s": -0.54,
        "altitude_m": 123479.4,
        "speed_rel_mps": 10733.84,
        "flight_path_angle_deg": -7.129,
        "longitude_deg": 153.932,
        "latitude_deg": 18.467,
        "azimuth_deg": 62.65,
        "notes": "TM X-58091 table I first row; flight-path angle and ground track are Tacode's "
        "assumptions (quadratic fit of the first rows; great circle back from splashdown)",
    },
}

# published 3-DOF reconstruction (Tacode's Apollo 4 validation): rms altitude error
PUBLISHED_RMS_ALTITUDE_M = {"drag_only": 27.1e3, "measured_lift": 5.4e3}


def _read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    out = {}
    for i, h in enumerate(header):
        out[h] = np.array([float(r[i]) if r[i].strip() else math.nan for r in rows[1:]])
    return out


def convert(src: str | Path, out: str | Path) -> Path:
    """Write the Apollo 4 record and sidecar from the shared CSV files.

    :param src: folder with ``bet.csv``, ``lift_vertical.csv`` and ``bank.csv``.
    :param out: output folder.
    :return: the record path.
    """
    src, out = Path(src), Path(out)
    bet = _read(src / "bet.csv")
    ldv = _read(src / "lift_vertical.csv")
    bank = _read(src / "bank.csv")
    # every file is on the same x.46 s grid: merge by time rounded to the millisecond
    keys = sorted({round(t, 3) for d in (bet, ldv, bank) for t in d["t_s"]})
    idx = {k: i for i, k in enumerate(keys)}
    n = len(keys)
    names = ("altitude_m", "speed_rel_mps", "density_kgpm3", "bank_rad", "lift_to_drag_vertical")
    cols = {c: np.full(n, math.nan) for c in names}
    for i, t in enumerate(bet["t_s"]):
        j = idx[round(t, 3)]
        for c in ("altitude_m", "speed_rel_mps", "density_kgpm3"):
            cols[c][j] = bet[c][i]
    for i, t in enumerate(ldv["t_s"]):
        cols["lift_to_drag_vertical"][idx[round(t, 3)]] = ldv["lift_to_drag_vertical"][i]
    for i, t in enumerate(bank["t_s"]):
        cols["bank_rad"][idx[round(t, 3)]] = math.radians(bank["bank_deg"][i])
    path = write_record(out / RECORD_NAME, np.array(keys), cols)
    (out / "apollo4.json").write_text(json.dumps(SIDECAR, indent=2) + "\n")
    return path


def record_path() -> Path:
    """The shipped Apollo 4 record (its sidecar ``apollo4.json`` lies beside it)."""
    return Path(str(resources.files("rventry_env.validation") / "data" / "apollo4" / RECORD_NAME))


def density_comparison(altitude: np.ndarray, density: np.ndarray, model: EntryModel) -> dict:
    """The record's flight-derived density against a model atmosphere at the same altitudes.

    :param altitude: record altitudes (m).
    :param density: record densities (kg/m^3), NaN where none.
    :param model: the model whose atmosphere is compared.
    :return: altitudes, the log ratio ln(rho_record / rho_model) and its summary.
    """
    from rventry_env.core.backend import NUMPY

    ok = np.isfinite(altitude) & np.isfinite(density) & (density > 0)
    h = altitude[ok]
    rho_model = np.asarray(model.atmosphere.density(h, NUMPY), float)
    lr = np.log(density[ok] / rho_model)
    return {
        "altitude_m": h.tolist(),
        "log_ratio_record_over_model": lr.tolist(),
        "rms_log_ratio": float(np.sqrt(np.mean(lr**2))),
        "mean_log_ratio": float(np.mean(lr)),
        "samples": int(ok.sum()),
    }


__all__ = [
    "PUBLISHED_RMS_ALTITUDE_M",
    "RECORD_NAME",
    "SIDECAR",
    "convert",
    "density_comparison",
    "record_path",
]
