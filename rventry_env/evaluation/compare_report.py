"""What ``rventry compare`` prints, built from its JSON report alone.

The command prints these tables and sentences, and the manual's results tables are rendered
from a saved report by the same functions (``docs/tools/tables.py``), so the terminal and the README
report the same statistics: the benchmark's success with its 95 % interval, the precision
tier, the miss and the vertical-impact error as p50 / p95, the path-violation rate and the
mean J/J*. Each table is a header row and rows of strings; :func:`rich_table` and
:func:`markdown_table` lay them out.
"""

from __future__ import annotations

import math

# why a user would pick each compared law (or not): what it is for, in words; the figures come from the run.
# Keys are agent names; a law not listed (a saved policy given by path) is described by its name.
WHY = {
    "learned": "it is the learned policy built for flight-grade uncertainty, and keeps its teacher's margins (load "
               "relief, q floor), which cost nominal precision and cost",
    "ppo": "it is PPO fine-tuning of the flight-set student, flown with its q floor",
    "dagger-flight": "it flies mpc-flight's flight-grade margins at a network's cost per decision",
    "dagger": "it lands like mpc on the standard and wide sets, at a network's cost per decision",
    "ppo-plain": "it is what off-the-shelf RL learns from scratch on the raw reward: a baseline, not a law to fly",
    "lqr": "it is the cheapest feedback law, exact nominally, but it tracks a fixed reference and cannot re-plan",
    "lqr-est": "it is TV-LQR with the estimated aerodynamic scales fed forward: estimation alone",
    "mpc": "it re-plans the optimum from where the vehicle is every 30 s: the most precise law, at seconds of CPU "
           "per decision",
    "mpc-flight": "it is mpc with flight-grade estimation and margins",
    "reference": "it is the optimum flown open loop: the cost floor nominally, no feedback under dispersions",
}  # fmt: skip

# the terms the command prints (each has a glossary entry)
TERMS = ("success", "95 % CI", "precision", "miss", "vertical-impact error", "speed error", "alpha(t_f)", "J/J*",
         "peak load factor", "min dynamic pressure", "path violation", "p5 / p50 / p95", "load relief",
         "re-solve time", "nominal", "dispersion set")  # fmt: skip


def _f(v, fmt: str) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def _sig(v, digits: int = 3) -> str:
    """``v`` to ``digits`` significant figures, never in exponent form for the ranges printed here."""
    if v is None or not math.isfinite(v):
        return "-"
    if v == 0:
        return "0"
    decimals = max(0, digits - 1 - int(math.floor(math.log10(abs(v)))))
    return f"{v:.{decimals}f}"


def rate(v: float) -> str:
    """A rate over episodes: three decimals where the third is not 0 (0.995, 0.805), else two (1.00, 0.74)."""
    text = f"{v:.3f}"
    return text[:-1] if text.endswith("0") else text


def _pair(p: dict, key: str, digits: int = 3) -> str:
    q = p.get(key) or {}
    return f"{_sig(q.get('p50'), digits)} / {_sig(q.get('p95'), digits)}"


def runs(doc: dict, case: str) -> list[tuple[str, dict]]:
    """(agent name, run document) of ``case`` ("nominal" or "dispersed"), in the report's order."""
    out = []
    for key, run in doc["runs"].items():
        c, _, _label = key.partition("/")
        if c == case:
            out.append((display_name(run), run))
    return out


def display_name(run: dict) -> str:
    """The name a run is shown by: its agent's name (a saved policy by its file's stem)."""
    agent = str(run["agent"])
    if "/" in agent or agent.endswith((".zip", ".json")):
        from pathlib import PurePath

        return PurePath(agent).stem
    return agent


def nominal_table(doc: dict) -> tuple[list[str], list[list[str]]]:
    """One row per law: the nominal flight's ending."""
    header = ["law", "success", "miss\n(km)", "vertical\n(deg)", "|speed\nerror|\n(m/s)", "alpha\n(t_f)\n(deg)",
              "J/J*", "peak\nload\n(g)", "min q\n(kPa)"]  # fmt: skip
    rows = []
    for name, run in runs(doc, "nominal"):
        s = run["summary"]
        q = s.get("min_dynamic_pressure_pa")
        rows.append([name, "yes" if s["success_rate"] == 1.0 else "no", _sig(s["miss_km"]), _sig(s["vertical_error_deg"]),
                     _sig(s["abs_speed_error_mps"]), _sig(s["alpha_final_deg"]), _f(s["cost_ratio"], ".3f"),
                     _f(s["max_load_factor_g"], ".2f"), "-" if q is None else f"{q / 1e3:.2f}"])  # fmt: skip
    return header, rows


def dispersed_table(doc: dict) -> tuple[list[str], list[list[str]]]:
    """One row per law: the dispersed episodes against the benchmark's success definition."""
    header = ["law", "episodes", "success\n[95 % CI]", "preci-\nsion", "miss (km)\np50 / p95",
              "vertical (deg)\np50 / p95", "path\nviol.", "J/J*\nmean"]  # fmt: skip
    rows = []
    for name, run in runs(doc, "dispersed"):
        s = run["summary"]
        lo, hi = s["success_rate_ci"]
        p = s["percentiles"]
        rows.append([name, str(s["episodes"]), f"{rate(s['success_rate'])} [{lo:.2f}, {hi:.2f}]",
                     rate(s["precision_success_rate"]), _pair(p, "miss_km"), _pair(p, "vertical_error_deg"),
                     rate(s["constraint_violation_rate"]), _sig(s["cost_ratio"])])  # fmt: skip
    return header, rows


def ranking(doc: dict) -> list[tuple[str, dict]]:
    """The dispersed runs, best first by the benchmark's success: the lower end of the success
    interval (so ten episodes do not outrank two hundred that land as often), then the success rate,
    then the median miss."""

    def key(item):
        s = item[1]["summary"]
        miss = (s["percentiles"].get("miss_km") or {}).get("p50")
        return (-s["success_rate_ci"][0], -s["success_rate"], miss if miss is not None else math.inf)

    return sorted(runs(doc, "dispersed"), key=key)


def verdict(doc: dict) -> list[str]:
    """Sentences: which law is best on the set flown and why a user would pick it, and what the law
    shown first trades where it is not the best."""
    order = ranking(doc)
    if not order:
        return []
    dispersion = doc["dispersion_set"]
    best, run = order[0]
    s = run["summary"]
    lo, hi = s["success_rate_ci"]
    miss = (s["percentiles"].get("miss_km") or {}).get("p50")
    lines = [f"Best on the {dispersion} set: {best}, success {rate(s['success_rate'])} [{lo:.2f}, {hi:.2f}] of "
             f"{s['episodes']}, median miss {_sig(miss)} km. Why pick it: {_why(best)}."]  # fmt: skip
    close = [(n, r) for n, r in order[1:] if r["summary"]["success_rate_ci"][1] >= s["success_rate"]
             and r["summary"]["success_rate"] > 0]  # fmt: skip
    if close:
        lines.append("As good within the intervals: " + ", ".join(
            f"{n} ({rate(r['summary']['success_rate'])} of {r['summary']['episodes']})" for n, r in close) + ".")
    first = runs(doc, "dispersed")[0][0]
    if first != best:
        lines.append(_trade(doc, first, best))
    return lines


def _why(name: str) -> str:
    return WHY.get(name, f"it is the policy {name}")


def _trade(doc: dict, first: str, best: str) -> str:
    """What the law shown first gives up against the best, nominally and on the set flown."""
    nominal = dict(runs(doc, "nominal"))
    dispersed = dict(runs(doc, "dispersed"))
    a, b = nominal[first]["summary"], nominal[best]["summary"]
    worse = []
    for key, what, fmt in (("cost_ratio", "nominal J/J*", ".3f"), ("vertical_error_deg", "nominal vertical error", ".2f"),
                           ("miss_km", "nominal miss", ".3g")):  # fmt: skip
        if a[key] is not None and b[key] is not None and a[key] > 1.2 * b[key]:
            unit = {"cost_ratio": "", "vertical_error_deg": " deg", "miss_km": " km"}[key]
            worse.append(f"{what} {a[key]:{fmt}}{unit} against {b[key]:{fmt}}{unit}")
    da, db = dispersed[first]["summary"], dispersed[best]["summary"]
    if da["success_rate"] < db["success_rate"]:
        worse.append(f"success {rate(da['success_rate'])} against {rate(db['success_rate'])}")
    head = f"{first} is shown first: {_why(first)}"
    if not worse:
        return head + f". On this set it is as good as {best} within the figures above."
    return head + f". On this set it trades, against {best}: " + ", ".join(worse) + "."


def limiter_lines(doc: dict) -> list[str]:
    """Re-planning solve times and the load relief's work, for the laws that have them (dispersed runs)."""
    lines = []
    for name, run in runs(doc, "dispersed"):
        s = run["summary"]
        if rp := s.get("replanning"):
            t = rp["solve_time_s"]
            lines.append(f"{name}: re-solve time p50 / p99 {t['p50']:.2f} / {t['p99']:.2f} s")
        if lr := s.get("load_relief"):
            lines.append(f"{name}: load relief capped {lr['capped_steps']} steps in {lr['episodes_capped']} of "
                         f"{s['episodes']} episodes")  # fmt: skip
    return lines


def title(doc: dict, case: str) -> str:
    if case == "nominal":
        return "Nominal flight (no dispersion)"
    counts = sorted(set(doc["episodes"].values()), reverse=True)
    few = [n for n, c in doc["episodes"].items() if c != counts[0]]
    n = f"{counts[0]} episodes per law" + (f" ({', '.join(_short(x, doc) for x in few)}: {counts[-1]})" if few else "")
    return f"{doc['dispersion_set'].capitalize()} set, seeds {doc['seed']}-{doc['seed'] + counts[0] - 1}: {n}"


def _short(label: str, doc: dict) -> str:
    run = doc["runs"].get(f"dispersed/{label}")
    return display_name(run) if run else label


SUCCESS_NOTE = ("success: impact within {miss_km:g} km of the target and {vertical_error_deg:g} deg of vertical, "
                "|speed error| <= {speed_error_mps:g} m/s, no path bound exceeded by more than {tol:g} %")  # fmt: skip


def success_note(doc: dict) -> str:
    """The benchmark's success definition, from the thresholds the report was measured with."""
    first = next(iter(doc["runs"].values()))["summary"]["success_thresholds"]
    return SUCCESS_NOTE.format(tol=100 * first["constraint_tolerance"], **first)


def rich_table(header: list[str], rows: list[list[str]], caption: str = ""):
    """A rich table that never wraps a cell (the header may take two lines)."""
    from rich import box
    from rich.table import Table

    t = Table(box=box.SIMPLE_HEAD, show_edge=False, pad_edge=False, padding=(0, 1), collapse_padding=True,
              title=caption or None, title_justify="left", title_style="bold")  # fmt: skip
    for i, h in enumerate(header):
        t.add_column(h, justify="left" if i == 0 else "right", no_wrap=True, header_style="bold")
    for r in rows:
        t.add_row(*r)
    return t


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    """The same table in Markdown (a header's line break becomes a space)."""
    cells = [[h.replace("-\n", "").replace("\n", " ") for h in header], *rows]
    lines = ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in cells]
    lines.insert(1, "|" + "|".join("---" for _ in header) + "|")
    return "\n".join(lines)


__all__ = ["WHY", "TERMS", "rate", "runs", "display_name", "nominal_table", "dispersed_table", "ranking", "verdict",
           "limiter_lines", "title", "success_note", "rich_table", "markdown_table"]
