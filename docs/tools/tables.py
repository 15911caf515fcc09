"""Every results table of the README and the manual, generated from its JSON record.

A table is an entry of :data:`TABLES`: a name, the records it reads (paths from the repository
root: ``docs/results/``, ``rventry_agents/data/``), a renderer that turns them into Markdown, and
the Markdown files that show it. In those files the table sits between two markers::

    <!-- table: NAME -->
    ...generated...
    <!-- end table -->

``python docs/tools/tables.py`` rewrites every marked region from its records;
``python docs/tools/tables.py --check`` changes nothing and exits 1 naming each region that
differs from what its records give (``tests/project/test_docs.py`` runs the same check). To add a table:
write a renderer (records -> Markdown), add one :class:`Table` entry, put the markers where it
goes, and run the script. A number in a table is never typed by hand.

``python docs/tools/tables.py --record-compare out/compare.json docs/results/compare_standard.json``
stores a ``rventry compare`` report as a record: the report less its per-episode lists.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[2]
START = re.compile(r"^<!-- table: ([a-z0-9.-]+) -->$", re.M)
END = "<!-- end table -->"


@dataclass(frozen=True)
class Table:
    """One generated table.

    :param name: the marker's name (``<!-- table: NAME -->``).
    :param records: the JSON records it is made from, paths from the repository root.
    :param render: records (loaded, in the order given) -> the Markdown between the markers.
    :param files: the Markdown files that show it, paths from the repository root.
    """

    name: str
    records: tuple[str, ...]
    render: Callable[..., str]
    files: tuple[str, ...]


def load(path: str):
    return json.loads((ROOT / path).read_text())


# ------------------------------------------------------------------ formatting
def sig(v, digits: int = 3) -> str:
    """``v`` to ``digits`` significant figures, in plain notation."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if v == 0:
        return "0"
    decimals = max(0, digits - 1 - int(math.floor(math.log10(abs(v)))))
    return f"{v:.{decimals}f}"


def sci(v: float, decimals: int) -> str:
    """``v`` in scientific notation without the exponent's padding: 9.22e-7."""
    mantissa, exponent = f"{v:.{decimals}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def rate(v) -> str:
    """A rate: three decimals where the third is not 0, else two (as ``rventry compare`` prints)."""
    text = f"{v:.3f}"
    return text[:-1] if text.endswith("0") else text


def ci(r: dict, key: str = "success_rate") -> str:
    lo, hi = r[f"{key}_ci"]
    return f"{rate(r[key])} [{lo:.2f}, {hi:.2f}]"


def md(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(out)


# scripts/ split into benchmarks/ (timings against targets) and studies/ (what was measured to choose a
# setting); a record written before keeps the command it ran, shown under the script's present name
RENAMED_SCRIPTS = {
    "scripts/bench_decision.py": "benchmarks/decision_cost.py", "scripts/bench_identify.py": "benchmarks/identify_speed.py",
    "scripts/bench_jax.py": "benchmarks/jax_backend.py", "scripts/bench_reference.py": "benchmarks/reference_solve.py",
    "scripts/bench_rhs.py": "benchmarks/rhs_forms.py", "scripts/bench_env.py": "benchmarks/env_speed.py",
    "scripts/bench_interrupt.py": "benchmarks/interrupt.py", "scripts/bench_baselines.py": "studies/baselines.py",
    "scripts/choose_q_floor.py": "studies/choose_q_floor.py", "scripts/compare_episodes.py": "studies/compare_episodes.py",
    "scripts/bench_sets.py": "studies/flight_sets.py", "scripts/bench_mpc.py": "studies/mpc_settings.py",
    "scripts/bench_random_actions.py": "studies/random_actions.py", "scripts/bench_seeds.py": "studies/seeds.py",
    "scripts/solve_spherical_singularity.py": "studies/spherical_singularity.py",
    "scripts/bench_observation_bounds.py": "studies/observation_bounds.py", "scripts/fuzz_cli.py": "studies/fuzz_cli.py",
    "scripts/ladder.py": "studies/ladder.py",
}  # fmt: skip


def present_command(command: str) -> str:
    """A record's command with its script under the name it has now (see :data:`RENAMED_SCRIPTS`)."""
    for old, new in RENAMED_SCRIPTS.items():
        command = command.replace(old, new)
    return command


def source(*paths: str, command: str | None = None) -> str:
    """The line under a table: its records, and the command that wrote them where one did (its script
    under its present name)."""
    text = "Records: " + ", ".join(f"`{p}`" for p in paths)
    return text + (f"; written by `{present_command(command)}`." if command else ".")


# ------------------------------------------------------------------ renderers
def compare_headline(doc: dict) -> str:
    """The README's table: ``rventry compare``'s dispersed table and its verdict, from its report."""
    return compare_tables(doc, nominal=False)


def compare_tables(doc: dict, nominal: bool = True) -> str:
    """``rventry compare``: the tables and the verdict it prints, from its report."""
    from rventry_env.evaluation import compare_report as cr

    parts = [f"**{cr.title(doc, 'dispersed')}**", "", cr.markdown_table(*cr.dispersed_table(doc)), ""]
    if nominal:
        parts += [f"**{cr.title(doc, 'nominal')}**", "", cr.markdown_table(*cr.nominal_table(doc)), ""]
    parts += [cr.success_note(doc).capitalize() + ".", ""]
    parts += [" ".join(doc.get("verdict") or cr.verdict(doc)), ""]
    parts.append(source("docs/results/compare_standard.json", command="rventry compare"))
    return "\n".join(parts)


def mpc_benchmark(doc: dict) -> str:
    """The re-planning benchmark: 200 standard and 200 wide episodes of ``mpc``, and its nominal flight."""
    rows = []
    sets = ("standard", "wide")
    get = {s: doc[s] for s in sets}
    rows.append(["success"] + [rate(get[s]["success_rate"]) for s in sets])
    rows.append(["path-violation rate"] + [rate(get[s]["violation_rate"]) for s in sets])
    rows.append(["miss p5 / p50 / p95 (m)"] + [" / ".join(sig(get[s]["miss_km"][p] * 1e3) for p in ("p5", "p50", "p95"))
                                               for s in sets])  # fmt: skip
    rows.append(["vertical-impact error p5 / p50 / p95 (deg)"] + [
        " / ".join(sig(get[s]["vertical_error_deg"][p]) for p in ("p5", "p50", "p95")) for s in sets])
    rows.append(["J/J*, mean"] + [f"{get[s]['cost_ratio']:.3f}" for s in sets])
    rows.append(["re-solve time p50 / p90 / p99 (max), s"] + [
        "{p50:.3f} / {p90:.3f} / {p99:.3f} ({max:.2f})".format(**get[s]["replanning"]["solve_time_s"]) for s in sets])
    rows.append(["first solve of an episode, p50 (max), s"] + [
        "{p50:.3f} ({max:.2f})".format(**get[s]["replanning"]["first_solve_time_s"]) for s in sets])
    rows.append(["failed or over-budget solves"] + [
        f"{get[s]['replanning']['replan_failures'] + get[s]['replanning']['replan_timeouts']} of "
        f"{get[s]['replanning']['solves']}" for s in sets])
    rows.append([f"wall time of the {doc['episodes']} episodes, {doc['workers']} workers (s)"] +
                [f"{get[s]['wall_s']:.0f}" for s in sets])  # fmt: skip
    n = doc["nominal"]
    nominal = (f"Nominally `mpc` lands {sig(n['miss_km'] * 1e3)} m from the target, {sig(n['vertical_error_deg'])} deg "
               f"from vertical, at J/J* {n['cost_ratio']:.3f}.")  # fmt: skip
    return "\n".join([md([f"`mpc`, {doc['episodes']} episodes per set (seeds 0-{doc['episodes'] - 1})", *sets], rows), "",
                      nominal, "", source("docs/results/bench_mpc_eval.json", command=doc["command"])])  # fmt: skip


def _law_row(label: str, r: dict, note: str = "") -> list[str]:
    """A row of the per-set tables from a law's figures (a ``summary`` or a ``bench_sets`` entry)."""
    miss = r.get("miss_m") or {}
    return [f"{label}{note}", str(r["episodes"]), ci(r), ci(r, "precision_success_rate"),
            f"{sig(miss.get('p50', math.nan) / 1e3)} / {sig(miss.get('p95', math.nan) / 1e3)}",
            rate(r["constraint_violation_rate"])]  # fmt: skip


# rows of the per-set tables: (label, record, where the figures are in it); a law is shown only where a
# record holds it. bench_sets.json's "learned" was the student of mpc when it ran: the row is `dagger`.
SET_ROWS = {
    "flight": (
        ("`reference`", "docs/results/bench_sets.json", ("sets", "flight", "laws", "reference")),
        ("`lqr`", "docs/results/bench_sets.json", ("sets", "flight", "laws", "lqr")),
        ("`lqr-est`", "docs/results/bench_sets.json", ("sets", "flight", "laws", "lqr-est")),
        ("`dagger`", "docs/results/bench_sets.json", ("sets", "flight", "laws", "learned")),
        ("`mpc`", "docs/results/bench_sets.json", ("sets", "flight", "laws", "mpc")),
        ("`mpc-flight`", "docs/results/mpc_flight_flight200.json", ("summary",)),
        ("`dagger-flight`", "docs/results/dagger_flight_flight200.json", ("summary",)),
        ("`ppo`", "docs/results/ppo_q_floor/ppo_flight.json", ("summary",)),
        ("`ppo-scratch-flight` (`learned`)", "docs/results/scratch_vs_imitation/ppo-scratch-flight_flight_seed0.json",
         ("summary",)),
    ),
    "peer": (
        ("`reference`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "reference")),
        ("`lqr`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "lqr")),
        ("`lqr-est`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "lqr-est")),
        ("`dagger`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "learned")),
        ("`mpc`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "mpc")),
        ("`mpc-flight`", "docs/results/bench_sets_mpc_flight.json", ("sets", "peer", "laws", "mpc-flight")),
        ("`mpc-peer`", "docs/results/mpc_peer_peer50.json", ("summary",)),
        ("`ppo`", "docs/results/ppo_q_floor/ppo_peer.json", ("summary",)),
    ),
    "peer-0.1": (
        ("`reference`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "reference")),
        ("`lqr`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "lqr")),
        ("`lqr-est`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "lqr-est")),
        ("`dagger`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "learned")),
        ("`mpc`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "mpc")),
        ("`mpc-flight`", "docs/results/mpc_flight_peer-0.1_100.json", ("summary",)),
        ("`ppo`", "docs/results/ppo_q_floor/ppo_peer-0.1.json", ("summary",)),
    ),
}


def _dig(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def set_table(dispersion: str) -> Callable[..., str]:
    """The laws on one dispersion set against the oracle's ceiling."""

    def render(*docs) -> str:
        oracle, records = docs[0]["summary"], dict(zip(_set_records(dispersion)[1:], docs[1:]))
        lo, hi = oracle["flyable_fraction_ci"]
        head = (f"Oracle ceiling on `{dispersion}`: flyable **{rate(oracle['flyable_fraction'])} [{lo:.2f}, {hi:.2f}]**, "
                f"precision {ci(oracle, 'precision_flyable_fraction')} on {oracle['draws']} draws "
                f"(IPOPT converged on {oracle['converged']}), J p50 {oracle['J']['p50']:.2f}.")  # fmt: skip
        rows = [_law_row(label, _dig(records[path], where)) for label, path, where in SET_ROWS[dispersion]]
        header = ["law", "episodes", "success [95 % CI]", "precision [95 % CI]", "miss p50 / p95 (km)", "path violations"]
        return "\n".join([head, "", md(header, rows), "", source(*_set_records(dispersion))])

    return render


def _set_records(dispersion: str) -> tuple[str, ...]:
    return (f"docs/results/oracle_{dispersion}.json", *dict.fromkeys(p for _, p, _ in SET_ROWS[dispersion]))


def navigation_tables(doc: dict) -> str:
    """Where ``mpc-flight``'s miss on ``flight`` comes from: the navigation's errors at the end."""
    rows = [["horizontal error"] + [sig(doc["horizontal_error_m"][p]) for p in ("p5", "p50", "p95")],
            ["vertical error (absolute)"] + [sig(doc["vertical_error_abs_m"][p]) for p in ("p5", "p50", "p95")],
            ["miss", "", sig(doc["miss_m"]["p50"]), sig(doc["miss_m"]["p95"])],
            ["the miss guidance believed", "", sig(doc["navigated_miss_m"]["p50"]), sig(doc["navigated_miss_m"]["p95"])]]
    first = md(["navigation at the end (m)", "p5", "p50", "p95"], rows)
    bands = []
    for b in doc["by_vertical_error"]:
        lo, hi = b["from_m"] / 1e3, (b["to_m"] or math.inf) / 1e3
        name = f"under {hi:g} km" if lo == 0 else (f"over {lo:g} km" if not math.isfinite(hi) else f"{lo:g}-{hi:g} km")
        bands.append([name, str(b["episodes"]), rate(b["success_rate"]), sig(b["vertical_error_deg_p50"]),
                      sig(b["abs_speed_error_mps_p50"])])  # fmt: skip
    second = md(["\\|vertical navigation error\\|", "episodes", "success", "vertical-impact error p50 (deg)",
                 "\\|speed error\\| p50 (m/s)"], bands)  # fmt: skip
    note = (f"{doc['within_precision_miss']:.2f} of the episodes end with a horizontal navigation error within the "
            f"precision tier's miss; correlation of the miss with the horizontal error {doc['corr_miss_horizontal_nav']:.2f}, "
            f"of the speed error with the vertical one {doc['corr_speed_error_vertical_nav']:.2f}.")  # fmt: skip
    return "\n".join([first, "", second, "", note, "", source("docs/results/nav_mpc_flight200.json", command=doc["command"])])


def seeds_table(doc: dict) -> str:
    """Success per training seed and set, with rliable's aggregates over runs and sets."""
    sets = doc["sets"]
    header = ["method", *[f"`{s}`" for s in sets], "IQM over runs and sets [95 % CI]", "mean over runs and sets [95 % CI]"]
    rows = []
    for method, runs in doc["runs"].items():
        cells = [" / ".join(f"{r['sets'][s]['success_rate']:.3f}" for r in runs) for s in sets]
        a = doc["aggregate"]["basic"][method]
        interval = (lambda k: f"{a[k]:.3f} [{a[k + '_ci'][0]:.3f}, {a[k + '_ci'][1]:.3f}]") if a["runs"] > 1 else \
            (lambda k: f"{a[k]:.3f}")  # fmt: skip
        label = f"`{method}`, {len(runs)} run{'s' if len(runs) > 1 else ''}" + (" (seeds " + " / ".join(
            str(i) for i in range(len(runs))) + ")" if len(runs) > 1 else "")
        rows.append([label, *cells, interval("iqm"), interval("mean")])
    return "\n".join([md(header, rows), "", f"Each rate over {doc['episodes']} episodes (seeds {doc['seed']}-"
                      f"{doc['seed'] + doc['episodes'] - 1}).", "", source("docs/results/bench_seeds_ppo.json")])  # fmt: skip


def scan_table(path: str) -> Callable[..., str]:
    """A re-planning scan: each variant's success, breaches, miss tail and nominal cost."""

    def render(doc: dict) -> str:
        rows = [[name, rate(v["success_rate"]), rate(v["violation_rate"]), sig(v["miss_km_p95"]),
                 f"{v['nominal_cost_ratio']:.3f}"] for name, v in doc["scan"].items()]  # fmt: skip
        seeds = f"seeds {doc['seed']}-{doc['seed'] + doc['episodes'] - 1}"
        header = [f"variant ({doc['episodes']} `{doc['dispersion']}` episodes, {seeds})", "success", "path-bound breaches",
                  "miss p95 (km)", "nominal J/J*"]  # fmt: skip
        return "\n".join([md(header, rows), "", source(path, command=doc.get("command"))])

    return render


def rounds_table(path: str) -> Callable[..., str]:
    """A DAgger run's rounds: the selection set's figures after each."""

    def render(rounds: list) -> str:
        rows = [[str(r["round"]), f"{r['beta']:g}", f"{r['samples']:,}", rate(r["select_success_rate"]),
                 sig(r["select_miss_km_p50"]), sig(r.get("select_vertical_error_deg_p50")),
                 rate(r["select_violation_rate"])] for r in rounds]  # fmt: skip
        header = ["round", "beta", "samples", "selection success", "miss p50 (km)", "vertical error p50 (deg)",
                  "path violations"]  # fmt: skip
        return "\n".join([md(header, rows), "", source(path)])

    return render


def _subset_rate(doc: dict, n: int) -> dict:
    """Success of an evaluation report's first ``n`` episodes (its seeds seed .. seed + n - 1), with its interval."""
    from rventry_env.evaluation.summary import rate_interval

    hits = [bool(e["success"]) for e in doc["episodes"][:n]]
    return {"success_rate": sum(hits) / len(hits), "success_rate_ci": rate_interval(hits), "episodes": len(hits)}


# the columns of the effects table: (label, record, the law's key in it)
EFFECT_COLUMNS = (
    ("`lqr`", "docs/results/bench_effects.json", "lqr"),
    ("`dagger` (student of `mpc`)", "docs/results/bench_effects.json", "learned"),  # `learned` was `dagger` then
    ("`dagger-flight`", "docs/results/bench_effects_dagger_flight.json", "dagger-flight"),
    ("`ppo`", "docs/results/bench_effects_ppo.json", "learned"),
)
# the whole `flight` set on the same seeds, from the laws' 200-episode evaluations where one was kept
EFFECT_WHOLE = {"`dagger-flight`": "docs/results/dagger_flight_flight200.json",
                "`ppo`": "docs/results/ppo_q_floor/ppo_flight.json"}
EFFECT_GLOSS = {"entry state, C_L/C_D, mass": "entry state, C_L/C_D 5 %, mass",
                "NRLMSIS climatology": "NRLMSIS climatology (departure from its mean)"}


def effects_records() -> tuple[str, ...]:
    return (*dict.fromkeys(path for _, path, _ in EFFECT_COLUMNS), *EFFECT_WHOLE.values())


def effects_table(*docs) -> str:
    """Which effect of the ``flight`` set breaks which law: each part alone, success [95 % CI]."""
    records = dict(zip(effects_records(), docs))
    effects = list(dict.fromkeys(e for _, path, _ in EFFECT_COLUMNS for e in records[path]["effects"]))
    n = {records[path]["effects"][e][key]["episodes"] for _, path, key in EFFECT_COLUMNS
         for e in effects if key in records[path]["effects"].get(e, {})}  # fmt: skip
    rows = []
    for e in effects:
        cells = [ci(records[path]["effects"][e][key]) if key in records[path]["effects"].get(e, {}) else "not flown"
                 for _, path, key in EFFECT_COLUMNS]  # fmt: skip
        rows.append([EFFECT_GLOSS.get(e, e), *cells])
    (episodes,) = n
    whole = [ci(_subset_rate(records[EFFECT_WHOLE[label]], episodes)) if label in EFFECT_WHOLE else "no record"
             for label, _, _ in EFFECT_COLUMNS]  # fmt: skip
    rows.append([f"the whole `flight` set (seeds 0-{episodes - 1} of the 200-episode evaluation)", *whole])
    header = [f"effect alone ({episodes} episodes, seeds 0-{episodes - 1})", *(label for label, _, _ in EFFECT_COLUMNS)]
    return "\n".join([md(header, rows), "", source(*effects_records())])


def _footprint_cells(r: dict | None) -> list[str]:
    """A set's two cells of the footprint table: success [95 % CI] (and the precision tier where any met
    it), miss p50 / p95."""
    if r is None:
        return ["not flown", ""]
    miss = r["miss_m"]
    unit, scale = ("m", 1.0) if miss["p95"] < 1e3 else ("km", 1e-3)
    precision = r.get("precision_success_rate") or 0.0
    return [ci(r) + (f", precision {rate(precision)}" if precision else ""),
            f"{sig(miss['p50'] * scale, 2)} / {sig(miss['p95'] * scale, 2)} {unit}"]


# the footprint table's rows: (label, {set: (record, where the law's figures are in it)}); a set a
# row does not name was not flown
FOOTPRINT_ROWS = (
    ("`mpc`", {s: ("docs/results/bench_footprint.json", ("sets", s, "laws", "mpc")) for s in ("standard", "flight")}),
    ("`mpc` as it flies today, with the terminal alpha bound",
     {"standard": ("docs/results/footprint_mpc_standard50.json", None)}),
    ("`mpc-flight` as it flies today", {"flight": ("docs/results/footprint_mpc_flight_flight50.json", None)}),
    ("`mpc-flight` before the flight-grade estimator and the 4 % relief",
     {"flight": ("docs/results/bench_footprint_mpc_flight.json", ("sets", "flight", "laws", "mpc-flight"))}),
    ("`dagger`", {s: ("docs/results/bench_footprint.json", ("sets", s, "laws", "learned")) for s in ("standard", "flight")}),
    ("`dagger-flight`", {s: ("docs/results/bench_footprint_dagger_flight.json", ("sets", s, "laws", "dagger-flight"))
                         for s in ("standard", "flight")}),
    ("`ppo`", {s: ("docs/results/bench_footprint_ppo.json", ("sets", s, "laws", "learned"))
                           for s in ("standard", "flight")}),
    ("`ppo-plain`", {s: ("docs/results/bench_footprint.json", ("sets", s, "laws", "ppo-plain")) for s in ("standard", "flight")}),
)  # fmt: skip


def footprint_records() -> tuple[str, ...]:
    return tuple(dict.fromkeys(path for _, where in FOOTPRINT_ROWS for path, _ in where.values()))


def footprint_table(*docs) -> str:
    """The laws on the footprint task (a target per episode), on ``standard`` and ``flight``."""
    records = dict(zip(footprint_records(), docs))
    refused = sorted({law for doc in records.values() for s in doc.get("sets", {}).values()
                      for law, r in s["laws"].items() if "refused" in r})  # fmt: skip
    rows = [[", ".join(f"`{law}`" for law in refused), "refused: cannot re-target", "", "refused", ""]] if refused else []
    for label, where in FOOTPRINT_ROWS:
        figures = {s: _dig(records[path], at or ("summary",)) for s, (path, at) in where.items()}
        n = {r["episodes"] for r in figures.values()}
        cells = [c for s in ("standard", "flight") for c in _footprint_cells(figures.get(s))]
        rows.append([f"{label}, {'/'.join(map(str, sorted(n)))} episodes", *cells])
    header = ["law", "`standard` + footprint: success [95 % CI]", "miss p50 / p95", "`flight` + footprint", "miss p50 / p95"]
    return "\n".join([md(header, rows), "", source(*footprint_records())])


def terminal_alpha_tables(doc: dict, extra: dict) -> str:
    """``mpc``'s terminal alpha bound: the nominal flight per aim, and 20 standard episodes per aim."""
    from rventry_env.guidance.replanning import ReplanningSettings

    default = ReplanningSettings().terminal_alpha_deg
    aims = sorted({r["aim_deg"]: r for r in doc["terminal_alpha"] + extra["terminal_alpha"]}.items())

    def label(aim: float) -> str:
        return "off" if aim == 0 else f"{aim:g} deg" + (" (the default)" if aim == default else "")

    nominal = [[label(a), f"{r['alpha_final_deg']:.2f} deg", f"{r['vertical_error_deg']:.2f} deg", f"{sig(r['miss_m'])} m",
                f"{r['cost_ratio']:.3f}"] for a, r in aims]  # fmt: skip
    rows = []
    for a, r in aims:
        x = r.get("dispersed")
        if not x:
            continue
        over = [f"{name} over 2 deg in {x[k]}" for name, k in (("alpha", "alpha_over_tier"), ("vertical", "vertical_over_tier"))
                if x[k]]  # fmt: skip
        rows.append([f"terminal alpha {label(a)}" if a == 0 else f"aimed at {label(a)}", rate(x["success_rate"]),
                     ci(x, "precision_success_rate") + (f" ({', '.join(over)})" if over else ""),
                     f"{x['alpha_final_deg']['p50']:.2f} / {x['alpha_final_deg']['p95']:.2f} deg",
                     f"{x['vertical_error_deg']['p50']:.2f} / {x['vertical_error_deg']['p95']:.2f} deg",
                     f"{x['miss_m_p50']:.0f} m"])  # fmt: skip
    (x,) = {tuple(r["dispersed"]["seeds"]) for _, r in aims if r.get("dispersed")}
    episodes = x[1] - x[0] + 1
    return "\n".join([
        md(["aiming at", "alpha(t_f)", "vertical-impact error", "miss", "J/J*"], nominal), "",
        f"On the same {episodes} standard-set episodes per aim (seeds {x[0]}-{x[1]}):", "",
        md([f"`mpc` on {episodes} standard episodes", "success", "precision [95 % CI]", "\\|alpha(t_f)\\| p50 / p95",
            "vertical error p50 / p95", "miss p50"], rows), "",
        source("docs/results/terminal_alpha_standard.json", "docs/results/terminal_alpha_nominal.json")])  # fmt: skip


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def jax_cpu_table(bench: dict, ppo: dict) -> str:
    """The JAX backend on two CPU cores: speed against NumPy, agreement, and PPO's env-steps/s."""
    v, a = bench["vector"], bench["agreement"]
    sps, first = v["vehicle_steps_per_s"], v["first_step_s"]
    numpy, f64, f32 = sps["numpy"], sps["jax_float64"], sps["jax_float32"]
    functional = {f["dtype"]: f for f in bench["functional"] if f["dispersion"] == "standard"}
    n_f = functional["float64"]["num_envs"]
    jax, sb3 = ppo["ppo"]["jax"], ppo["ppo"]["sb3"]
    speedup = jax["env_steps_per_s"] / sb3["env_steps_per_s"]
    rows = [
        [f"vector env, N = {v['num_envs']:,}: NumPy / JAX float64 / JAX float32",
         f"{numpy:,.0f} / {f64:,.0f} (**{f64 / numpy:.2f}x**) / {f32:,.0f} ({f32 / numpy:.2f}x) vehicle-steps/s; first step "
         f"(compilation) {first['jax_float64']:.1f} s / {first['jax_float32']:.1f} s",
         f"float64 >= 2x NumPy, float32 >= 5M: {_met(f64 >= 2 * numpy and f32 >= 5e6)}"],
        [f"functional env, N = {n_f:,}, `jit` of `lax.scan` over `vmap`-ed gymnax steps with autoreset (what JAX RL "
         "libraries run)",
         f"float64 {functional['float64']['vehicle_steps_per_s']:,.0f} (**{functional['float64']['vehicle_steps_per_s'] / numpy:.2f}x** "
         f"NumPy), float32 {functional['float32']['vehicle_steps_per_s']:,.0f} "
         f"({functional['float32']['vehicle_steps_per_s'] / numpy:.2f}x) vehicle-steps/s; compilation "
         f"{functional['float64']['first_call_s']:.1f} s / {functional['float32']['first_call_s']:.1f} s", ""],
        [f"JAX float64 vs NumPy, {a['episodes']} whole standard-set episodes, same seed and actions",
         f"largest observation difference **{a['max_obs_diff_float64']:.1e}**; final positions within "
         f"{a['impact_position_error_float64_vs_numpy_m']:.1e} m", f"<= 1e-5: {_met(a['max_obs_diff_float64'] <= 1e-5)}"],
        [f"JAX float32 vs float64, the same {a['episodes']} episodes",
         f"final position: median {a['float32_end_position_error_m']['median']:.1f} m, largest "
         f"{a['float32_end_position_error_m']['max'] / 1e3:.2f} km; the same ending in {a['float32_same_ending']}/{a['episodes']}",
         "stated"],
        [f"PPO training, env-steps/s: rejax on the functional env ({jax['num_envs']} vehicles, `{jax['config']}`) vs "
         "stable-baselines3 on the plain baselines' config",
         f"rejax **{jax['env_steps_per_s']:,.0f}** (after {jax['compile_s']:.0f} s of compilation; "
         f"{jax['timesteps'] / 1e6:.1f}M steps), SB3 {sb3['env_steps_per_s']:,.0f}: **{speedup:.1f}x**",
         f">= 3x SB3: {_met(speedup >= 3)}"],
    ]  # fmt: skip
    loads = ", ".join(f"{name}: load average {m['load_average'][0]:.1f} at the start and {m['load_average_end'][0]:.1f} "
                      "at the end" for name, m in (("speed", bench["machine"]), ("PPO", ppo["machine"])))  # fmt: skip
    machine = bench["machine"]
    note = (f"{machine['cpus']} CPU cores, jax {machine['jax']}, the default {bench['task']['substeps']} substep "
            f"of {bench['task']['dt']:g} s; {loads}.")
    return "\n".join([md(["", "measured", "target"], rows), "", note, "",
                      source("docs/results/bench_jax_cpu.json", "docs/results/bench_jax_ppo_cpu.json")])


def scratch_scan_table(doc: dict) -> str:
    """The from-scratch learner's training throughput against its batch shape (``benchmarks/scratch_scan.py``)."""
    rows, base = [], next(r for r in doc["variants"] if r["name"] == "shipped" and not r["one_core"])
    for r in doc["variants"]:
        changed = ", ".join(f"{sec}.{k} = {v}" for sec, fields in r["changes"].items() for k, v in fields.items())
        rows.append([f"`{r['name']}`", changed or "as shipped", "one (taskset)" if r["one_core"] else "two",
                     f"{r['train_env_steps_per_s']:,.0f}", f"{r['wall_env_steps_per_s']:,.0f}",
                     f"**{r['wall_env_steps_per_s'] / base['wall_env_steps_per_s']:.2f}x**",
                     f"{r['updates_per_million_steps']:.0f}"])  # fmt: skip
    m = doc["provenance"]["machine"]
    note = (f"Each variant the shipped config's first sections (`rventry_agents/ppo_scratch.toml`, no stages) with the "
            f"settings named changed, {doc['chunks']} chunks in a fresh process, one variant at a time on a "
            f"{m['cores']}-core {m['cpu']} (load average {m['load_average_start'][0]:.1f} at the start, "
            f"{m['load_average_end'][0]:.1f} at the end). Training: the learner's own env-steps/s, the median chunk "
            "after the first, its evaluations excluded; wall clock: the median of one chunk's training and the "
            "evaluations before it (the curriculum's frontier, the selection set and the probes), the first two "
            "left out as they compile, which is what a budget in hours pays.")  # fmt: skip
    header = ["variant", "settings changed", "cores", "training env-steps/s", "wall-clock env-steps/s", "wall, against shipped",
              "updates a million steps"]  # fmt: skip
    return "\n".join([md(header, rows), "", note, "",
                      source("docs/results/bench_scratch_scan.json", command="python benchmarks/scratch_scan.py --json PATH")])


def _per_s(v: float) -> str:
    """Vehicle-steps/s as the GPU table writes them: millions, or 1e9 from a billion up."""
    return f"{v / 1e9:.2f}e9" if v >= 1e9 else f"{v / 1e6:.0f}M"


def _functional(runs: list, dtype: str, dispersion: str = "standard") -> dict:
    """A functional-env run list's vehicle-steps/s by vehicle count, for one number type and set."""
    return {r["num_envs"]: r["vehicle_steps_per_s"] for r in runs if r["dtype"] == dtype and r["dispersion"] == dispersion}


def _passed(text: str) -> str:
    """``N passed in S s`` from a test run's result line."""
    m = re.search(r"(\d+) passed in ([\d.]+) ?s", text)
    return f"{m.group(1)} passed in {float(m.group(2)):.0f} s"


def jax_gpu_table(h200: dict, h100: dict, kernels: dict) -> str:
    """The JAX backend on one GPU: the functional env's throughput on an H100 and an H200, where the
    H100's time goes, the Gymnasium face, agreement with NumPy, the tests and PPO end to end."""
    f64, f32 = _functional(h100["functional"]["runs"], "float64"), _functional(h100["functional"]["runs"], "float32")
    b64 = _functional(h100["functional_before_sqrt"]["runs"], "float64")
    sizes = sorted(f64)
    r = h200["runs"]
    s64, s32 = _functional(r["functional_sizes"]["functional"], "float64"), _functional(r["functional_sizes"]["functional"], "float32")
    p64, p32 = (next(x for x in r["functional_parts"]["functional"] if x["dtype"] == d) for d in ("float64", "float32"))
    face = r["gymnasium_face_flight_and_agreement"]
    fl64, fl32 = _functional(face["functional"], "float64", "flight"), _functional(face["functional"], "float32", "flight")
    (n_flight,) = fl64
    v, a = face["vector"], face["agreement"]
    vs, first = v["vehicle_steps_per_s"], v["first_step_s"]
    ppo = r["jax_ppo_gpu"]
    compile_s = [x["first_call_s"] for x in r["functional_sizes"]["functional"] if x["dtype"] == "float64"]
    # the H100's Nsight Compute profile: the kernels launched at every step of the scan (the others run once)
    step = [k for k in kernels["ncu_kernels_per_step_N_1048576"]["base"] if k["launches"] > 1]
    n_ncu = 1_048_576
    physics = [k for k in step if k["registers_per_thread"] == max(x["registers_per_thread"] for x in step)]
    reset = next(k for k in step if k["kernel"].startswith("loop_select_fusion"))  # gymnax's autoreset select
    variant = {}
    for x in kernels["runs"]:
        variant.setdefault((x["variant"], x["num_envs"]), x["vehicle_steps_per_s"])  # the first run of each
    big = max(n for _, n in variant)
    best_64 = max(f64.values())
    rows = [
        [f"**H100**, functional env, float64, `{present_command(h100['commands']['functional'])}`, the package as it is now",
         " and ".join(_per_s(f64[n]) if n != sizes[-1] else f"**{_per_s(f64[n])}**" for n in sizes)
         + f" vehicle-steps/s (the same machine, before `aero_accel` used `sqrt`: {' and '.join(_per_s(b64[n]) for n in sizes)})",
         f">= 1e9 on an H100-class card: {_met(best_64 >= 1e9)} ({min(f64.values()) / 1e9:.2f}-{best_64 / 1e9:.2f}e9)"],
        ["**H100**, the same, float32",
         " and ".join(_per_s(f32[n]) if n != sizes[-1] else f"**{_per_s(f32[n])}**" for n in sizes) + " vehicle-steps/s", ""],
        [f"**H100**, where the float64 time goes (Nsight Compute at N = {n_ncu:,}, kernels over 50 us; "
         "`docs/results/bench_jax_h100_kernels.json`, [docs/env.md](../env.md))",
         f"{sum(k['time_ms'] for k in step):.1f} ms of kernels a step: the physics step "
         f"{' + '.join(sig(k['time_ms'], 2) for k in physics)} ms at {physics[0]['registers_per_thread']} registers per thread "
         f"({' and '.join(format(k['local_load_bytes'] / n_ncu / 1e3, '.2f') for k in physics)} KB of spilled registers per vehicle); "
         f"**gymnax's autoreset {reset['time_ms']:.2f} ms**, its select with the whole reset fused in, compiled at "
         f"**{reset['registers_per_thread']} registers** with {reset['local_load_bytes'] / n_ncu / 1e3:.1f} KB per vehicle of "
         f"local-memory loads. Tried and not kept, none faster at {big / 2**20:.0f}M vehicles: a kernel per RK4 stage "
         f"({_per_s(variant['stages', n_ncu])} at 1M and {_per_s(variant['stages', big])} at {big / 2**20:.0f}M, against "
         f"{_per_s(variant['base', n_ncu])} and {_per_s(variant['base', big])}), the reset cut out of the select "
         f"({_per_s(variant['reset', n_ncu])} at 1M), XLA's unrolling off, multi-output and horizontal fusion off", ""],
        [f"H200, functional env, float64, `jit` of `lax.scan` over {r['functional_sizes']['functional'][0]['steps']} "
         f"`vmap`-ed steps with autoreset (`{present_command(r['functional_sizes']['command'])}`), before both changes above",
         "; ".join(f"N = {n:,}: {_per_s(s64[n])}" + (f" ({_per_s(p64['vehicle_steps_per_s'])} on a second machine of the kind)"
                                                      if n == p64["num_envs"] else "") for n in sorted(s64))
         + f" vehicle-steps/s; compilation {min(compile_s):.0f}-{max(compile_s):.0f} s", ""],
        ["H200, the same, float32",
         " / ".join((f"**{_per_s(s32[n])}**" if n == max(s32) else _per_s(s32[n]))
                    + (f" ({_per_s(p32['vehicle_steps_per_s'])} on the second machine)" if n == p32["num_envs"] else "")
                    for n in sorted(s32)) + " vehicle-steps/s", ""],
        [f"H200, the autoreset's share (`--functional-sizes {p64['num_envs']} --functional-parts`)",
         f"`step_env` alone (no autoreset) {_per_s(p64['step_env_only_per_s'])}/s, the whole step "
         f"{_per_s(p64['vehicle_steps_per_s'])}/s (the H100's kernel profile above puts half the step in the autoreset's "
         "kernel; why the `step_env`-only scan was no faster was not found)", ""],
        [f"functional env, `flight` set (NRLMSIS and Gauss-Markov profiles, winds, sensor and navigation errors; pool of "
         f"256), N = {n_flight:,}", f"float64 {_per_s(fl64[n_flight])}, float32 {_per_s(fl32[n_flight])} vehicle-steps/s", ""],
        [f"Gymnasium face (`gym.make_vec(..., backend=\"jax\")`), N = {v['num_envs']:,}, against the NumPy vector env on the "
         f"machine's {face['machine']['cpus']} cores (`{present_command(face['command'])}`, which also gave the `flight` row "
         "above and the agreement below)",
         f"NumPy {vs['numpy'] / 1e6:.2f}M; JAX float64 **{vs['jax_float64'] / 1e6:.2f}M ({vs['jax_float64'] / vs['numpy']:.1f}x)**; "
         f"float32 {vs['jax_float32'] / 1e6:.2f}M vehicle-steps/s; first step {first['jax_float64']:.1f} s / "
         f"{first['jax_float32']:.1f} s", "(the 2x target is for two cores, where it is not met: table above)"],
        [f"JAX float64 on the GPU vs NumPy on the CPU, {a['episodes']} whole standard-set episodes, same seed and actions",
         f"largest observation difference **{sig(a['max_obs_diff_float64'], 2)}**"
         + (" (the float32 observations equal bit for bit)" if a["max_obs_diff_float64"] == 0 else "")
         + f"; final positions within {a['impact_position_error_float64_vs_numpy_m']:.1e} m; float32 vs float64: median "
         f"{a['float32_end_position_error_m']['median']:.1f} m, largest {a['float32_end_position_error_m']['max'] / 1e3:.1f} km, "
         f"the same ending in {a['float32_same_ending']}/{a['episodes']}", f"<= 1e-5: {_met(a['max_obs_diff_float64'] <= 1e-5)}"],
        [f"`tests/envs/test_jax.py` on the GPU (`{r['test_jax']['command']}`)",
         f"{_passed(r['test_jax']['result'])} on the H200; {_passed(h100['tests'])} on the H100 with the package as it is now", ""],
        ["end-to-end PPO in JAX on the GPU (`rventry train jax-ppo --config rventry_agents/baselines/jax_ppo_gpu.toml "
         "--max-wall-s 150`: 4,096 vehicles, rollouts of 262,144 steps)",
         f"**{ppo['env_steps_per_s'] / 1e6:.2f}M env-steps/s** after {ppo['compile_s']:.0f} s of compilation: "
         f"{ppo['timesteps'] / 1e6:.0f}M steps in {ppo['wall_s']:.0f} s, "
         + ("one training program compiled" if ppo["train_compilations"] == 1 else f"{ppo['train_compilations']} training programs compiled"),
         f">= 1e6: {_met(ppo['env_steps_per_s'] >= 1e6)}"],
    ]  # fmt: skip
    return "\n".join([md(["", "measured", "target"], rows), "",
                      source("docs/results/bench_jax_h200.json", "docs/results/bench_jax_h100.json",
                             "docs/results/bench_jax_h100_kernels.json")])


PPO_RECORDS = (*(f"docs/results/ppo_q_floor/ppo_{s}.json" for s in ("flight", "standard", "wide", "peer-0.1")),
               "docs/results/bench_seeds_ppo.json", "docs/results/q_floor_dagger_flight_heldout.json",
               "docs/results/mpc_flight_flight200.json", "rventry_agents/data/ppo_finetune/metadata.json")  # fmt: skip


def _bold_ci(r: dict, key: str = "success_rate") -> str:
    lo, hi = r[f"{key}_ci"]
    return f"**{rate(r[key])}** [{lo:.2f}, {hi:.2f}]"


def ppo_table(flight: dict, standard: dict, wide: dict, peer: dict, seeds: dict, start_floor: dict, mpc: dict,
              metadata: dict) -> str:
    """The shipped ``ppo`` held out: with its q floor, as trained, its start, its start with the same floor."""
    import numpy as np

    from rventry_env.evaluation.seeds import seed_statistics
    from rventry_env.evaluation.summary import rate_interval

    floor = {"flight": flight["summary"], "standard": standard["summary"], "wide": wide["summary"], "peer-0.1": peer["summary"]}
    trained, start = seeds["runs"]["ppo"][0]["sets"], seeds["runs"]["dagger-flight"][0]["sets"]
    margin = start_floor["chosen"]
    floored = start_floor["success"][next(k for k in start_floor["success"] if k != "none" and float(k) == margin)]
    n = start_floor["episodes"]

    def start_floor_cell(s: str, interval: bool = False) -> str:
        if s not in floored:
            return "no record"
        if not interval:
            return rate(floored[s])
        k = round(floored[s] * n)
        lo, hi = rate_interval([True] * k + [False] * (n - k))
        return f"{rate(floored[s])} [{lo:.2f}, {hi:.2f}]"

    m = mpc["summary"]["success_rate"]
    both = lambda d: f"{rate(d['standard']['success_rate'])} / {rate(d['wide']['success_rate'])}"  # noqa: E731
    sw_met = floor["standard"]["success_rate"] >= 0.99 and floor["wide"]["success_rate"] >= 0.98
    runs = [r["sets"]["flight"]["success_rate"] for r in seeds["runs"]["ppo"]]
    iqm = seed_statistics({"ppo": np.array([[x] for x in runs])})["ppo"]
    wall, steps = float(metadata["wall_time_s"]), int(metadata["timesteps"])
    rows = [
        ["`flight`, basic success", _bold_ci(floor["flight"]), ci(trained["flight"]), ci(start["flight"]),
         start_floor_cell("flight", True),
         f">= 0.97, and >= `mpc`'s on the same seeds (`mpc-flight` {rate(m)}): "
         f"{_met(floor['flight']['success_rate'] >= max(0.97, m))}"],
        ["`flight`, precision tier", ci(floor["flight"], "precision_success_rate"),
         rate(trained["flight"]["precision_success_rate"]), rate(start["flight"]["precision_success_rate"]), "no record",
         f">= 0.80: {_met(floor['flight']['precision_success_rate'] >= 0.80)}"],
        ["standard / wide, basic", f"**{both(floor)}**", both(trained), both(start),
         f"{start_floor_cell('standard')} / {start_floor_cell('wide')}", f">= 0.99 / >= 0.98: {_met(sw_met)}"],
        ["`peer-0.1`, basic", _bold_ci(floor["peer-0.1"]), rate(trained["peer-0.1"]["success_rate"]),
         rate(start["peer-0.1"]["success_rate"]), start_floor_cell("peer-0.1"),
         f">= 0.97: {_met(floor['peer-0.1']['success_rate'] >= 0.97)}"],
        ["training wall time", f"{wall:.0f} s ({steps / 1e6:g}M steps, seed {metadata['seed']})", "", "", "",
         f"<= 2 h: {_met(wall <= 7200)}"],
        [f"IQM over {len(runs)} seeds, `flight` (as trained)", "",
         f"**{iqm['iqm']:.3f}** [{iqm['iqm_ci'][0]:.3f}, {iqm['iqm_ci'][1]:.3f}] (seeds 0-{len(runs) - 1}: "
         f"{', '.join(f'{x:.3f}' for x in runs)})", rate(start["flight"]["success_rate"]), "", "reported"],
    ]  # fmt: skip
    header = [f"`ppo` (PPO-trained), {flight['summary']['episodes']} episodes, seed 0", "measured, with the q floor",
              "as trained", "its start, `dagger-flight`", "its start with the same q floor", "target"]  # fmt: skip
    return "\n".join([md(header, rows), "", source(*PPO_RECORDS)])


SHIPPED_REFERENCE = "rventry_env/reference/data/entry_reference_v1.json"


def _exact_ends(d: dict) -> str:
    """The optimum's final eB1 and etaB: exactly 0, or their values."""
    return "exactly 0" if d["final_eB1"] == 0 and d["final_etaB"] == 0 else f"{d['final_eB1']:.1e}, {d['final_etaB']:.1e}"


def _optimum_rows(doc: dict, cost: str, tf: str, violation: str) -> list:
    """The rows every table of a collocation optimum opens with: its cost, final time, mesh error and
    constraint violation, under the given names."""
    return [
        [cost, f"{doc['cost']:.6f}", ""],
        [tf, f"{doc['tf_s']:.3f} s", ""],
        ["final mesh max relative error", f"{sci(doc['mesh_error'], 2)} ({doc['n_intervals']} intervals, {doc['n_nodes']} nodes)",
         f"<= {sci(doc['mesh_tolerance'], 0)}"],
        [violation, sci(doc["max_constraint_violation"], 1), ""],
    ]  # fmt: skip


def reference_table(doc: dict) -> str:
    """The shipped collocation optimum, from the summary its solve wrote beside it."""
    d = doc["diagnostics"]
    rows = [
        *_optimum_rows(doc, "J*", "t_f", "max constraint violation (scaled NLP)"),
        ["eB1(t_f), etaB(t_f)", _exact_ends(d), "exact"],
        ["IPOPT iterations per mesh pass", ", ".join(map(str, doc["nlp_iterations_per_pass"])), ""],
        ["|lambda|, the norm-keeping control, largest", f"{sci(d['max_abs_lambda_per_s'], 1)} /s", "0 (the paper's problem)"],
        ["the shipped file's solve: wall (CPU), peak memory of the process",
         f"{doc['solve_time_s']:.1f} s ({doc['solve_cpu_s']:.1f} s), {doc['rss_peak_mb']:.0f} MB", ""],
    ]  # fmt: skip
    return "\n".join([md(["quantity (`rventry reference show`)", "measured", "target"], rows), "",
                      source(SHIPPED_REFERENCE, command=doc.get("command"))])



def reference_show_table(doc: dict) -> str:
    """``rventry reference show``: the shipped optimum, its ends against the boundary conditions, its norm drift
    and its path constraints against their bounds."""
    d, bounds = doc["diagnostics"], doc["constants"]["problem"]
    ends = (d["final_radius_error_m"], d["final_speed_error_mps"], d["final_alpha_deg"])
    miss = d["target_miss_m"]
    load, q = d["max_aero_accel_g"], d["min_dynamic_pressure_pa"]
    rows = [
        *_optimum_rows(doc, "J* (Eq. `Ex2-Cost`)", "tf", "max constraint violation (scaled NLP, IPOPT's view)"),
        [f"r(tf) - R_e, v(tf) - {bounds['final_speed']:g} m/s, alpha(tf)", ", ".join(f"{v:g}" for v in ends), ""],
        ["eB1(tf), etaB(tf)", _exact_ends(d), "vertical impact, exact"],
        ["target miss", "< 1 mm" if miss < 1e-3 else f"{sig(miss)} m", ""],
        ["unit-norm drift at the nodes / between nodes", f"{sci(d['norm_drift_nodes'], 1)} / {sci(d['norm_drift_between_nodes'], 1)}", ""],
        ["max aero load, min dynamic pressure (at the nodes and between them)", f"{load:.3f} g, {q / 1e3:.2f} kPa",
         f"<= {bounds['a_max_g']:g} g, >= {bounds['q_min'] / 1e3:g} kPa"],
    ]  # fmt: skip
    return "\n".join([md(["quantity", "value", "target"], rows), "", source(SHIPPED_REFERENCE, command=doc.get("command"))])

ORBIT_RECORDS = ("docs/results/orbit.json", "docs/results/orbit_n.json")


def orbit_table(sweep: dict, chosen: dict) -> str:
    """Example 1: one period of the orbit in rv-Euler and in spherical coordinates, against the analytic one."""
    rows = {r["n"]: r for r in chosen["results"]}
    at = rows[chosen["n1000"]["n"]]
    n1, n2 = sorted(n for n in rows if n != chosen["n1000"]["n"])[:2]
    order = {form: math.log(rows[n1][f"{form}_km"] / rows[n2][f"{form}_km"]) / math.log(n2 / n1)
             for form in ("rv_euler", "spherical")}  # fmt: skip
    from rventry_env.examples.orbit.numerics import PLATEAU_N as plateau

    floor = sweep["floor_km"]
    table = [
        [f"e_r,max at N = {at['n']}, rv-Euler / spherical (`rventry orbit --n {at['n']}`)",
         f"{sci(at['rv_euler_km'], 2)} km / {sci(at['spherical_km'], 2)} km, ratio {chosen['n1000']['ratio_of_max']:.0f}",
         '"three orders of magnitude"'],
        [f"median error ratio after the South-Pole pass, N = {at['n']}", f"{chosen['n1000']['median_ratio_after_south_pole']:.0f}", ""],
        [f"floor, median over N >= {plateau}, rv-Euler / spherical",
         f"{sci(floor['rv_euler']['plateau_median'], 1)} km / {sci(floor['spherical']['plateau_median'], 1)} km",
         '"around 1e-10 km"'],
        [f"convergence order (N = {n1} -> {n2})", f"{order['rv_euler']:.1f} / {order['spherical']:.1f}", ""],
    ]  # fmt: skip
    commands = f"`rventry orbit --json PATH` (the paper's {len(sweep['results'])} values of N) and " \
               f"`rventry orbit {' '.join(f'--n {n}' for n in sorted(rows))} --json PATH`"  # fmt: skip
    return "\n".join([md(["quantity", "measured", "paper"], table), "",
                      f"Records: {', '.join(f'`{p}`' for p in ORBIT_RECORDS)}; written by {commands}."])


def orbit_sweep_table(sweep: dict) -> str:
    """Example 1's error against N: every third of ``rventry orbit``'s step counts, and the last."""
    results = sweep["results"]
    shown = results[::3] + ([results[-1]] if (len(results) - 1) % 3 else [])
    rows = [[str(r["n"]), f"{r['rv_euler_km']:.3e}", f"{r['spherical_km']:.3e}", f"{r['spherical_km'] / r['rv_euler_km']:.0f}"]
            for r in shown]  # fmt: skip
    return "\n".join([md(["N", "rv-Euler", "spherical", "ratio"], rows), "",
                      f"Every third row of the {len(results)}, and the last; the command prints all of them.", "",
                      source(ORBIT_RECORDS[0], command="rventry orbit --json PATH")])


BUDGET = ("train.total_timesteps", "train.max_wall_s")  # how long a run was allowed, not how it trained


def _wall_range(walls_s: list[float]) -> str:
    """Wall times as a range: in seconds under 10 minutes (a quick start's are minutes apart by seconds), else minutes."""
    unit, scale = ("s", 1.0) if max(walls_s) < 600 else ("min", 60.0)
    lo, hi = (f"{w / scale:.0f}" for w in (min(walls_s), max(walls_s)))
    return f"{lo} {unit}" if lo == hi else f"{lo}-{hi} {unit}"


def ladder_table(doc: dict) -> str:
    """Each learner on each rung of the ladder: success over training seeds (rliable's IQM), with the
    steps and wall time a seed took."""
    header = ["learner", "rung", "seeds", "success per seed", "IQM [95 % CI]", "steps per seed", "wall time per seed"]
    rows = []
    for e in doc["entries"]:
        runs = e["runs"]
        trained = sorted({r.get("trained_on", e["rung"]) for r in runs})
        learner = e["learner"] + ("" if trained == [e["rung"]] else f", trained on `{'`, `'.join(trained)}`")
        walls = [r["wall_s"] for r in runs]
        rows.append([learner, f"`{e['rung']}`", str(e["seeds"]), " / ".join(f"{r['evaluation']['success']:.2f}" for r in runs),
                     f"{e['iqm']:.2f} [{e['iqm_ci'][0]:.2f}, {e['iqm_ci'][1]:.2f}]",
                     " / ".join(f"{r['timesteps'] / 1e6:,.0f}M" if r["timesteps"] >= 1e9 else f"{r['timesteps'] / 1e6:.3g}M"
                                for r in runs),
                     _wall_range(walls)])  # fmt: skip
    episodes = sorted({r["evaluation"]["episodes"] for e in doc["entries"] for r in e["runs"]})
    return "\n".join([md(header, rows), "", f"Each success rate over {' or '.join(map(str, episodes))} held-out episodes "
                      f"(seeds from {doc['evaluation_seed']}); wall times as each run measured them on a two-core machine, most of them beside another "
                      "run (each run's load average is in its provenance in the record).", "",
                      source("docs/results/ladder.json", command="python studies/ladder.py")])  # fmt: skip


# the README's ladder at a glance: plain learners, the shipped staged policy and the one-config recipes, each
# by the start of its learner's name in the ladder (the full ladder, every learner, is on the results page)
README_LADDER = (
    ("SB3 PPO, plain", "SB3 PPO (plain)"),
    ("rejax PPO, plain (no curriculum, trained on the rung or a later start)", "rejax PPO, attitude commands"),
    ("rejax PPO, the staged recipe, then stages on `wide` and `flight`, shipped as `ppo-scratch-flight`",
     "rejax PPO, the staged recipe, then a stage on wide and one on flight"),
    ("rejax PPO, the landing recipe, one config from step 0, two hours", "rejax PPO, the landing recipe (GAE lambda 0.99"),
    ("the same, with the features as the environment scales them",
     "rejax PPO, the landing recipe with the features as the environment scales them"),
    ("the same, with the window moved back by at most 60 s a step (95 or 110 minutes)",
     "rejax PPO, the landing recipe with the window moved back by at most 60 s"),
)  # fmt: skip


def ladder_summary(doc: dict) -> str:
    """The ladder at a glance (the README keeps one results table): for the plain learners, the shipped
    staged policy and the one-config recipes, each rung's success, IQM over the training seeds."""
    from rventry_env.evaluation.rungs import RUNGS

    lines = []
    for label, prefix in README_LADDER:
        entries = [e for e in doc["entries"] if e["learner"].startswith(prefix)]
        learners = {e["learner"] for e in entries}
        if len(learners) != 1:
            raise ValueError(f"the ladder has {len(learners)} learners named {prefix!r}...: the README shows one")
        by_rung = {e["rung"]: e for e in entries}
        seeds = sorted({e["seeds"] for e in entries})
        cells = [f"`{r}` {by_rung[r]['iqm']:.2f}" for r in RUNGS if r in by_rung]
        lines.append(f"- {label} ({'/'.join(map(str, seeds))} seed{'s' if seeds != [1] else ''}): " + ", ".join(cells))
    episodes = sorted({r["evaluation"]["episodes"] for e in doc["entries"] for r in e["runs"]})
    return "\n".join([*lines, "", f"Success IQM over training seeds on {' or '.join(map(str, episodes))} held-out "
                       "episodes of each rung (the staged recipe's seeds are those of its last stage). Every learner, every "
                       "run with its steps and wall time, and the intervals are in "
                       "[the ladder](docs/benchmarks/learned_policies.md#the-ladder)."])  # fmt: skip


def scratch_runs_table(doc: dict) -> str:
    """The from-scratch runs as they stood when they stopped: settings changed, window, success."""
    header = ["run", "settings changed from `ppo_scratch.toml`", "steps", "wall", "window", "frontier", "full task"]
    rows = []
    for r in doc["runs"]:
        changed = ", ".join(f"{k.split('.', 1)[1]} {v}" for k, v in r["changed"].items()
                            if k not in BUDGET and not (isinstance(v, str) and v.startswith("not in"))) or "none"  # fmt: skip
        start = r.get("init_from")
        if start:  # started from another run's checkpoint: its steps and wall time are in this run's
            changed = (f"from {Path(start['run']).name} at {start['timesteps'] / 1e6:.1f}M steps "
                       f"(window {start['window_s']:.0f} s); {changed}")  # fmt: skip
        window = "-" if r["window_s"] is None else f"{r['window_s']:.0f} s"
        front = "-" if r["frontier_success"] is None else f"{r['frontier_success']:.2f}"
        rows.append([r["run"], changed, f"{r['timesteps'] / 1e6:.1f}M", f"{r['wall_s'] / 60:.0f} min", window, front,
                     f"{r['select_success']:.2f}"])  # fmt: skip
    return "\n".join([md(header, rows), "", "Window: how far before impact the curriculum started episodes when the "
                      "run stopped; frontier: success from the window's far end; full task: the selected policy's "
                      "success from the task's own initial state. A run started from another's checkpoint counts "
                      "that run's steps and wall time in its own.", "",
                      source("docs/results/scratch_runs.json", command="python studies/ladder.py histories RUN ...")])  # fmt: skip


def _identify_row(r: dict, flight: bool) -> list[str]:
    """One identification: what it found, where the trace points, the residual, the time it took."""
    found = " + ".join(f"`{e}`" for e in r["effects"]) or "none"
    if r["unexplained"]:
        found += " (unexplained)"
    unit, scale = ("km", 1e3) if flight else ("m", 1.0)
    rms = f"{sig(r['rms_before'] / scale)} -> {sig(r['rms_after'] / scale)}"
    if r.get("rms_after_trace") is not None and r.get("trace"):
        rms += f" ({sig(r['rms_after_trace'] / scale)} after the trace)"
    name = {"apollo4": "Apollo 4 (`rventry identify apollo4`)",
            "apollo10": "Apollo 10 (`rventry identify apollo10`)"}.get(r["case"], f"`{r['case']}`")
    trace = r.get("trace") or "-"
    if r.get("bank_offset_deg") is not None:
        trace += f" (a bank offset of {r['bank_offset_deg']:+.2f} deg)"
    return [name, str(r["samples"]), found, trace, f"{rms} {unit}",
            f"{r['cpu_s']:.1f} ({r['wall_s']:.0f})"]  # fmt: skip


def identify_table(paths: tuple[str, ...]) -> Callable[..., str]:
    """Identifications benchmarked by ``benchmarks/identify_speed.py``: one row per record, from its ``--json``."""

    def render(*docs) -> str:
        rows, notes, sources = [], [], []
        for path, doc in zip(paths, docs):
            rows += [_identify_row(r, False) for r in doc["cases"]]
            rows += [_identify_row(doc[k], True) for k in ("apollo4", "apollo10") if doc.get(k)]
            a10 = doc.get("apollo10")
            if a10 and a10.get("entry_altitude_offset_m"):
                off = a10["entry_altitude_offset_m"]
                by = ", ".join(f"`{x}`" for x in a10.get("entry_offset_explained_by") or []) or "no reference"
                notes.append(f"Apollo 10: entry altitude offset {off['value']:+.0f} +/- {off['stderr']:.0f} m, "
                             f"explained by {by}.")  # fmt: skip
            prov = doc.get("provenance") or {}  # a record written through util.provenance; earlier ones carry the keys
            machine = prov.get("machine") or {}
            load, cpus = doc.get("load_average") or [], doc.get("cpus", machine.get("cores"))
            if machine.get("load_average_start") and machine.get("load_average_end"):
                load = [machine["load_average_start"][0], machine["load_average_end"][0]]
            load_text = f", load average {load[0]:.1f} -> {load[1]:.1f} on {cpus} shared cores" if len(
                load) == 2 and None not in load else ""  # fmt: skip
            # the command as it ran, writing this record (where it wrote first is not part of the figures)
            ran = doc.get("command") or prov.get("command")
            command = present_command(re.sub(r"--json \S+", f"--json {path}", ran)) if ran else None
            sources.append(f"`{path}`" + (f" (`{command}`{load_text})" if command else ""))
        header = ["record", "samples", "identified", "trace (size, band)", "rms before -> after",
                  "CPU s (wall s)"]  # fmt: skip
        parts = [md(header, rows), ""]
        if notes:
            parts += [" ".join(notes), ""]
        parts.append("Records: " + "; ".join(sources) + ".")
        return "\n".join(parts)

    return render


IDENTIFY_TABLES = {
    "identify-findings": ("docs/results/bench_identify_bank_bias.json", "docs/results/bench_identify_density_wave.json"),
    "identify-heldout": ("docs/results/bench_identify_heldout.json",),
    "identify-flights": ("docs/results/bench_identify_flights.json",),
    "identify-speed-before": ("docs/results/bench_identify_speed_before.json",),
    "identify-speed": ("docs/results/bench_identify_speed.json",),
    "identify-speed-50hz-before": ("docs/results/bench_identify_speed_50hz_before.json",),
    "identify-speed-50hz": ("docs/results/bench_identify_speed_50hz.json",),
}


OBSERVATION_BOUNDS = "docs/results/observation_bounds.json"


def observation_bounds_table(doc: dict) -> str:
    """Where flown observations lie against the observation Box: the steps the env clipped, per set and law."""
    import statistics

    rows = []
    for key, m in doc.items():
        if key == "provenance":  # where the record was made, not a set / law
            continue
        names = [n for i, n in enumerate(m["names"]) if m["below"][i] or m["above"][i]]
        lowest, errors = "", ""
        if m["clipped_steps"]:
            i = m["names"].index("altitude") if "altitude" in m["names"] else None
            if i is not None and m["below"][i]:
                lowest = f"{m['min'][i]:.4f} ({m['min'][i] * 40:.2f} km)"
            e = m["nav_vertical_error_m"]
            if e:
                errors = f"{min(e):.0f} to {max(e):.0f}, median {statistics.median(e):.0f}"
        rows.append([key.replace("/", " / "), f"{m['episodes']:,}", f"{m['clipped_steps']:,} of {m['steps']:,}",
                     f"{m['clipped_episodes']:,}", ", ".join(names) or "none", lowest, errors])  # fmt: skip
    header = ["set / law", "episodes", "clipped steps", "episodes with one", "features outside the Box",
              "altitude feature, lowest (navigated altitude)", "navigation's vertical error there (m)"]  # fmt: skip
    command = ("nice -n 19 python studies/observation_bounds.py --sets flight standard --laws reference zero "
               "--episodes 1000 --json docs/results/observation_bounds.json")  # fmt: skip
    return "\n".join([md(header, rows), "", "Seeds 0-999 per set and law, vector env, the features before clipping; "
                      "`zero`: zero rates (alpha and bank held where they start).", "",
                      source(OBSERVATION_BOUNDS, command=command)])  # fmt: skip


# ------------------------------------------------------------------ learned from scratch against imitation
# `learned` on held-out `flight` draws beside the policies built by imitation and their teacher: for each set of
# draws, each law's report and, where one was flown on the same draws, studies/compare_episodes.py's pairing of
# `ppo-scratch-flight` with it (A: ppo-scratch-flight, B: the law)
SCRATCH_VS = "docs/results/scratch_vs_imitation"
SCRATCH_VS_DRAWS = {  # first seed -> law -> its `rventry evaluate` report on 200 `flight` episodes from that seed
    0: {"ppo-scratch-flight": f"{SCRATCH_VS}/ppo-scratch-flight_flight_seed0.json",
        "ppo": "docs/results/ppo_q_floor/ppo_flight.json", "dagger-flight": "docs/results/dagger_flight_flight200.json",
        "mpc-flight": "docs/results/mpc_flight_flight200.json"},
    1000: {"ppo-scratch-flight": "docs/results/ppo_scratch_flight_flight200.json",
           "ppo": f"{SCRATCH_VS}/ppo_flight_seed1000.json", "dagger-flight": f"{SCRATCH_VS}/dagger-flight_flight_seed1000.json"},
}  # fmt: skip
SCRATCH_VS_LAWS = tuple(dict.fromkeys(law for laws in SCRATCH_VS_DRAWS.values() for law in laws))  # rows, in order


def scratch_vs_records() -> tuple[str, ...]:
    reports = [p for laws in SCRATCH_VS_DRAWS.values() for p in laws.values()]
    pairs = [f"{SCRATCH_VS}/vs_{law}_seed{seed}.json" for seed, laws in SCRATCH_VS_DRAWS.items() for law in laws
             if law != "ppo-scratch-flight"]  # fmt: skip
    return (*reports, *pairs)


def scratch_vs_imitation_table(*docs) -> str:
    """``ppo-scratch-flight`` (``learned``) against ``ppo``, ``dagger-flight`` and ``mpc-flight`` on the same held-out
    ``flight`` draws: each law's success, and the episodes only one of the two lands, with the sign test on them."""
    paths = scratch_vs_records()
    records = dict(zip(paths, docs))
    seeds = list(SCRATCH_VS_DRAWS)
    for seed, laws in SCRATCH_VS_DRAWS.items():
        for law, path in laws.items():
            d = records[path]
            if d["seed"] != seed or d["dispersion_set"] != "flight" or d["n_episodes"] != 200:
                raise ValueError(f"{path}: expected 200 flight episodes from seed {seed}, got {d['n_episodes']} "
                                 f"{d['dispersion_set']} episodes from seed {d['seed']}")  # fmt: skip
    rows = []
    for law in SCRATCH_VS_LAWS:
        row = [f"`{law}`" + (" (`learned`)" if law == "ppo-scratch-flight" else "")]
        for seed in seeds:
            path = SCRATCH_VS_DRAWS[seed].get(law)
            if path is None:
                row += ["not flown", ""]
                continue
            summary = records[path]["summary"]
            if law == "ppo-scratch-flight":
                row += [_bold_ci(summary), ""]
                continue
            pair = records[f"{SCRATCH_VS}/vs_{law}_seed{seed}.json"]
            if list(pair["labels"]) != ["ppo-scratch-flight", law] or pair["paired"]["episodes"] != 200:
                raise ValueError(f"{SCRATCH_VS}/vs_{law}_seed{seed}.json does not pair ppo-scratch-flight with {law} "
                                 "on 200 episodes")  # fmt: skip
            c = pair["paired"]
            row += [ci(summary), f"{c['only_a']} / {c['only_b']}, p = {c['sign_test_p']:.2g}"]
        rows.append(row)
    header = ["law", *(x for seed in seeds for x in (f"seeds {seed}-{seed + 199}: success [95 % CI]",
                                                     "only `ppo-scratch-flight` / only this law lands, sign test"))]
    return "\n".join([md(header, rows), "", source(*paths)])


# ------------------------------------------------------------------ the students held out
HELDOUT = "docs/results/heldout"
DAGGER_HELDOUT = tuple(f"{HELDOUT}/dagger_{s}.json" for s in ("none", "standard", "wide"))
COMPARE = "docs/results/compare_standard.json"
# the benchmark's targets for a learned policy (held out: 200 standard and 200 wide episodes from seed 0)
LEARNED_TARGETS = {"standard": 0.95, "wide": 0.90, "nominal_miss_km": 1.0, "nominal_vertical_deg": 1.0,
                   "nominal_cost_ratio": 1.3, "over_lqr": 0.10}  # fmt: skip


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def _pp(s: dict, key: str, unit: str, scale: float = 1.0) -> str:
    p = s["percentiles"][key]
    return f"{p['p50'] * scale:.2f} / {p['p95'] * scale:.2f} {unit}"


def _command(doc: dict, path: str) -> str:
    """The ``rventry evaluate`` command that writes an evaluation report like ``doc``."""
    return (f"rventry evaluate --agent {doc['agent']} --episodes {doc['n_episodes']} --dispersion "
            f"{doc['dispersion_set']} --seed {doc['seed']} --json {path}")


def dagger_heldout_table(nominal: dict, standard: dict, wide: dict, compare: dict) -> str:
    """``dagger`` held out: the nominal flight, 200 standard and 200 wide episodes from seed 0, against the
    benchmark's targets for a learned policy; its gain over TV-LQR from ``rventry compare``'s record."""
    n, s, w = nominal["summary"], standard["summary"], wide["summary"]
    t = LEARNED_TARGETS
    lqr = compare["runs"]["dispersed/TV-LQR"]["summary"]["success_rate"]
    gain = s["success_rate"] - lqr
    cr = compare["runs"]["dispersed/TV-LQR"]
    same = cr["seed"] == standard["seed"] and cr["n_episodes"] == standard["n_episodes"]

    def viol(x: dict) -> str:
        r = x["constraint_violation_rate"]
        return "none" if r == 0 else rate(r) + (f" ({round(r * x['episodes'])} of {x['episodes']})" if x["episodes"] > 1 else "")

    def peak(x: dict) -> str:
        p = x["percentiles"]["max_load_factor_g"]
        return f"{p['p50']:.2f} g" if x["episodes"] == 1 else f"{p['p50']:.2f} g ({p['p95']:.2f})"

    rows = [
        ["success", "yes" if n["success_rate"] == 1 else "no", f"**{rate(s['success_rate'])}**", f"**{rate(w['success_rate'])}**",
         f">= {t['standard']:.2f} / >= {t['wide']:.2f}: {_met(s['success_rate'] >= t['standard'] and w['success_rate'] >= t['wide'])}"],
        ["success [95 % CI]", "", ci(s), ci(w), ""],
        ["success over TV-LQR without estimation" + (" (same episodes, `rventry compare`)" if same else ""), "",
         f"**{gain:+.3f}** ({rate(s['success_rate'])} against {rate(lqr)})", "",
         f">= +{t['over_lqr']:.2f}: {_met(gain >= t['over_lqr'])}"],
        ["miss p50 / p95", f"**{sig(n['miss_km'], 2)} km**", _pp(s, "miss_km", "km"), _pp(w, "miss_km", "km"),
         f"nominal <= {t['nominal_miss_km']:g} km: {_met(n['miss_km'] <= t['nominal_miss_km'])}"],
        ["vertical-impact error p50 / p95", f"**{sig(n['vertical_error_deg'], 2)} deg**", _pp(s, "vertical_error_deg", "deg"),
         _pp(w, "vertical_error_deg", "deg"),
         f"nominal <= {t['nominal_vertical_deg']:g} deg: {_met(n['vertical_error_deg'] <= t['nominal_vertical_deg'])}"],
        ["speed error, mean of abs", *(f"{x['abs_speed_error_mps']:.1f} m/s" for x in (n, s, w)), ""],
        ["alpha at impact, mean", *(f"{x['alpha_final_deg']:.1f} deg" for x in (n, s, w)), "(the optimum's: 0)"],
        ["peak load p50 (p95)", *(peak(x) for x in (n, s, w)), "bound 12 g"],
        ["path violations", *(viol(x) for x in (n, s, w)), ""],
        ["J / J*, mean", f"**{n['cost_ratio']:.3f}**", f"{s['cost_ratio']:.3f}", f"{w['cost_ratio']:.3f}",
         f"nominal <= {t['nominal_cost_ratio']:g}: {_met(n['cost_ratio'] <= t['nominal_cost_ratio'])}"],
    ]  # fmt: skip
    header = ["`dagger`, held out (seeds 0-199)", "nominal", f"standard, {s['episodes']}", f"wide, {w['episodes']}", "target"]
    commands = "; ".join(f"`{_command(d, p)}`" for d, p in zip((nominal, standard, wide), DAGGER_HELDOUT))
    return "\n".join([md(header, rows), "", f"Records: {', '.join(f'`{p}`' for p in DAGGER_HELDOUT)}, written by "
                      f"{commands}; TV-LQR's success from `{COMPARE}` (`rventry compare`)."])  # fmt: skip


DAGGER_FLIGHT_HELDOUT = {"flight": "docs/results/dagger_flight_flight200.json",
                         **{s: f"{HELDOUT}/dagger-flight_{s}.json" for s in ("standard", "wide", "peer-0.1")}}
DAGGER_ON_FLIGHT = (f"{HELDOUT}/dagger_flight.json", DAGGER_HELDOUT[1], DAGGER_HELDOUT[2])
MPC_FLIGHT_ON_FLIGHT = "docs/results/mpc_flight_flight200.json"


def dagger_flight_records() -> tuple[str, ...]:
    return (*DAGGER_FLIGHT_HELDOUT.values(), *DAGGER_ON_FLIGHT, MPC_FLIGHT_ON_FLIGHT)


def dagger_flight_heldout_table(*docs) -> str:
    """``dagger-flight`` held out on four sets (200 episodes from seed 0), with ``dagger`` and ``mpc-flight`` on the
    same episodes where a record holds them."""
    records = dict(zip(dagger_flight_records(), docs))
    sets = list(DAGGER_FLIGHT_HELDOUT)
    df = {st: records[p] for st, p in DAGGER_FLIGHT_HELDOUT.items()}
    for st, d in df.items():
        if d["seed"] != 0 or d["dispersion_set"] != st:
            raise ValueError(f"{DAGGER_FLIGHT_HELDOUT[st]}: not the {st} set from seed 0")
    dagger = {st: records[p] for st, p in zip(("flight", "standard", "wide"), DAGGER_ON_FLIGHT)}
    mpc = records[MPC_FLIGHT_ON_FLIGHT]

    def cell(d: dict | None, bold: bool = False) -> str:
        if d is None:
            return ""
        text = ci(d["summary"])
        return f"**{rate(d['summary']['success_rate'])}** " + text.split(" ", 1)[1] if bold else text

    rows = [["`dagger-flight` success", *(cell(df[s], s == "flight") for s in sets)],
            ["`dagger` success, same episodes", *(cell(dagger.get(s)) for s in sets)],
            ["`mpc-flight` success, same episodes", *(cell(mpc) if s == mpc["dispersion_set"] else "" for s in sets)],
            ["`dagger-flight` miss p50 / p95", *(_pp(df[s]["summary"], "miss_km", "km") for s in sets)],
            ["`dagger-flight` J/J*, mean", *(f"{df[s]['summary']['cost_ratio']:.2f}" for s in sets)]]  # fmt: skip
    n = {d["n_episodes"] for d in (*df.values(), dagger["flight"], mpc)}
    header = [f"{'/'.join(map(str, sorted(n)))} episodes, seed 0", *(f"`{s}`" if s in ("flight", "peer-0.1") else s for s in sets)]
    written = [f"`{_command(records[p], p)}`" for p in (*list(DAGGER_FLIGHT_HELDOUT.values())[1:], DAGGER_ON_FLIGHT[0])]
    return "\n".join([md(header, rows), "", "Records: " + ", ".join(f"`{p}`" for p in dagger_flight_records()) +
                      "; the new ones written by " + "; ".join(written) + "."])  # fmt: skip


# ------------------------------------------------------------------ Apollo 4, the environment's checks, mpc's defaults
APOLLO4 = "docs/results/apollo4_identify.json"


def apollo4_table(doc: dict) -> str:
    """Apollo 4's altitude rms: the published reconstruction, the declared state replayed, and ``rventry identify``."""
    from rventry_env.validation.apollo4 import PUBLISHED_RMS_ALTITUDE_M as published

    km = lambda m: f"{m / 1e3:.3g} km"  # noqa: E731  (3 significant figures, no padding: 5.4, 27.1, 0.33)
    d, b, a = doc["declared_entry_state"], doc["before"], doc["after"]
    found = " + ".join(f"`{e}`" for e in doc["effects"])
    params = ", ".join(f"`{k}` = {v:.3f} +/- {doc['parameter_stderr'][k]:.3f}" for k, v in doc["parameters"].items())
    rows = [["published 3-DOF reconstruction (Tacode)", km(published["drag_only"]), km(published["measured_lift"]) + " (measured lift)",
             "the reconstruction"],
            ["rventry, declared entry state, nothing fitted", km(d["current_model"]["altitude_rms_m"]),
             km(d["declared_vehicle"]["altitude_rms_m"]) + " (measured lift)", "`declared_entry_state`"],
            ["rventry, declared entry state, identified model", "", km(d["identified_model"]["altitude_rms_m"]),
             "`declared_entry_state.identified_model`"],
            ["**rventry identify**", f"**{km(b['altitude_rms_m'])}** (`before`)",
             f"**{km(a['altitude_rms_m'])}** (`after`), max {km(a['altitude_max_m'])}; speed rms "
             f"{b['speed_rms_mps']:.0f} -> {a['speed_rms_mps']:.1f} m/s", "`before` / `after`"]]  # fmt: skip
    note = (f"Identified: {found} ({params})" + ("; an unexplained residual remains" if doc["unexplained"] else "")
            + f". {doc['record']['samples']} samples, {doc['replays']} replays.")
    command = "rventry identify apollo4 --json out/apollo4_report.json"
    return "\n".join([md(["altitude error, rms", "drag-only", "with lift", "in the report"], rows), "", note, "",
                      source(APOLLO4, command=command) + " The report is stored as the command wrote it."])  # fmt: skip


ENV_ACCURACY = "docs/results/env_accuracy.json"
SCENARIOS = {"reference": "the reference's controls", "dive": "a violent dive",
             "s-turn": "an aggressive S-turn: alpha 20 deg, bank reversed between +-90 deg every 20 s at the full rate"}


def env_accuracy_table(doc: dict) -> str:
    """The default step's integration error against DOP853 (rtol 1e-12) under the same controls."""
    rows_in = doc["accuracy"]
    substeps = sorted({r["substeps"] for r in rows_in})
    dt = {r["dt_s"] for r in rows_in}
    (dt,) = dt
    rows = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows_in):
        by = {r["substeps"]: r for r in rows_in if r["scenario"] == scenario}
        peak = max(r["peak_load_g"] for r in by.values())
        rows.append([SCENARIOS.get(scenario, scenario), f"{sig(peak, 2)} g",
                     *(f"{sig(by[k]['impact_position_error_m'], 3)} m" + (" at impact" if k == substeps[0] and not rows else "")
                       for k in substeps)])  # fmt: skip
    header = ["scenario", "peak load", *(f"dt = {dt:g} s, {k} RK4 substep" + ("s" if k > 1 else "") + (" (default)" if k == 1 else "")
                                        for k in substeps)]  # fmt: skip
    return "\n".join([md(header, rows), "", "Position error at impact against the tight replay (integration error "
                      "alone; no timing).", "",
                      source(ENV_ACCURACY, command="python benchmarks/env_speed.py --accuracy --json out/env_accuracy.json")])


def reference_dt_table(doc: dict) -> str:
    """The reference's step-mean rates flown through the env at several dt: the running cost's O(dt) gap to J*."""
    rows = [[f"{r['dt_s']:g}", f"{r['cost_ratio']:.3f}", f"{sig(r['miss_km'] * 1e3, 2)} m", f"{sig(r['vertical_error_deg'], 2)} deg",
             "yes" if r["is_success"] else "**no**"] for r in doc["reference_dt"]]  # fmt: skip
    header = ["dt (s), one substep", "running cost / J*", "miss", "vertical error", "success"]
    return "\n".join([md(header, rows), "", "The nominal flight, flown by `ReferencePolicy` (the step-mean rates).", "",
                      source(ENV_ACCURACY, command="python benchmarks/env_speed.py --accuracy --json out/env_accuracy.json")])


RANDOM_ACTIONS = "docs/results/random_actions.json"


def _load_text(doc: dict) -> str:
    m = (doc.get("provenance") or {}).get("machine") or {}
    s, e = m.get("load_average_start"), m.get("load_average_end")
    cores = f"{m['cores_usable']} of {m['cores']}" if m.get("cores_usable") != m.get("cores") else f"{m.get('cores')}"
    return f", load average {s[0]:.1f} -> {e[0]:.1f} on {cores} shared cores" if s and e else ""


def random_actions_table(doc: dict) -> str:
    """Random actions, bad model fields and extreme reset states: every episode ends cleanly, or is refused by name."""
    t, m, s = doc["totals"], doc["models"], doc["states"]
    endings: dict[str, int] = {}  # the random-action episodes' (the totals add the model and state sweeps' flights)
    for case in doc["cases"].values():
        for counts in case.values():
            for k, v in counts.items():
                if k.startswith("ending: "):
                    endings[k[8:]] = endings.get(k[8:], 0) + v
    order = [k for k in ("impact", "skip-out", "stall", "non-finite state", "time limit") if k in endings]
    order += [k for k in endings if k not in order]
    rows = [["crash or NumPy warning", f"{t['crash']:,}"],
            ["non-finite observation or reward", f"{t['non-finite observation'] + t['non-finite reward']:,}"],
            ["observation outside its bounds", f"{t['observation out of bounds']:,}"],
            ["an ended episode without the end keys", f"{t['ended without an end key']:,}"],
            ["random actions, endings: " + " / ".join(order), " / ".join(f"{endings[k]:,}" for k in order)],
            ["bad model fields: refused as the part is built, naming the part and field / accepted and flown (16 episodes "
             "each) / refused without naming it", f"{m.get('refused, naming the field', 0):,} / {m.get('accepted', 0):,} / "
             f"{m.get('refused without naming the field', 0):,}"],
            ["extreme reset states: refused at `reset`, naming the component / flown to a clean end / refused without "
             "naming it", f"{s.get('refused, naming the component', 0):,} / {s.get('accepted', 0):,} / "
             f"{s.get('refused without naming the component', 0):,}"]]  # fmt: skip
    ran = (doc.get("provenance") or {}).get("command")
    text = (f"{doc['episodes_vector']:,} vector-env and {doc['episodes_single']:,} single-env episodes of random "
            f"actions, {doc['wall_time_s']:,.0f} s{_load_text(doc)}.")
    return "\n".join([md(["check", "count"], rows), "", text, "",
                      source(RANDOM_ACTIONS, command=ran)])  # fmt: skip


SCAN_DEFAULTS = "docs/results/scan_mpc.json"  # studies/mpc_settings.py --scan


def scan_defaults_table(doc: dict) -> str:
    """How ``mpc``'s defaults were chosen: each setting varied alone, success, cost and the solver's time."""
    rows = []
    for name, v in doc["scan"].items():
        rows.append([f"**{name}**" if name == "defaults" else name, f"{v['success_rate']:.2f}", f"{v['violation_rate']:.2f}",
                     f"{v['cost_ratio_mean']:.3f}, {v['nominal_cost_ratio']:.3f}",
                     f"{v['resolve_p50_s']:.2f} / {v['resolve_p99_s']:.2f}", f"{v['replans_per_episode']:.0f}",
                     str(v["replan_failures"]), f"{v['episode_cpu_s']:.1f}"])  # fmt: skip
    header = ["variant", "success", "path violations", f"J/J* ({doc['dispersion']} set, nominal)", "re-solve p50 / p99 (s)",
              "solves per episode", "failed solves", "solve time per episode (s)"]  # fmt: skip
    seeds = f"seeds {doc['seed']}-{doc['seed'] + doc['episodes'] - 1}"
    text = (f"{doc['episodes']} `{doc['dispersion']}` episodes ({seeds}) and the nominal flight per variant, "
            f"{doc['wall_s']:.0f} s on {doc['workers']} worker{'s' if doc['workers'] != 1 else ''}{_load_text(doc)}: "
            "the times are this machine's.")
    command = doc.get("command") or (doc.get("provenance") or {}).get("command")
    return "\n".join([md(header, rows), "", text, "", source(SCAN_DEFAULTS, command=command)])


BASELINES = "docs/results/bench_baselines.json"
JAX_BASELINES = ("rventry_agents/data/baselines/jax_ppo_evaluations.json",
                 "rventry_agents/data/baselines/jax_ppo_gpu_evaluations.json")
BASELINE_NAMES = {"ppo": ("PPO", "ppo-plain"), "recurrent_ppo": ("RecurrentPPO", "recurrent-ppo-plain"),
                  "sac": ("SAC", "sac-plain")}
# the JAX learner's runs, evaluated by themselves (128 standard vehicles in JAX): label, command, machine
JAX_RUNS = (("PPO end to end in JAX", "rventry train jax-ppo --config rventry_agents/baselines/jax_ppo.toml --out "
             "runs/baseline_jax_ppo --max-wall-s 2400", "rejax on the functional env, two shared CPU cores; not shipped"),
            ("PPO end to end in JAX on a GPU", "rventry train jax-ppo --config rventry_agents/baselines/jax_ppo_gpu.toml "
             "--out runs/jax_ppo_gpu --max-wall-s 150", "one NVIDIA H200; not shipped"))  # fmt: skip


def _steps(n: float) -> str:
    return f"{n / 1e6:.0f}M" if n >= 1e7 else f"{n / 1e6:.1f}M"


def baselines_table(doc: dict, jax_cpu: list, jax_gpu: list) -> str:
    """The plain-RL baselines held out (``studies/baselines.py``), and the JAX learner's runs by their own evaluation."""
    rows = []
    for run in doc["runs"].values():
        name, agent = BASELINE_NAMES.get(run["algorithm"], (run["algorithm"], None))
        t, st, wd, nom = run["training"], run["standard"], run["wide"], run["nominal"]
        command = re.sub(r"^\S*rventry ", "rventry ", t["command"]).replace(" --no-progress", "")
        label = f"{name} (`{command}`" + (f"; shipped as `{agent}`)" if agent else ")")
        miss = st["percentiles"]["miss_km"]
        rows.append([label, _steps(t["timesteps"]), f"{t['wall_time_s']:,.0f} s", f"**{st['success_rate']:.2f}**",
                     f"**{wd['success_rate']:.2f}**", f"{sig(miss['p50'])} / {sig(miss['p95'])} km",
                     f"{sig(st['percentiles']['vertical_error_deg']['p50'])} deg", f"{1 - st['constraint_violation_rate']:.2f}",
                     f"{sig(nom['miss_km'])} km", sig(nom["cost_ratio"])])  # fmt: skip
    missing = "not evaluated"
    for (label, command, where), evals in zip(JAX_RUNS, (jax_cpu, jax_gpu)):
        last = evals[-1]
        best = min(evals, key=lambda e: e["miss_km_p50"])
        km = lambda v: f"{v:,.0f}" if v >= 1e3 else sig(v)  # noqa: E731
        miss = f"{km(last['miss_km_p50'])} km median at the end" + (
            f"; best {km(best['miss_km_p50'])} km at {_steps(best['timesteps'])} steps" if best is not last else "")
        first = evals[0]
        speed = (last["timesteps"] - first["timesteps"]) / (last["wall_s"] - first["wall_s"])  # past the compiling chunk
        rows.append([f"{label} (`{command}`; {where})", _steps(last["timesteps"]),
                     f"{last['wall_s']:,.0f} s ({sig(speed / 1e6, 2)}M env-steps/s after the first chunk)" if speed >= 1e6
                     else f"{last['wall_s']:,.0f} s ({speed:,.0f} env-steps/s after the first chunk)",
                     f"{last['success_rate']:.2f} (its own evaluation: 128 standard vehicles in JAX)", missing,
                     miss + " (its own evaluation)", missing, missing, missing, missing])  # fmt: skip
    header = ["baseline (config in `rventry_agents/baselines/`)", "steps", "wall", "standard success", "wide success",
              "miss p50 / p95, standard", "vertical error p50, standard", "no path violation, standard", "nominal miss",
              "nominal J/J*"]  # fmt: skip
    text = (f"Held out: the nominal flight and {doc['episodes']} standard and {doc['episodes']} wide episodes from seed "
            f"{doc['seed']}, flown by each run's selected model.")
    return "\n".join([md(header, rows), "", text, "", source(BASELINES, *JAX_BASELINES,
                      command=(doc.get("provenance") or {}).get("command"))])  # fmt: skip

# ------------------------------------------------------------------ timings
# A timing belongs to its machine: each table below says which one ran it, from the record's provenance.
ENV_SPEED = "docs/results/env_speed.json"
REFERENCE_SOLVE = "docs/results/reference_solve.json"
DECISION_COST = "docs/results/decision_cost.json"


def _omp(doc: dict) -> str | None:
    """OMP_NUM_THREADS as the run had it (the provenance's; a record before it held it: the record's own)."""
    machine = (doc.get("provenance") or {}).get("machine") or {}
    return machine["omp_num_threads"] if "omp_num_threads" in machine else doc.get("omp_num_threads")


def _timed_command(doc: dict) -> str | None:
    """The command that wrote a timing record, with OMP_NUM_THREADS in front where the run had it set."""
    command = doc.get("command") or (doc.get("provenance") or {}).get("command")
    omp = _omp(doc)
    if command and omp is not None and "OMP_NUM_THREADS=" not in command:
        command = f"OMP_NUM_THREADS={omp} {command}"
    return command


def machine_note(doc: dict, packages: tuple[str, ...]) -> str:
    """Where and when a timing was measured: the CPU, the cores, the threads, the load, the versions."""
    p = doc.get("provenance") or {}
    if not p:
        return f"The record names no machine (OMP_NUM_THREADS={_omp(doc) or 'unset'})."
    m, v = p.get("machine") or {}, p.get("versions") or {}
    cores = m.get("cores")
    if m.get("cores_usable") not in (None, cores):
        cores = f"{m['cores_usable']} of {cores}"
    s, e = m.get("load_average_start"), m.get("load_average_end")
    load = f"load average {s[0]:.2f} at the start and {e[0]:.2f} at the end" if s and e else "load average not recorded"
    omp = _omp(doc)
    when = (p.get("started_utc") or "")[:10] or "date not recorded"
    wall = f", {p['wall_time_s']:,.0f} s in all" if p.get("wall_time_s") is not None else ""
    versions = ", ".join(f"{name} {v[name]}" for name in ("python", *packages) if v.get(name))
    c = p.get("commit") or {}
    at = f" at commit {c['sha'][:7]}" + (" with uncommitted changes" if c.get("dirty") else "") if c.get("sha") else ""
    return (f"Measured {when}{at} on {m.get('cpu', 'an unrecorded CPU')}, {cores} cores, "
            f"OMP_NUM_THREADS={'unset' if omp is None else omp}, {load}{wall}; {versions}.")  # fmt: skip


def env_speed_table(doc: dict) -> str:
    """``benchmarks/env_speed.py``: the single env's steps/s and the vector env's against a ``SyncVectorEnv``."""
    single = doc["single_env_steps_per_s"]
    rows = [["single env through `gym.make` (with Gymnasium's wrappers)", f"{single:,.0f} steps", "", "",
             f">= 1e4: {_met(single >= 1e4)}"]]
    for r in doc["vector"]:
        n, vec = r["num_envs"], r["vector_vehicle_steps_per_s"]
        rows.append([f"vector env, N = {n}", f"{vec:,.0f} vehicle-steps", f"{r['sync_vehicle_steps_per_s']:,.0f}",
                     f"{sig(r['speedup'], 2)}x", f">= 1e6: {_met(vec >= 1e6)}" if n == 8192 else ""])  # fmt: skip
    header = ["", "per second", f"a `SyncVectorEnv` of N single envs", "vector / sync", "target"]
    scale = doc.get("scale", 1.0)
    steps = "" if scale == 1 else f" Steps timed: {scale * 100:g} % of the default's (noisier figures)."
    return "\n".join([md(header, rows), "", machine_note(doc, ("numpy", "gymnasium")) + steps, "",
                      source(ENV_SPEED, command=_timed_command(doc))])


def _passes(r: dict) -> str:
    return ", ".join(f"{it} ({n})" for it, n in zip(r["iterations_per_pass"], r["nodes_per_pass"]))


def _optimum_found(runs: list, shipped: dict) -> str:
    """Whether each cold solve found the shipped optimum (J* to 1e-4 relative and t_f to 0.1 s, as
    ``tests/reference/test_reference_cold_solve.py`` asks) or another local optimum."""
    found = [abs(r["cost"] - shipped["cost"]) <= 1e-4 * shipped["cost"] and abs(r["tf_s"] - shipped["tf_s"]) <= 0.1
             for r in runs]  # fmt: skip
    if all(found):
        return f"Every cold solve found the shipped optimum (J* = {shipped['cost']:.6f}, t_f = {shipped['tf_s']:.3f} s)."
    missed = ", ".join(f"run {i} (J = {r['cost']:.6f}, t_f = {r['tf_s']:.1f} s)" for i, (r, ok) in
                       enumerate(zip(runs, found)) if not ok)  # fmt: skip
    return (f"**Not the shipped optimum** (J* = {shipped['cost']:.6f}, t_f = {shipped['tf_s']:.3f} s): {missed} converged "
            f"on a local optimum of higher cost.")


def reference_solve_table(doc: dict, shipped: dict) -> str:
    """``benchmarks/reference_solve.py``: each cold-start solve of the entry problem, in a fresh process, and
    whether it found the shipped optimum."""
    runs = doc["entry"]
    wall = statistics.median(r["wall_s"] for r in runs)
    first = _passes(runs[0])
    rows = [["wall time (guess + all mesh passes)", *(f"{r['wall_s']:.1f} s" for r in runs),
             f"median {wall:.1f} s < 30 s: {_met(wall < 30)}"],
            ["CPU time of the process", *(f"{r['cpu_s']:.1f} s" for r in runs), ""],
            ["of which the guess", *(f"{r['guess_s']:.1f} s" for r in runs), ""],
            ["module imports (not included above)", *(f"{r['import_s']:.1f} s" for r in runs), ""],
            ["IPOPT iterations per pass (nodes)", *(_passes(r) if i == 0 or _passes(r) != first else "same"
                                                    for i, r in enumerate(runs)), ""],
            ["peak resident memory (whole process)", *(f"{r['rss_peak_mb']:.0f} MB" for r in runs), ""],
            ["J*, t_f, final mesh error", *(f"{r['cost']:.6f}, {r['tf_s']:.3f} s, {sci(r['mesh_error'], 2)}" for r in runs),
             ""]]  # fmt: skip
    header = ["", *(f"run {i}" for i in range(len(runs))), "target"]
    return "\n".join([md(header, rows), "", _optimum_found(runs, shipped), "", machine_note(doc, ("casadi", "numpy", "scipy")),
                      "", source(REFERENCE_SOLVE, SHIPPED_REFERENCE, command=_timed_command(doc))])


def reference_solve_summary(doc: dict, shipped: dict) -> str:
    """The benchmark page's lines of ``benchmarks/reference_solve.py``: the cold-start solve's wall time, memory and
    optimum, and the shipped optimum replayed open loop."""
    runs, replay = doc["entry"], doc["replay"]
    wall = statistics.median(r["wall_s"] for r in runs)
    err = replay["position_error_at_impact_m"]
    rows = [["cold-start solve, wall (each run in a fresh process)", ", ".join(f"{r['wall_s']:.1f} s" for r in runs),
             f"median < 30 s: {_met(wall < 30)}"],
            ["CPU time of the process", ", ".join(f"{r['cpu_s']:.1f} s" for r in runs), ""],
            ["peak memory (whole process)", ", ".join(f"{r['rss_peak_mb']:.0f} MB" for r in runs), ""],
            ["J found by the cold solve", ", ".join(f"{r['cost']:.6f}" for r in runs), f"J* = {shipped['cost']:.6f}"],
            [(f"the shipped optimum's controls replayed open loop through `entry_rhs`, {replay['method']} rtol "
              f"{replay['rtol']:g}: position error at impact"), f"{sig(err, 2)} m", f"<= 100 m: {_met(err <= 100)}"]]  # fmt: skip
    return "\n".join([md(["quantity", "measured", "target"], rows), "", _optimum_found(runs, shipped), "",
                      machine_note(doc, ("casadi",)), "", source(REFERENCE_SOLVE, SHIPPED_REFERENCE, command=_timed_command(doc))])


def _betts_case(case: str) -> str:
    """``no_heating_limit`` -> "no heating limit"; ``heating_limit_70`` -> "q <= 70 BTU/ft^2/s"."""
    if case.startswith("heating_limit_"):
        return f"q <= {case.removeprefix('heating_limit_')} BTU/ft^2/s"
    return case.replace("_", " ")


def betts_table(doc: dict) -> str:
    """``benchmarks/reference_solve.py``: Betts' Space Shuttle maximum crossrange against the published optimum."""
    rows = []
    for b in doc["betts"]:
        p = b["published"]
        rows.append([_betts_case(b["case"]), f"{b['tf_s']:.3f} s ({p['tf_s']:g})", sci(b["tf_rel_error"], 0),
                     f"{b['latitude_deg']:.5f} deg ({p['latitude_deg']:g})", sci(b["latitude_rel_error"], 0),
                     sci(b["mesh_error"], 1), str(b["n_nodes"]), f"{b['wall_s']:.1f} s"])  # fmt: skip
    header = ["case", "tf (published)", "rel. error", "final latitude (published)", "rel. error", "mesh error", "nodes",
              "wall"]  # fmt: skip
    worst = max(max(b["tf_rel_error"], b["latitude_rel_error"]) for b in doc["betts"])
    verdict = f"Largest relative error {sci(worst, 0)} against the target's 1e-3: {_met(worst <= 1e-3)}."
    return "\n".join([md(header, rows), "", verdict, "", machine_note(doc, ("casadi",)), "",
                      source(REFERENCE_SOLVE, command=_timed_command(doc))])


# the laws of benchmarks/decision_cost.py: what each is, and the targets of a learned policy per vehicle in a
# batch of TARGET_BATCH (at most 1 ms and at least 1000x cheaper than mpc; one trained by PPO: at most 10 us)
TARGET_BATCH = 1024
DECISION_LAWS = {
    "ppo": ("PPO's weights on `dagger-flight`'s network, estimator and relief, with its q floor; in torch", "10 us", 10e-6),
    "dagger-flight": ("the flight-set student: one network, its estimator and its load relief", "1 ms", 1e-3),
    "dagger": ("one network, its estimator and its load relief", "1 ms", 1e-3),
    "ppo-residual": ("the PPO residual with its TV-LQR", "10 us", 10e-6),
    "ppo-scratch-flight": ("PPO from scratch: one 64x64 network; in NumPy", "10 us", 10e-6),
}  # fmt: skip


def _decision_law(name: str, doc: dict) -> tuple[str, str | None, float | None]:
    """A law's label, and its target per vehicle in a batch (text and seconds; None: no target)."""
    shown = doc.get("learned") if name == "learned" else None  # `learned` names a shipped policy: the record says which
    what, target, limit = DECISION_LAWS.get(shown or name, (None, None, None))
    label = f"`{name}`" + (f" (`{shown}`" + (f": {what})" if what else ")") if shown else f" ({what})" if what else "")
    return label, target, limit


def _duration(s: float) -> str:
    """A time per decision: us below 1 ms, ms from 1 ms, s from 1 s (3 significant figures, at most one decimal)."""
    if s >= 1:
        return f"{s:.1f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.1f} ms" if s < 0.1 else f"{s * 1e3:.0f} ms"
    return f"{s * 1e6:.1f} us" if s < 1e-4 else f"{s * 1e6:.0f} us"


def _per_decision(r: dict) -> str:
    return (f"{_duration(r['per_decision_mean_s'])} ({_duration(r['per_decision_p50_s'])} / "
            f"{_duration(r['per_decision_p99_s'])})")


def decision_cost_table(doc: dict) -> str:
    """``benchmarks/decision_cost.py``: the time per decision of each law, one vehicle and batched, against ``mpc``."""
    laws, batch = doc["laws"], doc["batch"]
    mpc = laws.get("mpc", {}).get("single", {}).get("per_decision_mean_s")
    rows = []
    for name, r in laws.items():
        label, target_text, limit = _decision_law(name, doc)
        batched = r.get("batched")
        if batched:
            cost = batched["per_decision_mean_s"]
            ratio = f"{mpc / cost:,.0f}x" if mpc else "-"
            cells = [_per_decision(batched), ratio]
        else:  # mpc: one NLP per vehicle, so a batch costs B times one vehicle
            cells = ["one NLP per vehicle: the same per vehicle", "1x" if name == "mpc" else "-"]
        target = ""
        if limit is not None and batched:
            ok = cost <= limit and mpc is not None and mpc / cost >= 1000
            target = f"<= {target_text}, >= 1,000x: " + (
                f"set for a batch of {TARGET_BATCH}" if batch != TARGET_BATCH else _met(ok) if mpc else "no `mpc` in the run")
        rows.append([label, _per_decision(r["single"]), *cells, target])
    header = ["law", "one vehicle: mean (median / p99 call)", f"batch of {batch}: mean per vehicle (median / p99 call)",
              "`mpc` / this, batched", "target"]  # fmt: skip
    n = {name: r["single"]["episodes"] for name, r in laws.items()}
    each = max(v for k, v in n.items() if k != "mpc") if set(n) - {"mpc"} else n["mpc"]
    flown = (f"Standard set from seed {doc['seed']}: one vehicle at a time {each} episode{'s' if each > 1 else ''} per "
             "law" + (f" ({n['mpc']} of `mpc`)" if "mpc" in n else "") +
             f", and {batch} in one batch; re-solves included in the mean.")  # fmt: skip
    return "\n".join([md(header, rows), "", flown + " " + machine_note(doc, ("numpy", "torch", "casadi")), "",
                      source(DECISION_COST, command=_timed_command(doc))])


RHS_FORMS = "docs/results/rhs_forms.json"
RHS_LABELS = {"rv-Euler": "rv-Euler two-body", "spherical": "spherical two-body", "Cartesian": "Cartesian two-body",
              "entry (rv-Euler)": "entry dynamics (`entry_rhs`, 12 states)"}  # fmt: skip


def _batch_label(b: str) -> str:
    """A batch column: "scalar", or B=10, B=1e3 from 1000 on."""
    if b == "scalar":
        return "scalar"
    n = int(b)
    return f"B={n}" if n < 1000 else f"B=1e{round(math.log10(n))}" if 10 ** round(math.log10(n)) == n else f"B={n:,}"


def rhs_throughput_table(doc: dict) -> str:
    """``benchmarks/rhs_forms.py``: states per second of each right-hand side, one state and NumPy batches."""
    rates = doc["throughput_states_per_s"]
    cols = list(next(iter(rates.values())))
    rows = [[RHS_LABELS.get(name, name), *(sci(r[c], 2) for c in cols)] for name, r in rates.items()]
    header = ["form", *(_batch_label(c) for c in cols)]
    table = md(header, rows).replace("|---|" + "---|" * len(cols), "|---|" + "---:|" * len(cols), 1)
    rv, sph = rates["rv-Euler"], rates["spherical"]
    big = [c for c in cols if c != "scalar" and int(c) >= 10_000]
    ratios = (f"rv-Euler / spherical: {', '.join(f'{rv[c] / sph[c]:.1f}x at {_batch_label(c)}' for c in big)}; "
              f"spherical / rv-Euler for one state in Python floats: {sph['scalar'] / rv['scalar']:.1f}x.")  # fmt: skip
    return "\n".join([table, "", ratios, "", machine_note(doc, ("numpy",)), "",
                      source(RHS_FORMS, command=_timed_command(doc))])


def _pair(built: dict, cse: dict | None, key: str, bold: bool = False) -> str:
    """A count as built / after CSE (one figure where they agree), in bold where asked."""
    a, b = built[key], (cse or built)[key]
    text = f"{a}" if a == b else f"{a} / {b}"
    return f"**{text}**" if bold else text


def rhs_op_count_table(doc: dict) -> str:
    """``benchmarks/rhs_forms.py --cse``: CasADi SX instructions per evaluation of each form, as built / after CSE."""
    built, cse = doc["op_counts"]["as built"], doc["op_counts"].get("with CSE")
    rows = []
    for name, c in built.items():
        e = (cse or {}).get(name)
        two_body = name in ("rv-Euler", "spherical")  # the paper's comparison: its arithmetic and trig in bold
        rows.append([RHS_LABELS.get(name, name).split(" (")[0], *(_pair(c, e, k) for k in ("add/sub", "mul", "div", "neg")),
                     _pair(c, e, "arithmetic", two_body), _pair(c, e, "sqrt"), _pair(c, e, "trig", two_body),
                     _pair(c, e, "exp/log/pow"), _pair(c, e, "weighted")])  # fmt: skip
    header = ["form", "add/sub", "mul", "div", "neg", "arithmetic", "sqrt", "trig", "exp", "14-flop-sin total"]
    table = md(header, rows).replace("|---|" + "---|" * 9, "|---|" + "---:|" * 9, 1)
    other = sorted({c["other"] for c in built.values() if c.get("other")})
    note = f"Instructions of no class counted: {'; '.join(other)}." if other else "Every instruction falls in a column."
    return "\n".join([table, "", note, "", source(RHS_FORMS, command=_timed_command(doc))])


# tables of timings: measured on a quiet machine, each by one command (docs/results/README.md)
SPHERICAL = "docs/results/spherical_singularity.json"


def _spherical_cell(r: dict | None, rv: dict | None) -> str:
    """One spherical-coordinate solve: its optimum beside rv-Euler's at the same angle, or how it failed."""
    if r is None:
        return "not run"
    iters = r.get("nlp_iterations") or []
    if not r.get("converged"):
        psi = r.get("max_abs_psi_rate_deg_s")
        return (f"**fails**: {r['status']}, mesh error {sci(r['mesh_error'], 1)} after {r.get('passes', 0)} passes "
                f"(IPOPT {', '.join(map(str, iters))} iterations)" + (f", |dpsi/dt| up to {sig(psi, 2)} deg/s" if psi else "")
                + (f"; J ends at {r['cost']:.3f}" if r.get("finite") and r.get("cost") is not None else ""))  # fmt: skip
    text = f"{r['cost']:.6f}, tf {r['tf_s']:.0f} s, mesh error {sci(r['mesh_error'], 1)}"
    if rv is not None and rv.get("cost"):
        text += f" ({(r['cost'] - rv['cost']) / rv['cost']:+.1%} against rv-Euler)"
    return text


def spherical_table(doc: dict) -> str:
    """``studies/spherical_singularity.py``: the entry problem in spherical coordinates, whose azimuth equation
    divides by cos(gamma), beside rv-Euler at the same terminal flight-path angle."""
    rv = {r["final_gamma_deg"]: r for r in doc["rv_euler"]}
    sph = {(r["guess"], r["final_gamma_deg"]): r for r in doc["spherical"]}
    rows = []
    for g in sorted({r["final_gamma_deg"] for r in doc["spherical"]} | set(rv)):
        r = rv.get(g)
        if r is None:
            first = "not run"
        elif r["status"] == "shipped":
            first = f"**{r['cost']:.6f}**, mesh error {sci(r['mesh_error'], 1)} (the shipped optimum)"
        else:
            first = f"{r['cost']:.6f}, tf {r['tf_s']:.0f} s, mesh error {sci(r['mesh_error'], 1)}"
        rows.append(["-90 (exact)" if g <= -90 else f"{g:g}", first,
                     *(_spherical_cell(sph.get((guess, g)), r) for guess in ("reference", "simulated"))])  # fmt: skip
    header = ["gamma(tf), deg", "rv-Euler J", "spherical, guess = rv-Euler optimum converted",
              "spherical, cold guess (the one rv-Euler uses)"]  # fmt: skip
    return "\n".join([md(header, rows), "", machine_note(doc, ("casadi", "numpy")), "",
                      source(SPHERICAL, command=_timed_command(doc))])


FORMULATIONS = "docs/results/formulations.json"
FORMULATION_LABELS = {"projection": "projection (shipped)", "paper": "paper (u1..u4, delta = {delta} band)",
                      "none": "none (Eq. Ex2-endpoint verbatim)"}  # fmt: skip
FORMULATION_GUESSES = {"cold": "generated (cold)", "optimum": "the shipped optimum"}
REPLAY_TARGET_M = 100.0  # the open-loop replay error at impact the shipped optimum is held to


def _distance(m: float) -> str:
    return f"{sig(m / 1e3, 2)} km" if m >= 1e3 else f"{sig(m, 2)} m"


def _formulation_row(r: dict, delta: float, star: float) -> list[str]:
    """One solve of ``studies/formulations.py``: its first pass and what it found, or how it failed."""
    first = r.get("first_pass")
    if first is None:
        passes = "-"
    else:
        passes = f"{first['nlp_iterations']} iterations, {first['wall_s']:.1f} s"
        passes += "" if first["status"] == "Solve_Succeeded" else f", `{first['status']}`"
    guess = FORMULATION_GUESSES.get(r["guess"], r["guess"])
    if len(r.get("stages") or ()) > 1:  # the exact problem failed from the guess: solved through a relaxed one
        guess += ", through the relaxed-angle continuation"
    head = [FORMULATION_LABELS.get(r["norm_mode"], r["norm_mode"]).format(delta=sci(delta, 0)), guess, passes]
    if not r["converged"]:
        why = f"**fails**: `{r['status']}`"
        if r.get("mesh_error") is not None:
            n = len(r["iterations_per_pass"])
            why += f", mesh error {sci(r['mesh_error'], 1)} after {n} pass{'es' if n > 1 else ''}"
        return head + [why, "-", "-", "-"]
    rel = (r["cost"] - star) / star
    cost = f"{r['cost']:.6f}" + (f" ({rel:+.2%})" if abs(rel) >= 1e-4 else " (J*)")
    replay = r.get("replay") or {}
    err = replay.get("position_error_at_impact_m")
    if err is None:
        where = f"not replayed: {replay.get('error', 'no replay recorded')}"
    else:
        where = f"**{_distance(err)}**" if err > REPLAY_TARGET_M else _distance(err)
    drift = sci(r["norm_drift_nodes"], 1) if r.get("norm_drift_nodes") is not None else "-"
    return head + [cost, f"{r['tf_s']:.2f} s", drift, where]


def formulation_table(doc: dict) -> str:
    """``studies/formulations.py``: Example 2 in each norm-keeping formulation, from the generated guess and from
    the shipped optimum, each solve in a fresh process."""
    star = doc["shipped"]["cost"]
    rows = [_formulation_row(r, doc["delta"], star) for r in doc["solves"]]
    header = ["formulation", "guess", "first pass", "J", "tf", "norm drift at nodes", "replay error at impact"]
    rtol = next((r["replay"]["rtol"] for r in doc["solves"] if r.get("replay")), None)
    notes = (f"J against the shipped optimum's J* = {star:.6f} (tf = {doc['shipped']['tf_s']:.2f} s), (J*) where it is "
             "within 1e-4 of it. First pass: IPOPT's iterations and the wall time of the first mesh pass "
             "(transcription, IPOPT, error estimate), with IPOPT's status where it is not `Solve_Succeeded`. Norm "
             "drift: the largest distance of |q_A| or |q_B| from 1 at the nodes.")  # fmt: skip
    if rtol is not None:
        notes += (f" Replay: the solution's (u_alpha, u_sigma) through `entry_rhs`, open loop (DOP853, rtol {rtol:g}), "
                  f"position error at impact; in bold beyond the {REPLAY_TARGET_M:g} m the shipped optimum is held to.")
    return "\n".join([md(header, rows), "", notes, "", machine_note(doc, ("casadi", "numpy", "scipy")), "",
                      source(FORMULATIONS, command=_timed_command(doc))])


TIMINGS: tuple[Table, ...] = (
    Table("env-speed", (ENV_SPEED,), env_speed_table, ("docs/benchmarks/environment.md",)),
    Table("reference-solve", (REFERENCE_SOLVE, SHIPPED_REFERENCE), reference_solve_table, ("docs/reference.md",)),
    Table("reference-solve-summary", (REFERENCE_SOLVE, SHIPPED_REFERENCE), reference_solve_summary,
          ("docs/benchmarks/collocation.md",)),
    Table("reference-betts", (REFERENCE_SOLVE,), betts_table, ("docs/reference.md",)),
    Table("decision-cost", (DECISION_COST,), decision_cost_table, ("docs/benchmarks/learned_policies.md",)),
    Table("rhs-throughput", (RHS_FORMS,), rhs_throughput_table, ("docs/core.md",)),
)  # fmt: skip


# ------------------------------------------------------------------ the registry
EXPLAINED_SCANS = ("aero", "final", "estimator", "split", "dive")  # also shown where the design page explains them
README = "README.md"
TABLES: tuple[Table, ...] = (
    Table("compare-standard", ("docs/results/compare_standard.json",), compare_headline, (README,)),
    Table("compare-standard-full", ("docs/results/compare_standard.json",), compare_tables,
          ("docs/benchmarks/guidance.md",)),
    Table("orbit", ORBIT_RECORDS, orbit_table, ("docs/benchmarks/rv_euler.md",)),
    Table("orbit-sweep", ORBIT_RECORDS[:1], orbit_sweep_table, ("docs/core.md",)),
    Table("reference-solution", (SHIPPED_REFERENCE,), reference_table, ("docs/benchmarks/collocation.md",)),
    Table("reference-show", (SHIPPED_REFERENCE,), reference_show_table, ("docs/reference.md",)),
    Table("mpc-benchmark", ("docs/results/bench_mpc_eval.json",), mpc_benchmark, ("docs/benchmarks/guidance.md",)),
    *(Table(f"set-{d}", _set_records(d), set_table(d), ("docs/benchmarks/flight_grade.md",))
      for d in ("flight", "peer", "peer-0.1")),
    Table("navigation-mpc-flight", ("docs/results/nav_mpc_flight200.json",), navigation_tables,
          ("docs/benchmarks/flight_grade.md",)),
    Table("seeds-ppo", ("docs/results/bench_seeds_ppo.json",), seeds_table, ("docs/benchmarks/learned_policies.md",)),
    Table("ppo-heldout", PPO_RECORDS, ppo_table, ("docs/benchmarks/learned_policies.md",)),
    Table("scan-defaults", (SCAN_DEFAULTS,), scan_defaults_table, ("docs/benchmarks/guidance.md",)),
    *(Table(f"scan-{name}", (f"docs/results/scan_mpc_{name}.json",), scan_table(f"docs/results/scan_mpc_{name}.json"),
            ("docs/benchmarks/guidance.md", *(("docs/guidance.md",) if name in EXPLAINED_SCANS else ())))
      for name in ("flight", "aero", "final", "estimator", "split", "dive", "track", "floor")),
    Table("effects-flight", effects_records(), effects_table, ("docs/benchmarks/flight_grade.md",)),
    Table("footprint", footprint_records(), footprint_table, ("docs/benchmarks/flight_grade.md",)),
    Table("terminal-alpha", ("docs/results/terminal_alpha_standard.json", "docs/results/terminal_alpha_nominal.json"),
          terminal_alpha_tables, ("docs/benchmarks/guidance.md",)),
    Table("jax-cpu", ("docs/results/bench_jax_cpu.json", "docs/results/bench_jax_ppo_cpu.json"), jax_cpu_table,
          ("docs/benchmarks/jax.md",)),
    Table("scratch-scan", ("docs/results/bench_scratch_scan.json",), scratch_scan_table, ("docs/benchmarks/jax.md",)),
    Table("jax-gpu", ("docs/results/bench_jax_h200.json", "docs/results/bench_jax_h100.json",
                      "docs/results/bench_jax_h100_kernels.json"), jax_gpu_table, ("docs/benchmarks/jax.md",)),
    Table("rounds-dagger", ("rventry_agents/data/dagger/rounds.json",), rounds_table("rventry_agents/data/dagger/rounds.json"),
          ("docs/benchmarks/learned_policies.md",)),
    Table("rounds-dagger-flight", ("rventry_agents/data/dagger_flight/rounds.json",),
          rounds_table("rventry_agents/data/dagger_flight/rounds.json"), ("docs/benchmarks/learned_policies.md",)),
    Table("ladder", ("docs/results/ladder.json",), ladder_table, ("docs/benchmarks/learned_policies.md",)),
    Table("scratch-vs-imitation", scratch_vs_records(), scratch_vs_imitation_table,
          ("docs/benchmarks/learned_policies.md",)),
    Table("ladder-summary", ("docs/results/ladder.json",), ladder_summary, (README,)),
    Table("scratch-runs", ("docs/results/scratch_runs.json",), scratch_runs_table, ("docs/design-log/index.md",)),
    *(Table(name, paths, identify_table(paths), ("docs/benchmarks/identification.md",))
      for name, paths in IDENTIFY_TABLES.items()),
    Table("observation-bounds", (OBSERVATION_BOUNDS,), observation_bounds_table, ("docs/benchmarks/environment.md",)),
    Table("dagger-heldout", (*DAGGER_HELDOUT, COMPARE), dagger_heldout_table,
          ("docs/benchmarks/learned_policies.md", "docs/learned.md")),
    Table("dagger-flight-heldout", dagger_flight_records(), dagger_flight_heldout_table,
          ("docs/benchmarks/learned_policies.md",)),
    Table("apollo4", (APOLLO4,), apollo4_table, ("docs/benchmarks/identification.md", "docs/validation.md")),
    Table("env-accuracy", (ENV_ACCURACY,), env_accuracy_table, ("docs/benchmarks/environment.md", "docs/env.md")),
    Table("env-reference-dt", (ENV_ACCURACY,), reference_dt_table, ("docs/env.md",)),
    Table("random-actions", (RANDOM_ACTIONS,), random_actions_table, ("docs/benchmarks/environment.md",)),
    Table("baselines", (BASELINES, *JAX_BASELINES), baselines_table, ("docs/benchmarks/learned_policies.md",)),
    Table("rhs-op-counts", (RHS_FORMS,), rhs_op_count_table, ("docs/core.md",)),
    Table("spherical-singularity", (SPHERICAL,), spherical_table, ("docs/reference.md",)),
    Table("reference-formulations", (FORMULATIONS,), formulation_table, ("docs/reference.md",)),
    *TIMINGS,
)  # fmt: skip


def rendered(table: Table) -> str:
    return table.render(*(load(p) for p in table.records)).rstrip("\n")


def regions(text: str) -> dict[str, str]:
    """Each marked region's name -> its content (between the markers, without them)."""
    out = {}
    for m in START.finditer(text):
        end = text.find(END, m.end())
        if end < 0:
            raise ValueError(f"table {m.group(1)!r}: no '{END}' after its start")
        out[m.group(1)] = text[m.end():end].strip("\n")
    return out


def replace_region(text: str, name: str, body: str) -> str:
    m = re.search(rf"^<!-- table: {re.escape(name)} -->$", text, re.M)
    end = text.find(END, m.end())
    return text[: m.end()] + "\n" + body + "\n" + text[end:]


def problems() -> list[str]:
    """What differs between the files and their records (empty: all in agreement)."""
    out = []
    known = {t.name for t in TABLES}
    shown: dict[str, list[str]] = {}
    for t in TABLES:
        missing = [p for p in t.records if not (ROOT / p).is_file()]
        if missing:
            out.append(f"table {t.name!r}: no record {', '.join(missing)}")
            for f in t.files:
                shown.setdefault(f, []).append(t.name)
            continue
        body = rendered(t)
        for f in t.files:
            found = regions((ROOT / f).read_text()) if (ROOT / f).exists() else {}
            shown.setdefault(f, []).append(t.name)
            if t.name not in found:
                out.append(f"{f}: no region for table {t.name!r}")
            elif found[t.name] != body:
                out.append(f"{f}: table {t.name!r} differs from its records {', '.join(t.records)}")
    for f in markdown_files():
        for name in regions(f.read_text()):
            rel = str(f.relative_to(ROOT))
            if name not in known:
                out.append(f"{rel}: region {name!r} is no table of the registry")
            elif rel not in shown or name not in shown[rel]:
                out.append(f"{rel}: region {name!r} is not listed among its table's files")
    return out


def markdown_files() -> list[Path]:
    return [ROOT / README, *sorted((ROOT / "docs").rglob("*.md"))]


def write_all() -> list[str]:
    """Rewrite every region from its records; return the files changed."""
    changed = []
    for f in dict.fromkeys(f for t in TABLES for f in t.files):
        path = ROOT / f
        text = old = path.read_text()
        for t in TABLES:
            if f in t.files and all((ROOT / p).is_file() for p in t.records):  # a missing record: --check names it
                text = replace_region(text, t.name, rendered(t))
        if text != old:
            path.write_text(text)
            changed.append(f)
    return changed


def record_compare(report: Path, dest: Path) -> None:
    """Store a ``rventry compare`` report as a record: every figure, less the per-episode lists."""
    doc = json.loads(Path(report).read_text())
    for run in doc["runs"].values():
        run.pop("episodes", None)
    Path(dest).write_text(json.dumps(doc, indent=1) + "\n")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--check", action="store_true", help="change nothing; exit 1 naming each region out of date")
    p.add_argument("--record-compare", nargs=2, metavar=("REPORT", "RECORD"),
                   help="store a rventry compare report as a record (without its per-episode lists)")
    args = p.parse_args(argv)
    if args.record_compare:
        record_compare(*map(Path, args.record_compare))
        return 0
    if args.check:
        found = problems()
        for line in found:
            print(line)
        return 1 if found else 0
    for f in write_all():
        print(f"wrote {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
