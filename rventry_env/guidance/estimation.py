"""Online estimation of the aerodynamic scale factors an accelerometer makes observable.

An accelerometer measures the aerodynamic specific force. With the navigation state
(altitude, speed, alpha, sigma) the nominal model predicts it; the ratio of the two
tells how far the true vehicle and atmosphere are from the model. Not every cause
can be told apart: the drag acceleration is rho C_D S v^2 / (2 m), so a density error,
a C_D error and a mass error look the same. What the measurement fixes is

* the **drag-acceleration scale** k_D = D_measured / D_model, and
* the **lift-to-drag scale** k_LD = (L/D)_measured / (L/D)_model,

and :func:`~rventry_env.physics.model.with_aero_scales` turns the two into a model
whose accelerations match (a guidance law keeps a margin on the dynamic pressure
for the part of k_D that may be density).

The filter
----------
Two scalar Kalman filters, one on k_D and one on the lift-acceleration scale
k_L = L_measured / L_model = k_D k_LD, each a random walk:

* **state and process noise**: k(t + dt) = k(t) + w, var(w) = ``drift^2 dt``. The
  drift (default 0.002 per sqrt(s)) is how fast an error may change along the flight
  (a density error that varies with altitude);
* **measurement**: z = a_measured / a_model with variance ``(accel_noise / |a_model|)^2``,
  the accelerometer's noise (default 0.05 m/s^2, 5 mg: a conservative tactical-grade
  figure) relative to the acceleration the model predicts. A measurement the model
  predicts to be small (little lift near alpha = 0) is therefore weighted little;
* **prior**: k = 1 +/- ``prior_sigma`` (0.2);
* **bounds**: an update that would carry a factor outside ``scale_bounds`` (0.1 to 10) is
  rejected and counted in :attr:`AeroScaleEstimator.rejected`. A measurement the model cannot
  explain (the lift seen along the commanded direction turned negative by a wind the model
  does not have, say) would otherwise drive k_L through zero, and ln k_LD, which the laws
  feed forward, to NaN. An update with a small gain (a measurement the model predicts to be
  small, weighted little) stays inside the bounds and is taken as before.

The lift is measured along the commanded lift direction (cos sigma b2 + sin sigma b3),
so the sign of C_L (negative at small alpha and high Mach) is kept. The filter
reports k_D, k_LD = k_L / k_D and their standard deviations (first-order
propagation for the ratio). With the defaults and the standard dispersions the
estimate is within 0.5 % of the truth after the first measurement (measured by
``tests/guidance/test_estimation.py``); with 0.05 m/s^2 white noise on every axis, within 0.5 %
after 2 s.

Everything is batched: one filter per vehicle, arrays of length N.

For flight-grade uncertainty, :class:`FlightEstimator` (below) replaces the fixed drift with the
published statistics (density as a process in altitude, the aerodynamic error in Mach) and adds
the horizontal wind; :func:`make_estimator` builds either from its settings.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics.entry import IDX, entry_forces
from rventry_env.physics.model import EntryModel
from rventry_env.physics.uncertainty import MachVaryingAerodynamics


@dataclass(frozen=True)
class EstimatorSettings:
    """Tuning of :class:`AeroScaleEstimator`.

    :param accel_noise: accelerometer noise, standard deviation per axis (m/s^2).
    :param drift: random-walk rate of the scale factors (1/sqrt(s)).
    :param prior_sigma: standard deviation of the factors before any measurement.
    """

    accel_noise: float = 0.05
    drift: float = 0.002
    prior_sigma: float = 0.2
    scale_bounds: tuple = (0.1, 10.0)

    def __post_init__(self):
        for name in ("accel_noise", "drift", "prior_sigma"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        lo, hi = self.scale_bounds
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < 1 < hi):
            raise ValueError(f"scale_bounds must be (low, high) with 0 < low < 1 < high, got {self.scale_bounds}")


class _ScaleEstimator:
    """What every estimator gives a guidance law: ``observe`` a measurement, the log-scales after it.
    A subclass has ``n``, ``reset``, ``update`` and the two scale properties."""

    def observe(self, measurement) -> np.ndarray:
        """Fold in a guidance law's :class:`~rventry_env.guidance.law.Measurement` (a batch of another
        size starts the filters again); the log-scales (N, 2) after it."""
        if self.n != measurement.n:
            self.reset(measurement.n)
        self.update(measurement.time_s, measurement.navigation_state, measurement.sensed_accel_b)
        return self.log_scales()

    def log_scales(self) -> np.ndarray:
        """(ln k_D, ln k_LD) per vehicle (N, 2): the parameters of the re-planning problem."""
        return np.log(np.stack([self.drag_accel_scale, self.lift_to_drag_scale], axis=-1))

    def _select(self, time_s, state, sensed_accel_b, rows):
        """The rows an update folds in (all by default), with their times, states and sensed forces."""
        idx = np.arange(self.n) if rows is None else np.asarray(rows)
        t = np.asarray(time_s, dtype=float).reshape(-1)[idx] if np.ndim(time_s) else np.full(idx.size, float(time_s))
        return idx, t, np.asarray(state, dtype=float)[idx], np.asarray(sensed_accel_b, dtype=float)[idx]


class AeroScaleEstimator(_ScaleEstimator):
    """Batched Kalman filters on the drag-acceleration and lift-to-drag scale factors.

    :param model: the nominal model the measurements are compared with.
    :param n: number of vehicles.
    :param settings: :class:`EstimatorSettings`.
    """

    def __init__(self, model: EntryModel | None = None, n: int = 1, settings: EstimatorSettings | None = None):
        self.model = EntryModel() if model is None else model
        self.settings = EstimatorSettings() if settings is None else settings
        self.reset(n)

    def reset(self, n: int) -> None:
        """Forget everything: n vehicles at the prior."""
        self.n = int(n)
        self.k = np.empty((self.n, 2))  # (k_D, k_L)
        self.var = np.empty((self.n, 2))
        self.t_last = np.empty(self.n)
        self.updates = np.empty(self.n, dtype=int)
        self.rejected = np.empty(self.n, dtype=int)  # per vehicle: factor updates refused by scale_bounds
        self.reset_rows(slice(None))

    def reset_rows(self, rows) -> None:
        """Forget everything for the vehicles ``rows`` (new episodes, or all): back to the prior."""
        self.k[rows] = 1.0
        self.var[rows] = self.settings.prior_sigma**2
        self.t_last[rows] = np.nan
        self.updates[rows] = 0
        self.rejected[rows] = 0

    def update(self, time_s, state, sensed_accel_b, rows=None) -> None:
        """Fold in one measurement per vehicle.

        :param time_s: measurement times (N,), s.
        :param state: navigation states (N, 12).
        :param sensed_accel_b: sensed aerodynamic specific force (N, 3), B components.
        :param rows: update only these vehicles (default: all).
        """
        idx, t, x, a = self._select(time_s, state, sensed_accel_b, rows)
        if idx.size == 0:
            return
        f = entry_forces(tuple(x.T), self.model, NUMPY)
        sigma = x[:, IDX.sigma]
        d_meas = -a[:, 0]
        l_meas = a[:, 1] * np.cos(sigma) + a[:, 2] * np.sin(sigma)  # along the commanded lift direction
        pred = np.stack([f.drag_accel, f.lift_accel], axis=-1)
        meas = np.stack([d_meas, l_meas], axis=-1)
        s = self.settings
        # predict: random walk over the time since the last measurement
        dt = np.where(np.isfinite(self.t_last[idx]), t - self.t_last[idx], 0.0)
        var = self.var[idx] + s.drift**2 * np.maximum(dt, 0.0)[:, None]
        k = self.k[idx]
        with np.errstate(divide="ignore", invalid="ignore"):
            z = meas / pred
            r = (s.accel_noise / np.abs(pred)) ** 2
        ok = np.isfinite(z) & np.isfinite(r) & np.all(np.isfinite(a), axis=1, keepdims=True)
        gain = np.where(ok, var / (var + np.where(ok, r, 1.0)), 0.0)
        k_new = k + gain * np.where(ok, z - k, 0.0)
        lo, hi = s.scale_bounds
        inside = (k_new >= lo) & (k_new <= hi)
        self.rejected[idx] += np.count_nonzero(ok & ~inside, axis=1)
        gain = np.where(inside, gain, 0.0)
        self.k[idx] = np.where(inside, k_new, k)
        self.var[idx] = (1.0 - gain) * var
        self.t_last[idx] = t
        self.updates[idx] += 1

    @property
    def drag_accel_scale(self) -> np.ndarray:
        """k_D (N,)."""
        return self.k[:, 0].copy()

    @property
    def lift_to_drag_scale(self) -> np.ndarray:
        """k_LD = k_L / k_D (N,)."""
        return self.k[:, 1] / self.k[:, 0]

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviations (N, 2) of k_D and k_LD (the ratio by first-order propagation)."""
        kd, kl = self.k[:, 0], self.k[:, 1]
        vd, vl = self.var[:, 0], self.var[:, 1]
        v_ld = vl / kd**2 + vd * kl**2 / kd**4
        return np.stack([np.sqrt(vd), np.sqrt(v_ld)], axis=-1)

    def estimated_model(self, i: int) -> EntryModel:
        """Vehicle i's model with its current estimates (:func:`~rventry_env.physics.model.with_aero_scales`)."""
        from rventry_env.physics.model import with_aero_scales

        return with_aero_scales(self.model, float(self.drag_accel_scale[i]), float(self.lift_to_drag_scale[i]))



# ---------------------------------------------------------------------------------------------
# Flight-grade estimation: density as a process in altitude, the aerodynamics as a process in
# Mach, and the horizontal wind
# ---------------------------------------------------------------------------------------------

WIND_LIMIT_MPS = 250.0  # an update that would carry a wind component past this is refused (counted)


@dataclass(frozen=True)
class FlightEstimatorSettings:
    """Tuning of :class:`FlightEstimator`: the published statistics of what it estimates, never a draw.

    :param accel_noise: accelerometer error per axis and sample (m/s^2): its noise, with room for
        its bias, scale and misalignment, which the filter does not model as states.
    :param drift: random walk of ln k_D and ln k_L in time (1/sqrt(s)), for whatever varies and
        has no statistics below.
    :param prior_sigma: standard deviation of ln k_D and ln k_L before any measurement.
    :param density_bands: the atmosphere's Gauss-Markov ln-density bands ((top m, rms, correlation
        length m), ...): moving dh in altitude adds 2 rms^2 (1 - exp(-|dh| / L)) to the variance of
        ln rho (:func:`~rventry_env.task.flight_grade.band_spread` squared), which scales the drag and the
        lift alike (one increment on both ln k_D and ln k_L).
    :param aero_mach_rms: the aerodynamic database's rms per Legendre coefficient in Mach
        (:func:`~rventry_env.physics.uncertainty.mach_legendre`, over ``aero_mach_range``): moving
        from Mach M to M' adds rms^2 |dP(M, M')|^2 to the variance of ln C_D and of ln C_L,
        independently.
    :param wind_sigma: prior rms of each horizontal wind component (m/s); None: no wind states.
    :param wind_bands: the wind's Gauss-Markov bands in altitude (rms m/s), as ``density_bands``;
        a component's variance never grows past ``wind_sigma``^2 plus the band's rms^2.
    """

    accel_noise: float = 0.05
    drift: float = 0.002
    prior_sigma: float = 0.2
    scale_bounds: tuple = (0.1, 10.0)
    density_bands: tuple | None = None
    aero_mach_rms: float | None = None
    aero_mach_range: tuple = (MachVaryingAerodynamics.mach_low, MachVaryingAerodynamics.mach_high)
    wind_sigma: float | None = None
    wind_bands: tuple | None = None

    def __post_init__(self):
        EstimatorSettings(self.accel_noise, self.drift, self.prior_sigma, self.scale_bounds)  # the shared checks
        from rventry_env.task.flight_grade import parse_bands

        for name in ("density_bands", "wind_bands"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, parse_bands(getattr(self, name), name))
        for name in ("aero_mach_rms", "wind_sigma"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be None (off) or a finite number >= 0, got {v!r}")
        if self.wind_bands is not None and self.wind_sigma is None:
            raise ValueError("wind_bands need wind_sigma: the wind states' prior")
        r = tuple(self.aero_mach_range)
        if not (len(r) == 2 and all(np.isfinite(v) for v in r) and 0 < r[0] < r[1]):
            raise ValueError(f"aero_mach_range must be (low, high) with 0 < low < high, got {self.aero_mach_range!r}")

    @classmethod
    def flight_grade(cls, **changes) -> "FlightEstimatorSettings":
        """The ``flight`` set's published statistics: its density and wind bands, its wind mean
        (10 m/s rms) and its aerodynamic database's 3 % rms per Legendre coefficient."""
        from rventry_env.task import FLIGHT_GRADE_ERRORS as F

        base = dict(density_bands=F.density_bands, aero_mach_rms=max(F.lift_mach, F.drag_mach),
                    wind_sigma=F.wind_mean_mps, wind_bands=F.wind_bands)
        return cls(**(base | changes))

    @property
    def n_states(self) -> int:
        return 2 if self.wind_sigma is None else 4


def _band_variance(bands, h_from, h_to) -> np.ndarray:
    """Variance a Gauss-Markov process in altitude gains from h_from to h_to
    (:func:`~rventry_env.task.flight_grade.band_spread` squared; zero without bands)."""
    if bands is None:
        return np.zeros_like(np.asarray(h_to, dtype=float))
    from rventry_env.task.flight_grade import band_spread

    return band_spread(bands, h_from, h_to) ** 2


class FlightEstimator(_ScaleEstimator):
    """An extended Kalman filter on the aerodynamic scales and the horizontal wind, batched over N vehicles.

    State per vehicle: theta = (ln k_D, ln k_L[, w_east, w_north]): the logarithms of the drag- and
    lift-acceleration scale factors (k_LD = k_L / k_D, as :class:`AeroScaleEstimator`) and the
    horizontal wind (m/s). The measurement is the whole sensed aerodynamic specific force (three B
    components), predicted by the one physics (:func:`~rventry_env.physics.entry.entry_forces`) on
    the navigation state with the scales and a uniform wind; its Jacobian is taken by differences.
    Why the wind: drag acts along the air-relative velocity, so a wind across the flight puts a
    part of the drag, D w / v, into the plane the lift is measured in. A filter without it reads
    that as lift: in a dive at 2 km/s a 20 m/s wind shifts 1 % of the drag, a sizeable fraction
    of the lift near alpha = 0.

    The process is what the statistics publish, not a fixed drift: ln k_D and ln k_L take one common
    increment as the altitude changes (density, :attr:`FlightEstimatorSettings.density_bands`) and
    independent ones as the Mach number changes (the database, ``aero_mach_rms``); the wind
    components take the wind bands' increments. In a glide, where the altitude barely changes, the
    filter averages long; in the final dive, where the air changes every few seconds, it follows.

    An update that would carry a scale outside ``scale_bounds`` or a wind component past
    :data:`WIND_LIMIT_MPS` is refused and counted (:attr:`rejected`).
    """

    def __init__(self, model: EntryModel | None = None, n: int = 1, settings: FlightEstimatorSettings | None = None):
        self.model = EntryModel() if model is None else model
        self.settings = FlightEstimatorSettings() if settings is None else settings
        self.reset(n)

    def reset(self, n: int) -> None:
        """Forget everything: n vehicles at the prior."""
        m = self.settings.n_states
        self.n = int(n)
        self.theta = np.zeros((self.n, m))
        self.cov = np.zeros((self.n, m, m))
        self.t_last = np.empty(self.n)
        self.h_last = np.empty(self.n)
        self.mach_last = np.empty(self.n)
        self.updates = np.empty(self.n, dtype=int)
        self.rejected = np.empty(self.n, dtype=int)
        self.reset_rows(slice(None))

    def reset_rows(self, rows) -> None:
        """Forget everything for the vehicles ``rows``: back to the prior."""
        s = self.settings
        prior = [s.prior_sigma**2] * 2 + ([s.wind_sigma**2] * 2 if s.wind_sigma is not None else [])
        self.theta[rows] = 0.0
        self.cov[rows] = np.diag(prior)
        self.t_last[rows] = np.nan
        self.h_last[rows] = np.nan
        self.mach_last[rows] = np.nan
        self.updates[rows] = 0
        self.rejected[rows] = 0

    def model_at(self, theta: np.ndarray) -> EntryModel:
        """The model with the scales and wind ``theta`` (N, n_states), one per vehicle."""
        from rventry_env.physics.model import with_aero_scales
        from rventry_env.physics.wind import HorizontalWind

        kd, kl = np.exp(theta[:, 0]), np.exp(theta[:, 1])
        model = with_aero_scales(self.model, kd, kl / kd)
        if theta.shape[1] == 4:
            model = replace(model, wind=HorizontalWind(east=theta[:, 2].copy(), north=theta[:, 3].copy()))
        return model

    def predicted(self, state: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The aerodynamic specific force (N, 3), B components, the model predicts at ``state`` with ``theta``."""
        return np.stack(entry_forces(tuple(state.T), self.model_at(theta), NUMPY).aero_b, axis=-1)

    def _process(self, idx, t, x) -> np.ndarray:
        """Process-noise covariance (n, m, m) from the last update to this one."""
        s = self.settings
        m = s.n_states
        h = x[:, IDX.r] - self.model.planet.radius
        mach = np.asarray(entry_forces(tuple(x.T), self.model, NUMPY).mach, dtype=float)
        first = ~np.isfinite(self.t_last[idx])
        dt = np.where(first, 0.0, np.maximum(t - np.where(first, t, self.t_last[idx]), 0.0))
        h0 = np.where(first, h, self.h_last[idx])
        q = np.zeros((len(idx), m, m))
        q[:, 0, 0] = q[:, 1, 1] = s.drift**2 * dt
        q[:, :2, :2] += _band_variance(s.density_bands, h0, h)[:, None, None]  # density: both alike
        if s.aero_mach_rms is not None:
            from rventry_env.physics.uncertainty import mach_spread

            m0 = np.where(first, mach, self.mach_last[idx])
            da = mach_spread(s.aero_mach_rms, m0, mach, *s.aero_mach_range) ** 2
            q[:, 0, 0] += da
            q[:, 1, 1] += da
        if m == 4:
            dw = _band_variance(s.wind_bands, h0, h)
            cap = s.wind_sigma**2
            if s.wind_bands is not None:
                from rventry_env.task.flight_grade import band_profile

                cap = cap + band_profile(s.wind_bands, h)[0] ** 2  # the mean's prior and the band's rms
            for j in (2, 3):
                q[:, j, j] = np.clip(np.minimum(dw, cap - self.cov[idx, j, j]), 0.0, None)
        self.h_last[idx], self.mach_last[idx] = h, mach
        return q

    def update(self, time_s, state, sensed_accel_b, rows=None) -> None:
        """Fold in one measurement per vehicle (times (N,), navigation states (N, 12), sensed
        specific force (N, 3) in B components); ``rows``: only these vehicles."""
        idx, t, x, z = self._select(time_s, state, sensed_accel_b, rows)
        if idx.size == 0:
            return
        s = self.settings
        m = s.n_states
        p = self.cov[idx] + self._process(idx, t, x)
        th = self.theta[idx]
        # the prediction and its Jacobian by forward differences, in one force evaluation: the
        # estimate and the m nudged copies of it, stacked
        k = len(idx)
        steps = np.array([1e-6, 1e-6, 1e-3, 1e-3])[:m]
        nudged = np.repeat(th[None], m + 1, axis=0)
        nudged[1 + np.arange(m), :, np.arange(m)] += steps[:, None]
        forces = self.predicted(np.tile(x, (m + 1, 1)), nudged.reshape(-1, m)).reshape(m + 1, k, 3)
        pred = forces[0]
        jac = ((forces[1:] - pred) / steps[:, None, None]).transpose(1, 2, 0)  # (k, 3, m)
        innov = z - pred
        ok = np.all(np.isfinite(innov), axis=1) & np.all(np.isfinite(jac), axis=(1, 2))
        innov = np.where(ok[:, None], innov, 0.0)
        jac = np.where(ok[:, None, None], jac, 0.0)
        ph = p @ jac.transpose(0, 2, 1)  # (n, m, 3)
        cov_z = jac @ ph + s.accel_noise**2 * np.eye(3)
        gain = np.linalg.solve(cov_z, ph.transpose(0, 2, 1)).transpose(0, 2, 1)  # P H^T S^-1
        th_new = th + np.einsum("nij,nj->ni", gain, innov)
        lo, hi = np.log(s.scale_bounds)
        inside = np.all((th_new[:, :2] >= lo) & (th_new[:, :2] <= hi), axis=1)
        if m == 4:
            inside &= np.all(np.abs(th_new[:, 2:]) <= WIND_LIMIT_MPS, axis=1)
        take = ok & inside
        self.rejected[idx] += ok & ~inside
        p_new = p - gain @ jac @ p
        p_new = 0.5 * (p_new + p_new.transpose(0, 2, 1))
        self.theta[idx] = np.where(take[:, None], th_new, th)
        self.cov[idx] = np.where(take[:, None, None], p_new, p)
        self.t_last[idx] = t
        self.updates[idx] += 1

    @property
    def drag_accel_scale(self) -> np.ndarray:
        """k_D (N,)."""
        return np.exp(self.theta[:, 0])

    @property
    def lift_to_drag_scale(self) -> np.ndarray:
        """k_LD = k_L / k_D (N,)."""
        return np.exp(self.theta[:, 1] - self.theta[:, 0])

    def log_scales(self) -> np.ndarray:
        """(ln k_D, ln k_LD) per vehicle (N, 2), straight from the filter's state."""
        return np.stack([self.theta[:, 0], self.theta[:, 1] - self.theta[:, 0]], axis=-1)

    @property
    def wind_en(self) -> np.ndarray:
        """The estimated horizontal wind (N, 2), east and north (m/s); zeros without wind states."""
        return self.theta[:, 2:4].copy() if self.settings.n_states == 4 else np.zeros((self.n, 2))

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviations (N, 2) of k_D and k_LD (first order in the logarithms)."""
        c = self.cov
        var_ld = c[:, 0, 0] + c[:, 1, 1] - 2.0 * c[:, 0, 1]
        return np.stack([self.drag_accel_scale * np.sqrt(c[:, 0, 0]),
                         self.lift_to_drag_scale * np.sqrt(np.maximum(var_ld, 0.0))], axis=-1)  # fmt: skip

    @property
    def wind_sigma(self) -> np.ndarray:
        """Standard deviations (N, 2) of the wind components (m/s); zeros without wind states."""
        if self.settings.n_states != 4:
            return np.zeros((self.n, 2))
        return np.sqrt(np.stack([self.cov[:, 2, 2], self.cov[:, 3, 3]], axis=-1))

    def estimated_model(self, i: int) -> EntryModel:
        """Vehicle i's model with its current estimates (scales and, with wind states, the wind)."""
        return self.model_at(self.theta[i : i + 1])


def make_estimator(model: EntryModel, n: int, settings) -> "AeroScaleEstimator | FlightEstimator":
    """The estimator its settings describe: :class:`FlightEstimator` for
    :class:`FlightEstimatorSettings`, :class:`AeroScaleEstimator` otherwise (None: its defaults)."""
    if isinstance(settings, FlightEstimatorSettings):
        return FlightEstimator(model, n, settings)
    return AeroScaleEstimator(model, n, settings)


__all__ = ["EstimatorSettings", "AeroScaleEstimator", "FlightEstimatorSettings", "FlightEstimator",
           "make_estimator"]  # fmt: skip
