"""Flight records (the format of docs/conventions.md): load, validate, and say what was used and ignored.

A record is a comma-separated text file with a header row and one row per sample, time
strictly increasing. It carries one observation set, the full ECEF state (``x_m .. vz_mps``)
or the reduced one (``altitude_m`` with ``speed_rel_mps``, the Earth-relative speed, or
``speed_inertial_mps``, the inertial speed many flight reports plot), optional controls (``alpha_rad``,
``bank_rad``, ``lift_to_drag_vertical``) and an optional measured ``density_kgpm3``. Empty
fields are gaps. A JSON sidecar ``<record>.json`` (or ``<record>.csv.json``) may name the
vehicle, the entry state and the measurement noise.

Everything that cannot be used is rejected with a :class:`RecordError` naming the row (the
file's line number, the header being line 1) or column: a file that is not text, another
delimiter, a literal NaN, a value that overflows, units that are off by a known factor (km for
m, km/s for m/s, degrees for radians, milliseconds for seconds), a gap the replay would have to
integrate blind. Everything read but not used is listed in :attr:`FlightRecord.notes`.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rventry_env.util.files import atomic_write

ECEF_COLUMNS = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
REDUCED_COLUMNS = ("altitude_m", "speed_rel_mps")
INERTIAL_SPEED = "speed_inertial_mps"  # the reduced set's speed may be the inertial one instead
CONTROL_COLUMNS = ("alpha_rad", "bank_rad", "lift_to_drag_vertical")
OPTIONAL_COLUMNS = CONTROL_COLUMNS + ("density_kgpm3",)
KNOWN_COLUMNS = ("t_s",) + ECEF_COLUMNS + REDUCED_COLUMNS + (INERTIAL_SPEED,) + OPTIONAL_COLUMNS

# plausibility bounds for an entry flight (the unit checks)
EARTH_RADIUS = 6378137.0
MAX_ALTITUDE = 1.0e6  # m: above this it is not an entry record
MIN_ALTITUDE = -5.0e3  # m
MAX_SPEED = 2.0e4  # m/s: faster than any Earth entry
MIN_ENTRY_SPEED = 50.0  # m/s: a record whose every speed is below this is in km/s
MAX_DURATION = 7200.0  # s: an entry lasts minutes; a longer span is a unit error (ms) or two flights
MAX_TIME_GAP = 600.0  # s: the replay would integrate this long with nothing to compare
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
    :param lines: the file line of every row (header = line 1), for messages.
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
    lines: np.ndarray | None = None

    @property
    def speed_frame(self) -> str:
        """``"earth"`` (Earth-relative speeds or the ECEF velocity) or ``"inertial"`` (``speed_inertial_mps``)."""
        return "inertial" if INERTIAL_SPEED in self.observation_names else "earth"

    @property
    def observed_rows(self) -> np.ndarray:
        """Indices of rows with at least one measured observation."""
        return np.flatnonzero(np.any(np.isfinite(self.observations), axis=1))

    @property
    def n_values(self) -> int:
        """Number of measured scalar observations."""
        return int(np.count_nonzero(np.isfinite(self.observations)))

    def line_of(self, row: int) -> int:
        """The file line of row index ``row`` (its index + 2 when the record was not read from a file)."""
        return int(self.lines[row]) if self.lines is not None else int(row) + 2

    def altitude(self) -> np.ndarray:
        """Measured altitude per row (m; NaN where unknown), from either observation set."""
        if self.kind == "reduced":
            return self.observations[:, 0]
        return row_norm(self.observations[:, :3]) - EARTH_RADIUS

    def speed(self) -> np.ndarray:
        """Measured speed per row (m/s; NaN where unknown): Earth-relative, or inertial where
        :attr:`speed_frame` says so (a few per cent more at entry speeds)."""
        if self.kind == "reduced":
            return self.observations[:, 1]
        return row_norm(self.observations[:, 3:6])


def row_norm(a: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row without overflow (|x| up to the largest float stays finite)."""
    a = np.asarray(a, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.max(np.abs(a), axis=-1)
        safe = np.where(scale > 0, scale, 1.0)
        return scale * np.sqrt(np.sum((a / safe[..., None]) ** 2, axis=-1))


def _parse_float(text: str, line: int, column: str) -> float:
    """A field as a float; '' is a gap (NaN). A literal NaN or inf, or an overflow, is an error."""
    text = text.strip()
    if text == "":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise RecordError(f"row {line}, column {column}: cannot read {text!r:.40} as a number") from None
    if not math.isfinite(value):
        if not any(word in text.lower() for word in ("nan", "inf")):
            raise RecordError(
                f"row {line}, column {column}: {text!r:.40} overflows a 64-bit float "
                "(beyond +/-1.8e308): a corrupted field or wrong units?"
            )
        raise RecordError(
            f"row {line}, column {column}: {text!r:.40} where a value is required "
            "(leave the field empty for a missing sample)"
        )
    return value


def _decode(path: Path, data: bytes) -> tuple[str, list[str]]:
    """The file as text, or an error that says why it is not a CSV text file."""
    notes = []
    if b"\x00" in data[:4096]:
        raise RecordError(f"{path}: not a text CSV file (it contains NUL bytes: binary data?)")
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
        notes.append("UTF-8 byte-order mark at the start of the file skipped")
    elif data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise RecordError(f"{path}: the file is UTF-16 text (byte-order mark {data[:2].hex()}); save it as UTF-8")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RecordError(
            f"{path}: not a UTF-8 text CSV file (byte 0x{data[exc.start]:02x} at offset {exc.start} "
            "cannot be decoded)"
        ) from None
    return text, notes


def _check_delimiter(path: Path, header_line: str) -> None:
    """The format is comma-separated: say what was found if the header uses another delimiter."""
    for delim, name in ((";", "semicolons ';'"), ("\t", "tabs"), ("|", "bars '|'")):
        if delim in header_line and header_line.count(delim) >= header_line.count(","):
            raise RecordError(
                f"{path}: the header row is separated by {name}, not commas "
                f"({header_line.strip()[:80]!r}); the record format is comma-separated "
                "(docs/conventions.md, 'Flight records'): convert the file"
            )


def _read_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray], list[str]]:
    data = path.read_bytes()
    text, notes = _decode(path, data)
    if not text.strip():
        raise RecordError(f"{path}: empty file (expected a header row)")
    first = text.lstrip("\r\n").splitlines()[0]
    _check_delimiter(path, first)
    reader = csv.reader(io.StringIO(text, newline=""))
    header = None
    rows = []
    try:
        for line, row in enumerate(reader, start=1):
            if header is None:
                if not row or all(not f.strip() for f in row):
                    continue
                header = [h.strip() for h in row]
                header_line = line
                continue
            if not row or all(not f.strip() for f in row):
                continue  # a blank line carries nothing
            if len(row) != len(header):
                raise RecordError(f"row {line}: {len(row)} fields, the header (line {header_line}) has {len(header)}")
            rows.append((line, row))
    except csv.Error as exc:
        raise RecordError(f"{path}: not a readable CSV file ({exc})") from None
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise RecordError(f"{path}: duplicate column(s) {', '.join(dupes)}")
    if "t_s" not in header:
        close = [h for h in header if h.lower().strip('"') in ("t_s", "t", "time", "time_s")]
        hint = f" (found {close[0]!r})" if close else ""
        raise RecordError(f"{path}: missing required column t_s{hint}; the header has {', '.join(header)[:120]}")
    if not rows:
        raise RecordError(f"{path}: no data rows")
    cols = {}
    for j, name in enumerate(header):
        if name in KNOWN_COLUMNS:
            cols[name] = np.array([_parse_float(r[j], line, name) for line, r in rows])
    cols["_line"] = np.array([line for line, _ in rows])
    return header, cols, notes


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


def _check_time_span(t: np.ndarray, observed: np.ndarray, lines: np.ndarray) -> None:
    """Bound the replay's work: no span of hours (milliseconds for seconds) and no blind gap."""
    rows = np.flatnonzero(observed)
    span = float(t[rows[-1]] - t[rows[0]]) if rows.size else 0.0
    step = float(np.median(np.diff(t[rows]))) if rows.size > 1 else math.nan
    if span > MAX_DURATION and step >= 10.0:
        raise RecordError(
            f"column t_s: the observations span {span:g} s (rows {lines[rows[0]]} to {lines[rows[-1]]}) with a "
            f"median step of {step:g} s; an entry lasts minutes (at most {MAX_DURATION:g} s here): "
            "is t_s in milliseconds?"
        )
    if rows.size > 1:
        gaps = np.diff(t[rows])
        k = int(np.argmax(gaps))
        if gaps[k] > MAX_TIME_GAP:
            raise RecordError(
                f"row {lines[rows[k + 1]]}, column t_s: {gaps[k]:g} s without an observation "
                f"(after t_s = {t[rows[k]]:g}, row {lines[rows[k]]}); the replay would integrate that long "
                f"blind (at most {MAX_TIME_GAP:g} s): split the record or check the time column"
            )
    if span > MAX_DURATION:
        raise RecordError(
            f"column t_s: the observations span {span:g} s (rows {lines[rows[0]]} to {lines[rows[-1]]}); "
            f"an entry lasts minutes, at most {MAX_DURATION:g} s here: split the record"
        )


def _first_bad(mask: np.ndarray, lines: np.ndarray) -> int:
    return int(lines[np.flatnonzero(mask)[0]])


def _check_components(cols: dict, names, limit: float, unit: str, lines: np.ndarray) -> None:
    """Every component on its own within ``limit``: a value that would overflow a norm never gets further."""
    for c in names:
        v = cols[c]
        bad = np.isfinite(v) & (np.abs(v) > limit)
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column {c}: {v[bad][0]:g} {unit} is out of range for an "
                f"entry flight (|value| at most {limit:g} {unit})"
            )


def _check_altitude_units(cols: dict, lines: np.ndarray) -> None:
    """Reject an altitude column in kilometres, or an altitude no entry flight reaches."""
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
                f"{h[bad][0]:g} m for an entry flight (between {MIN_ALTITUDE:g} and {MAX_ALTITUDE:g} m)"
            )


def _check_position_units(cols: dict, lines: np.ndarray) -> None:
    """Reject ECEF positions in feet or kilometres, or at an altitude no entry flight reaches."""
    if all(c in cols for c in ECEF_COLUMNS[:3]):
        pos = np.stack([cols[c] for c in ECEF_COLUMNS[:3]], axis=1)
        ratio = row_norm(pos) / EARTH_RADIUS
        ratio = ratio[np.isfinite(ratio)]
        if ratio.size and np.all((ratio > 3.1) & (ratio < 3.5)):
            raise RecordError(
                f"columns x_m, y_m, z_m: |r| is {np.median(ratio):.4g} Earth radii throughout; "
                "this looks like feet where metres are expected"
            )
        _check_components(cols, ECEF_COLUMNS[:3], EARTH_RADIUS + MAX_ALTITUDE, "m", lines)
        rn = row_norm(pos)
        ok = np.isfinite(rn)
        if np.any(ok) and np.max(rn[ok]) < 1.0e5:
            raise RecordError(
                f"columns x_m, y_m, z_m: implausible unit, |r| is at most {np.max(rn[ok]):g}; "
                "this looks like kilometres where metres are expected"
            )
        alt = rn - EARTH_RADIUS
        bad = ok & ((alt > MAX_ALTITUDE) | (alt < MIN_ALTITUDE))
        if np.any(bad):
            ratio = rn[bad][0] / EARTH_RADIUS
            hint = " (feet where metres are expected?)" if 3.1 < ratio < 3.5 else ""
            raise RecordError(
                f"row {_first_bad(bad, lines)}, columns x_m, y_m, z_m: implausible position, altitude "
                f"{alt[bad][0]:g} m (|r| = {rn[bad][0]:g} m) for an entry flight about an Earth of radius "
                f"{EARTH_RADIUS:g} m{hint}"
            )


def _check_speed_units(cols: dict, lines: np.ndarray) -> None:
    """Reject speeds or velocities in km/s, above an Earth entry's, or not positive."""
    for names in (("speed_rel_mps",), (INERTIAL_SPEED,), ECEF_COLUMNS[3:]):
        if not all(c in cols for c in names):
            continue
        vel = np.stack([cols[c] for c in names], axis=1)
        _check_components(cols, names, MAX_SPEED, "m/s", lines)
        speed = row_norm(vel)
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
                f"row {_first_bad(bad, lines)}, column(s) {label}: implausible speed {speed[bad][0]:g} m/s "
                f"(at most {MAX_SPEED:g} m/s for an Earth entry)"
            )
        bad = ok & (speed <= 0)
        if np.any(bad):
            raise RecordError(f"row {_first_bad(bad, lines)}, column(s) {label}: speed must be positive")


def _check_other_units(cols: dict, lines: np.ndarray) -> None:
    """Reject angles in degrees, and densities or lift-to-drag ratios no entry flight has."""
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
        bad = np.isfinite(d) & ((d <= 0) | (d > 2.0))
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column density_kgpm3: "
                f"implausible density {d[bad][0]:g} kg/m^3 (positive, at most 2)"
            )
    if "lift_to_drag_vertical" in cols:
        ld = cols["lift_to_drag_vertical"]
        bad = np.isfinite(ld) & (np.abs(ld) > 5.0)
        if np.any(bad):
            raise RecordError(
                f"row {_first_bad(bad, lines)}, column lift_to_drag_vertical: "
                f"implausible value {ld[bad][0]:g}"
            )


def _check_units(cols: dict, lines: np.ndarray) -> None:
    """Reject values whose magnitude says the unit is wrong (km for m, km/s for m/s, deg for rad)."""
    _check_altitude_units(cols, lines)
    _check_position_units(cols, lines)
    _check_speed_units(cols, lines)
    _check_other_units(cols, lines)


def _check_time_unit_ecef(t: np.ndarray, obs: np.ndarray, lines: np.ndarray) -> None:
    """Positions and velocities of an ECEF record must agree on the time unit.

    Over short steps the chord speed |r(i+1) - r(i)| / dt is the speed the velocity columns
    give. A ratio of 1e-3 is t_s in milliseconds; 1e3 is t_s in kiloseconds (or km/s).
    """
    full = np.all(np.isfinite(obs), axis=1)
    i = np.flatnonzero(full[:-1] & full[1:])
    if i.size < 3:
        return
    dt = t[i + 1] - t[i]
    chord = row_norm(obs[i + 1, :3] - obs[i, :3]) / dt
    speed = 0.5 * (row_norm(obs[i, 3:]) + row_norm(obs[i + 1, 3:]))
    short = dt <= 60.0
    if np.count_nonzero(short) < 3:
        # every step is long in seconds: compare anyway (a chord is shorter than the arc by < 5 %)
        short = np.ones_like(dt, dtype=bool)
    ratio = float(np.median(chord[short] / speed[short]))
    if not 0.2 < ratio < 5.0:
        hint = ""
        if 3e-4 < ratio < 3e-3:
            hint = ": t_s looks like milliseconds"
        elif 300 < ratio < 3000:
            hint = ": t_s looks like kiloseconds, or the velocities are in km/s"
        raise RecordError(
            f"column t_s (rows {lines[i[0]]} onward): the positions move {np.median(chord[short]):.4g} m per unit "
            f"of t_s while the velocity columns say {np.median(speed[short]):.4g} m/s (ratio {ratio:.3g}){hint}"
        )


def sidecar_path(path: Path) -> Path | None:
    """The sidecar of a record: ``<stem>.json`` or ``<name>.json`` beside it, if one exists."""
    for cand in (path.with_suffix(".json"), path.with_name(path.name + ".json")):
        if cand.is_file():
            return cand
    return None


def load_sidecar(path: Path) -> dict:
    """Parse a sidecar or vehicle JSON file (an object at top level)."""
    path = Path(path)
    if path.is_dir():
        raise RecordError(f"{path}: is a directory, not a JSON file")
    if not path.exists():
        raise FileNotFoundError(f"no such file: {path}")
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RecordError(f"{path}: not UTF-8 JSON text (byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise RecordError(f"{path}: not valid JSON ({exc})") from None
    except ValueError as exc:
        raise RecordError(f"{path}: {exc}") from None
    if not isinstance(data, dict):
        raise RecordError(f"{path}: expected a JSON object at top level, got {type(data).__name__}")
    return data


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a JSON number (give a finite value)")


def _required_columns(header: list, cols: dict) -> tuple[list, list, str]:
    """The record's observation columns, checked: the full ECEF set, or altitude and a speed.

    :return: ``(has_ecef, has_red, speed_col)``: the ECEF and the reduced-set columns present,
        and the speed column the reduced set would use.
    :raises RecordError: naming the missing columns.
    """
    has_ecef = [c for c in ECEF_COLUMNS if c in cols]
    has_red = [c for c in REDUCED_COLUMNS + (INERTIAL_SPEED,) if c in cols]
    if has_ecef and len(has_ecef) < 6:
        missing = [c for c in ECEF_COLUMNS if c not in cols]
        raise RecordError(f"missing required column(s) {', '.join(missing)} (the ECEF set needs all six)")
    speed_col = "speed_rel_mps" if "speed_rel_mps" in cols else INERTIAL_SPEED
    if not has_ecef and not ("altitude_m" in cols and speed_col in cols):
        if has_red:
            missing = ["altitude_m"] if "altitude_m" not in cols else ["speed_rel_mps (or speed_inertial_mps)"]
            raise RecordError(f"missing required column(s) {', '.join(missing)} (the reduced set needs both)")
        raise RecordError(
            "missing required columns: need x_m, y_m, z_m, vx_mps, vy_mps, vz_mps (ECEF) "
            f"or altitude_m, speed_rel_mps (reduced); the header has {', '.join(header)[:120]}"
        )
    return has_ecef, has_red, speed_col


def _observations(cols: dict, names, kind: str, lines: np.ndarray, notes: list) -> np.ndarray:
    """The observation matrix (one column per name), checked for enough rows, a time span and (ECEF)
    the time unit; rows with only controls or density and empty fields are noted in ``notes``.
    """
    # a position without its velocity (or the reverse) in one row is kept: each
    # channel enters the residual on its own
    obs = np.stack([cols[c] for c in names], axis=1)
    observed = np.any(np.isfinite(obs), axis=1)
    n_obs_rows = int(np.count_nonzero(observed))
    if n_obs_rows < MIN_OBSERVATIONS:
        raise RecordError(
            f"only {n_obs_rows} row(s) with observations; at least {MIN_OBSERVATIONS} are needed"
        )
    _check_time_span(cols["t_s"], observed, lines)
    if kind == "ecef":
        _check_time_unit_ecef(cols["t_s"], obs, lines)
    other = len(obs) - n_obs_rows
    if other:
        notes.append(
            f"{n_obs_rows} row(s) carry observations; {other} row(s) carry only controls or density "
            "(a merged time axis), which is not missing data"
        )
    partial = int(np.count_nonzero(~np.isfinite(obs[observed])))
    if partial:
        notes.append(f"{partial} empty observation field(s) in rows with observations are left out of the residual")
    return obs


def load_record(path: str | Path, *, sidecar: dict | None = None, use_sidecar: bool = True) -> FlightRecord:
    """Read and validate a flight record.

    :param path: the CSV file.
    :param sidecar: a parsed sidecar to use instead of the file beside the record.
    :param use_sidecar: look for ``<record>.json`` when ``sidecar`` is None.
    :raises RecordError: with the row or column at fault.
    """
    path = Path(path)
    if path.is_dir():
        raise RecordError(f"{path}: is a directory, not a record file (give the CSV file)")
    if not path.is_file():
        raise FileNotFoundError(f"no such record: {path}")
    header, cols, notes = _read_csv(path)
    lines = cols.pop("_line")
    _check_time(cols["t_s"], lines)
    has_ecef, has_red, speed_col = _required_columns(header, cols)
    _check_units(cols, lines)
    kind = "ecef" if has_ecef else "reduced"
    names = ECEF_COLUMNS if kind == "ecef" else ("altitude_m", speed_col)
    if kind == "ecef" and has_red:
        notes.append(f"columns {', '.join(has_red)} ignored: the full ECEF set is used")
    elif kind == "reduced" and speed_col == "speed_rel_mps" and INERTIAL_SPEED in cols:
        notes.append(f"column {INERTIAL_SPEED} ignored: the Earth-relative speed_rel_mps is used")
    for c in names:
        if not np.any(np.isfinite(cols[c])):
            raise RecordError(f"column {c}: present but every field is empty (the {kind} set needs its values)")
    unknown = [h for h in header if h not in KNOWN_COLUMNS]
    if unknown:
        notes.append(f"columns not in the record format ignored: {', '.join(unknown)}")
    obs = _observations(cols, names, kind, lines, notes)
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
        lines=lines,
    )
    for name, arr in (("alpha_rad", rec.alpha), ("bank_rad", rec.bank), ("lift_to_drag_vertical",
                                                                            rec.lift_to_drag_vertical)):
        if arr is not None and not np.any(np.isfinite(arr)):
            raise RecordError(f"column {name}: present but every field is empty")
    return rec


def record_text(t: np.ndarray, columns: dict[str, np.ndarray]) -> str:
    """A record as CSV text (NaN written as an empty field, every digit of each value)."""
    names = ["t_s", *columns]
    data = [np.asarray(t, float)] + [np.asarray(v, float) for v in columns.values()]
    for name, col in zip(names, data):
        if col.shape != data[0].shape:
            raise ValueError(f"column {name}: {col.shape[0]} values for {data[0].shape[0]} times")
        if np.any(np.isinf(col)):
            raise ValueError(f"column {name}: infinite value; a record holds finite numbers or gaps")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(names)
    for i in range(len(data[0])):
        w.writerow(["" if not np.isfinite(col[i]) else repr(float(col[i])) for col in data])
    return buf.getvalue()


def write_record(path: str | Path, t: np.ndarray, columns: dict[str, np.ndarray]) -> Path:
    """Write a record CSV whole or not at all (:func:`~rventry_env.util.files.atomic_write`).

    :param path: output file.
    :param t: times (s).
    :param columns: name -> values, in the order to write.
    """
    return atomic_write(Path(path), record_text(t, columns))


__all__ = [
    "ECEF_COLUMNS",
    "INERTIAL_SPEED",
    "KNOWN_COLUMNS",
    "REDUCED_COLUMNS",
    "FlightRecord",
    "RecordError",
    "load_record",
    "load_sidecar",
    "record_text",
    "row_norm",
    "sidecar_path",
    "write_record",
]
