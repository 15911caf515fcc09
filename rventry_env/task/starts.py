"""Start states: episodes that begin part-way along a trajectory instead of at the task's initial state.

A reinforcement learner that only ever starts at the entry interface sees the terminal
conditions (the miss, the vertical dive, the impact speed) a thousand steps after the
decisions that decide them. Starting some episodes from states along a known trajectory
(reference-state initialisation, as DeepMimic does; or a reverse curriculum, Florensa et al.
2017, by moving the window back) puts the learner near those conditions at once.

:class:`StartStates` is a table of states along a trajectory with their flight times, a window
of how long before the table's end an episode may start, uniform perturbations of the picked
state (the flight-grade dispersion's own rule, :func:`~rventry_env.task.disperse_state`), and the
share of episodes that start this way; the rest start at the task's own initial state. The
environments draw it after every other draw of a reset, so an environment without start
states draws exactly what it always did. An episode started at table time t runs its clock
from t (the observation's time feature), and its time limit counts its own steps.

The table is data: :func:`rventry_env.reference.reference_starts` builds one from the shipped
collocation reference. A start-state table is a training aid or the definition of an easier
task; the benchmark's own evaluation always starts at the task's initial state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics.entry import IDX, N_STATE
from rventry_env.task.dispersion import disperse_state

# the perturbations a start state may draw, in the order of SCALAR_FIELDS' state part
PERTURBATIONS = ("altitude_m", "speed_mps", "flight_path_deg", "heading_deg", "alpha_deg", "sigma_deg")
# numbers a start draw takes from the generator, whatever it decides (so streams stay aligned)
DRAWS = 2 + len(PERTURBATIONS)
NORM_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class StartStates:
    """Where episodes may start instead of the task's initial state (see the module docstring).

    :param times: the table's flight times (K,), s, strictly increasing.
    :param states: its states (K, 12), state order of docs/conventions.md, above the surface.
    :param before_end_s: (earliest, latest) start, as seconds before the table's last time: the
        start time is drawn uniformly in it and the nearest table state taken. (0, span) is
        anywhere along the table.
    :param probability: the share of episodes that start from the table (the others start at the
        task's initial state with the environment's dispersion).
    :param far_weight: k >= 0: the start time's density within the window grows as
        (s - earliest)^k with s the seconds before the table's end, so that a reverse curriculum's
        frontier, the window's far end, gets more episodes (0: uniform).
    :param step_weighted: draw the start time with density 1/s instead (log-uniform in s, which
        must then be > 0 across the window), so that each part of the window gets about the same
        number of steps flown rather than of episodes: a start s seconds before the table's end
        flies about s seconds to the end of the task when the table ends near it, as the
        reference's does (one step before impact). Not with ``far_weight``.
    :param altitude_m, speed_mps, flight_path_deg, heading_deg, alpha_deg, sigma_deg: uniform
        half-widths of the perturbations of the picked state (alpha is then held in [0, alpha_max]).
    :param label: what the table is, for records and messages.
    """

    times: np.ndarray
    states: np.ndarray
    before_end_s: tuple[float, float]
    probability: float = 1.0
    far_weight: float = 0.0
    step_weighted: bool = False
    altitude_m: float = 0.0
    speed_mps: float = 0.0
    flight_path_deg: float = 0.0
    heading_deg: float = 0.0
    alpha_deg: float = 0.0
    sigma_deg: float = 0.0
    label: str = "custom"

    def __post_init__(self):
        t = _array("times", self.times, 1)
        x = _array("states", self.states, 2)
        if x.shape != (t.size, N_STATE):
            raise ValueError(f"start states: states must have shape ({t.size}, {N_STATE}) for {t.size} times, got {x.shape}")
        if t.size < 1 or np.any(np.diff(t) <= 0):
            raise ValueError("start states: times must be one or more strictly increasing numbers")
        for name, part in (("eA", x[:, IDX.e_a]), ("eB", x[:, IDX.e_b])):
            bad = np.nonzero(np.abs(np.linalg.norm(part, axis=1) - 1.0) > NORM_TOL)[0]
            if bad.size:
                raise ValueError(f"start states: the {name} Euler parameters of row {bad[0]} do not have unit norm")
        if np.any(x[:, IDX.v] <= 0):
            raise ValueError(f"start states: row {int(np.argmax(x[:, IDX.v] <= 0))} has a speed <= 0")
        window = tuple(float(w) for w in self.before_end_s) if np.ndim(self.before_end_s) == 1 else ()
        span = float(t[-1] - t[0])
        if len(window) != 2 or not all(math.isfinite(w) for w in window) or not 0 <= window[0] <= window[1] <= span:
            raise ValueError(f"start states: before_end_s must be (earliest, latest) with 0 <= earliest <= latest <= "
                             f"{span:g} s (the table's span), got {self.before_end_s!r}")  # fmt: skip
        p = self.probability
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 < p <= 1:
            raise ValueError(f"start states: probability must lie in (0, 1], got {p!r}")
        for name in (*PERTURBATIONS, "far_weight"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"start states: {name} must be a finite half-width >= 0, got {v!r}")
        if not isinstance(self.step_weighted, (bool, np.bool_)):
            raise ValueError(f"start states: step_weighted must be True or False, got {self.step_weighted!r}")
        if self.step_weighted and self.far_weight:
            raise ValueError("start states: step_weighted and far_weight both shape the start time's density; "
                             "give one of them")  # fmt: skip
        if self.step_weighted and not window[0] > 0:
            raise ValueError("start states: step_weighted draws the start with density 1/s in the seconds s before "
                             f"the table's end, so the window must end before it: got before_end_s {window!r}")  # fmt: skip
        t.setflags(write=False)
        x.setflags(write=False)
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "states", x)
        object.__setattr__(self, "before_end_s", window)
        object.__setattr__(self, "probability", float(p))
        object.__setattr__(self, "step_weighted", bool(self.step_weighted))

    @property
    def half_widths(self) -> np.ndarray:
        """The perturbations' half-widths (6,), in :data:`PERTURBATIONS` order."""
        return np.array([getattr(self, n) for n in PERTURBATIONS], dtype=float)

    def window_times(self) -> tuple[float, float]:
        """The table times the window spans (earliest, latest)."""
        end = float(self.times[-1])
        return end - self.before_end_s[1], end - self.before_end_s[0]

    def with_window(self, before_end_s, probability: float | None = None) -> "StartStates":
        """The same table and perturbations with another window (a reverse curriculum's step)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values["before_end_s"] = before_end_s
        if probability is not None:
            values["probability"] = probability
        return StartStates(**values)

    def pick(self, u) -> tuple:
        """The table row and time for uniform numbers ``u`` in [0, 1) (arrays or numbers; NumPy)."""
        t = window_time(u, self.window_times(), self.far_weight, np, float(self.times[-1]), self.step_weighted)
        k = np.clip(np.searchsorted(self.times, t), 0, self.times.size - 1)
        return k, self.times[k]

    def draw(self, rng: np.random.Generator, alpha_max: float):
        """One episode's start: (time, state (12,)) from the table, or None for the task's own start.

        Always takes :data:`DRAWS` numbers from ``rng``, whichever it decides.
        """
        u = rng.uniform(size=DRAWS)
        if not u[0] < self.probability:
            return None
        k, t0 = self.pick(u[1])
        return float(t0), perturbed(self.states[k], (2.0 * u[2:] - 1.0) * self.half_widths, alpha_max, NUMPY)

    def describe(self) -> dict:
        """A JSON-friendly description (the table by its size and span, not its numbers)."""
        out = {n: getattr(self, n) for n in ("label", "before_end_s", "probability", "far_weight", "step_weighted",
                                            *PERTURBATIONS)}  # fmt: skip
        out.update(rows=int(self.times.size), span_s=float(self.times[-1] - self.times[0]))
        out["before_end_s"] = list(self.before_end_s)
        return out


def window_time(u, window, far_weight, xp, end=None, step_weighted=False):
    """The table time for a uniform number ``u``: within ``window`` = (earliest, latest) table times,
    with density growing as (latest - t)^far_weight toward the earliest (the far end), or where
    ``step_weighted`` (a bool, or 0/1 in JAX), with density 1/(end - t), ``end`` the table's last
    time. NumPy or JAX."""
    frac = xp.power(u, 1.0 / (1.0 + far_weight))  # density (frac)^k on [0, 1)
    t = window[1] - frac * (window[1] - window[0])
    if end is None:
        return t
    near = xp.maximum(end - window[1], 1e-6)  # seconds before the end, > 0 where step_weighted (checked)
    far = xp.maximum(end - window[0], near)
    logs = end - near * xp.power(far / near, u)  # log-uniform in the seconds before the end
    return xp.where(step_weighted, logs, t)


def perturbed(x, d, alpha_max: float, ns) -> tuple:
    """State components ``x`` (12) perturbed by ``d`` (the 6 of :data:`PERTURBATIONS`), with
    alpha held in [0, alpha_max]: :func:`~rventry_env.task.disperse_state` without the model draws.
    Returns the 12 components (NumPy arrays or JAX values)."""
    zero = 0.0 * d[0]
    out = list(disperse_state(tuple(x[i] for i in range(N_STATE)), (zero, zero, zero, *(d[i] for i in range(6))), ns))
    out[IDX.alpha] = ns.fmin(ns.fmax(out[IDX.alpha], 0.0), alpha_max)
    if ns is NUMPY:
        return np.array([float(c) for c in out])
    return tuple(out)


def _array(name: str, value, ndim: int) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"start states: {name} must be numbers, got {value!r:.80}") from None
    if a.ndim != ndim:
        raise ValueError(f"start states: {name} must have {ndim} dimension(s), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"start states: {name} contain NaN or inf")
    return a


__all__ = ["StartStates", "PERTURBATIONS", "DRAWS", "perturbed", "window_time"]
