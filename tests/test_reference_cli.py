"""``rventry reference show/export/plot`` and their error handling."""

import csv
import json

import numpy as np
import pytest

from rventry_env.cli import main
from rventry_env.reference import load_reference
from rventry_env.reference.cli import export_grid

COLUMNS = ["t_s", "r", "eA1", "eA2", "eA3", "etaA", "v", "eB1", "eB2", "eB3", "etaB", "alpha", "sigma",
           "u_alpha", "u_sigma"]  # fmt: skip


def test_show_writes_the_summary(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["reference", "show", "--json", str(out)]) == 0
    s = json.loads(out.read_text())
    for key in ("tf_s", "cost", "mesh_error", "max_constraint_violation", "solve_time_s"):
        assert key in s
    assert s["cost"] == pytest.approx(load_reference().cost)
    assert "tf_s" in capsys.readouterr().out


@pytest.mark.parametrize("dt", [0.1, 7.0])
def test_export_uniform_grid_ending_at_tf(tmp_path, dt):
    out = tmp_path / "r.csv"
    args = ["reference", "export", "--csv", str(out)] + ([] if dt == 0.1 else ["--dt", str(dt)])
    assert main(args) == 0
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == COLUMNS
    data = np.array(rows[1:], dtype=float)
    ref = load_reference()
    assert data[0, 0] == 0.0 and data[-1, 0] == ref.tf  # exactly tf
    steps = np.diff(data[:, 0])
    assert np.allclose(steps[:-1], dt, atol=1e-9) and 0 < steps[-1] <= dt + 1e-9
    np.testing.assert_allclose(data[-1, 1:13], ref.x[-1], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(data[:, 1:13], ref.state(data[:, 0]), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("bad", ["0", "-0.5", "nan", "abc"])
def test_export_rejects_bad_dt(tmp_path, bad, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["reference", "export", "--csv", str(tmp_path / "x.csv"), "--dt", bad])
    assert exc.value.code == 2
    assert "--dt" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


def test_export_grid_rejects_bad_dt_in_python():
    with pytest.raises(ValueError, match="--dt"):
        export_grid(load_reference(), -1.0)


def test_plot_writes_the_six_panels(tmp_path):
    assert main(["reference", "plot", str(tmp_path / "fig")]) == 0
    names = sorted(p.name for p in (tmp_path / "fig").glob("*.png"))
    assert names == sorted(["altitude.png", "speed.png", "c_ae_euler_parameters.png", "c_ba_euler_parameters.png",
                            "alpha.png", "sigma.png"])  # fmt: skip
    assert all((tmp_path / "fig" / n).stat().st_size > 1000 for n in names)


def test_missing_reference_file_is_a_clear_error(tmp_path, capsys):
    assert main(["reference", "show", "--file", str(tmp_path / "missing.npz")]) == 2
    assert "rventry reference solve" in capsys.readouterr().err
