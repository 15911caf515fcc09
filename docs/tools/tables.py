"""Every results table of the README and the manual, generated from its JSON record.

A table is an entry of :data:`TABLES`: a name, the records it reads (paths from the repository
root: ``docs/results/``, ``rventry_agents/data/``), a renderer that turns them into Markdown, and
the Markdown files that show it. In those files the table sits between two markers::

    <!-- table: NAME -->
    ...generated...
    <!-- end table -->

``python docs/tools/tables.py`` rewrites every marked region from its records;
``python docs/tools/tables.py --check`` changes nothing and exits 1 naming each region that
differs from what its records give (``tests/test_docs.py`` runs the same check). To add a table:
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


def source(*paths: str, command: str | None = None) -> str:
    """The line under a table: its records, and the command that wrote them where one did."""
    text = "Records: " + ", ".join(f"`{p}`" for p in paths)
    return text + (f"; written by `{command}`." if command else ".")


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
        ("`learned` (`ppo`)", "docs/results/ppo_q_floor/ppo_flight.json", ("summary",)),
    ),
    "peer": (
        ("`reference`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "reference")),
        ("`lqr`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "lqr")),
        ("`lqr-est`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "lqr-est")),
        ("`dagger`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "learned")),
        ("`mpc`", "docs/results/bench_sets.json", ("sets", "peer", "laws", "mpc")),
        ("`mpc-flight`", "docs/results/bench_sets_mpc_flight.json", ("sets", "peer", "laws", "mpc-flight")),
        ("`mpc-peer`", "docs/results/mpc_peer_peer50.json", ("summary",)),
        ("`learned` (`ppo`)", "docs/results/ppo_q_floor/ppo_peer.json", ("summary",)),
    ),
    "peer-0.1": (
        ("`reference`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "reference")),
        ("`lqr`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "lqr")),
        ("`lqr-est`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "lqr-est")),
        ("`dagger`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "learned")),
        ("`mpc`", "docs/results/bench_sets.json", ("sets", "peer-0.1", "laws", "mpc")),
        ("`mpc-flight`", "docs/results/mpc_flight_peer-0.1_100.json", ("summary",)),
        ("`learned` (`ppo`)", "docs/results/ppo_q_floor/ppo_peer-0.1.json", ("summary",)),
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


OBSERVATION_BOUNDS = "docs/results/observation_bounds.json"


def observation_bounds_table(doc: dict) -> str:
    """Where flown observations lie against the observation Box: the steps the env clipped, per set and law."""
    import statistics

    rows = []
    for key, m in doc.items():
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
    command = ("nice -n 19 python scripts/bench_observation_bounds.py --sets flight standard --laws reference zero "
               "--episodes 1000 --json docs/results/observation_bounds.json")  # fmt: skip
    return "\n".join([md(header, rows), "", "Seeds 0-999 per set and law, vector env, the features before clipping; "
                      "`zero`: zero rates (alpha and bank held where they start).", "",
                      source(OBSERVATION_BOUNDS, command=command)])  # fmt: skip


# ------------------------------------------------------------------ the registry
README = "README.md"
TABLES: tuple[Table, ...] = (
    Table("compare-standard", ("docs/results/compare_standard.json",), compare_headline, (README,)),
    Table("compare-standard-full", ("docs/results/compare_standard.json",), compare_tables,
          ("docs/benchmarks/guidance.md",)),
    Table("mpc-benchmark", ("docs/results/bench_mpc_eval.json",), mpc_benchmark, ("docs/benchmarks/guidance.md",)),
    *(Table(f"set-{d}", _set_records(d), set_table(d), ("docs/benchmarks/flight_grade.md",))
      for d in ("flight", "peer", "peer-0.1")),
    Table("navigation-mpc-flight", ("docs/results/nav_mpc_flight200.json",), navigation_tables,
          ("docs/benchmarks/flight_grade.md",)),
    Table("seeds-ppo", ("docs/results/bench_seeds_ppo.json",), seeds_table, ("docs/benchmarks/learned_policies.md",)),
    *(Table(f"scan-{name}", (f"docs/results/scan_mpc_{name}.json",), scan_table(f"docs/results/scan_mpc_{name}.json"),
            ("docs/benchmarks/guidance.md",))
      for name in ("flight", "aero", "final", "estimator", "split", "dive", "track", "floor")),
    Table("rounds-dagger", ("rventry_agents/data/dagger/rounds.json",), rounds_table("rventry_agents/data/dagger/rounds.json"),
          ("docs/benchmarks/learned_policies.md",)),
    Table("rounds-dagger-flight", ("rventry_agents/data/dagger_flight/rounds.json",),
          rounds_table("rventry_agents/data/dagger_flight/rounds.json"), ("docs/benchmarks/learned_policies.md",)),
    Table("observation-bounds", (OBSERVATION_BOUNDS,), observation_bounds_table, ("docs/benchmarks/environment.md",)),
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
            if f in t.files:
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
