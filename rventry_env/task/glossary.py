"""The words the ``rventry`` commands print, explained: ``rventry glossary [TERM]``.

One table, :data:`TERMS`, is the source of the command's answers, of the manual's glossary page
(generated from it, so the two never differ) and of the "terms" line under each command's
output, which names every term the command printed with its anchor on that page. Thresholds are
read from the task's own defaults (:class:`~rventry_env.task.SuccessThresholds`,
:class:`~rventry_env.task.PrecisionThresholds`), never retyped.
"""

from __future__ import annotations

import argparse
import re
import sys
import textwrap
from typing import NamedTuple

from rventry_env.task.definition import PrecisionThresholds, SuccessThresholds
from rventry_env.task.problem import EntryProblem

# where the manual's glossary lives in the source tree (the docs site renders it as glossary.html)
GLOSSARY_PAGE = "docs/reference/glossary.md"


def slug(name: str) -> str:
    """A term's anchor on the glossary page: lower case, each run of other characters one hyphen."""
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")


class Term(NamedTuple):
    """One glossary entry.

    :param name: the word as the commands print it.
    :param short: one line, for the list.
    :param text: what it means, in a few sentences.
    :param see: the manual page that explains it further (a path under ``docs/``), or "".
    """

    name: str
    short: str
    text: str
    see: str = ""

    @property
    def anchor(self) -> str:
        """The entry's anchor on the glossary page (``#anchor``): :func:`slug` of the name."""
        return slug(self.name)


def _terms() -> tuple[Term, ...]:
    s, p, problem = SuccessThresholds(), PrecisionThresholds(), EntryProblem()
    margin = f"{100 * s.constraint_tolerance:g} %"
    return (
        Term("success", "a landed episode, by the benchmark's thresholds",
             f"The benchmark's definition of a landed episode: impact with a miss of at most {s.miss_km:g} km, "
             f"a vertical-impact error of at most {s.vertical_error_deg:g} deg, a speed error of at most "
             f"+/-{s.speed_error_mps:g} m/s, and no path bound (load factor, dynamic pressure) exceeded by more "
             f"than {margin}. The success rate is the fraction of episodes that meet it, shown with its 95 % "
             "Wilson interval where the episode count matters.", "env.md"),
        Term("precision", "a precise impact: the tier beside success",
             f"The precision tier, reported beside success: impact with a miss of at most {p.miss_m:g} m, a "
             f"vertical-impact error of at most {p.vertical_error_deg:g} deg, |alpha(t_f)| of at most "
             f"{p.alpha_final_deg:g} deg, a speed error of at most +/-{p.speed_error_mps:g} m/s and no path bound "
             "breached. What a flight project asks of a precise impact; on the flight-grade set the unaided "
             "inertial navigation alone bounds it.", "uncertainty.md"),
        Term("miss", "distance from the impact point to the target",
             "The great-circle distance on the surface between the impact point and the target, in km (or m).",
             "env.md"),
        Term("vertical-impact error", "angle of the impact velocity from the vertical",
             "The angle between the velocity at impact and the local vertical, in degrees: the paper's Example 2 "
             "asks for an exactly vertical impact (0 deg).", "env.md"),
        Term("speed error", "impact speed less the required speed",
             f"The speed at impact less the required {problem.final_speed:g} m/s; |speed error| is its magnitude.",
             "env.md"),
        Term("alpha(t_f)", "angle of attack at impact",
             "The angle of attack at impact, in degrees; Example 2 asks for zero.", "guidance.md"),
        Term("J/J*", "the paper's cost of a flight over the optimum's",
             "The paper's running cost J of a flight (Eq. Ex2-Cost) over the optimal cost J* of the shipped "
             "collocation reference. Below 1 is possible only because the environment holds each rate for a "
             "whole control step, which trims the optimum's final alpha bang. Under dispersions each draw has its "
             "own optimum, so the dispersed J/J* compares different problems and is shown for reference only.",
             "reference.md"),
        Term("path violation", "a load or dynamic-pressure bound breached beyond its margin",
             f"An episode whose load factor exceeded {problem.a_max_g:g} g, or whose dynamic pressure fell under "
             f"{problem.q_min / 1e3:g} kPa, by more than {margin}; the path-violation rate is the fraction of "
             "episodes with one. Such an episode is not a success.", "env.md"),
        Term("peak load factor", "the flight's largest aerodynamic load, in g",
             "The largest aerodynamic load factor of the flight, sqrt(L^2 + D^2) / (m g0), in g.", "env.md"),
        Term("min dynamic pressure", "the flight's smallest dynamic pressure, in kPa",
             "The smallest dynamic pressure q = rho v^2 / 2 of the flight, in kPa.", "env.md"),
        Term("p5 / p50 / p95", "percentiles over the episodes (p50: the median)",
             "Percentiles over the episodes: p50 is the median, p95 the value 95 % of the episodes stay under.",
             ""),
        Term("95 % CI", "the 95 % Wilson interval of a rate",
             "The 95 % Wilson score interval of a rate over the episodes flown (scipy's binomtest): the range the "
             "true rate lies in, given so few episodes. Ten episodes cannot tell 0.9 from 1.0.", ""),
        Term("endings", "how the episodes ended (impact, skip-out, ...)",
             "How the episodes ended: impact, skip-out (above the ceiling), stall, a non-finite state, or the "
             "time limit.", "env.md"),
        Term("load relief", "a limiter that keeps the load factor under its bound",
             f"A limiter between a law and the vehicle: where the load factor predicted one step ahead "
             f"(the model's own dynamics, calibrated on the accelerometer) would pass {problem.a_max_g:g} g less a "
             "margin, it lowers the angle-of-attack rate to the highest that keeps the load under it. The learned "
             "policies fly it, and mpc-flight; 'capped steps (episodes)' counts the steps it acted on and the "
             "episodes it acted in.", "learned.md"),
        Term("q floor", "a limiter that keeps dynamic pressure over its bound",
             "A limiter for the dynamic-pressure bound: where a climbing vehicle's apex, predicted on the model's "
             "equations, would take q under its bound plus a margin, the bank is held or rolled to put lift away "
             "from the vertical. The PPO-trained policy flies it.", "ppo.md"),
        Term("re-solve time", "wall time of one re-planning solve",
             "The wall time of one re-planning solve (IPOPT on the collocation problem from the current state); "
             "p50 / p99 over the solves of the episodes flown.", "guidance.md"),
        Term("navigation", "the vehicle's own idea of where it is, against the truth",
             "Where the vehicle's own navigation put it at the end, against the truth: horizontal and vertical "
             "error, and the miss it believed it made. Zero on sets without sensor or navigation errors.",
             "uncertainty.md"),
        Term("flyable", "the oracle's ceiling: draws a perfect-knowledge plan lands",
             "The oracle's figure: the fraction of draws that, solved with perfect knowledge of the draw and "
             "tracked through it, land as a success. A lower bound of what any law could land on the set.",
             "uncertainty.md"),
        Term("dispersion set", "what each episode draws: none, standard, wide, flight, peer",
             "What an episode draws: none (nominal), standard (uniform density, C_L, C_D and entry-state errors), "
             "wide (about twice as wide, plus heading), flight (flight-grade: NRLMSIS atmosphere and Gauss-Markov "
             "density and winds, Mach-dependent aerodynamics, mass, accelerometer and inertial navigation errors), "
             "peer (RLReentry's set mapped onto this entry) and peer-0.1 (a tenth of it).", "uncertainty.md"),
        Term("nominal", "the undispersed flight",
             "The undispersed flight: the paper's initial state and the documented default models.", ""),
        Term("learned", "the shipped learned policy that lands most of the flight set",
             "The name of the shipped learned policy that lands most of the flight-grade set; the command that "
             "flies it prints which policy it is.", "learned.md"),
        Term("J*", "the optimal cost: the collocation reference's J",
             "The paper's cost (Eq. Ex2-Cost) of the optimal solution of Example 2, as the shipped collocation "
             "reference solves it; every law's J/J* is measured against it.", "reference.md"),
        Term("mesh error", "the collocation's largest relative error between nodes",
             "The largest relative error of the collocation polynomials against the dynamics, measured between "
             "the nodes of every mesh interval; the hp refinement adds intervals or degree until it is under the "
             "tolerance (1e-6 by default).", "reference.md"),
        Term("max violation", "the NLP's largest constraint violation",
             "The largest violation of any constraint of the scaled nonlinear program at IPOPT's solution "
             "(dynamics defects, path and endpoint constraints).", "reference.md"),
        Term("e_r,max", "Example 1's largest position error",
             "The largest position error over one orbit period against the analytic trajectory, in km: Example 1 "
             "of the paper compares it in rv-Euler parameters and in spherical coordinates.", "core.md"),
        Term("BIC", "Bayesian information criterion (identification)",
             "The Bayesian information criterion of a fitted model (identification): the fit's misfit plus a "
             "price per parameter. An effect is added only while it lowers the BIC by the threshold.",
             "validation.md"),
        Term("unexplained", "a residual that is not noise (identification)",
             "An identification whose final residual is not noise: the report says so, and traces what is left.",
             "validation.md"),
    )


TERMS: tuple[Term, ...] = _terms()
_BY_NAME = {t.name.lower(): t for t in TERMS} | {t.anchor: t for t in TERMS}


def term(name: str) -> Term:
    """The entry of ``name`` (as printed, or its anchor; any case).

    :raises KeyError: no such term, naming the known ones.
    """
    t = _BY_NAME.get(name.strip().lower())
    if t is None:
        raise KeyError(f"no glossary entry {name!r}; entries: {', '.join(x.name for x in TERMS)}")
    return t


def terms_line(names: list[str] | tuple[str, ...], width: int = 100) -> str:
    """The lines a command prints under its output: each term it printed, linked to its glossary entry
    (the page's anchor of a term is :func:`slug` of its name)."""
    entries = [term(n) for n in dict.fromkeys(names)]
    text = f"terms ({GLOSSARY_PAGE}#term, or `rventry glossary TERM`): " + ", ".join(t.name for t in entries)
    return textwrap.fill(text, width, subsequent_indent="  ", break_on_hyphens=False, break_long_words=False)


def glossary_markdown() -> str:
    """The manual's glossary page, in MyST Markdown: a ``glossary`` directive, one entry per term."""
    lines = [
        "# Glossary",
        "",
        "The words the `rventry` commands print. Each command ends with a line naming the terms it",
        "printed and their anchors here; `rventry glossary TERM` prints the same entry. This page is",
        "generated from `rventry_env/task/glossary.py`.",
        "",
    ]
    for t in TERMS:
        lines += [f"({t.anchor})=", f"## {t.name}", "", t.text]
        if t.see:
            lines += ["", f"More: [{t.see}](../{t.see})."]
        lines.append("")
    return "\n".join(lines)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("glossary", help="explain a word the commands print (success, precision, load relief, ...)")
    p.add_argument("term", nargs="*", help="the term (as printed, any case); none: list every term")
    p.set_defaults(func=_glossary)


def _glossary(args) -> int:
    if not args.term:
        width = max(len(t.name) for t in TERMS)
        for t in TERMS:
            print(f"{t.name:<{width}}  {t.short}")
        print(f"\n`rventry glossary TERM` for the whole entry; the manual's page: {GLOSSARY_PAGE}")
        return 0
    try:
        t = term(" ".join(args.term))
    except KeyError as exc:
        print(f"rventry glossary: error: {exc.args[0]}", file=sys.stderr)
        return 2
    print(t.name)
    print(textwrap.fill(t.text, 96, initial_indent="  ", subsequent_indent="  "))
    if t.see:
        print(f"  more: docs/{t.see}; {GLOSSARY_PAGE}#{t.anchor}")
    return 0


__all__ = ["Term", "TERMS", "GLOSSARY_PAGE", "term", "terms_line", "glossary_markdown", "register"]
