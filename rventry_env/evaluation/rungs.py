"""The ladder: task rungs from an easy late start to the full benchmark.

Each rung is one ``gym.make("RvEntry-v0", **rung(name).env_kwargs())`` call: the same
environment, reward and success definition, with the episodes started later along the shipped
reference (the easy rungs) or drawn from a harder set. A learner that fails the full task can
be placed on the ladder: the rung where it stops is where the task's difficulty lies for it.

========= =============================================================================== ========
rung      episodes start                                                                  draws
========= =============================================================================== ========
late      on the reference 30-60 s before impact, perturbed: the terminal dive alone      none
half      on the reference 450-550 s before impact: the last two skips and the dive       none
nominal   at the paper's initial state: the whole flight                                  none
standard  at the initial state, standard set                                              standard
wide      at the initial state, wide set                                                  wide
flight    at the initial state, flight-grade set (profiles, sensors, navigation)          flight
footprint at the initial state, standard set, a target drawn in the footprint per episode standard
========= =============================================================================== ========

The late starts are perturbed by 200 m in altitude, 10 m/s in speed, 0.1 deg in flight-path
angle and heading, 0.5 deg of alpha and 2 deg of bank (uniform half-widths), then held inside the
path bounds (:func:`~rventry_env.envs.common.within_path_bounds`); their clock runs from the
reference's time.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

RUNG_PERTURBATIONS = {"altitude_m": 200.0, "speed_mps": 10.0, "flight_path_deg": 0.1, "heading_deg": 0.1,
                      "alpha_deg": 0.5, "sigma_deg": 2.0}  # fmt: skip


@dataclass(frozen=True)
class Rung:
    """One rung: where its episodes start, what they draw, which target they fly."""

    name: str
    description: str
    dispersion: str = "none"
    before_impact_s: tuple[float, float] | None = None  # start states on the reference; None: the initial state
    targets: str = "fixed"

    def starts(self):
        """The rung's start states (None: the task's initial state)."""
        return None if self.before_impact_s is None else rung_starts(self.name)

    def env_kwargs(self) -> dict:
        """Keyword arguments of ``gym.make("RvEntry-v0", ...)`` for this rung."""
        out: dict = {"dispersion": self.dispersion}
        if self.before_impact_s is not None:
            out["starts"] = self.starts()
        if self.targets != "fixed":
            out["targets"] = self.targets
        return out


RUNGS: dict[str, Rung] = {r.name: r for r in (
    Rung("late", "the terminal dive alone: from the reference 30-60 s before impact, perturbed", "none", (30.0, 60.0)),
    Rung("half", "the last two skips and the dive: from the reference 450-550 s before impact", "none", (450.0, 550.0)),
    Rung("nominal", "the whole flight from the paper's initial state, no dispersion"),
    Rung("standard", "the whole flight, standard set (density 5 %, C_L and C_D 3 %, entry state)", "standard"),
    Rung("wide", "the whole flight, wide set (density 10 %, C_L and C_D 5 %, entry state and heading)", "wide"),
    Rung("flight", "the whole flight, flight-grade set (profiles, winds, sensors, unaided navigation)", "flight"),
    Rung("footprint", "the whole flight, standard set, a target drawn within +-300 km / +-150 km", "standard",
         targets="footprint"),
)}  # fmt: skip


def rung(name: str) -> Rung:
    """The rung called ``name`` (:data:`RUNGS`)."""
    if name not in RUNGS:
        raise ValueError(f"no rung {name!r}; the ladder: {', '.join(RUNGS)}")
    return RUNGS[name]


@lru_cache(maxsize=None)
def rung_starts(name: str):
    """The start states of rung ``name`` (built once: the shipped reference sampled every second)."""
    from rventry_env.reference.starts import reference_starts

    r = rung(name)
    if r.before_impact_s is None:
        raise ValueError(f"the rung {name!r} starts at the task's initial state, not from start states")
    return reference_starts(r.before_impact_s, label=f"the {name} rung: {r.description}", **RUNG_PERTURBATIONS)


__all__ = ["RUNGS", "RUNG_PERTURBATIONS", "Rung", "rung", "rung_starts"]
