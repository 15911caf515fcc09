"""Controls of a replay, taken from the record: angle of attack and bank at any time.

The record gives the conventional bank mu (0 = lift up). The rv-Euler dynamics
need the paper's sigma, which depends on the state: sigma = mu + theta_u, with
theta_u the lift-up angle of the current velocity frame
(:func:`~rventry_env.core.conversions.lift_up_angle`). So the bank is converted
at every evaluation of the right-hand side, not once per sample.

A capsule may instead record the vertical lift-to-drag ratio; then
mu = +-arccos((L/D)_v / (L/D)) with the declared L/D, the sign taken from a bank
record if there is one (lift to the right otherwise).

Between samples the controls are interpolated by modified Akima cubics (the bank
after unwrapping, so a roll through 180 deg is not interpolated the long way
round). Why not linear: a chord always lies on one side of a curving control, so
its error accumulates; on a 1 Hz record of a smoothly varying CAV-H flight linear
interpolation alone leaves 3 m of position error after 400 s, Akima a few
millimetres. Akima rather than a global spline because it stays local: one bad
sample (the digitised Apollo data have some) only disturbs its neighbours.
Outside a control's first and last sample it is held. Both are reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rventry_env.validation.record import FlightRecord, RecordError


class Interpolant:
    """A control history through its finite samples, held constant beyond its ends.

    :param t: sample times (s), increasing.
    :param v: values.
    """

    def __init__(self, t: np.ndarray, v: np.ndarray):
        self.t = np.asarray(t, float)
        self.v = np.asarray(v, float)
        self._spline = None
        self._rate = None
        if len(self.t) >= 5:
            from scipy.interpolate import Akima1DInterpolator

            self._spline = Akima1DInterpolator(self.t, self.v, method="makima")

    def __call__(self, t: float) -> float:
        tc = min(max(t, self.t[0]), self.t[-1])
        if self._spline is None:
            return float(np.interp(tc, self.t, self.v))
        return float(self._spline(tc))

    def many(self, t: np.ndarray) -> np.ndarray:
        """Values at an array of times (held beyond the ends)."""
        tc = np.clip(np.asarray(t, float), self.t[0], self.t[-1])
        if self._spline is None:
            return np.interp(tc, self.t, self.v)
        return np.asarray(self._spline(tc), float)

    def rate(self, t: np.ndarray) -> np.ndarray:
        """Time derivatives at an array of times: the interpolant's own (0 where it is held beyond the ends)."""
        t = np.asarray(t, float)
        inside = (t >= self.t[0]) & (t <= self.t[-1])
        tc = np.clip(t, self.t[0], self.t[-1])
        if self._spline is None:
            k = np.clip(np.searchsorted(self.t, tc, side="right") - 1, 0, len(self.t) - 2)
            slope = (self.v[k + 1] - self.v[k]) / (self.t[k + 1] - self.t[k])
        else:
            if self._rate is None:
                self._rate = self._spline.derivative()
            slope = np.asarray(self._rate(tc), float)
        return np.where(inside, slope, 0.0)


def _series(t: np.ndarray, values: np.ndarray | None, unwrap: bool = False) -> Interpolant | None:
    if values is None:
        return None
    ok = np.isfinite(values)
    if not np.any(ok):
        return None
    v = values[ok]
    if unwrap:
        v = np.unwrap(v)
    return Interpolant(t[ok], v)


@dataclass
class ControlSchedule:
    """Control histories (modified Akima cubics through the samples).

    :param alpha: angle of attack (rad) history, or None (held at ``alpha_default``).
    :param bank: conventional bank mu (rad, unwrapped) history, or None.
    :param ld_vertical: vertical L/D history, or None.
    :param lift_to_drag: the declared L/D used with ``ld_vertical``.
    :param alpha_default: angle of attack when the record has none (a capsule's trim is in its C_D).
    :param notes: how the record's controls are used.
    """

    alpha: Interpolant | None
    bank: Interpolant | None
    ld_vertical: Interpolant | None
    lift_to_drag: float | None
    alpha_default: float = 0.0
    notes: list = field(default_factory=list)
    _cache: dict = field(default_factory=dict, repr=False)

    def at(self, t: float) -> tuple[float, float]:
        """(alpha, conventional bank mu) in rad at time ``t``.

        Cached per time: a replay asks for the same RK4 stage times on every pass.
        """
        hit = self._cache.get(t)
        if hit is None:
            hit = self._cache[t] = (self._alpha(t), self._bank(t))
        return hit

    def many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(alpha, conventional bank mu) in rad at an array of times (same values as :meth:`at`)."""
        t = np.asarray(t, float)
        alpha = np.full(t.shape, self.alpha_default) if self.alpha is None else self.alpha.many(t)
        if self.ld_vertical is not None:
            ratio = self.ld_vertical.many(t) / self.lift_to_drag
            mu = np.arccos(np.clip(ratio, -1.0, 1.0))
            if self.bank is not None:
                mu = np.where(np.sin(self.bank.many(t)) < 0, -mu, mu)
        elif self.bank is None:
            mu = np.zeros(t.shape)
        else:
            mu = self.bank.many(t)
        return alpha, mu

    def rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Time derivatives (rad/s) of :meth:`many`'s alpha and mu at an array of times.

        A bank from the vertical L/D, mu = +-arccos((L/D)_v / (L/D)), has the derivative of the arccos
        (0 where the ratio is clipped); the sign taken from the bank record changes nowhere smoothly
        and has none.
        """
        t = np.asarray(t, float)
        alpha_rate = np.zeros(t.shape) if self.alpha is None else self.alpha.rate(t)
        if self.ld_vertical is not None:
            ratio = self.ld_vertical.many(t) / self.lift_to_drag
            inside = np.abs(ratio) < 1.0
            mu_rate = np.where(inside, -self.ld_vertical.rate(t) / self.lift_to_drag
                               / np.sqrt(np.where(inside, 1.0 - ratio * ratio, 1.0)), 0.0)  # fmt: skip
            if self.bank is not None:
                mu_rate = np.where(np.sin(self.bank.many(t)) < 0, -mu_rate, mu_rate)
        elif self.bank is None:
            mu_rate = np.zeros(t.shape)
        else:
            mu_rate = self.bank.rate(t)
        return alpha_rate, mu_rate

    def _alpha(self, t: float) -> float:
        return self.alpha_default if self.alpha is None else self.alpha(t)

    def _bank(self, t: float) -> float:
        if self.ld_vertical is not None:
            ratio = self.ld_vertical(t) / self.lift_to_drag
            mu = float(np.arccos(np.clip(ratio, -1.0, 1.0)))
            if self.bank is not None and np.sin(self.bank(t)) < 0:
                mu = -mu
            return mu
        return 0.0 if self.bank is None else self.bank(t)


def control_schedule(record: FlightRecord, lift_to_drag: float | None, needs_alpha: bool) -> ControlSchedule:
    """Build the control histories of a record.

    :param record: the validated record.
    :param lift_to_drag: declared constant L/D of a capsule (None for a lifting body).
    :param needs_alpha: True when the aerodynamic model depends on the angle of attack.
    :raises RecordError: when the record lacks a control the vehicle needs.
    """
    t = record.t
    alpha = _series(t, record.alpha)
    bank = _series(t, record.bank, unwrap=True)
    ldv = _series(t, record.lift_to_drag_vertical)
    notes = []
    if needs_alpha and alpha is None:
        raise RecordError(
            "missing column alpha_rad: this vehicle's aerodynamics depend on the angle of attack"
        )
    if ldv is not None and lift_to_drag is None:
        raise RecordError(
            "column lift_to_drag_vertical needs a capsule with a declared constant L/D "
            "(vehicle.aerodynamics.type 'constant' in the sidecar or --vehicle file)"
        )
    if ldv is not None and lift_to_drag <= 0:
        raise RecordError("column lift_to_drag_vertical needs a declared lift_to_drag > 0")
    if bank is None and ldv is None:
        notes.append("no bank_rad or lift_to_drag_vertical column: flown lift up (mu = 0)")
    if alpha is None and not needs_alpha:
        notes.append("no alpha_rad column: not needed (constant aerodynamic coefficients)")
    elif record.alpha is not None and not needs_alpha:
        notes.append("column alpha_rad ignored: the aerodynamic coefficients do not depend on it")
    if ldv is not None:
        n_over = int(np.count_nonzero(np.abs(ldv.v) > lift_to_drag))
        notes.append(
            f"bank from lift_to_drag_vertical: mu = arccos((L/D)_v / {lift_to_drag:g})"
            + (", sign from bank_rad" if bank is not None else ", sign positive (no bank_rad)")
            + (f"; {n_over} sample(s) with |(L/D)_v| > L/D clipped" if n_over else "")
        )
    obs_t = record.t[record.observed_rows]
    for name, s in (("alpha_rad", alpha), ("bank_rad", bank), ("lift_to_drag_vertical", ldv)):
        if s is None:
            continue
        # a merged time axis leaves a control's field empty in the rows of other series: that is
        # not missing data; what matters is how long the control goes without a sample
        steps = np.diff(s.t)
        if steps.size:
            k = int(np.argmax(steps))
            typical = float(np.median(steps))
            if steps[k] > LONG_GAP_FACTOR * typical:
                notes.append(
                    f"{name}: sampled every {typical:g} s; longest interval {steps[k]:g} s "
                    f"({s.t[k]:g} to {s.t[k + 1]:g} s), interpolated"
                )
        if s.t[0] > obs_t[0] or s.t[-1] < obs_t[-1]:
            notes.append(f"{name}: covers {s.t[0]:g} to {s.t[-1]:g} s only, held at its end values outside")
    return ControlSchedule(alpha, bank, ldv, lift_to_drag, notes=notes)


LONG_GAP_FACTOR = 3.0  # a control interval this many times its typical sampling step is reported

__all__ = ["ControlSchedule", "Interpolant", "control_schedule"]
