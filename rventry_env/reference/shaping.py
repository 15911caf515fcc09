"""The energy-range profile of the shipped reference, for the ``"energy"`` shaping potential
(:class:`~rventry_env.envs.shaping.PotentialShaping`)."""

from __future__ import annotations

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.core.euler_parameters import dcm
from rventry_env.core.targeting import specific_energy, surface_angle, target_in_a
from rventry_env.physics.model import EntryModel
from rventry_env.reference.data_file import Reference, load_reference
from rventry_env.task import EntryProblem


def energy_range_profile(reference: Reference | None = None, model: EntryModel | None = None,
                         problem: EntryProblem | None = None, step_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(specific energies, ranges to go) along the reference every ``step_s``, energies increasing.

    The specific energy v^2/2 + mu/R - mu/r falls monotonically along the reference (drag only
    takes energy away); the range to go is the great-circle distance to the target.
    """
    ref = load_reference() if reference is None else reference
    model = EntryModel() if model is None else model
    problem = EntryProblem() if problem is None else problem
    planet = model.planet
    t = np.append(np.arange(ref.t0, ref.tf, step_s), ref.tf)
    x = tuple(ref.state(t).T)
    e = specific_energy(x, planet.mu, planet.radius)
    target = tuple(float(c) for c in problem.target_unit_vector())
    r = planet.radius * surface_angle(target_in_a(dcm(*x[1:5]), target), NUMPY)
    order = np.argsort(e)
    e, r = e[order], r[order]
    if np.any(np.diff(e) <= 0):
        raise ValueError("the reference's specific energy does not fall monotonically: no energy-range profile")
    return e, np.maximum(r, 0.0)


def fade_energies(seconds: float, reference: Reference | None = None,
                  model: EntryModel | None = None) -> tuple[float, float]:  # fmt: skip
    """(e_full, e_zero): the reference's specific energy ``seconds`` before its end and at its end,
    for a potential that fades out over the reference's last ``seconds``
    (:class:`~rventry_env.envs.shaping.PotentialShaping`'s ``fade_energies``)."""
    ref = load_reference() if reference is None else reference
    planet = (EntryModel() if model is None else model).planet
    duration = ref.tf - ref.t0
    if not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool) and 0 < seconds < duration):
        raise ValueError(f"a fade must last more than 0 s and less than the reference's {duration:.1f} s, got {seconds!r}")
    x = tuple(ref.state(np.array([ref.tf - seconds, ref.tf])).T)
    full, zero = (float(v) for v in specific_energy(x, planet.mu, planet.radius))
    return full, zero


__all__ = ["energy_range_profile", "fade_energies"]
