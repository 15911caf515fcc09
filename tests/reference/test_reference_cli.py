"""``rventry reference show/export/plot`` and their error handling."""

import csv
import json
import types

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


COARSE = ["--first-mesh", "12", "4", "--end-fraction", "0.05", "--mesh-tolerance", "1e-2", "--max-mesh-iterations",
          "2", "--quiet"]  # fmt: skip


@pytest.mark.slow
def test_solve_writes_where_out_says_and_never_the_packaged_file(tmp_path, capsys):
    from rventry_env.reference.data_file import DEFAULT_PATH, GUIDANCE_PATH

    shipped = {p: p.stat().st_mtime_ns for p in (DEFAULT_PATH, GUIDANCE_PATH)}
    out = tmp_path / "coarse.npz"
    assert main(["reference", "solve", "--out", str(out), *COARSE]) == 0
    ref = load_reference(out)
    assert ref.x[-1, 6] == 0.0 and ref.x[-1, 9] == 0.0  # the exact vertical impact holds on any mesh
    assert ref.summary()["converged"] is True and ref.summary()["mesh_error"] <= 1e-2
    assert {p: p.stat().st_mtime_ns for p in shipped} == shipped


@pytest.mark.slow
def test_an_unconverged_solve_writes_nothing(tmp_path, capsys):
    out = tmp_path / "never.npz"
    args = ["reference", "solve", "--out", str(out), "--first-mesh", "8", "4", "--end-fraction", "0",
            "--mesh-tolerance", "1e-9", "--max-mesh-iterations", "1", "--quiet"]  # fmt: skip
    assert main(args) == 1
    assert "did not converge" in capsys.readouterr().err
    assert not out.exists() and not out.with_suffix(".json").exists()
    assert list(tmp_path.iterdir()) == []  # no temporary file left behind either


def test_ship_refuses_margins_that_are_not_the_shipped_files(tmp_path, capsys):
    assert main(["reference", "solve", "--ship", "optimum", "--q-margin", "0.1", "--quiet"]) == 2
    assert "--ship optimum is the reference solved with --q-margin 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reference", "solve", "--ship", "guidance", "--out", str(tmp_path / "x.npz")])
    assert "not allowed with argument" in capsys.readouterr().err


def test_export_bounds_the_number_of_rows(tmp_path, capsys):
    assert main(["reference", "export", "--csv", str(tmp_path / "x.csv"), "--dt", "1e-7"]) == 2
    err = capsys.readouterr().err
    assert "--dt 1e-07 s would export" in err and "rows" in err
    assert not (tmp_path / "x.csv").exists()


def test_a_file_that_is_not_a_reference_is_named_never_unpickled(tmp_path, capsys):
    bogus = tmp_path / "bogus.npz"
    bogus.write_bytes(b"\x80\x04K\x01.")  # a pickle: must never be loaded
    assert main(["reference", "show", "--file", str(bogus)]) == 2
    err = capsys.readouterr().err
    assert "is not an rventry reference file" in err and "allow_pickle" not in err
    assert main(["reference", "show", "--file", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_ship_keeps_the_shipped_file_against_a_worse_local_optimum(tmp_path, monkeypatch, capsys):
    """A converged solve whose cost is above the shipped file's is a local optimum: the file stays."""
    from rventry_env.reference import data_file
    from rventry_env.reference import pipeline

    shipped = data_file.DEFAULT_PATH
    copy = tmp_path / shipped.name
    copy.write_bytes(shipped.read_bytes())
    (tmp_path / shipped.with_suffix(".json").name).write_bytes(shipped.with_suffix(".json").read_bytes())
    before = copy.read_bytes()
    j_star = load_reference(copy).cost

    class Worse:  # what solve_reference returns, at J = 2.38: converged, and not the optimum
        converged, timings = True, {"solve_time_s": 1.0}
        solution = types.SimpleNamespace(cost=2.380528, tf=814.4, max_error=8.9e-7, max_violation=1e-9,
                                         success=True, status="Solve_Succeeded")  # fmt: skip

    monkeypatch.setattr(data_file, "DEFAULT_PATH", copy)
    monkeypatch.setattr(pipeline, "solve_reference", lambda *a, **k: Worse())
    assert main(["reference", "solve", "--ship", "optimum", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"J* = 2.380528 is above the shipped file's {j_star:.6f}" in err and "not replaced" in err
    assert copy.read_bytes() == before


def test_out_writes_a_local_optimum_of_the_shipped_problem_with_a_warning(tmp_path, monkeypatch, capsys):
    """``--out`` writes what was solved, and names a cost above the shipped optimum's a local optimum."""
    from rventry_env.reference import pipeline

    j_star = load_reference().cost
    written = []

    def solved(cost):
        return types.SimpleNamespace(converged=True, timings={"solve_time_s": 1.0}, solution=types.SimpleNamespace(
            cost=cost, tf=814.4, max_error=8.9e-7, max_violation=1e-9, success=True, status="Solve_Succeeded"))  # fmt: skip

    def save(rs, out):
        written.append((rs.solution.cost, out))
        return out, out.with_suffix(".json")

    monkeypatch.setattr(pipeline, "save_reference", save)
    out = tmp_path / "cold.npz"
    monkeypatch.setattr(pipeline, "solve_reference", lambda *a, **k: solved(2.380528))
    assert main(["reference", "solve", "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert f"warning: rventry reference solve: J* = 2.380528 is above the shipped file's {j_star:.6f}" in err
    assert f"written to {out}" in err and written == [(2.380528, out)]
    # the optimum itself, and a problem no shipped file solves (other margins), pass without a word
    monkeypatch.setattr(pipeline, "solve_reference", lambda *a, **k: solved(j_star))
    assert main(["reference", "solve", "--out", str(out), "--quiet"]) == 0
    monkeypatch.setattr(pipeline, "solve_reference", lambda *a, **k: solved(9.0))
    assert main(["reference", "solve", "--out", str(out), "--q-margin", "0.1", "--quiet"]) == 0
    assert "local optimum" not in capsys.readouterr().err and len(written) == 3
