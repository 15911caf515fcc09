"""Output-error least squares: the initial state and an effect's parameters against a record.

The residual is (replayed - measured) / sigma on every measured value. The
Jacobian is by forward differences, but all of its columns come from one
*batched* replay (member 0 the point itself, member j the j-th parameter
perturbed), so a Jacobian costs about one trajectory. Since that batch also
contains the residual at the point, every call of the residual function computes
the Jacobian speculatively and the solver's Jacobian call is served from the
cache.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rventry_env.physics import EntryModel
from rventry_env.validation.effects import Effect, build_model
from rventry_env.validation.record_replay import Replay
from rventry_env.validation.replay_setup import ReplaySetup
from rventry_env.validation.statistics import bic

BAD_RESIDUAL = 1e4  # stands in for a diverged replay (normalized units), so the solver backs off


@dataclass
class FitResult:
    """One fitted model.

    :param effects: the effects included.
    :param names: parameter names (initial-state offsets first).
    :param values: fitted values.
    :param stderr: their standard errors from the Gauss-Newton covariance (noise profiled).
    :param prediction: replayed observations ``(n_obs, m)``.
    :param residual: replayed - measured ``(n_obs, m)``, NaN in gaps.
    :param rss_by_group: residual sums of squares per observation group (physical units).
    :param n_by_group: measured values per group.
    :param bic: information criterion (noise profiled per group).
    :param model: the fitted :class:`EntryModel`.
    :param nfev: residual evaluations (batched replays).
    :param message: the solver's message.
    """

    effects: tuple
    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    prediction: np.ndarray
    residual: np.ndarray
    rss_by_group: list
    n_by_group: list
    bic: float
    model: EntryModel
    nfev: int
    message: str
    extra: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.values)

    def parameters(self, include_initial: bool = False) -> dict:
        """Fitted values by name (effect parameters only unless ``include_initial``)."""
        n0 = 0 if include_initial else self.extra.get("n_initial", 0)
        return {k: float(v) for k, v in zip(self.names[n0:], self.values[n0:])}


class OutputErrorProblem:
    """The least-squares problem of one set of effects.

    :param replay: the record's replay.
    :param setup: the current model and declared facts.
    :param knots: density-correction knots (m).
    :param effects: the effects whose parameters are fitted (with the initial state).
    :param sigma: noise standard deviation per observation channel (the weights).
    :param groups: observation group per channel (profiled separately in BIC).
    :param fd_step: finite-difference step in units of each parameter's scale.
    :param init_bound: half-widths ``(n_init,)`` bounding the initial-state offsets (the
        record's noise), or None for a free initial state.
    """

    def __init__(
        self,
        replay: Replay,
        setup: ReplaySetup,
        knots: tuple,
        effects: list[Effect],
        sigma: np.ndarray,
        groups: np.ndarray,
        fd_step: float = 1e-5,
        init_bound: np.ndarray | None = None,
    ):
        self.replay = replay
        self.setup = setup
        self.knots = knots
        self.effects = list(effects)
        init = replay.init
        self.n_init = init.size
        self.names = tuple(init.names) + tuple(n for e in self.effects for n in e.param_names)
        self.start = np.concatenate([np.zeros(init.size)] + [np.array(e.start, float) for e in self.effects])
        self.scale = np.concatenate([init.scales] + [np.array(e.scale, float) for e in self.effects])
        half = np.full(init.size, np.inf) if init_bound is None else np.asarray(init_bound, float)
        self.lower = np.concatenate([-half] + [np.array(e.lower, float) for e in self.effects])
        self.upper = np.concatenate([half] + [np.array(e.upper, float) for e in self.effects])
        self.sigma = np.asarray(sigma, float)
        self.groups = np.asarray(groups)
        self.mask = np.isfinite(replay.y)
        self.fd_step = fd_step
        self._cache_key = None
        self._cache = None
        self.nfev = 0

    # parameters <-> scaled unknowns z (theta = start + scale z)
    def theta(self, z: np.ndarray) -> np.ndarray:
        return self.start + self.scale * z

    def z(self, theta: np.ndarray) -> np.ndarray:
        return (np.asarray(theta, float) - self.start) / self.scale

    def model(self, theta: np.ndarray) -> EntryModel:
        """The model for parameters ``theta (n,)`` or a batch ``(B, n)`` (then with array parts)."""
        theta = np.asarray(theta, float)
        values = {name: theta[..., i] for i, name in enumerate(self.names[self.n_init:], start=self.n_init)}
        if theta.ndim == 1:
            values = {k: float(v) for k, v in values.items()}
        return build_model(self.setup, self.knots, values)

    def predict(self, thetas: np.ndarray) -> np.ndarray:
        """Replayed observations ``(n_obs, m, B)`` for parameter sets ``thetas (B, n)``."""
        thetas = np.atleast_2d(thetas)
        return self.replay.predict(self.model(thetas), thetas[:, : self.n_init])

    def _normalized(self, pred: np.ndarray) -> np.ndarray:
        """Residual vectors ``(B, n_res)`` from predictions ``(n_obs, m, B)``."""
        r = (pred - self.replay.y[..., None]) / self.sigma[None, :, None]
        r = np.moveaxis(r, -1, 0)[:, self.mask]
        return np.where(np.isfinite(r), r, BAD_RESIDUAL)

    def _evaluate(self, z: np.ndarray):
        """(residual, Jacobian, prediction) at ``z``, from one batched replay (cached)."""
        key = z.tobytes()
        if key != self._cache_key:
            n = len(z)
            zs = np.repeat(z[None, :], n + 1, axis=0)
            zs[1:] += self.fd_step * np.eye(n)
            pred = self.predict(self.theta(zs))
            res = self._normalized(pred)
            self.nfev += 1
            jac = (res[1:] - res[0]).T / self.fd_step
            self._cache_key, self._cache = key, (res[0], jac, pred[..., 0])
        return self._cache

    def solve(self, theta0: np.ndarray | None = None, max_nfev: int = 60) -> FitResult:
        """Fit from ``theta0`` (default: the current model, zero initial-state offsets)."""
        from scipy.optimize import least_squares

        theta0 = self.start if theta0 is None else np.asarray(theta0, float)
        lo, hi = self.z(self.lower), self.z(self.upper)
        z0 = np.clip(self.z(theta0), lo + 1e-9, hi - 1e-9)
        sol = least_squares(
            lambda z: self._evaluate(z)[0],
            z0,
            jac=lambda z: self._evaluate(z)[1],
            bounds=(lo, hi),
            method="trf",
            x_scale=1.0,
            # a relative cost change of 1e-8 is far below what moves BIC by one unit
            ftol=1e-8,
            xtol=1e-9,
            gtol=1e-9,
            max_nfev=max_nfev,
        )
        return self.result(sol.x, sol.message)

    def at_bound(self, theta: np.ndarray, rel: float = 1e-4) -> list[str]:
        """Names of the effect parameters that ended on a bound (a fit that is not credible)."""
        out = []
        for i in range(self.n_init, len(theta)):
            width = self.upper[i] - self.lower[i]
            if min(theta[i] - self.lower[i], self.upper[i] - theta[i]) < rel * width:
                out.append(self.names[i])
        return out

    def linearized_chi2(self, theta: np.ndarray, subsets: dict[str, list[int]]) -> dict[str, float]:
        """Weighted RSS after one Gauss-Newton step on each subset of the parameters.

        One batched replay gives the Jacobian of every parameter at ``theta``; each
        subset's least-squares step is then linear algebra. This screens candidate
        additions in forward selection before the few promising ones are fitted.

        :param theta: the linearization point.
        :param subsets: name -> parameter indices (the initial state should be included).
        """
        res, jac, _ = self._evaluate(self.z(theta))
        out = {}
        for name, idx in subsets.items():
            js = jac[:, idx]
            step, *_ = np.linalg.lstsq(js, -res, rcond=None)
            r = res + js @ step
            out[name] = float(r @ r)
        return out

    def result(self, z: np.ndarray, message: str = "") -> FitResult:
        """A :class:`FitResult` at scaled unknowns ``z``."""
        res, jac, pred = self._evaluate(np.asarray(z, float))
        theta = self.theta(z)
        resid = np.where(self.mask, pred - self.replay.y, np.nan)
        rss, nval = [], []
        for g in np.unique(self.groups):
            cols = self.groups == g
            e = resid[:, cols]
            rss.append(float(np.nansum(e**2)))
            nval.append(int(np.count_nonzero(np.isfinite(e))))
        # covariance with the weighted residual's variance as the noise level
        dof = max(len(res) - len(z), 1)
        s2 = float(res @ res) / dof
        try:
            cov_z = np.linalg.pinv(jac.T @ jac) * s2
            stderr = np.sqrt(np.clip(np.diag(cov_z), 0, None)) * self.scale
        except np.linalg.LinAlgError:
            stderr = np.full(len(z), np.nan)
        return FitResult(
            effects=tuple(e.name for e in self.effects),
            names=self.names,
            values=theta,
            stderr=stderr,
            prediction=pred,
            residual=resid,
            rss_by_group=rss,
            n_by_group=nval,
            bic=bic(rss, nval, len(z)),
            model=self.model(theta),
            nfev=self.nfev,
            message=message,
            extra={"n_initial": self.n_init, "cost": 0.5 * float(res @ res), "knots": self.knots,
                   "at_bound": self.at_bound(theta)},
        )


__all__ = ["FitResult", "OutputErrorProblem"]
