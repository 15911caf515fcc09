"""Start states along the shipped reference: reference-state initialisation and late-start tasks."""

from __future__ import annotations

import numpy as np

from rventry_env.reference.data_file import Reference, load_reference
from rventry_env.task.starts import StartStates

STEP_S = 1.0  # the table's spacing: the environment's default control step


def reference_starts(before_impact_s: tuple[float, float] | None = None, probability: float = 1.0, *,
                     reference: Reference | None = None, step_s: float = STEP_S, label: str | None = None,
                     far_weight: float = 0.0, step_weighted: bool = False, **perturbations: float) -> StartStates:  # fmt: skip
    """Start states taken from the reference trajectory, ``before_impact_s`` = (earliest, latest)
    seconds before its impact (default: anywhere from its entry to one step before impact).

    The table holds the reference's states every ``step_s`` seconds, counted back from the impact
    (the impact state itself, on the surface, is left out); an episode started from it runs its
    clock from the reference's time there. ``perturbations`` are :class:`StartStates`' half-widths
    (``altitude_m``, ``speed_mps``, ``flight_path_deg``, ``heading_deg``, ``alpha_deg``, ``sigma_deg``);
    ``far_weight`` and ``step_weighted`` shape the start time's density (:class:`StartStates`).
    """
    ref = load_reference() if reference is None else reference
    if not (isinstance(step_s, (int, float)) and 0 < step_s < ref.tf - ref.t0):
        raise ValueError(f"step_s must lie in (0, {ref.tf - ref.t0:g}) s, got {step_s!r}")
    back = np.arange(step_s, ref.tf - ref.t0 + 1e-9, step_s)  # seconds before impact, one step and more
    times = (ref.tf - back)[::-1]
    span = float(back[-1])
    lo, hi = (step_s, span) if before_impact_s is None else (float(before_impact_s[0]), float(before_impact_s[1]))
    if not step_s <= lo <= hi <= span:
        raise ValueError(f"before_impact_s must satisfy {step_s:g} <= earliest <= latest <= {span:g} s (from one step "
                         f"before impact back to the entry), got {before_impact_s!r}")  # fmt: skip
    if label is None:
        label = f"reference, {lo:g}-{hi:g} s before impact"
    return StartStates(times, ref.state(times), (lo - step_s, hi - step_s), probability, label=label,
                       far_weight=far_weight, step_weighted=step_weighted, **perturbations)  # fmt: skip


__all__ = ["reference_starts"]
