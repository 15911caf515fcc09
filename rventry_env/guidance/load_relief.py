"""Load relief: a predictive cap on the angle-of-attack rate that keeps the load factor in bound.

Near the ground the load factor is steep in alpha: at 5 km and Mach 5 one degree of alpha is
about 2 g. A law that tracks a plan riding the 12 g bound a fraction of a degree late overruns
it. :class:`LoadRelief` sits after any law's rates and, for each vehicle, predicts the load
factor one control step ahead with the rates the law asks for:

* the model's own forces and equations of motion (:func:`~rventry_env.physics.entry.entry_forces`,
  :func:`~rventry_env.physics.entry.entry_rhs`), one explicit step of the control interval;
* calibrated by what the accelerometer senses now: the prediction is scaled by the ratio of the
  sensed load factor to the model's at the current state, which absorbs the density and
  aerodynamic errors a dispersed vehicle flies with.

Where the prediction exceeds ``a_max (1 - margin)``, the alpha rate is lowered to the highest
rate whose predicted load meets that limit (down to the full down-rate when none does). The rate
enters the step only through alpha itself (the state's alpha derivative *is* the rate), so the
search needs the forces at the step's end alone, and it tries 15 rates per vehicle at once, four
halvings of the interval per evaluation: a batch pays four vectorized force evaluations, not one
per halving. The bank rate is untouched: the load factor does not depend on it. A cap on the
*rate*, one step ahead, acts only in the seconds where the bound is about to be crossed; a cap that
starts early takes away the lift the final pull-down turns the velocity vertical with
(docs/learned.md).

**A margin that follows the uncertainty of the next second** (``sigmas`` > 0 with ``density_bands``
and/or ``aero_mach_rms``). The calibration holds the density ratio and the aerodynamic error where
the vehicle is; one step later it is lower in the air and slower, where both differ. In a final dive
the vehicle drops more than a kilometre a second, and a density perturbation of 3 % rms with an
8 km correlation length moves the ratio by 1.6 % (1 sigma) in that second: on a flight-grade draw
the predicted load was 11.71 g and the flown one 12.16 g. With the atmosphere's published bands and
the aerodynamic database's spread in Mach, the limit for each vehicle is lowered by ``sigmas`` of
the spread between now and one step ahead (:func:`~rventry_env.task.flight_grade.band_spread` and
:func:`~rventry_env.physics.uncertainty.mach_spread` in quadrature): a chance constraint on the next
step that costs nothing in a glide, where the altitude barely changes.

It sees only what a vehicle measures: the navigation state and the sensed acceleration.
"""

from __future__ import annotations

import numpy as np

from rventry_env.task import EntryTask
from rventry_env.physics import EntryModel
from rventry_env.physics.entry import IDX, entry_forces, entry_rhs
from rventry_env.physics.uncertainty import MachVaryingAerodynamics

SEARCH_BITS = 4  # halvings per vectorized evaluation: 15 trial rates per vehicle


class RateLimiter:
    """What a limiter of a law's rates shares (:class:`LoadRelief`, :class:`~rventry_env.guidance.q_floor.QFloor`):
    its model and task, :attr:`active` (N,), the vehicles it changed in the last call, :attr:`steps`
    (N,), the steps it changed each vehicle's rates since :meth:`reset`, and the checks of a call's
    inputs. ``who`` names it in an error."""

    who = "a rate limiter"

    def __init__(self, model: EntryModel | None, task: EntryTask | None):
        self.model = EntryModel() if model is None else model
        self.task = EntryTask() if task is None else task
        self.reset(0)

    def reset(self, n: int) -> None:
        self.active = np.zeros(n, dtype=bool)
        self.steps = np.zeros(n, dtype=np.int64)

    def _inputs(self, rates, state, sensed_accel_b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A call's rates (a copy, N x 2), navigation states (N, 12) and sensed acceleration (N, 3) as
        float arrays, checked; a batch of another size starts the counts again."""
        if sensed_accel_b is None:
            raise ValueError(f"{self.who} needs the sensed acceleration (info['sensed_accel_b'])")
        rates = np.array(rates, dtype=float)
        x = np.asarray(state, dtype=float)
        sensed = np.asarray(sensed_accel_b, dtype=float)
        if rates.shape != (len(x), 2) or x.shape[1:] != (12,) or sensed.shape != (len(x), 3):
            raise ValueError(f"{self.who} needs rates (N, 2), state (N, 12) and sensed acceleration (N, 3), got "
                             f"{rates.shape}, {x.shape} and {sensed.shape}")  # fmt: skip
        if len(self.steps) != len(x):
            self.reset(len(x))
        return rates, x, sensed

    def _count(self, count) -> None:
        """Add this call's :attr:`active` to :attr:`steps`; ``count`` (N,) bool, when given, the
        vehicles counted (a caller leaves out the frozen copies of ended episodes)."""
        self.steps += self.active if count is None else self.active & np.asarray(count, dtype=bool)


class LoadRelief(RateLimiter):
    """Caps the alpha rate of a batch of vehicles so that the predicted load factor stays at or
    below ``a_max (1 - margin)``.

    :param margin: fraction of the bound kept free (0 <= margin < 1).
    :param iterations: halvings of the alpha rate's interval (a resolution of 2 / 2**iterations of
        its bound or finer), made four at a time.
    :param sigmas: lower each vehicle's limit by this many sigma of the spread of the density ratio
        (``density_bands``, the atmosphere's Gauss-Markov bands) and of the aerodynamic error
        (``aero_mach_rms`` per Legendre coefficient over ``aero_mach_range``) between now and one
        step ahead (0: the fixed margin alone).

    After each call, :attr:`active` (N,) says which vehicles were capped, and :attr:`steps`
    (N,) counts the capped steps of each vehicle since :meth:`reset`.
    """

    who = "load relief"

    def __init__(self, model: EntryModel | None = None, task: EntryTask | None = None, margin: float = 0.01,
                 iterations: int = 14, sigmas: float = 0.0, density_bands: tuple | None = None,
                 aero_mach_rms: float | None = None,
                 aero_mach_range: tuple = (MachVaryingAerodynamics.mach_low, MachVaryingAerodynamics.mach_high)):  # fmt: skip
        if not (0.0 <= margin < 1.0):
            raise ValueError(f"load relief margin must lie in [0, 1), got {margin!r}")
        if int(iterations) < 1:
            raise ValueError(
                f"load relief needs at least one halving of the rate interval, got iterations = {iterations!r}"
            )
        if not (np.isfinite(sigmas) and sigmas >= 0):
            raise ValueError(f"load relief sigmas must be a finite number >= 0, got {sigmas!r}")
        if sigmas > 0 and density_bands is None and aero_mach_rms is None:
            raise ValueError("load relief sigmas need the uncertainty they count: density_bands and/or aero_mach_rms")
        if density_bands is not None:
            from rventry_env.task.flight_grade import parse_bands

            density_bands = parse_bands(density_bands, "load relief density_bands")
        self.sigmas, self.density_bands = float(sigmas), density_bands
        self.aero_mach_rms, self.aero_mach_range = aero_mach_rms, tuple(aero_mach_range)
        super().__init__(model, task)
        self.margin = float(margin)
        self.iterations = int(iterations)
        self.limit_g = self.task.problem.a_max_g * (1.0 - self.margin)

    def _loads(self, x: np.ndarray, u_alpha: np.ndarray, u_sigma: np.ndarray):
        """The model's load factor (g) now and one control step ahead with the given rates (rad/s),
        the state one step ahead, and each vehicle's limit (g) for that step."""
        g0 = self.model.planet.g0
        f = entry_forces(tuple(x.T), self.model)
        x_ahead = x + self.task.dt * np.stack(entry_rhs(tuple(x.T), (u_alpha, u_sigma), self.model, forces=f), axis=1)
        ahead = entry_forces(tuple(x_ahead.T), self.model)
        spread = np.zeros(len(x))
        if self.sigmas > 0:
            if self.density_bands is not None:
                from rventry_env.task.flight_grade import band_spread

                spread = band_spread(self.density_bands, np.asarray(f.altitude), np.asarray(ahead.altitude))
            if self.aero_mach_rms is not None:
                from rventry_env.physics.uncertainty import mach_spread

                m = mach_spread(self.aero_mach_rms, np.asarray(f.mach), np.asarray(ahead.mach), *self.aero_mach_range)
                spread = np.hypot(spread, m)
        limit = self.limit_g * np.exp(-self.sigmas * spread)
        return np.asarray(f.aero_accel) / g0, np.asarray(ahead.aero_accel) / g0, x_ahead, limit

    def _load_at_alpha(self, x_ahead: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """The load factor (g) of states ``x_ahead`` (N, 12) with alpha set to ``alpha`` (N, M): (N, M)."""
        n, m = alpha.shape
        xs = np.repeat(x_ahead, m, axis=0)
        xs[:, IDX.alpha] = alpha.ravel()
        return (np.asarray(entry_forces(tuple(xs.T), self.model).aero_accel) / self.model.planet.g0).reshape(n, m)

    def __call__(self, rates, state, sensed_accel_b, count=None) -> np.ndarray:
        """The rates (N, 2), fractions of their bounds, with the alpha rate capped where needed.
        ``count`` (N,) bool: which vehicles' capped steps :attr:`steps` counts (default all; a
        caller leaves out the frozen copies of ended episodes)."""
        rates, x, sensed = self._inputs(rates, state, sensed_accel_b)
        p = self.task.problem
        n_now, n_ahead, x_ahead, limit = self._loads(x, rates[:, 0] * p.u_alpha_max, rates[:, 1] * p.u_sigma_max)
        calib = np.linalg.norm(sensed, axis=1) / self.model.planet.g0 / np.maximum(n_now, 1e-9)
        over = calib * n_ahead > limit
        self.active = over
        if np.any(over):
            self._count(count)
            xs, k, alpha0, lim = x_ahead[over], calib[over], x[over, IDX.alpha], limit[over, None]
            lo = np.full(len(xs), -1.0)  # the full down-rate: taken when no rate meets the limit
            hi = rates[over, 0]  # over the limit
            left = self.iterations
            while left > 0:
                bits = min(SEARCH_BITS, left)
                left -= bits
                width = (hi - lo) / 2**bits
                trial = lo[:, None] + width[:, None] * np.arange(1, 2**bits)  # the interval's inner grid points
                alpha = alpha0[:, None] + self.task.dt * p.u_alpha_max * trial
                ok = k[:, None] * self._load_at_alpha(xs, alpha) <= lim
                j = np.where(ok.any(axis=1), ok.shape[1] - np.argmax(ok[:, ::-1], axis=1), 0)  # highest ok point, 0: lo
                lo, hi = lo + j * width, lo + (j + 1) * width
            rates[over, 0] = lo
        return rates


__all__ = ["RateLimiter", "LoadRelief"]
