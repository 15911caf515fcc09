"""Hostile inputs to ``rventry identify`` / ``simulate-record`` and the record reader.

A seeded corpus of bad records, sidecars and options. For each: exit code 2, no traceback, a
message that names the field (row, column, sidecar key or option), and a report written by an
earlier run left exactly as it was.
"""

import json
import math
import os
import resource
import subprocess
import sys

import numpy as np
import pytest

from rventry_env.cli import main as rventry_main
from rventry_env.validation.record import load_record, record_text
from rventry_env.validation.synthetic.simulate import simulate_record

OLD_REPORT = '{"effect": "from an earlier run"}\n'
RNG_SEED = 20240


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A clean 60 s ECEF record and a reduced one with its sidecar, as text to mutate."""
    d = tmp_path_factory.mktemp("base")
    ecef = simulate_record(d / "ecef.csv", {}, noise=(20.0, 0.2), duration=60.0, rate=1.0, seed=1)
    red = simulate_record(d / "red.csv", {}, noise=(20.0, 0.2), duration=60.0, rate=1.0, seed=2, observe="reduced")
    return {
        "ecef": ecef.read_text(),
        "reduced": red.read_text(),
        "sidecar": json.loads(red.with_suffix(".json").read_text()),
    }


def _rows(text):
    lines = text.splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def _join(header, rows):
    return "\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n"


def _set(text, row, column, value):
    header, rows = _rows(text)
    rows[row][header.index(column)] = value
    return _join(header, rows)


def _run(tmp_path, capsys, args, record_text_=None, sidecar=None, record_name="rec.csv"):
    """Run ``rventry identify`` (or the given command) in-process; return (exit code, stderr)."""
    report = tmp_path / "report.json"
    report.write_text(OLD_REPORT)
    if record_text_ is not None:
        rec = tmp_path / record_name
        (rec.write_bytes if isinstance(record_text_, bytes) else rec.write_text)(record_text_)
        if sidecar is not None:
            side = rec.with_suffix(".json")
            (side.write_text(sidecar) if isinstance(sidecar, str) else side.write_text(json.dumps(sidecar)))
    argv = [a.replace("{rec}", str(tmp_path / record_name)).replace("{json}", str(report)) for a in args]
    try:
        code = rventry_main(argv)
    except SystemExit as exc:  # argparse rejects an option
        code = exc.code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert report.read_text() == OLD_REPORT, "an earlier report was touched"
    return code, err


IDENTIFY = ["identify", "{rec}", "--json", "{json}", "--quiet", "--h-max", "2"]
_rng = np.random.default_rng(RNG_SEED)
# overflowing or absurd magnitudes in a seeded row of each observation column
OVERFLOW = [(col, int(_rng.integers(3, 50)), val) for col, val in
            [("x_m", "1e300"), ("y_m", "1.5e154"), ("vx_mps", "1e300"), ("vz_mps", "2e154"), ("z_m", "-1e200")]]


@pytest.mark.parametrize("column,row,value", OVERFLOW, ids=[f"{c}={v}" for c, _, v in OVERFLOW])
def test_overflowing_values_are_rejected(tmp_path, capsys, base, column, row, value):
    code, err = _run(tmp_path, capsys, IDENTIFY, _set(base["ecef"], row, column, value))
    assert code == 2 and f"row {row + 2}, column {column}" in err, err


def test_overflowing_reduced_speed(tmp_path, capsys, base):
    code, err = _run(tmp_path, capsys, IDENTIFY, _set(base["reduced"], 7, "speed_rel_mps", "1e300"), base["sidecar"])
    assert code == 2 and "row 9, column speed_rel_mps" in err, err


RECORD_CASES = {
    # name: (mutation of the ECEF text, words the message must hold)
    "semicolons": (lambda t: t.replace(",", ";"), ["semicolons", "comma-separated"]),
    "tabs": (lambda t: t.replace(",", "\t"), ["tabs", "comma-separated"]),
    "binary": (lambda t: bytes(np.random.default_rng(RNG_SEED).integers(0, 256, 4000, dtype=np.uint8)),
               ["not a", "text"]),
    "latin1": (lambda t: t.encode("utf-8") + b"\xff\xfe\xfa\n", ["UTF-8", "0xff"]),
    "empty": (lambda t: "", ["empty file"]),
    "header only": (lambda t: t.splitlines()[0] + "\n", ["no data rows"]),
    "nan literal": (lambda t: _set(t, 4, "y_m", "nan"), ["row 6, column y_m", "'nan'"]),
    "float overflow": (lambda t: _set(t, 9, "vx_mps", "1e400"), ["row 11, column vx_mps", "overflows"]),
    "milliseconds": (lambda t: _scale_time(t, 1000.0), ["column t_s", "milliseconds"]),
    "one long gap": (lambda t: _shift_after(t, 30, 1e5), ["column t_s", "without an observation"]),
    "four rows": (lambda t: "\n".join(t.splitlines()[:5]) + "\n", ["only 4 row(s)"]),
    "kilometres": (lambda t: _scale_cols(t, ("x_m", "y_m", "z_m"), 1e-3), ["x_m, y_m, z_m", "kilometres"]),
    "feet": (lambda t: _scale_cols(t, ("x_m", "y_m", "z_m"), 1 / 0.3048), ["x_m, y_m, z_m", "feet"]),
    "degrees": (lambda t: _scale_cols(t, ("bank_rad",), 180 / math.pi * 10), ["column bank_rad", "degrees"]),
    "duplicate time": (lambda t: _set(t, 5, "t_s", "4.0"), ["row 7, column t_s", "duplicate"]),
}


def _scale_time(text, k):
    header, rows = _rows(text)
    for r in rows:
        r[0] = repr(float(r[0]) * k)
    return _join(header, rows)


def _shift_after(text, row, dt):
    header, rows = _rows(text)
    for r in rows[row:]:
        r[0] = repr(float(r[0]) + dt)
    return _join(header, rows)


def _scale_cols(text, cols, k):
    header, rows = _rows(text)
    for c in cols:
        j = header.index(c)
        for r in rows:
            if r[j]:
                r[j] = repr(float(r[j]) * k)
    return _join(header, rows)


@pytest.mark.parametrize("case", list(RECORD_CASES))
def test_bad_records(tmp_path, capsys, base, case):
    mutate, words = RECORD_CASES[case]
    code, err = _run(tmp_path, capsys, IDENTIFY, mutate(base["ecef"]))
    assert code == 2, err
    for w in words:
        assert w in err, (case, err)


def test_a_directory_is_not_a_record(tmp_path, capsys):
    (tmp_path / "dir.csv").mkdir()
    code, err = _run(tmp_path, capsys, ["identify", str(tmp_path / "dir.csv"), "--json", "{json}"])
    assert code == 2 and "is a directory" in err and "no such record" not in err


def test_a_missing_record_is_named(tmp_path, capsys):
    code, err = _run(tmp_path, capsys, ["identify", str(tmp_path / "nope.csv"), "--json", "{json}"])
    assert code == 2 and "no such record" in err


def _sidecar(base, path, value):
    side = json.loads(json.dumps(base["sidecar"]))
    node = side
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return side


SIDECAR_CASES = {
    "speed true": (("entry_state", "speed_rel_mps"), True, ["entry_state.speed_rel_mps", "must be a number"]),
    "speed text": (("entry_state", "speed_rel_mps"), "6500", ["entry_state.speed_rel_mps", "must be a number"]),
    "altitude in km": (("entry_state", "altitude_m"), 60.0, ["entry_state.altitude_m", "kilometres"]),
    "inertial speed": (("entry_state", "speed_rel_mps"), 6880.0, ["entry_state.speed_rel_mps", "inertial"]),
    "negative scale height": (("atmosphere",), {"scale_height_m": -7200}, ["atmosphere.scale_height_m"]),
    "vehicle as text": (("vehicle",), "CAV-H", ["sidecar: vehicle", "expected a JSON object"]),
    "aero as text": (("vehicle", "aerodynamics"), "constant", ["vehicle.aerodynamics", "expected a JSON object"]),
    "negative mass": (("vehicle", "mass_kg"), -907.2, ["vehicle.mass_kg", "positive"]),
    "typo vehicel": (("vehicel",), {"mass_kg": 907.2}, ["'vehicel'", "did you mean 'vehicle'"]),
    "typo in entry state": (("entry_state", "altitude"), 60e3, ["'altitude'", "altitude_m"]),
    "noise zero": (("noise",), {"altitude_m": 0, "speed_mps": 0.2}, ["noise.altitude_m", "positive"]),
    "unknown aero type": (("vehicle", "aerodynamics", "type"), "newtonian", ["aerodynamics.type", "newtonian"]),
}


@pytest.mark.parametrize("case", list(SIDECAR_CASES))
def test_bad_sidecars(tmp_path, capsys, base, case):
    path, value, words = SIDECAR_CASES[case]
    code, err = _run(tmp_path, capsys, IDENTIFY, base["reduced"], _sidecar(base, path, value))
    assert code == 2, err
    for w in words:
        assert w in err, (case, err)


def test_sidecar_that_is_not_json(tmp_path, capsys, base):
    code, err = _run(tmp_path, capsys, IDENTIFY, base["reduced"], '{"vehicle": {"mass_kg": NaN}}')
    assert code == 2 and "NaN" in err and "rec.json" in err


def test_record_altitude_in_feet_against_the_sidecar(tmp_path, capsys, base):
    code, err = _run(tmp_path, capsys, IDENTIFY, _scale_cols(base["reduced"], ("altitude_m",), 1 / 0.3048),
                     base["sidecar"])  # fmt: skip
    assert code == 2 and "entry_state.altitude_m" in err and "the record in feet" in err, err


OPTION_CASES = {
    "max effects -1": (["--max-effects", "-1"], "--max-effects"),
    "max effects text": (["--max-effects", "two"], "--max-effects"),
    "threshold nan": (["--threshold", "nan"], "--threshold"),
    "threshold inf": (["--threshold", "inf"], "--threshold"),
    "threshold negative": (["--threshold", "-3"], "--threshold"),
    "h-max 0": (["--h-max", "0"], "--h-max"),
    "h-max -1": (["--h-max", "-1"], "--h-max"),
    "h-max huge": (["--h-max", "1e6"], "--h-max"),
    "noise nan": (["--noise", "nan,0.2"], "--noise"),
    "noise one value": (["--noise", "20"], "--noise"),
    "noise zero": (["--noise", "0,0.2"], "--noise"),
    "unknown candidate": (["--candidates", "gravity_waves"], "gravity_waves"),
    "start model": (["--start", "lifted"], "--start"),
}


@pytest.mark.parametrize("case", list(OPTION_CASES))
def test_bad_options(tmp_path, capsys, base, case):
    extra, word = OPTION_CASES[case]
    code, err = _run(tmp_path, capsys, IDENTIFY[:4] + extra, base["ecef"])
    assert code == 2 and word in err, (case, err)


SIMULATE_CASES = {
    "noise nan": (["--noise", "nan"], "--noise"),
    "noise negative": (["--noise", "-1,0.2"], "--noise"),
    "rate zero": (["--rate", "0"], "--rate"),
    "duration inf": (["--duration", "inf"], "--duration"),
    "seed negative": (["--seed", "-4"], "--seed"),
    "effect value nan": (["--effect", "wind=nan"], "wind"),
    "effect unknown": (["--effect", "gravity_waves"], "gravity_waves"),
}


@pytest.mark.parametrize("case", list(SIMULATE_CASES))
def test_bad_simulate_options(tmp_path, capsys, case):
    extra, word = SIMULATE_CASES[case]
    out = tmp_path / "sim.csv"
    code, err = _run(tmp_path, capsys, ["simulate-record", "--out", str(out), "--duration", "20"] + extra)
    assert code == 2 and word in err, (case, err)
    assert not out.exists()


def test_vehicle_option_pointing_at_a_directory(tmp_path, capsys, base):
    (tmp_path / "veh").mkdir()
    code, err = _run(tmp_path, capsys, IDENTIFY + ["--vehicle", str(tmp_path / "veh")], base["ecef"])
    assert code == 2 and "--vehicle" in err and "directory" in err


def test_unwritable_destinations_fail_before_the_run(tmp_path, capsys, base):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    for extra in (["--plots", str(blocker)], ["--model-out", str(blocker / "m.json")]):
        code, err = _run(tmp_path, capsys, IDENTIFY + extra, base["ecef"])
        assert code == 2 and str(blocker) in err, err
        assert "identify " not in err  # no progress line: nothing ran
    code, err = _run(tmp_path, capsys, ["identify", "{rec}", "--json", str(blocker / "r.json")], base["ecef"])
    assert code == 2 and "cannot write" in err


def test_a_full_disk_leaves_the_old_report_whole(tmp_path, base):
    """A write that fails part-way (a file-size limit) leaves the old report intact; exit 2, no traceback."""
    rec = tmp_path / "rec.csv"
    rec.write_text(base["ecef"])
    report = tmp_path / "report.json"
    report.write_text(OLD_REPORT)

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "rventry_env.cli", "identify", str(rec), "--json", str(report), "--quiet",
         "--h-max", "2", "--max-effects", "0"],
        preexec_fn=limit, capture_output=True, text=True, env=env, cwd=os.getcwd(),
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "could not write" in proc.stderr
    assert report.read_text() == OLD_REPORT
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".report.json")]


def test_a_byte_order_mark_is_read(tmp_path, base):
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + base["ecef"].encode())
    rec = load_record(p)
    assert rec.kind == "ecef" and any("byte-order mark" in n for n in rec.notes)


def test_record_writer_refuses_infinity():
    with pytest.raises(ValueError, match="column x_m: infinite"):
        record_text(np.arange(3.0), {"x_m": np.array([1.0, np.inf, 2.0])})
