"""Flight records (PROBLEM.md format): load, validate, and say what was used and ignored.

A record is a CSV file with a header row and one row per sample, time strictly
increasing. It carries one observation set, the full ECEF state
(``x_m .. vz_mps``) or the reduced one (``altitude_m, speed_rel_mps``), optional
controls (``alpha_rad``, ``bank_rad``, ``lift_to_drag_vertical``) and an optional
measured ``density_kgpm3``. Empty fields are gaps. A JSON sidecar
``<record>.json`` (or ``<record>.csv.json``) may name the vehicle and, for the
reduced set, the entry state.

Everything that cannot be used is rejected with a :class:`RecordError` naming the
row (the file's line number, the header being line 1) or column; everything that
is read but not used is listed in :attr:`FlightRecord.notes`.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ECEF_COLUMNS = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
REDUCED_COLUMNS = ("altitude_m", "speed_rel_mps")
CONTROL_COLUMNS = ("alpha_rad", "bank_rad", "lift_to_drag_vertical")
OPTIONAL_COLUMNS = CONTROL_COLUMNS + ("density_kgpm3",)
KNOWN_COLUMNS = ("t_s",) + ECEF_COLUMNS + REDUCED_COLUMNS + OPTIONAL_COLUMNS

# plausibility bounds for an entry flight (the unit checks)
EARTH_RADIUS = 6378137.0
MAX_ALTITUDE = 1.0e6  # m: above this it is not an entry record
MIN_ALTITUDE = -5.0e3  # m
MAX_SPEED = 2.0e4  # m/s: faster than any Earth entry
MIN_ENTRY_SPEED = 50.0  # m/s: a record whose every speed is below this is in km/s
MIN_OBSERVATIONS = 5


class RecordError(ValueError):
    """A record (or its sidecar) that cannot be used, with the reason and where."""


@dataclass
class FlightRecord:
    """A validated flight record.

    :param t: sample times (s), strictly increasing, one per CSV row.
    :param kind: ``"ecef"`` or ``"reduced"``, the observation set used.
    :param observations: ``(n, m)`` measured values, NaN in gaps; columns
        :attr:`observation_names`.
    :param observation_names: the columns of ``observations``.
    :param alpha: angle of attack (rad) per row, NaN in gaps, or None.
    :param bank: conventional bank angle mu (rad) per row, or None.
    :param lift_to_drag_vertical: vertical L/D per row, or None.
    :param density: measured density (kg/m^3) per row, or None.
    :param sidecar: the parsed sidecar JSON, or None.
    :param notes: what was read but ignored, and how gaps are handled.
    :param path: the file it came from.
    """

    t: np.ndarray
    kind: str
    observations: np.ndarray
    observation_names: tuple
    alpha: np.ndarray | None = None
    bank: np.ndarray | None = None
    lift_to_drag_vertical: np.ndarray | None = None
    density: np.ndarray | None = None
    sidecar: dict | None = None
    notes: list = field(default_factory=list)
    path: Path | None = None

    @property
    def observed_rows(self) -> np.ndarray:
        """Indices of rows with at least one measured observation."""
        return np.flatnonzero(np.any(np.isfinite(self.observations), axis=1))

    @property
    def n_values(self) -> int:
        """Number of measured scalar observations."""
        return int(np.count_nonzero(np.isfinite(self.observations)))

    def altitude(self) -> np.ndarray:
        """Measured altitude per row (m; NaN where unknown), from either observation set."""
        if self.kind == "reduced":
            return self.observations[:, 0]
        return np.linalg.norm(self.observations[:, :3], axis=1) - EARTH_RADIUS


def _parse_float(text: str, line: int, column: str) -> float:
    """A field as a float; '' is a gap (NaN). A literal NaN or inf is an error, not a gap."""
    text = text.strip()
    if text == "":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise RecordError(f"row {line}, column {column}: cannot read {text!r} as a number") from None
    if not math.isfinite(value):
        raise RecordError(
            f"row {line}, column {column}: {text!r} where a value is required "
            "(leave the field empty for a missing sample)"
        )
    return value


def _read_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise RecordError(f"{path}: empty file (expected a header row)") from None
        dupes = sorted({h for h in header if header.count(h) > 1})
        if dupes:
            raise RecordError(f"{path}: duplicate column(s) {', '.join(dupes)}")
        rows = []
        for line, row in enumerate(reader, start=2):
            if not row or all(not f.strip() for f in row):
                continue  # a blank line carries nothing
            if len(row) != len(header):
                raise RecordError(f"row {line}: {len(row)} fields, the header has {len(header)}")
            rows.append((line, row))
    if not rows:
        raise RecordError(f"{path}: no data rows")
    cols = {}
    for j, name in enumerate(header):
        if name in KNOWN_COLUMNS:
            cols[name] = np.array([_parse_float(r[j], line, name) for line, r in rows])
    cols["_line"] = np.array([line for line, _ in rows])
    return header, cols


def _check_time(t: np.ndarray, lines: np.ndarray) -> None:
    missing = np.flatnonzero(~np.isfinite(t))
    if missing.size:
        raise RecordError(f"row {lines[missing[0]]}, column t_s: time is required in every row")
    dt = np.diff(t)
    dup = np.flatnonzero(dt == 0)
    if dup.size:
        k = dup[0] + 1
        raise RecordError(
            f"row {lines[k]}, column t_s: duplicate time t_s = {t[k]:g} (same as row {lines[k - 1]}); "
            "time must be strictly increasing"
        )
    back = np.flatnonzero(dt < 0)
    if back.size:
        k = back[0] + 1
        raise RecordError(
            f"row {lines[k]}, column t_s: non-monotonic time, t_s = {t[k]:g} after {t[k - 1]:g} "
            f"(row {lines[k - 1]}); time must be strictly increasing"
        )


def _first_bad(mask: np.ndarray, lines: np.ndarray) -> int:
    return int(lines[np.flatnonzero(mask)[0]])


def _check_units(cols: dict, lines: np.ndarray) -> None:
    """Reject values whose magnitude says the unit is wrong (km for m, km/s for m/s, deg for rad)."""
    if "altitude_m" in cols:
        h = cols["altitude_m"]
        hf = h[np.isfinite(h)]
        if hf.size and np.max(np.abs(hf)) < 1000.0:
            raise RecordError(
                f"column altitude_m: implausible unit, every altitude is below 1000 (max {np.max(hf):g}); "
                "this looks like kilometres where metres are expected"
            )
        bad = np.isfinite(h) & ((h > MAX_ALTITUDE) | (h < MIN_ALTITUDE))
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column altitude_m: implausible altitude "
                f"{h[bad][0]:g} m for an entry flight"
            )
    if all(c in cols for c in ECEF_COLUMNS[:3]):
        rn = np.linalg.norm(np.stack([cols[c] for c in ECEF_COLUMNS[:3]], axis=1), axis=1)
        ok = np.isfinite(rn)
        if np.any(ok) and np.max(rn[ok]) < 1.0e5:
            raise RecordError(
                f"columns x_m, y_m, z_m: implausible unit, |r| is at most {np.max(rn[ok]):g}; "
                "this looks like kilometres where metres are expected"
            )
        alt = rn - EARTH_RADIUS
        bad = ok & ((alt > MAX_ALTITUDE) | (alt < MIN_ALTITUDE))
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, columns x_m, y_m, z_m: implausible position, altitude "
                f"{alt[bad][0]:g} m (|r| = {rn[bad][0]:g} m) for an entry flight about an Earth of radius "
                f"{EARTH_RADIUS:g} m"
            )
    for names in (("speed_rel_mps",), ECEF_COLUMNS[3:]):
        if not all(c in cols for c in names):
            continue
        speed = np.linalg.norm(np.stack([cols[c] for c in names], axis=1), axis=1)
        ok = np.isfinite(speed)
        label = ", ".join(names)
        if np.any(ok) and np.max(speed[ok]) < MIN_ENTRY_SPEED:
            raise RecordError(
                f"column(s) {label}: implausible unit, every speed is below {MIN_ENTRY_SPEED:g} "
                f"(max {np.max(speed[ok]):g}); this looks like km/s where m/s is expected"
            )
        bad = ok & (speed > MAX_SPEED)
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column(s) {label}: implausible speed {speed[bad][0]:g} m/s"
            )
    for name in ("alpha_rad", "bank_rad"):
        if name in cols:
            a = cols[name]
            bad = np.isfinite(a) & (np.abs(a) > 2.0 * math.pi + 1e-9)
            if np.any(bad):
                raise RecordError(
                    f"row {_first_bad(bad, lines)}, column {name}: |{a[bad][0]:g}| exceeds 2 pi; "
                    "this looks like degrees where radians are expected"
                )
    if "density_kgpm3" in cols:
        d = cols["density_kgpm3"]
        bad = np.isfinite(d) & ((d < 0) | (d > 2.0))
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column density_kgpm3: "
                f"implausible density {d[bad][0]:g} kg/m^3"
            )
    if "lift_to_drag_vertical" in cols:
        ld = cols["lift_to_drag_vertical"]
        bad = np.isfinite(ld) & (np.abs(ld) > 5.0)
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column lift_to_drag_vertical: "
                f"implausible value {ld[bad][0]:g}"
            )


def sidecar_path(path: Path) -> Path | None:
    """The sidecar of a record: ``<stem>.json`` or ``<name>.json`` beside it, if one exists."""
    for cand in (path.with_suffix(".json"), path.with_name(path.name + ".json")):
        if cand.is_file():
            return cand
    return None


def load_sidecar(path: Path) -> dict:
    """Parse a sidecar or vehicle JSON file (an object at top level)."""
    try:
        data = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise RecordError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise RecordError(f"{path}: expected a JSON object at top level")
    return data


def load_record(path: str | Path, *, sidecar: dict | None = None, use_sidecar: bool = True) -> FlightRecord:
    """Read and validate a flight record.

    :param path: the CSV file.
    :param sidecar: a parsed sidecar to use instead of the file beside the record.
    :param use_sidecar: look for ``<record>.json`` when ``sidecar`` is None.
    :raises RecordError: with the row or column at fault.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such record: {path}")
    header, cols = _read_csv(path)
    lines = cols.pop("_line")
    notes: list[str] = []
    if "t_s" not in cols:
        raise RecordError("missing required column t_s")
    _check_time(cols["t_s"], lines)
    has_ecef = [c for c in ECEF_COLUMNS if c in cols]
    has_red = [c for c in REDUCED_COLUMNS if c in cols]
    if has_ecef and len(has_ecef) < 6:
        missing = [c for c in ECEF_COLUMNS if c not in cols]
        raise RecordError(f"missing required column(s) {', '.join(missing)} (the ECEF set needs all six)")
    if not has_ecef and len(has_red) < 2:
        if has_red:
            missing = [c for c in REDUCED_COLUMNS if c not in cols]
            raise RecordError(f"missing required column(s) {', '.join(missing)} (the reduced set needs both)")
        raise RecordError(
            "missing required columns: need x_m, y_m, z_m, vx_mps, vy_mps, vz_mps (ECEF) "
            "or altitude_m, speed_rel_mps (reduced)"
        )
    _check_units(cols, lines)
    kind = "ecef" if has_ecef else "reduced"
    names = ECEF_COLUMNS if kind == "ecef" else REDUCED_COLUMNS
    if kind == "ecef" and has_red:
        notes.append("columns altitude_m, speed_rel_mps ignored: the full ECEF set is used")
    unknown = [h for h in header if h not in KNOWN_COLUMNS]
    if unknown:
        notes.append(f"columns not in the record format ignored: {', '.join(unknown)}")
    # a position without its velocity (or the reverse) in one row is kept: each
    # channel enters the residual on its own
    obs = np.stack([cols[c] for c in names], axis=1)
    n_obs_rows = int(np.count_nonzero(np.any(np.isfinite(obs), axis=1)))
    if n_obs_rows < MIN_OBSERVATIONS:
        raise RecordError(
            f"only {n_obs_rows} row(s) with observations; at least {MIN_OBSERVATIONS} are needed"
        )
    gaps = int(np.count_nonzero(~np.isfinite(obs)))
    if gaps:
        notes.append(
            f"{n_obs_rows} row(s) carry observations, {len(obs) - n_obs_rows} none (controls only); "
            f"the {gaps} empty observation field(s) are left out of the residual"
        )
    sc = sidecar
    if sc is None and use_sidecar:
        sp = sidecar_path(path)
        if sp is not None:
            sc = load_sidecar(sp)
            notes.append(f"sidecar {sp.name} read")
    rec = FlightRecord(
        t=cols["t_s"],
        kind=kind,
        observations=obs,
        observation_names=names,
        alpha=cols.get("alpha_rad"),
        bank=cols.get("bank_rad"),
        lift_to_drag_vertical=cols.get("lift_to_drag_vertical"),
        density=cols.get("density_kgpm3"),
        sidecar=sc,
        notes=notes,
        path=path,
    )
    for name, arr in (("alpha_rad", rec.alpha), ("bank_rad", rec.bank), ("lift_to_drag_vertical",
                                                                            rec.lift_to_drag_vertical)):
        if arr is not None and not np.any(np.isfinite(arr)):
            raise RecordError(f"column {name}: present but every field is empty")
    return rec


def write_record(path: str | Path, t: np.ndarray, columns: dict[str, np.ndarray]) -> Path:
    """Write a record CSV (NaN written as an empty field, 10 significant digits or more).

    :param path: output file.
    :param t: times (s).
    :param columns: name -> values, in the order to write.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = ["t_s", *columns]
    data = [np.asarray(t, float)] + [np.asarray(v, float) for v in columns.values()]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for i in range(len(data[0])):
            w.writerow(["" if not np.isfinite(col[i]) else repr(float(col[i])) for col in data])
    return path


__all__ = [
    "ECEF_COLUMNS",
    "REDUCED_COLUMNS",
    "KNOWN_COLUMNS",
    "RecordError",
    "FlightRecord",
    "load_record",
    "load_sidecar",
    "sidecar_path",
    "write_record",
]
