"""Potential-based reward shaping: a training aid that leaves every optimal policy unchanged.

With a potential Phi over states and the learner's discount gamma, each step also pays
F = gamma Phi(s') - Phi(s), with Phi = 0 at a terminal state (Ng, Harada & Russell 1999).
Along any episode that terminates, the discounted sum of F telescopes to -Phi(s_0): the shaped
return of every policy is its own return less the same constant, so the ordering of policies,
and with it every optimal policy, is unchanged. What changes is what a critic must learn: it
now learns V(s) - Phi(s), which is easy where Phi is close to V. A potential is a prior for the
critic, not a new objective.

An episode cut by the time limit is not terminal (the state has a future): it pays gamma
Phi(s') - Phi(s) like any other step, so a learner that bootstraps the cut (Gymnasium's
semantics) sees the same telescoping sum. Where training charges the cut as a failure
(``time_limit_is_failure``), the cut is terminal and Phi(s') = 0.

Potentials (:data:`POTENTIALS`), each evaluated on the true state (the reward is a training
signal; a guidance law never sees it) and written once for floats, NumPy and JAX:

* ``"range"``: -w * (great-circle range to go, km), w the reward's miss weight. It says nothing
  of energy: a vehicle gains potential by closing range however it spends its energy (an early
  plunge pays as well as a glide).
* ``"energy"``: -w * |range to go - R(e)| (km), the range the vehicle is off the profile R(e)
  of range to go against specific energy e = v^2/2 + mu/R - mu/r that a trajectory of the task
  flies (``energies`` and ``ranges``; :func:`rventry_env.reference.shaping.energy_range_profile`
  gives the shipped reference's). It is the classical entry-guidance
  prediction of the miss: at a given energy, the range the vehicle can still cover is about the
  profile's, so a vehicle short of energy for its range (a plunge) or with energy to spare
  loses potential, and one that keeps range and energy in step keeps it.

Either potential may fade out at the end of the flight (``fade_energies = (e_full, e_zero)``):
its weight is w above the specific energy e_full, none below e_zero, and linear in energy between,
so Phi = -w f(e) d with f = clip((e - e_zero) / (e_full - e_zero), 0, 1). It is still a function of
the state alone, so still policy-invariant. It leaves the end of the flight, the pull-down and the
dive that the task's terminal terms judge (miss, speed, angle from vertical), to those terms
alone: on the shipped reference the last minute runs the profile from 90 km to none while the
energy falls by two thirds. :func:`rventry_env.reference.shaping.fade_energies` gives the energies
of the reference's last seconds.

Either potential may take on the terminal terms at the end of the flight (``terminal``: weights
of :class:`~rventry_env.envs.reward.RewardWeights`, the reward's own or some of them, and
``terminal_energies = (e_none, e_whole)``): -g(e) times the terminal penalty of the current state,
read as if the flight ended there (:func:`rventry_env.envs.outcome.metrics_at`: its range to the
target, its angle from vertical, its speed against the impact speed, its alpha), with
g = clip((e_none - e) / (e_none - e_whole), 0, 1) rising from none at e_none to whole at e_whole.
Below e_whole the potential is the terminal penalty itself, so over the last seconds each step
pays what it took off (or put on) the miss and the dive, where the unshaped reward pays all of it
at the impact. It is a function of the state, so it changes no optimal policy either; the critic
it helps is the one that must learn the dive, the condition a late flight loses first. It is a
prior for the last seconds alone: along the shipped reference the angle from vertical falls from
88 deg 60 s before the impact to 42 deg 10 s before it and to none at it, so a longer rise
charges the optimal dive itself on the way down (and repays it at the impact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.core.targeting import specific_energy, surface_angle, target_in_a
from rventry_env.envs.outcome import metrics_at, terminal_penalty
from rventry_env.envs.reward import RewardWeights

POTENTIALS = ("range", "energy")


@dataclass(frozen=True, eq=False)
class PotentialShaping:
    """Potential-based shaping (see the module docstring).

    :param potential: one of :data:`POTENTIALS`.
    :param gamma: the learner's discount (the shaping is policy-invariant only with it).
    :param weight: reward per km of the potential's range (default 0.2, the reward's miss weight).
    :param energies: ``"energy"``: the profile's specific energies (J/kg), increasing.
    :param ranges: ``"energy"``: the range to go (m) at each of them.
    :param fade_energies: ``(e_full, e_zero)``, J/kg with e_full > e_zero >= 0: the potential fades
        linearly in specific energy from its whole weight at e_full to none at e_zero (None: no fade).
    :param terminal: the weights of the terminal terms taken on at the end (their miss, vertical,
        speed and alpha weights; None: none).
    :param terminal_energies: with ``terminal``: ``(e_none, e_whole)``, J/kg with e_none > e_whole >= 0,
        the terminal terms' weight rising linearly in specific energy from none to whole.
    :param final_speed: with ``terminal``: the task's impact speed (m/s) its speed term reads against.
    """

    potential: str
    gamma: float
    weight: float = 0.2
    energies: np.ndarray | None = None
    ranges: np.ndarray | None = None
    fade_energies: tuple[float, float] | None = None
    terminal: RewardWeights | None = None
    terminal_energies: tuple[float, float] | None = None
    final_speed: float | None = None

    def __post_init__(self):
        if self.potential not in POTENTIALS:
            raise ValueError(f"shaping potential must be one of {POTENTIALS}, got {self.potential!r}")
        g = self.gamma
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not 0 < g <= 1:
            raise ValueError(f"shaping gamma must be the learner's discount, in (0, 1], got {g!r}")
        w = self.weight
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w <= 0:
            raise ValueError(f"shaping weight must be a finite number > 0 (reward per km), got {w!r}")
        if self.potential == "energy":
            e, r = (np.asarray(a, dtype=float) if a is not None else None for a in (self.energies, self.ranges))
            if e is None or r is None or e.ndim != 1 or e.shape != r.shape or e.size < 2:
                raise ValueError("the 'energy' potential needs energies and ranges: two 1-D arrays of one length >= 2")
            if not (np.all(np.isfinite(e)) and np.all(np.isfinite(r)) and np.all(np.diff(e) > 0) and np.all(r >= 0)):
                raise ValueError("the 'energy' potential's energies must increase strictly and its ranges be >= 0, all finite")
            e.setflags(write=False)
            r.setflags(write=False)
            object.__setattr__(self, "energies", e)
            object.__setattr__(self, "ranges", r)
        if self.fade_energies is not None:
            object.__setattr__(self, "fade_energies", _energy_pair(self.fade_energies, "fade_energies", "e_full", "e_zero"))
        if self.terminal is not None:
            if not isinstance(self.terminal, RewardWeights):
                raise ValueError(f"shaping terminal must be RewardWeights (the terminal terms' weights), "
                                 f"got {type(self.terminal).__name__}")  # fmt: skip
            pair = _energy_pair(self.terminal_energies, "terminal_energies", "e_none", "e_whole")
            object.__setattr__(self, "terminal_energies", pair)
            v = self.final_speed
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"shaping terminal needs final_speed, the task's impact speed (m/s) > 0, got {v!r}")
            object.__setattr__(self, "final_speed", float(v))
        elif self.final_speed is not None or self.terminal_energies is not None:
            raise ValueError("shaping final_speed and terminal_energies are read by the terminal terms alone, "
                             "and terminal is None")  # fmt: skip
        object.__setattr__(self, "gamma", float(g))
        object.__setattr__(self, "weight", float(w))

    def phi(self, x, c_ae, target_e, mu: float, radius: float, ns):
        """The potential of states ``x`` (components; C_AE at them ``c_ae``) flying to ``target_e``."""
        range_to_go_m = radius * surface_angle(target_in_a(c_ae, target_e), ns)
        late = self.terminal is not None
        e = specific_energy(x, mu, radius) if self.potential == "energy" or self.fade_energies or late else None
        if self.potential == "range":
            off_m = range_to_go_m
        else:
            off_m = ns.fabs(range_to_go_m - ns.interp(e, self.energies, self.ranges))
        phi = -self.weight * off_m / 1000.0
        if self.fade_energies is not None:
            phi = phi * _rise(e, *self.fade_energies, ns)  # whole above e_full, none below e_zero
        if not late:
            return phi
        g = _rise(e, *self.terminal_energies[::-1], ns)  # none above e_none, whole below e_whole
        return phi - g * terminal_penalty(metrics_at(x, c_ae, self.final_speed, target_e, radius, ns), self.terminal, ns)

    def reward(self, phi_before, phi_after, terminal, ns):
        """F = gamma Phi(s') - Phi(s), with Phi(s') = 0 where the step ended the episode for good."""
        return self.gamma * ns.where(terminal, 0.0, phi_after) - phi_before

    def key(self) -> tuple:
        """The shaping's value, arrays included: equal shapings pay equal rewards (an unpickled copy too)."""
        arrays = tuple(None if a is None else (a.shape, a.tobytes()) for a in (self.energies, self.ranges))
        return (self.potential, self.gamma, self.weight, self.fade_energies, self.terminal, self.terminal_energies,
                self.final_speed, *arrays)

    def __eq__(self, other):
        return isinstance(other, PotentialShaping) and self.key() == other.key()

    def __hash__(self):
        return hash(self.key())

    def describe(self) -> dict:
        out = {"potential": self.potential, "gamma": self.gamma, "weight_per_km": self.weight}
        if self.energies is not None:
            out["profile_points"] = int(self.energies.size)
        if self.fade_energies is not None:
            out["fade_energies_j_per_kg"] = list(self.fade_energies)
        if self.terminal is not None:
            w = self.terminal
            out["terminal"] = {"miss_per_km": w.miss_per_km, "vertical_per_deg": w.vertical_per_deg,
                               "speed_per_mps": w.speed_per_mps, "alpha_per_deg": w.alpha_per_deg,
                               "energies_j_per_kg": list(self.terminal_energies), "final_speed_mps": self.final_speed}  # fmt: skip
        return out


def _energy_pair(pair, field: str, first: str, second: str) -> tuple[float, float]:
    """``pair`` as two floats (first, second) J/kg with first > second >= 0, or a ValueError naming ``field``."""
    try:
        a, b = (float(v) for v in pair)
    except (TypeError, ValueError):
        raise ValueError(f"shaping {field} must be two numbers ({first}, {second}) in J/kg, got {pair!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and a > b >= 0):
        raise ValueError(f"shaping {field} ({first}, {second}) must be finite with {first} > {second} >= 0 J/kg, "
                         f"got {pair!r}")  # fmt: skip
    return a, b


def _rise(e, to: float, frm: float, ns):
    """A weight linear in energy ``e``: 0 at ``frm``, 1 at ``to``, clipped to [0, 1] past them (either order)."""
    return ns.fmin(ns.fmax((e - frm) / (to - frm), 0.0), 1.0)


def check_shaping(shaping) -> PotentialShaping | None:
    if shaping is None or isinstance(shaping, PotentialShaping):
        return shaping
    raise TypeError(f"shaping must be a PotentialShaping (rventry_env.envs.shaping) or None, got {type(shaping).__name__}")


__all__ = ["POTENTIALS", "PotentialShaping", "check_shaping"]
