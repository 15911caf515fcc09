"""The tables of timings (environment speed, the reference solve, the cost per decision) and of the solves of the
norm-keeping formulations: each renderer turns a small hand-written record into the rows it must show, every column
and the machine that ran it."""

from __future__ import annotations

import copy
import json
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def tables():
    spec = importlib.util.spec_from_file_location("tables", ROOT / "docs" / "tools" / "tables.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("tables", module)
    spec.loader.exec_module(module)
    return module


PROVENANCE = {
    "commit": {"sha": "0123456789abcdef0123456789abcdef01234567", "dirty": False},
    "machine": {"cpu": "Example CPU @ 2.10GHz", "cores_usable": 2, "cores": 2, "system": "Linux",
                "load_average_start": [0.04, 0.1, 0.2], "load_average_end": [0.52, 0.3, 0.2], "omp_num_threads": "1"},
    "versions": {"python": "3.12.3", "numpy": "2.1.3", "scipy": "1.14.1", "casadi": "3.6.7", "gymnasium": "1.0.0",
                 "torch": "2.5.1", "jax": None},
    "command": "python benchmarks/x.py --json docs/results/x.json",
    "started_utc": "2026-11-28T00:05:00+00:00",
    "wall_time_s": 301.6,
}  # fmt: skip

ENV_SPEED = {
    "scale": 1.0,
    "single_env_steps_per_s": 12215.4,
    "vector": [
        {"num_envs": 1, "vector_vehicle_steps_per_s": 1432.2, "sync_vehicle_steps_per_s": 8579.3, "speedup": 0.16694},
        {"num_envs": 64, "vector_vehicle_steps_per_s": 83130.0, "sync_vehicle_steps_per_s": 10391.0, "speedup": 8.0002},
        {"num_envs": 8192, "vector_vehicle_steps_per_s": 1152330.4, "sync_vehicle_steps_per_s": 10141.0, "speedup": 113.63},
    ],
    "accuracy": [],
    "provenance": {**PROVENANCE, "command": "python benchmarks/env_speed.py --json docs/results/env_speed.json"},
}

ENTRY_RUN = {"import_s": 0.41, "wall_s": 14.26, "cpu_s": 13.93, "guess_s": 0.78, "iterations_per_pass": [87, 18, 16],
             "nodes_per_pass": [267, 281, 290], "rss_peak_mb": 183.6, "cost": 1.4589471, "tf_s": 1033.9291,
             "mesh_error": 9.22e-7, "max_violation": 9.6e-9, "converged": True}  # fmt: skip
REFERENCE_SOLVE = {
    "load_average": 0.04,
    "entry": [ENTRY_RUN, {**ENTRY_RUN, "wall_s": 13.81, "cpu_s": 13.52, "guess_s": 0.71, "import_s": 0.39,
                          "rss_peak_mb": 184.2}],
    "betts": [
        {"case": "no_heating_limit", "tf_s": 2008.5877, "latitude_deg": 34.141183,
         "published": {"tf_s": 2008.59, "latitude_deg": 34.1412}, "tf_rel_error": 9.1e-7, "latitude_rel_error": 4.9e-7,
         "mesh_error": 8.7e-7, "n_nodes": 194, "wall_s": 3.81, "cpu_s": 3.7, "iterations_per_pass": [40, 9],
         "rss_peak_mb": 150.0},
        {"case": "heating_limit_70", "tf_s": 2198.6601, "latitude_deg": 30.625471,
         "published": {"tf_s": 2198.67, "latitude_deg": 30.6255}, "tf_rel_error": 4.6e-6, "latitude_rel_error": 1.2e-6,
         "mesh_error": 6.1e-7, "n_nodes": 185, "wall_s": 5.62, "cpu_s": 5.5, "iterations_per_pass": [55, 12],
         "rss_peak_mb": 152.0},
    ],
    "replay": {"rtol": 1e-11, "method": "DOP853", "position_error_at_impact_m": 0.0716, "max_position_error_m": 0.122,
               "altitude_at_tf_m": 0.0046, "wall_s": 12.0},
    "provenance": {**PROVENANCE, "command": "python benchmarks/reference_solve.py --repeat 2 --json "
                                            "docs/results/reference_solve.json"},
}  # fmt: skip
SHIPPED = {"cost": 1.4589471, "tf_s": 1033.9291}  # the shipped optimum's summary: what a cold solve is held to


def _timing(mean, p50, p99, batch=1, episodes=20):
    return {"batch": batch, "episodes": episodes, "calls": 1000, "decisions": 1000 * batch, "flown_steps": 1000,
            "per_decision_mean_s": mean, "per_decision_p50_s": p50, "per_decision_p99_s": p99, "per_decision_max_s": p99}


DECISION_COST = {
    "laws": {
        "learned": {"single": _timing(1.03e-3, 6.6e-4, 4.3e-3), "batched": _timing(8.33e-6, 7.19e-6, 2.61e-5, 1024, 1024)},
        "dagger": {"single": _timing(5.5e-4, 5.1e-4, 1.1e-3), "batched": _timing(5.3e-6, 4.8e-6, 9.0e-6, 1024, 1024)},
        "lqr": {"single": _timing(3.7e-5, 3.1e-5, 8.7e-5), "batched": _timing(1.35e-7, 1.1e-7, 3.0e-7, 1024, 1024)},
        "mpc": {"single": _timing(8.8e-3, 4.3e-4, 0.308, 1, 5)},
    },
    "batch": 1024, "seed": 0, "dispersion": "standard", "omp_num_threads": "1", "single_episodes": 20,
    "mpc_episodes": 5, "learned": "ppo",
    "command": "OMP_NUM_THREADS=1 python benchmarks/decision_cost.py --json docs/results/decision_cost.json",
    "provenance": {**PROVENANCE, "command": "python benchmarks/decision_cost.py --json docs/results/decision_cost.json"},
}  # fmt: skip

MACHINE = ("Measured 2026-11-28 at commit 0123456 on Example CPU @ 2.10GHz, 2 cores, OMP_NUM_THREADS=1, load average "
           "0.04 at the start and 0.52 at the end, 302 s in all; ")  # fmt: skip


def lines(text: str) -> list[str]:
    return text.split("\n")


def test_environment_speed_shows_every_figure_and_its_machine():
    out = lines(tables().env_speed_table(ENV_SPEED))
    assert out[:5] == [
        "|  | per second | a `SyncVectorEnv` of N single envs | vector / sync | target |",
        "|---|---|---|---|---|",
        "| single env through `gym.make` (with Gymnasium's wrappers) | 12,215 steps |  |  | >= 1e4: met |",
        "| vector env, N = 1 | 1,432 vehicle-steps | 8,579 | 0.17x |  |",
        "| vector env, N = 64 | 83,130 vehicle-steps | 10,391 | 8.0x |  |",
    ]
    assert out[5] == "| vector env, N = 8192 | 1,152,330 vehicle-steps | 10,141 | 114x | >= 1e6: met |"
    assert out[7] == MACHINE + "python 3.12.3, numpy 2.1.3, gymnasium 1.0.0."
    assert out[9] == ("Records: `docs/results/env_speed.json`; written by `OMP_NUM_THREADS=1 python benchmarks/env_speed.py "
                      "--json docs/results/env_speed.json`.")  # fmt: skip
    slow = copy.deepcopy(ENV_SPEED)
    slow["single_env_steps_per_s"], slow["vector"][2]["vector_vehicle_steps_per_s"], slow["scale"] = 9000.0, 9.5e5, 0.01
    out = lines(tables().env_speed_table(slow))
    assert out[2].endswith("| 9,000 steps |  |  | >= 1e4: **not met** |")
    assert out[5] == "| vector env, N = 8192 | 950,000 vehicle-steps | 10,141 | 114x | >= 1e6: **not met** |"
    assert out[7].endswith("Steps timed: 1 % of the default's (noisier figures).")


def test_the_reference_solve_shows_each_run_and_betts_cases():
    t = tables()
    out = lines(t.reference_solve_table(REFERENCE_SOLVE, SHIPPED))
    assert out[:9] == [
        "|  | run 0 | run 1 | target |",
        "|---|---|---|---|",
        "| wall time (guess + all mesh passes) | 14.3 s | 13.8 s | median 14.0 s < 30 s: met |",
        "| CPU time of the process | 13.9 s | 13.5 s |  |",
        "| of which the guess | 0.8 s | 0.7 s |  |",
        "| module imports (not included above) | 0.4 s | 0.4 s |  |",
        "| IPOPT iterations per pass (nodes) | 87 (267), 18 (281), 16 (290) | same |  |",
        "| peak resident memory (whole process) | 184 MB | 184 MB |  |",
        "| J*, t_f, final mesh error | 1.458947, 1033.929 s, 9.22e-7 | 1.458947, 1033.929 s, 9.22e-7 |  |",
    ]
    assert out[10] == "Every cold solve found the shipped optimum (J* = 1.458947, t_f = 1033.929 s)."
    assert out[12] == MACHINE + "python 3.12.3, casadi 3.6.7, numpy 2.1.3, scipy 1.14.1."
    assert out[14] == ("Records: `docs/results/reference_solve.json`, `rventry_env/reference/data/entry_reference_v1.json`; "
                       "written by `OMP_NUM_THREADS=1 python benchmarks/reference_solve.py --repeat 2 --json "
                       "docs/results/reference_solve.json`.")  # fmt: skip
    other = copy.deepcopy(REFERENCE_SOLVE)
    other["entry"][1]["iterations_per_pass"] = [90, 18, 16]
    other["entry"][1]["wall_s"] = 47.0
    assert lines(t.reference_solve_table(other, SHIPPED))[6] == ("| IPOPT iterations per pass (nodes) | 87 (267), 18 (281), "
                                                                 "16 (290) | 90 (267), 18 (281), 16 (290) |  |")  # fmt: skip
    assert lines(t.reference_solve_table(other, SHIPPED))[2].endswith("| 47.0 s | median 30.6 s < 30 s: **not met** |")
    # a cold solve that converged on another local optimum is named as such, with its cost
    local = copy.deepcopy(REFERENCE_SOLVE)
    local["entry"][1].update(cost=2.380528, tf_s=814.413)
    assert lines(t.reference_solve_table(local, SHIPPED))[10] == (
        "**Not the shipped optimum** (J* = 1.458947, t_f = 1033.929 s): run 1 (J = 2.380528, t_f = 814.4 s) converged "
        "on a local optimum of higher cost.")  # fmt: skip

    out = lines(t.reference_solve_summary(REFERENCE_SOLVE, SHIPPED))
    assert out[:7] == [
        "| quantity | measured | target |",
        "|---|---|---|",
        "| cold-start solve, wall (each run in a fresh process) | 14.3 s, 13.8 s | median < 30 s: met |",
        "| CPU time of the process | 13.9 s, 13.5 s |  |",
        "| peak memory (whole process) | 184 MB, 184 MB |  |",
        "| J found by the cold solve | 1.458947, 1.458947 | J* = 1.458947 |",
        ("| the shipped optimum's controls replayed open loop through `entry_rhs`, DOP853 rtol 1e-11: position error at "
         "impact | 0.072 m | <= 100 m: met |"),
    ]
    assert out[8] == "Every cold solve found the shipped optimum (J* = 1.458947, t_f = 1033.929 s)."
    assert out[10] == MACHINE + "python 3.12.3, casadi 3.6.7."
    assert lines(t.reference_solve_summary(local, SHIPPED))[8].startswith("**Not the shipped optimum**")

    out = lines(t.betts_table(REFERENCE_SOLVE))
    assert out[:4] == [
        "| case | tf (published) | rel. error | final latitude (published) | rel. error | mesh error | nodes | wall |",
        "|---|---|---|---|---|---|---|---|",
        "| no heating limit | 2008.588 s (2008.59) | 9e-7 | 34.14118 deg (34.1412) | 5e-7 | 8.7e-7 | 194 | 3.8 s |",
        "| q <= 70 BTU/ft^2/s | 2198.660 s (2198.67) | 5e-6 | 30.62547 deg (30.6255) | 1e-6 | 6.1e-7 | 185 | 5.6 s |",
    ]
    assert out[5] == "Largest relative error 5e-6 against the target's 1e-3: met."
    assert out[7] == MACHINE + "python 3.12.3, casadi 3.6.7."  # its wall times are that machine's


def test_the_cost_per_decision_shows_every_law_one_vehicle_and_batched():
    out = lines(tables().decision_cost_table(DECISION_COST))
    assert out[:6] == [
        "| law | one vehicle: mean (median / p99 call) | batch of 1024: mean per vehicle (median / p99 call) | "
        "`mpc` / this, batched | target |",
        "|---|---|---|---|---|",
        "| `learned` (`ppo`: PPO's weights on `dagger-flight`'s network, estimator and relief, with its q floor; in torch) "
        "| 1.0 ms (660 us / 4.3 ms) | 8.3 us (7.2 us / 26.1 us) | 1,056x | <= 10 us, >= 1,000x: met |",
        "| `dagger` (one network, its estimator and its load relief) | 550 us (510 us / 1.1 ms) | 5.3 us (4.8 us / 9.0 us) "
        "| 1,660x | <= 1 ms, >= 1,000x: met |",
        "| `lqr` | 37.0 us (31.0 us / 87.0 us) | 0.1 us (0.1 us / 0.3 us) | 65,185x |  |",
        "| `mpc` | 8.8 ms (430 us / 308 ms) | one NLP per vehicle: the same per vehicle | 1x |  |",
    ]  # fmt: skip
    assert out[7] == ("Standard set from seed 0: one vehicle at a time 20 episodes per law (5 of `mpc`), and 1024 in one "
                      "batch; re-solves included in the mean. " + MACHINE + "python 3.12.3, numpy 2.1.3, torch 2.5.1, "
                      "casadi 3.6.7.")  # fmt: skip
    assert out[9] == ("Records: `docs/results/decision_cost.json`; written by `OMP_NUM_THREADS=1 python "
                      "benchmarks/decision_cost.py --json docs/results/decision_cost.json`.")  # fmt: skip
    dear = copy.deepcopy(DECISION_COST)
    dear["laws"]["learned"]["batched"]["per_decision_mean_s"] = 12e-6  # over a PPO-trained policy's 10 us
    assert lines(tables().decision_cost_table(dear))[2].endswith("| 733x | <= 10 us, >= 1,000x: **not met** |")
    small = copy.deepcopy(DECISION_COST)  # a smoke run: the targets are set for a batch of 1024
    small["batch"], small["laws"]["mpc"]["single"]["per_decision_mean_s"] = 16, 2.5
    out = lines(tables().decision_cost_table(small))
    assert out[2].endswith("| 300,120x | <= 10 us, >= 1,000x: set for a batch of 1024 |")
    assert out[5] == "| `mpc` | 2.5 s (430 us / 308 ms) | one NLP per vehicle: the same per vehicle | 1x |  |"


def _formulation_solve(mode, guess, iterations, wall, cost, tf, drift, error, first_status="Solve_Succeeded"):
    return {"norm_mode": mode, "guess": guess, "converged": True, "status": "Solve_Succeeded",
            "first_pass": {"nlp_iterations": iterations, "wall_s": wall, "status": first_status, "nodes": 267},
            "iterations_per_pass": [iterations, 18, 16], "cost": cost, "tf_s": tf, "mesh_error": 9.2e-7,
            "norm_drift_nodes": drift, "replay": {"rtol": 1e-11, "method": "DOP853", "position_error_at_impact_m": error}}


FORMULATIONS = {
    "delta": 1e-6, "shipped": {"cost": 1.4589471, "tf_s": 1033.9291},
    "solves": [
        _formulation_solve("projection", "cold", 87, 8.14, 1.4589471, 1033.9291, 3.2e-12, 0.0716),
        _formulation_solve("projection", "optimum", 12, 3.07, 1.4589473, 1033.929, 2.9e-12, 0.0702),
        _formulation_solve("paper", "cold", 141, 26.04, 1.419678, 1037.37, 9.3e-4, 24123.0),
        {"norm_mode": "paper", "guess": "optimum", "converged": False, "status": "Maximum_Iterations_Exceeded",
         "first_pass": {"nlp_iterations": 3000, "wall_s": 171.3, "status": "Maximum_Iterations_Exceeded", "nodes": 267},
         "iterations_per_pass": [3000], "cost": 1.2, "tf_s": 1000.0, "mesh_error": 3.14e-4, "norm_drift_nodes": 1e-2,
         "replay": {"rtol": 1e-11, "error": "replay integration failed"}},
        _formulation_solve("none", "cold", 1158, 176.2, 1.4589471, 1033.9291, 8.5e-7, 0.0716,
                           first_status="Solved_To_Acceptable_Level"),
        {"norm_mode": "none", "guess": "optimum", "converged": False, "status": "timed out after 1800 s",
         "first_pass": None, "wall_s": 1800.2},
    ],
    "provenance": {**PROVENANCE, "command": "python studies/formulations.py --out docs/results/formulations.json"},
}  # fmt: skip


def test_the_formulations_table_shows_each_solve_and_each_failure():
    out = lines(tables().formulation_table(FORMULATIONS))
    assert out[:8] == [
        "| formulation | guess | first pass | J | tf | norm drift at nodes | replay error at impact |",
        "|---|---|---|---|---|---|---|",
        "| projection (shipped) | generated (cold) | 87 iterations, 8.1 s | 1.458947 (J*) | 1033.93 s | 3.2e-12 | 0.072 m |",
        "| projection (shipped) | the shipped optimum | 12 iterations, 3.1 s | 1.458947 (J*) | 1033.93 s | 2.9e-12 | 0.070 m |",
        # below J* by 2.7 %, and the replay beyond 100 m: in bold
        ("| paper (u1..u4, delta = 1e-6 band) | generated (cold) | 141 iterations, 26.0 s | 1.419678 (-2.69%) "
         "| 1037.37 s | 9.3e-4 | **24 km** |"),
        # a solve that ran out of iterations: its status and mesh error, none of its figures
        ("| paper (u1..u4, delta = 1e-6 band) | the shipped optimum | 3000 iterations, 171.3 s, "
         "`Maximum_Iterations_Exceeded` | **fails**: `Maximum_Iterations_Exceeded`, mesh error 3.1e-4 after 1 pass "
         "| - | - | - |"),
        ("| none (Eq. Ex2-endpoint verbatim) | generated (cold) | 1158 iterations, 176.2 s, "
         "`Solved_To_Acceptable_Level` | 1.458947 (J*) | 1033.93 s | 8.5e-7 | 0.072 m |"),
        # a solve that gave no solution at all
        "| none (Eq. Ex2-endpoint verbatim) | the shipped optimum | - | **fails**: `timed out after 1800 s` | - | - | - |",
    ]  # fmt: skip
    assert out[9].startswith("J against the shipped optimum's J* = 1.458947 (tf = 1033.93 s), (J*) where it is within 1e-4")
    assert out[9].endswith("(DOP853, rtol 1e-11), position error at impact; in bold beyond the 100 m the shipped optimum "
                           "is held to.")  # fmt: skip
    assert out[11] == MACHINE + "python 3.12.3, casadi 3.6.7, numpy 2.1.3, scipy 1.14.1."
    assert out[13] == ("Records: `docs/results/formulations.json`; written by `OMP_NUM_THREADS=1 python "
                       "studies/formulations.py --out docs/results/formulations.json`.")  # fmt: skip
    # a converged solve whose replay could not run says so; a J within 1e-4 of J* is J*, one beyond is its difference
    other = copy.deepcopy(FORMULATIONS)
    other["solves"][0]["replay"] = {"rtol": 1e-11, "error": "replay integration failed on [0.000, 3.876] s"}
    other["solves"][1]["cost"] = 1.4589471 * 1.0002
    other["solves"][4]["stages"] = ["exact", "relaxed gamma <= -75 deg", "exact from relaxed"]
    out = lines(tables().formulation_table(other))
    assert out[2].endswith("| not replayed: replay integration failed on [0.000, 3.876] s |")
    assert "| 1.459239 (+0.02%) |" in out[3]
    assert out[6].startswith("| none (Eq. Ex2-endpoint verbatim) | generated (cold), through the relaxed-angle "
                             "continuation | 1158 iterations")  # fmt: skip


def test_each_timing_table_reads_its_record_and_renders_it():
    t = tables()
    rhs = json.loads((ROOT / t.RHS_FORMS).read_text())  # the committed record: its table is checked against it too
    fixtures = {t.ENV_SPEED: ENV_SPEED, t.REFERENCE_SOLVE: REFERENCE_SOLVE, t.DECISION_COST: DECISION_COST, t.RHS_FORMS: rhs,
                t.SHIPPED_REFERENCE: SHIPPED}  # fmt: skip
    names = {x.name for x in t.TIMINGS}
    assert names == {"env-speed", "reference-solve", "reference-solve-summary", "reference-betts", "decision-cost",
                     "rhs-throughput"}
    for table in t.TIMINGS:
        assert table.render(*(fixtures[p] for p in table.records)).startswith("|"), table.name


def test_the_defaults_scan_shows_every_variant_the_defaults_first_and_its_workers():
    t = tables()
    doc = json.loads((ROOT / t.SCAN_DEFAULTS).read_text())
    out = lines(t.scan_defaults_table(doc))
    rows = [line for line in out if line.startswith("| ") and not line.startswith("| variant")]
    assert len(rows) == len(doc["scan"]) and rows[0].startswith("| **defaults** | 1.00 | 0.00 | 0.845, 0.952 |")
    assert "| budget 25 iterations | 1.00 | 0.00 | 0.976, 0.851 |" in rows[10] and rows[10].endswith("| 53 | 9.3 |")
    assert " on 1 worker, " in "\n".join(out) and " on 2 workers, " in t.scan_defaults_table(dict(doc, workers=2))
