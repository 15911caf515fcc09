"""Benchmark of the re-planning guidance (``mpc``): how each default was chosen, and the targets.

Two parts:

``--scan``: each setting of :class:`~rventry_env.guidance.replanning.ReplanningSettings`
varied alone around the defaults, flown on the same episodes (default: 40 of the wide set,
seeds 100000...) and nominally. Prints success rate, path violations, J/J*, the re-solve
time percentiles and the failed solves for every variant.

``--evaluate``: the benchmark's targets: success on 200 episodes of the standard and the wide
sets (seed 0), the nominal J/J*, re-solve time median / p99, and the wall time of the
200-episode evaluation with ``--workers``.

``--terminal-alpha A,B,...``: the nominal flight with the terminal alpha bound aimed at each
value (deg; 0 = off): alpha(t_f), the vertical-impact error, the miss and J/J*; with
``--episodes N``, also N episodes of ``--dispersion`` per aim, with the precision tier.

``--navigation REPORT``: what navigation leaves to guidance, from an evaluation report: the
navigation's errors at the end, the share of episodes whose horizontal error alone is within the
precision tier's miss, and success by the size of the vertical (altitude) error.

    python studies/mpc_settings.py --evaluate --workers 2 --json out/bench_mpc.json
    python studies/mpc_settings.py --scan --episodes 40 --workers 2 --json out/scan_mpc.json
    python studies/mpc_settings.py --scan --variants flight --dispersion flight --episodes 12 --workers 2 --json out/scan_mpc_flight.json
    python studies/mpc_settings.py --scan --variants aero --dispersion flight --episodes 20 --seed 1000 --workers 2 --json out/scan_mpc_aero.json

Timings depend on the machine: the manual's results quote this 2-core machine's (``--workers 2``).
Success rates do not: the solver's budget is an iteration count.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict, replace

import numpy as np

from rventry_env.task import FLIGHT_GRADE_ERRORS, NAMED_SETS, EntryTask, PrecisionThresholds
from rventry_env.evaluation.parallel import EvaluationJob, evaluate_many
from rventry_env.evaluation.agents import peer_settings
from rventry_env.evaluation.summary import summarize
from rventry_env.guidance.estimation import FlightEstimatorSettings
from rventry_env.guidance.replanning import ReplanningSettings
from rventry_env.util.args import non_negative_int, positive_int
from rventry_env.util.provenance import start_run, write_record

TARGETS = {"standard_success": 0.99, "wide_success": 0.95, "nominal_cost_ratio": 1.10, "resolve_p50_s": 0.5,
           "resolve_p99_s": 2.0, "wall_200_standard_s": 1800.0}  # fmt: skip

DEFAULT = ReplanningSettings()
# The scans below vary one setting at a time around the defaults as they were when each was measured:
# before the terminal alpha bound became a default. Their base keeps it off, so that every scan's
# command still reproduces its recorded table.
SCANNED = replace(DEFAULT, terminal_alpha=False)
VARIANTS = {
    "defaults": {},
    "replan every 20 s": {"replan_s": 20.0},
    "replan every 45 s": {"replan_s": 45.0},
    "mesh 15 x 4": {"mesh_intervals": 15},
    "mesh 30 x 4": {"mesh_intervals": 30},
    "mesh 20 x 5": {"mesh_degree": 5},
    "no end block (20 equal intervals)": {"end_fraction": 0.0},
    "end block of 2 intervals": {"end_intervals": 2},
    "margins q 2 %, load 1 %": {"q_margin": 0.02, "load_margin": 0.01},
    "margins q 8 %, load 4 %": {"q_margin": 0.08, "load_margin": 0.04},
    "budget 25 iterations": {"max_iterations": 25},
    "penalty 10": {"soft_penalty": 10.0},
    "penalty 100": {"soft_penalty": 100.0},
    "freeze 10 s": {"freeze_s": 10.0},
    "freeze 60 s": {"freeze_s": 60.0},
}

# the density perturbation's published statistics (the flight set's bands: what a law may know)
FLIGHT_BANDS = FLIGHT_GRADE_ERRORS.density_bands
# the flight-grade scan: the settings the flight set's failures point to (load-factor breaches in
# the final pull-down, q dips at a skip's apex where the air is thinner than estimated lower down)
FLIGHT_VARIANTS = {
    "defaults": {},
    "load relief 2 %": {"load_relief_margin": 0.02},
    "load relief 2 %, q margin 8 %": {"load_relief_margin": 0.02, "q_margin": 0.08},
    "load relief 2 %, q 8 %, terminal alpha 0.5": {"load_relief_margin": 0.02, "q_margin": 0.08,
                                                    "terminal_alpha": True},
    "load relief 2 %, density margins 1 sigma": {"load_relief_margin": 0.02, "density_bands": FLIGHT_BANDS,
                                                  "density_sigmas": 1.0},
    "load relief 2 %, density margins 2 sigma": {"load_relief_margin": 0.02, "density_bands": FLIGHT_BANDS,
                                                  "density_sigmas": 2.0},
}
# the margins for the aerodynamics' uncertainty in Mach, around the flight-grade preset
# (ReplanningSettings.flight_grade() with the 2 % load relief it had then, agent mpc-flight before the
# final-dive and estimator scans below): its fields that differ from the defaults
_FLIGHT_GRADE = {k: v for k, v in asdict(ReplanningSettings.flight_grade(load_relief_margin=0.02)).items()
                 if getattr(SCANNED, k) != v}  # fmt: skip
_LR_D1 = {k: _FLIGHT_GRADE[k] for k in ("load_relief_margin", "density_bands", "density_sigmas")}
_AERO = {"aero_mach_rms": _FLIGHT_GRADE["aero_mach_rms"]}
AERO_VARIANTS = {
    "load relief 2 %, density 1 sigma": _LR_D1,
    "+ aero margins 1 sigma": _LR_D1 | _AERO,
    "+ aero margins 2 sigma": _LR_D1 | _AERO | {"aero_sigmas": 2.0},
    "+ aero 1 sigma, q 8 %": _LR_D1 | _AERO | {"q_margin": 0.08},
    "+ aero 1 sigma, q 10 % (mpc-flight)": _FLIGHT_GRADE,
    "density 2 sigma, aero 1 sigma": _LR_D1 | _AERO | {"density_sigmas": 2.0},
}
# the final dive, around mpc-flight: its remaining flight failures end there (a load bound crossed by
# a few per cent, or 5-10 deg from vertical and 50-100 m/s fast after tracking a plan made 30-60 s before)
_FINAL_REPLANS = {"final_replan_s": 10.0, "final_window_s": 120.0, "freeze_s": 10.0}
FINAL_VARIANTS = {
    "mpc-flight": _FLIGHT_GRADE,
    "+ final re-plans 10 s, freeze 10 s": _FLIGHT_GRADE | _FINAL_REPLANS,
    "+ terminal alpha 0.5 deg": _FLIGHT_GRADE | {"terminal_alpha": True},
    "+ load relief 4 %": _FLIGHT_GRADE | {"load_relief_margin": 0.04},
    "+ final re-plans, terminal alpha": _FLIGHT_GRADE | _FINAL_REPLANS | {"terminal_alpha": True},
}
# the flight-grade estimator (density as a process in altitude, aerodynamics in Mach, the wind) around mpc-flight
_FLIGHT_EST = {"estimator_settings": FlightEstimatorSettings.flight_grade()}
ESTIMATOR_VARIANTS = {
    "+ flight estimator": _FLIGHT_GRADE | _FLIGHT_EST,
    "+ flight estimator, no wind states": _FLIGHT_GRADE | {"estimator_settings": FlightEstimatorSettings.flight_grade(
        wind_sigma=None, wind_bands=None)},
    "+ flight estimator, load relief 4 %": _FLIGHT_GRADE | _FLIGHT_EST | {"load_relief_margin": 0.04},
}
# the flight estimator with the load relief's chance margin (2 sigma of the density's and the aerodynamics' spread
# over the next step), and the q bound with the drag scale's share that is not density (C_D: 5 % rms in the flight set)
_SPLIT = {"drag_rms": 0.05, "split_sigmas": 1.0}
SPLIT_VARIANTS = {
    "+ flight estimator, relief 2 sigma": _FLIGHT_GRADE | _FLIGHT_EST | {"load_relief_sigmas": 2.0},
    "+ flight estimator, relief 2 sigma, drag split": _FLIGHT_GRADE | _FLIGHT_EST | {"load_relief_sigmas": 2.0} | _SPLIT,
    "+ flight estimator, relief 2 sigma, drag split, q 5 %": _FLIGHT_GRADE | _FLIGHT_EST | _SPLIT
                                                            | {"load_relief_sigmas": 2.0, "q_margin": 0.05},
}
# mpc-flight as shipped, and plans that turn vertical above the target, the law diving straight from there: the
# navigated altitude is a kilometre off at impact, and the optimum's turn to vertical takes its last second
_MPC_FLIGHT = {k: v for k, v in asdict(ReplanningSettings.flight_grade()).items() if getattr(SCANNED, k) != v} | _FLIGHT_EST
DIVE_VARIANTS = {
    "mpc-flight": _MPC_FLIGHT,
    "+ vertical dive 700 m": _MPC_FLIGHT | {"vertical_dive_m": 700.0},
    "+ vertical dive 1200 m": _MPC_FLIGHT | {"vertical_dive_m": 1200.0},
}
# tracking that feeds forward the estimate against the plan's pessimistic L/D, instead of the plan's own scales
TRACK_VARIANTS = {"+ tracking with the estimate": _MPC_FLIGHT | {"track_estimate": True}}
# mpc-flight told the peer set's published statistics instead of the flight set's: density a constant factor of
# 25 % rms (one band, correlation far longer than the flight), C_D 20 % rms, and the q bound with the drag scale's
# share that is C_D
PEER_VARIANTS = {
    "mpc-flight": _MPC_FLIGHT,
    "+ the peer set's statistics, drag split (mpc-peer)": {k: v for k, v in asdict(peer_settings()).items()
                                                           if getattr(SCANNED, k) != v} | _FLIGHT_EST,
}
# a predictive floor on q at a climb's apex, between plans, at the learned policy's margin (its q breaches on wide and
# flight went); mpc-flight itself is the 200-episode evaluation on the same seeds (docs/results/mpc_flight_flight200.json)
FLOOR_VARIANTS = {"+ q floor 8 %": _MPC_FLIGHT | {"q_floor_margin": 0.08}}
VARIANT_SETS = {"defaults": VARIANTS, "flight": FLIGHT_VARIANTS, "aero": AERO_VARIANTS, "final": FINAL_VARIANTS,
                "estimator": ESTIMATOR_VARIANTS, "split": SPLIT_VARIANTS, "dive": DIVE_VARIANTS,
                "track": TRACK_VARIANTS, "peer": PEER_VARIANTS, "floor": FLOOR_VARIANTS}


def _reference_cost() -> float:
    from rventry_env.reference import load_reference

    return float(load_reference().cost)


def run_all(jobs: dict, workers: int, progress_label: str) -> dict:
    """Run {name: (job, seeds)} on one pool (``evaluate_many``); returns {name: batch}."""
    from rich.progress import Progress

    names = list(jobs)
    with Progress() as bar:
        job_bar = bar.add_task(progress_label, total=sum(len(seeds) for _, seeds in jobs.values()))
        batches = evaluate_many([jobs[name] for name in names], workers,
                                progress=lambda _job, episodes: bar.advance(job_bar, episodes))  # fmt: skip
    return dict(zip(names, batches))


def _failures(batch) -> list[dict]:
    """Each failed episode: its seed and what it missed (miss, vertical error, speed, load, q)."""
    return [{"seed": int(batch.seeds[i]), "miss_km": round(float(batch.miss_km[i]), 3),
             "vertical_error_deg": round(float(batch.vertical_error_deg[i]), 2),
             "speed_error_mps": round(float(batch.speed_error_mps[i]), 1),
             "max_load_factor_g": round(float(batch.max_load_factor_g[i]), 3),
             "min_dynamic_pressure_pa": round(float(batch.min_dynamic_pressure_pa[i]), 1),
             "navigation_vertical_error_m": round(float(batch.navigation[i, 1]), 1)}
            for i in np.nonzero(~batch.is_success)[0]]  # fmt: skip


def _row(summary: dict, nominal: dict, wall_per_episode: float, failures: list) -> dict:
    rp = summary["replanning"]
    return {
        "failures": failures,
        "success_rate": summary["success_rate"],
        "violation_rate": summary["constraint_violation_rate"],
        "miss_km_p95": summary["percentiles"]["miss_km"]["p95"],
        "cost_ratio_mean": summary["cost_ratio"],
        "nominal_cost_ratio": nominal["cost_ratio"],
        "nominal_success": nominal["success_rate"],
        "resolve_p50_s": rp["solve_time_s"]["p50"],
        "resolve_p99_s": rp["solve_time_s"]["p99"],
        "replans_per_episode": rp["replans"] / summary["episodes"],
        "replan_failures": rp["replan_failures"],
        "episode_cpu_s": wall_per_episode,
    }


def scan(args) -> dict:
    task = EntryTask()
    seeds = list(range(args.seed, args.seed + args.episodes))
    jobs = {}
    variants = VARIANT_SETS[args.variants]
    for name, change in variants.items():
        change = dict(change)
        estimator = change.pop("estimator_settings", None)
        opts = (("settings", replace(SCANNED, **change)),) + ((("estimator_settings", estimator),) if estimator else ())
        jobs[name] = (EvaluationJob("mpc", args.dispersion, task, opts), seeds)
        jobs[name + " (nominal)"] = (EvaluationJob("mpc", "none", task, opts), [0])
    t0 = time.time()
    batches = run_all(jobs, args.workers, f"scan: {len(variants)} variants x {args.episodes} episodes")
    wall = time.time() - t0
    ref_cost = _reference_cost()
    rows = {}
    for name in variants:
        s = summarize(batches[name], ref_cost, task)
        nominal = summarize(batches[name + " (nominal)"], ref_cost, task)
        cpu = float(np.mean([sum(st["solve_times_s"]) for st in batches[name].law_stats]))
        rows[name] = _row(s, nominal, cpu, _failures(batches[name]))
    print(f"\n{args.episodes} episodes of the {args.dispersion} set (seeds {seeds[0]}...) per variant, "
          f"and the nominal flight; {wall:.0f} s on {args.workers} workers")  # fmt: skip
    head = f"{'variant':28s} {'success':>8s} {'viol.':>6s} {'miss p95':>9s} {'J/J*':>6s} {'nom J/J*':>9s} " \
           f"{'p50 (s)':>8s} {'p99 (s)':>8s} {'solves':>7s} {'failed':>7s} {'solve s/ep':>10s}"
    print(head)
    for name, r in rows.items():
        print(f"{name:28s} {r['success_rate']:8.3f} {r['violation_rate']:6.3f} {r['miss_km_p95']:9.3f} "
              f"{r['cost_ratio_mean']:6.3f} {r['nominal_cost_ratio']:9.3f} {r['resolve_p50_s']:8.3f} "
              f"{r['resolve_p99_s']:8.3f} {r['replans_per_episode']:7.1f} {r['replan_failures']:7d} "
              f"{r['episode_cpu_s']:10.1f}")  # fmt: skip
    return {"scan": rows, "episodes": args.episodes, "dispersion": args.dispersion, "seed": args.seed,
            "wall_s": wall, "workers": args.workers, "defaults": asdict(SCANNED)}  # fmt: skip


def evaluate(args) -> dict:
    from rventry_env.evaluation.parallel import evaluate as run

    task = EntryTask()
    ref_cost = _reference_cost()
    out = {"defaults": asdict(DEFAULT), "workers": args.workers, "episodes": args.episodes}
    nominal = summarize(run(EvaluationJob("mpc", "none", task), [0]), ref_cost, task)
    out["nominal"] = {k: nominal[k] for k in ("success_rate", "miss_km", "vertical_error_deg", "abs_speed_error_mps",
                                              "cost_ratio")}  # fmt: skip
    from rich.progress import Progress

    for dispersion in args.sets:
        t0 = time.time()
        with Progress() as bar:
            job_bar = bar.add_task(f"mpc, {dispersion} set", total=args.episodes)
            batch = run(EvaluationJob("mpc", dispersion, task), list(range(args.seed, args.seed + args.episodes)),
                        workers=args.workers, progress=lambda n: bar.advance(job_bar, n))  # fmt: skip
        wall = time.time() - t0
        s = summarize(batch, ref_cost, task)
        out[dispersion] = {
            "success_rate": s["success_rate"], "violation_rate": s["constraint_violation_rate"],
            "miss_km": s["percentiles"]["miss_km"], "vertical_error_deg": s["percentiles"]["vertical_error_deg"],
            "cost_ratio": s["cost_ratio"], "endings": s["endings"], "replanning": s["replanning"], "wall_s": wall,
            "failed_episodes": [{"seed": int(batch.seeds[i]), "miss_km": float(batch.miss_km[i]),
                                 "vertical_error_deg": float(batch.vertical_error_deg[i]),
                                 "speed_error_mps": float(batch.speed_error_mps[i]),
                                 "violation": bool(batch.constraint_violation[i]), "failure": str(batch.failure[i])}
                                for i in np.nonzero(~batch.is_success)[0]],
        }  # fmt: skip
    print(f"\nmpc with its defaults, {args.workers} worker(s)")
    print(f"  nominal: J/J* {out['nominal']['cost_ratio']:.3f} (target <= {TARGETS['nominal_cost_ratio']}), "
          f"miss {out['nominal']['miss_km'] * 1000:.1f} m, vertical {out['nominal']['vertical_error_deg']:.2f} deg")
    for dispersion in args.sets:
        r = out[dispersion]
        rp = r["replanning"]
        target = TARGETS.get(f"{dispersion}_success")
        print(f"  {dispersion}: success {r['success_rate']:.3f}" + (f" (target >= {target})" if target else "")
              + f", violations {r['violation_rate']:.3f}, miss p95 {r['miss_km']['p95'] * 1000:.0f} m, "
              f"re-solve p50 {rp['solve_time_s']['p50']:.3f} s / p99 {rp['solve_time_s']['p99']:.3f} s "
              f"(targets {TARGETS['resolve_p50_s']} / {TARGETS['resolve_p99_s']}), {rp['replan_failures']} failed of "
              f"{rp['replans']} solves, {args.episodes} episodes in {r['wall_s']:.0f} s")  # fmt: skip
    return out


def _aims(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"give aims in deg separated by commas, got {text!r}") from None
    if not values or any(not np.isfinite(v) or v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"aims must be finite and >= 0 deg (0: off), got {text!r}")
    return values


def terminal_alpha(aims: list[float], episodes: int | None = None, dispersion: str = "standard", seed: int = 0,
                   workers: int = 2) -> dict:  # fmt: skip
    """The nominal flight with the terminal alpha bound aimed at each value (deg; 0: off), and, with
    ``episodes``, that many episodes of ``dispersion`` from ``seed`` per aim: success, the precision
    tier, and the two terminal errors it weighs (|alpha(t_f)| and the vertical-impact error)."""
    from rventry_env.evaluation.parallel import evaluate as run
    from rventry_env.evaluation.rollout import rollout
    from rventry_env.guidance.replanning import ReplanningGuidance

    task = EntryTask()
    j_star = _reference_cost()
    rows = []
    for aim in aims:
        settings = replace(DEFAULT, terminal_alpha=aim > 0, terminal_alpha_deg=aim if aim > 0 else DEFAULT.terminal_alpha_deg)
        b = rollout(ReplanningGuidance(settings=settings), 1)
        rows.append({"aim_deg": aim, "alpha_final_deg": float(b.alpha_final_deg[0]),
                     "vertical_error_deg": float(b.vertical_error_deg[0]), "miss_m": 1000 * float(b.miss_km[0]),
                     "cost_ratio": float(b.cost[0] / j_star), "success": bool(b.is_success[0])})  # fmt: skip
        r = rows[-1]
        print(f"aim {'off' if aim == 0 else f'{aim:g} deg'}: alpha(t_f) {r['alpha_final_deg']:.2f} deg, vertical error "
              f"{r['vertical_error_deg']:.2f} deg, miss {r['miss_m']:.1f} m, J/J* {r['cost_ratio']:.3f}", flush=True)  # fmt: skip
        if episodes:
            d = run(EvaluationJob("mpc", dispersion, task, (("settings", settings),)), list(range(seed, seed + episodes)),
                    workers=workers)  # fmt: skip
            sm = summarize(d, j_star, task)
            alpha, vertical = np.abs(d.alpha_final_deg), d.vertical_error_deg
            tier = PrecisionThresholds()
            r["dispersed"] = {
                "dispersion": dispersion, "seeds": [seed, seed + episodes - 1], "success_rate": sm["success_rate"],
                "precision_success_rate": sm["precision_success_rate"], "precision_success_rate_ci": sm["precision_success_rate_ci"],
                "alpha_final_deg": {"p50": float(np.median(alpha)), "p95": float(np.percentile(alpha, 95))},
                "vertical_error_deg": {"p50": float(np.median(vertical)), "p95": float(np.percentile(vertical, 95))},
                "miss_m_p50": 1000 * float(np.median(d.miss_km)),
                "alpha_over_tier": int(np.sum(alpha > tier.alpha_final_deg)),
                "vertical_over_tier": int(np.sum(vertical > tier.vertical_error_deg)),
            }  # fmt: skip
            x = r["dispersed"]
            print(f"  {episodes} {dispersion} episodes: success {x['success_rate']:.2f}, precision "
                  f"{x['precision_success_rate']:.2f}; |alpha(t_f)| p50/p95 {x['alpha_final_deg']['p50']:.2f}/"
                  f"{x['alpha_final_deg']['p95']:.2f} deg (over the tier's {tier.alpha_final_deg:g}: {x['alpha_over_tier']}), "
                  f"vertical p50/p95 {x['vertical_error_deg']['p50']:.2f}/{x['vertical_error_deg']['p95']:.2f} deg "
                  f"(over {tier.vertical_error_deg:g}: {x['vertical_over_tier']}), miss p50 {x['miss_m_p50']:.0f} m",
                  flush=True)  # fmt: skip
    return {"terminal_alpha": rows}


NAV_BINS_M = (0.0, 500.0, 900.0, 1300.0, np.inf)


def navigation(path: str) -> dict:
    """What navigation leaves to guidance, from an evaluation report (``rventry evaluate --json``):
    the navigation's errors at the end, the share of episodes whose horizontal error alone is
    within the precision tier's miss, success by the size of the vertical error, and how the
    speed and vertical-impact errors follow it."""
    import json
    from pathlib import Path

    doc = json.loads(Path(path).read_text())
    eps = [e for e in doc["episodes"] if "navigation_error_m" in e]
    if not eps:
        raise SystemExit(f"{path}: no episode records the navigation error (a report from an older evaluation?)")
    h = np.array([e["navigation_error_m"]["horizontal"] for e in eps])
    v = np.array([e["navigation_error_m"]["vertical"] for e in eps])
    ok = np.array([e["success"] for e in eps])
    speed = np.array([e["speed_error_mps"] for e in eps])
    vert = np.array([e["vertical_error_deg"] for e in eps])
    miss = np.array([e["miss_km"] for e in eps]) * 1000.0
    believed = np.array([e["navigated_miss_km"] for e in eps]) * 1000.0
    tier = PrecisionThresholds().miss_m
    out = {
        "report": path, "agent": doc.get("agent"), "dispersion": doc.get("dispersion_set"), "episodes": len(eps),
        "horizontal_error_m": {f"p{q}": float(np.percentile(h, q)) for q in (5, 50, 95)},
        "vertical_error_abs_m": {f"p{q}": float(np.percentile(np.abs(v), q)) for q in (5, 50, 95)},
        "within_precision_miss": float(np.mean(h <= tier)),
        "miss_m": {f"p{q}": float(np.percentile(miss, q)) for q in (50, 95)},
        "navigated_miss_m": {f"p{q}": float(np.percentile(believed, q)) for q in (50, 95)},
        "corr_speed_error_vertical_nav": float(np.corrcoef(speed, v)[0, 1]),
        "corr_miss_horizontal_nav": float(np.corrcoef(miss, h)[0, 1]),
        "by_vertical_error": [],
    }
    print(f"{out['agent']} on {out['dispersion']}, {len(eps)} episodes ({path})")
    print(f"navigation at the end: horizontal error p5/p50/p95 {out['horizontal_error_m']['p5']:.0f}/"
          f"{out['horizontal_error_m']['p50']:.0f}/{out['horizontal_error_m']['p95']:.0f} m; |vertical| "
          f"{out['vertical_error_abs_m']['p5']:.0f}/{out['vertical_error_abs_m']['p50']:.0f}/"
          f"{out['vertical_error_abs_m']['p95']:.0f} m; within the precision tier's {tier:.0f} m: "
          f"{out['within_precision_miss']:.3f} of the episodes")
    print(f"miss p50/p95 {out['miss_m']['p50']:.0f}/{out['miss_m']['p95']:.0f} m, the miss guidance believed "
          f"{out['navigated_miss_m']['p50']:.0f}/{out['navigated_miss_m']['p95']:.0f} m; correlation of the miss with "
          f"the horizontal error {out['corr_miss_horizontal_nav']:.2f}, of the speed error with the vertical error "
          f"{out['corr_speed_error_vertical_nav']:.2f}")
    print(f"{'|vertical nav error| (m)':26s} {'episodes':>8s} {'success':>8s} {'vertical err p50':>17s} {'|speed err| p50':>16s}")
    for lo, hi in zip(NAV_BINS_M[:-1], NAV_BINS_M[1:]):
        sel = (np.abs(v) >= lo) & (np.abs(v) < hi)
        row = {"from_m": lo, "to_m": None if np.isinf(hi) else hi, "episodes": int(sel.sum()),
               "success_rate": float(ok[sel].mean()) if sel.any() else None,
               "vertical_error_deg_p50": float(np.median(vert[sel])) if sel.any() else None,
               "abs_speed_error_mps_p50": float(np.median(np.abs(speed[sel]))) if sel.any() else None}  # fmt: skip
        out["by_vertical_error"].append(row)
        if sel.any():
            print(f"{f'{lo:.0f} - {hi:.0f}':26s} {row['episodes']:8d} {row['success_rate']:8.3f} "
                  f"{row['vertical_error_deg_p50']:17.2f} {row['abs_speed_error_mps_p50']:16.1f}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--scan", action="store_true", help="vary each setting alone around the defaults")
    mode.add_argument("--evaluate", action="store_true", help="the benchmark's targets with the defaults")
    mode.add_argument("--terminal-alpha", type=_aims, metavar="DEG,...",
                      help="the nominal flight with the terminal alpha bound aimed at each value (0: off)")
    mode.add_argument("--navigation", metavar="REPORT",
                      help="what navigation leaves to guidance, from an evaluation report (rventry evaluate --json)")
    ap.add_argument("--episodes", type=positive_int, help="episodes per variant (scan: 40) or per set (evaluate: 200)")
    ap.add_argument("--dispersion", default="wide", choices=NAMED_SETS,
                    help="the scan's set (wide)")
    ap.add_argument("--variants", default="defaults", choices=tuple(VARIANT_SETS),
                    help="defaults: each setting varied alone; flight: the flight-grade remedies; aero: the "
                         "margins for the aerodynamics' uncertainty in Mach, with and around mpc-flight's; "
                         "final: the final dive's settings around mpc-flight; estimator: the flight-grade "
                         "estimator around mpc-flight; split: the "
                         "flight estimator with the load relief's chance margin and the q bound's drag split; "
                         "dive: plans that turn vertical above the target, around mpc-flight; track: mpc-flight's "
                         "tracking fed the estimate rather than the plan's pessimistic L/D; peer: mpc-flight told "
                         "the peer set's statistics; floor: mpc-flight with a q floor between plans")
    ap.add_argument("--sets", nargs="+", default=["standard", "wide"], choices=("standard", "wide"))
    ap.add_argument("--seed", type=non_negative_int, help="first seed (scan: 100000, evaluate: 0)")
    ap.add_argument("--workers", type=positive_int, default=2)
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    start_run(None if argv is None else ["python", __file__, *argv])
    dispersed = args.episodes  # --terminal-alpha flies dispersed episodes only when asked
    if args.episodes is None:
        args.episodes = 40 if args.scan else 200
    if args.seed is None:
        args.seed = 100_000 if args.scan else 0
    if args.navigation:
        out = navigation(args.navigation)
    else:
        out = scan(args) if args.scan else evaluate(args) if args.evaluate else terminal_alpha(
            args.terminal_alpha, dispersed, args.dispersion, args.seed, args.workers)
    out["command"] = " ".join(["python studies/mpc_settings.py", *(argv if argv is not None else sys.argv[1:])])
    if args.json:
        print(f"wrote {write_record(args.json, out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
