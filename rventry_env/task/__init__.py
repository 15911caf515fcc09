"""The entry task, without Gymnasium: what a flight must achieve and what the benchmark draws.

* :class:`EntryProblem` - the paper's Example 2: boundary conditions, cost, path bounds;
* :class:`EntryTask` - the problem flown in control steps (``dt``, ``substeps``), the
  success thresholds and the episode-end rules (skip-out ceiling, stall speed);
* :class:`Dispersion` - the named and custom dispersion sets, and their draws.

The environments, the collocation reference, the guidance laws and the evaluation all read
these; the reward an RL agent is paid stays with the environment
(:class:`rventry_env.envs.reward.RewardWeights`).
"""

from rventry_env.task.definition import TARGETS, EntryTask, Footprint, PrecisionThresholds, SuccessThresholds, footprint_target
from rventry_env.task.dispersion import (
    FLIGHT_GRADE_ERRORS,
    NAMED_SETS,
    SET_CHOICES,
    SCALAR_FIELDS,
    Dispersion,
    apply_state_dispersion,
    disperse_state,
    draw_dispersion,
    draw_extras,
)
from rventry_env.task.flight_grade import FlightGradeErrors
from rventry_env.task.problem import EntryProblem

__all__ = [
    "EntryProblem",
    "EntryTask",
    "Footprint",
    "TARGETS",
    "footprint_target",
    "SuccessThresholds",
    "PrecisionThresholds",
    "NAMED_SETS",
    "SET_CHOICES",
    "SCALAR_FIELDS",
    "FLIGHT_GRADE_ERRORS",
    "FlightGradeErrors",
    "draw_extras",
    "Dispersion",
    "apply_state_dispersion",
    "disperse_state",
    "draw_dispersion",
]
