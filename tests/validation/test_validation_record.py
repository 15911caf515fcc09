"""Flight-record validation: what is rejected (with the row or column named) and what is reported."""

import json

import numpy as np
import pytest

from rventry_env.validation.record import RecordError, load_record, write_record
from rventry_env.validation.replay.controls import control_schedule
from rventry_env.validation.replay.replay_setup import replay_setup

R_E = 6378137.0


def _ecef_columns(n=12):
    t = np.arange(n, dtype=float)
    x = R_E + 60e3 - 10.0 * t
    return t, {
        "x_m": x, "y_m": 6500.0 * t, "z_m": np.zeros(n),
        "vx_mps": np.full(n, -10.0), "vy_mps": np.full(n, 6500.0), "vz_mps": np.zeros(n),
        "alpha_rad": np.full(n, 0.2), "bank_rad": np.zeros(n),
    }  # fmt: skip


def _write(tmp_path, t, cols, name="rec.csv"):
    return write_record(tmp_path / name, t, cols)


def _write_text(tmp_path, text, name="rec.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_valid_record_loads_and_reports(tmp_path):
    t, cols = _ecef_columns()
    cols["x_m"][3] = np.nan  # a gap
    cols["comment"] = np.zeros(len(t))  # a column outside the format
    rec = load_record(_write(tmp_path, t, cols))
    assert rec.kind == "ecef" and rec.observations.shape == (12, 6)
    assert np.isnan(rec.observations[3, 0]) and np.isfinite(rec.observations[3, 1])
    notes = " ".join(rec.notes)
    assert "comment" in notes and "ignored" in notes
    assert "1 empty observation field(s) in rows with observations" in notes


def test_missing_required_column(tmp_path):
    t, cols = _ecef_columns()
    del cols["vz_mps"]
    with pytest.raises(RecordError, match="missing required column.*vz_mps"):
        load_record(_write(tmp_path, t, cols))
    with pytest.raises(RecordError, match="missing required column t_s"):
        load_record(_write_text(tmp_path, "time,altitude_m,speed_rel_mps\n0,60000,6000\n"))
    with pytest.raises(RecordError, match="missing required columns: need x_m"):
        load_record(_write_text(tmp_path, "t_s,alpha_rad\n0,0.1\n1,0.1\n"))
    with pytest.raises(RecordError, match=r"missing required column\(s\) speed_rel_mps"):
        load_record(_write_text(tmp_path, "t_s,altitude_m\n0,60000\n1,59000\n"))


def test_non_monotonic_and_duplicate_time(tmp_path):
    t, cols = _ecef_columns()
    t2 = t.copy()
    t2[5] = t2[4]
    with pytest.raises(RecordError, match=r"row 7, column t_s: duplicate time t_s = 4 \(same as row 6\)"):
        load_record(_write(tmp_path, t2, cols))
    t3 = t.copy()
    t3[5] = 2.5
    with pytest.raises(RecordError, match=r"row 7, column t_s: non-monotonic time, t_s = 2.5 after 4"):
        load_record(_write(tmp_path, t3, cols))


def test_nan_where_required(tmp_path):
    t, cols = _ecef_columns()
    p = _write(tmp_path, t, cols)
    lines = p.read_text().splitlines()
    fields = lines[4].split(",")
    fields[2] = "NaN"  # y_m of the 4th data row (file line 5)
    lines[4] = ",".join(fields)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordError, match=r"row 5, column y_m: 'NaN' where a value is required"):
        load_record(p)
    fields[2] = "1e400"  # parses to inf: an overflow, not a literal infinity
    lines[4] = ",".join(fields)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordError, match=r"row 5, column y_m: '1e400' overflows a 64-bit float"):
        load_record(p)
    lines = _write(tmp_path, t, cols).read_text().splitlines()
    lines[2] = "," + lines[2].split(",", 1)[1]  # empty time in file line 3
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordError, match="row 3, column t_s: time is required"):
        load_record(p)


def test_kilometres_for_metres(tmp_path):
    t = np.arange(10.0)
    cols = {"altitude_m": 60.0 - 0.1 * t, "speed_rel_mps": 6000.0 - t}
    with pytest.raises(RecordError, match="column altitude_m: implausible unit.*kilometres where metres"):
        load_record(_write(tmp_path, t, cols))
    t, cols = _ecef_columns()
    for c in ("x_m", "y_m", "z_m"):
        cols[c] = cols[c] / 1e3
    with pytest.raises(RecordError, match="columns x_m, y_m, z_m: implausible unit.*kilometres"):
        load_record(_write(tmp_path, t, cols))


def test_km_per_s_and_degrees(tmp_path):
    t = np.arange(10.0)
    cols = {"altitude_m": 60e3 - 100 * t, "speed_rel_mps": 6.0 - 0.001 * t}
    with pytest.raises(RecordError, match=r"speed_rel_mps: implausible unit.*km/s where m/s"):
        load_record(_write(tmp_path, t, cols))
    t, cols = _ecef_columns()
    cols["bank_rad"] = np.full(len(t), 45.0)
    with pytest.raises(RecordError, match="row 2, column bank_rad: .*degrees where radians"):
        load_record(_write(tmp_path, t, cols))


def test_implausible_values_name_the_row(tmp_path):
    t = np.arange(10.0)
    h = 60e3 - 100 * t
    h[6] = 5e6
    with pytest.raises(RecordError, match="row 8, column altitude_m: implausible altitude"):
        load_record(_write(tmp_path, t, {"altitude_m": h, "speed_rel_mps": 6000 - t}))


def test_reduced_record_needs_an_entry_state(tmp_path):
    t = np.arange(10.0)
    rec = load_record(_write(tmp_path, t, {"altitude_m": 60e3 - 100 * t, "speed_rel_mps": 6000 - t,
                                           "alpha_rad": np.full(10, 0.2)}))  # fmt: skip
    with pytest.raises(RecordError, match="needs the entry state in its sidecar"):
        replay_setup(rec)
    side = {"entry_state": {"t_s": 0, "altitude_m": 60e3, "speed_rel_mps": 6000, "flight_path_angle_deg": 0,
                            "longitude_deg": 0, "latitude_deg": 0, "azimuth_deg": 90}}  # fmt: skip
    (tmp_path / "rec.json").write_text(json.dumps(side))
    rec = load_record(tmp_path / "rec.csv")
    assert replay_setup(rec).entry_state.speed == 6000
    assert any("sidecar rec.json" in n for n in rec.notes)


def test_lifting_body_needs_alpha_and_capsule_needs_declared_lift(tmp_path):
    t, cols = _ecef_columns()
    del cols["alpha_rad"]
    rec = load_record(_write(tmp_path, t, cols))
    with pytest.raises(RecordError, match="missing column alpha_rad"):
        control_schedule(rec, None, needs_alpha=True)
    t, cols = _ecef_columns()
    cols["lift_to_drag_vertical"] = np.full(len(t), 0.3)
    rec = load_record(_write(tmp_path, t, cols))
    with pytest.raises(RecordError, match="lift_to_drag_vertical needs a capsule"):
        control_schedule(rec, None, needs_alpha=True)


def test_capsule_bank_from_vertical_lift_to_drag(tmp_path):
    """bank = +-arccos((L/D)_v / (L/D)), sign from the bank record; gaps interpolated and reported."""
    t, cols = _ecef_columns(20)
    ldv = np.linspace(0.3, -0.2, 20)
    ldv[7] = np.nan
    cols["lift_to_drag_vertical"] = ldv
    cols["bank_rad"] = np.where(t < 10, 0.5, -0.5)
    rec = load_record(_write(tmp_path, t, cols))
    cs = control_schedule(rec, 0.368, needs_alpha=False)
    assert cs.at(2.0)[1] == pytest.approx(np.arccos(ldv[2] / 0.368))
    assert cs.at(15.0)[1] == pytest.approx(-np.arccos(ldv[15] / 0.368))
    notes = " ".join(cs.notes)
    assert "sign from bank_rad" in notes
    # one missing sample in a 1 s series is no gap worth a note (a merged time axis is not missing data)
    assert "lift_to_drag_vertical: sampled" not in notes


def test_control_gaps_are_intervals_not_empty_fields(tmp_path):
    """A control sampled on its own rows of a merged time axis is not missing data; a long interval is noted."""
    t, cols = _ecef_columns(40)
    bank = np.full(40, 0.3)
    bank[1::2] = np.nan  # the bank series has its own, every-other-row sampling
    bank[20:30] = np.nan  # and one long interval
    cols["bank_rad"] = bank
    rec = load_record(_write(tmp_path, t, cols))
    cs = control_schedule(rec, None, needs_alpha=True)
    notes = " ".join(cs.notes)
    assert "bank_rad: sampled every 2 s; longest interval 12 s (18 to 30 s)" in notes
    assert "empty field" not in notes
