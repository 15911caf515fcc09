"""studies/formulations.py without IPOPT: a solve's entry of the record, and failures recorded, never dropped."""

import json
import subprocess
from types import SimpleNamespace

import pytest
from script_modules import load_script  # (tests/ is on the path)

from rventry_env.reference.collocation.progress import MeshIterationRecord


@pytest.fixture(scope="module")
def study():
    return load_script("studies/formulations")


def _pass(it, iters, nodes, seconds, status="Solve_Succeeded", label=""):
    return MeshIterationRecord(iteration=it, n_intervals=nodes // 6, n_nodes=nodes, max_error=1e-5 / (it + 1),
                               status=status, success=status == "Solve_Succeeded", nlp_iterations=iters,
                               solve_time_s=seconds, cost=1.45, tf=1033.0, label=label)  # fmt: skip


def _solve(converged=True):
    sol = SimpleNamespace(status="Solve_Succeeded", success=True, cost=1.4589471, tf=1033.93, max_error=9.2e-7,
                          max_violation=9.6e-9)  # fmt: skip
    diagnostics = {"norm_drift_nodes": 3.2e-12, "norm_drift_between_nodes": 7.6e-7, "final_flight_path_deg": -90.0,
                   "target_miss_m": 0.4}  # fmt: skip
    timings = {"solve_time_s": 14.3, "solve_cpu_s": 13.9, "guess_s": 0.8, "rss_peak_mb": 184.0}
    return SimpleNamespace(solution=sol, diagnostics=diagnostics, converged=converged, stages=["exact"], timings=timings,
                           records=[_pass(0, 87, 267, 8.1), _pass(1, 18, 281, 2.9), _pass(2, 16, 290, 2.6)])  # fmt: skip


def test_a_solve_is_recorded_pass_by_pass_with_its_drift_and_replay(study, tmp_path):
    replay = {"rtol": 1e-11, "method": "DOP853", "position_error_at_impact_m": 0.0716, "max_position_error_m": 0.12,
              "altitude_at_tf_m": 0.004}  # fmt: skip
    ends = [{"wall_s": 9.0, "cpu_s": 8.8}, {"wall_s": 11.9, "cpu_s": 11.6}, {"wall_s": 14.3, "cpu_s": 13.9}]
    row = study.solve_row("paper", "optimum", _solve(), replay, 0.4, ends)
    assert (row["norm_mode"], row["guess"], row["converged"], row["status"]) == ("paper", "optimum", True, "Solve_Succeeded")
    assert row["first_pass"] == {"nlp_iterations": 87, "wall_s": 8.1, "status": "Solve_Succeeded", "nodes": 267,
                                 "cpu_s_from_start": 8.8, "wall_s_from_start": 9.0}  # fmt: skip
    assert row["iterations_per_pass"] == [87, 18, 16] and row["nodes_per_pass"] == [267, 281, 290]
    assert row["pass_labels"] == ["0", "1", "2"] and row["pass_end_cpu_s"] == [8.8, 11.6, 13.9]
    assert (row["wall_s"], row["cpu_s"], row["import_s"]) == (14.3, 13.9, 0.4)
    assert (row["cost"], row["tf_s"], row["mesh_error"]) == (1.4589471, 1033.93, 9.2e-7)
    assert row["norm_drift_nodes"] == 3.2e-12 and row["replay"] is replay
    # the record is strict JSON through the run's provenance
    study.start_run(["python", "studies/formulations.py"])
    doc = json.loads(study.write_record(tmp_path / "r.json", {"solves": [row]}).read_text())
    assert doc["solves"][0]["first_pass"]["nlp_iterations"] == 87 and doc["provenance"]["command"]


def test_an_unconverged_solve_keeps_its_status_and_figures(study):
    rs = _solve(converged=False)
    rs.solution.status, rs.solution.success = "Maximum_Iterations_Exceeded", False
    rs.records[0] = _pass(0, 3000, 267, 170.0, status="Maximum_Iterations_Exceeded")
    row = study.solve_row("none", "cold", rs, {"error": "replay integration failed"}, 0.4, [])
    assert row["converged"] is False and row["status"] == "Maximum_Iterations_Exceeded"
    assert row["first_pass"]["status"] == "Maximum_Iterations_Exceeded" and row["first_pass"]["cpu_s_from_start"] is None
    assert row["replay"] == {"error": "replay integration failed"}


def test_a_solve_that_crashes_or_hangs_is_recorded_with_its_status(study, monkeypatch):
    def timeout(cmd, **kw):
        raise subprocess.TimeoutExpired(cmd, kw["timeout"])

    monkeypatch.setattr(study.subprocess, "run", timeout)
    row = study.run_solve("none", "cold", 5.0, None)
    assert (row["norm_mode"], row["guess"], row["converged"], row["status"]) == ("none", "cold", False,
                                                                                 "timed out after 5 s")
    assert row["first_pass"] is None and row["wall_s"] >= 0
    monkeypatch.setattr(study.subprocess, "run", lambda cmd, **kw: SimpleNamespace(returncode=-9, stdout=""))
    assert study.run_solve("paper", "optimum", 5.0, None)["status"] == "the solve's process exited with status -9"
    good = {"norm_mode": "paper", "guess": "optimum", "converged": True, "status": "Solve_Succeeded"}
    monkeypatch.setattr(study.subprocess, "run",
                        lambda cmd, **kw: SimpleNamespace(returncode=0, stdout="a line\n" + json.dumps(good) + "\n"))
    assert study.run_solve("paper", "optimum", 5.0, None) == good


def test_an_error_in_the_solve_becomes_its_row(study, monkeypatch, capsys):
    def broken(mode, guess, keep):
        raise RuntimeError("CasADi: NaN detected")

    monkeypatch.setattr(study, "_one_solve", broken)
    assert study._child("paper", "cold", "") == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row == {"norm_mode": "paper", "guess": "cold", "converged": False, "first_pass": None, "wall_s": None,
                   "status": "error: RuntimeError: CasADi: NaN detected"}  # fmt: skip


def test_every_solve_reaches_the_record_in_order(study, monkeypatch, tmp_path, capsys):
    done = []

    def fake(mode, guess, timeout_s, keep):
        done.append((mode, guess))
        if mode == "none":
            return study.failed_row(mode, guess, "timed out after 60 s", 60.0)
        return study.solve_row(mode, guess, _solve(), {"rtol": 1e-11, "position_error_at_impact_m": 0.07}, 0.4, [])

    monkeypatch.setattr(study, "run_solve", fake)
    out = tmp_path / "f.json"
    assert study.main(["--modes", "projection,none", "--guesses", "optimum,cold", "--timeout", "60", "--out", str(out)]) == 0
    assert done == [("projection", "optimum"), ("projection", "cold"), ("none", "optimum"), ("none", "cold")]
    doc = json.loads(out.read_text())
    assert [(r["norm_mode"], r["guess"], r["converged"]) for r in doc["solves"]] == [
        ("projection", "optimum", True), ("projection", "cold", True), ("none", "optimum", False), ("none", "cold", False)]
    assert doc["delta"] == 1e-6 and doc["shipped"]["cost"] > 0 and doc["timeout_s"] == 60.0
    assert "--modes projection,none" in doc["provenance"]["command"]
    printed = capsys.readouterr().out
    assert "[4/4] norm mode none, from the cold guess" in printed
    assert "none       cold    NOT CONVERGED (timed out after 60 s)" in printed
    assert "first pass 87 iterations, 8.1 s" in printed


@pytest.mark.parametrize("argv, match", [
    (["--modes", "projection,exact"], "comma-separated list of projection, paper, none, got 'projection,exact'"),
    (["--guesses", "cold,cold"], "given twice"),
    (["--guesses", ""], "comma-separated list of cold, optimum"),
    (["--timeout", "0"], "--timeout must be a positive number of seconds"),
])  # fmt: skip
def test_bad_options_are_refused_by_name(study, argv, match, capsys):
    with pytest.raises(SystemExit) as exc:
        study.main(argv)
    assert exc.value.code == 2 and match in capsys.readouterr().err


def test_the_pass_clock_stamps_each_pass_from_its_start_and_forwards_it(study):
    seen = []
    clock = study.PassClock(seen.append)
    clock.start()
    for rec in (_pass(0, 87, 267, 8.1), _pass(1, 18, 281, 2.9)):
        sum(i * i for i in range(20000))  # some CPU time between the passes
        clock(rec)
    assert [r.iteration for r in seen] == [0, 1]
    assert 0 <= clock.ends[0]["cpu_s"] <= clock.ends[1]["cpu_s"] and 0 < clock.ends[0]["wall_s"] < clock.ends[1]["wall_s"]
