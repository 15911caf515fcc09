"""Output-error least squares: the initial state and an effect set's parameters against a record.

The residual is (replayed - measured) / sigma on every measured value. Its Jacobian is exact:
the derivative of the discrete RK4 replay, propagated step by step by CasADi's forward-mode
automatic differentiation (:mod:`~rventry_env.validation.replay.sensitivity`); one evaluation gives the
residual and the Jacobian together, and the solver's Jacobian call is served from that cache.
``scipy.optimize.least_squares`` (trust-region reflective) keeps every parameter inside its
physical bounds, and a fit that ends on one is reported as such (:attr:`FitResult.extra`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rventry_env.physics import EntryModel
from rventry_env.validation.search.effects import (
    EARTH_J2,
    Param,
    Structure,
    build_model,
    structure_parameters,
)
from rventry_env.validation.search.statistics import bic

BAD_RESIDUAL = 1e4  # stands in for a diverged replay (normalized units), so the solver backs off
BOUND_REL = 1e-4  # a parameter within this fraction of its range from a bound is on the bound


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
    :param nfev: residual evaluations (replays with sensitivities).
    :param message: the solver's message.
    :param structure: the effects and their knots.
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
    structure: Structure = field(default_factory=Structure)
    extra: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.values)

    def parameters(self, include_initial: bool = False) -> dict:
        """Fitted values by name (effect parameters only unless ``include_initial``)."""
        n0 = 0 if include_initial else self.extra.get("n_initial", 0)
        return {k: float(v) for k, v in zip(self.names[n0:], self.values[n0:])}

    @property
    def credible(self) -> bool:
        """No parameter on a physical bound, the initial state within its bound, nothing implausible."""
        x = self.extra
        return not (x.get("at_bound") or x.get("initial_state_at_bound") or x.get("implausible"))


class OutputErrorProblem:
    """The least-squares problem of one effect set.

    :param replay: the record's replay.
    :param setup: the current model and declared facts.
    :param structure: the effects fitted (with the initial state) and their knots.
    :param sigma: noise standard deviation per observation channel (the weights).
    :param groups: observation group per channel (profiled separately in BIC).
    :param init_bound: half-widths ``(n_init,)`` bounding the initial-state offsets (the
        record's noise), or None for a free initial state.
    :param engines: a cache of compiled sensitivity replays shared between problems.
    :param extra_params: parameters fitted besides the structure's (e.g. a free J2 for the
        check of the known value).
    :param replays: the replays kept for points asked for again
        (:class:`~rventry_env.validation.replay.sensitivity.ReplayCache`, shared between problems);
        a problem of its own keeps its last two.
    """

    def __init__(
        self,
        replay,
        setup,
        structure: Structure,
        sigma: np.ndarray,
        groups: np.ndarray,
        init_bound: np.ndarray | None = None,
        engines: dict | None = None,
        extra_params: tuple = (),
        replays=None,
    ):
        self.replay = replay
        self.setup = setup
        self.structure = structure
        self.params: list[Param] = structure_parameters(setup, structure) + list(extra_params)
        init = replay.init
        self.n_init = init.size
        self.names = tuple(init.names) + tuple(p.name for p in self.params)
        self.start = np.concatenate([np.zeros(init.size), [p.start for p in self.params]])
        self.scale = np.concatenate([init.scales, [p.scale for p in self.params]])
        half = np.full(init.size, np.inf) if init_bound is None else np.asarray(init_bound, float)
        self.lower = np.concatenate([-half, [p.lower for p in self.params]])
        self.upper = np.concatenate([half, [p.upper for p in self.params]])
        self.sigma = np.asarray(sigma, float)
        self.groups = np.asarray(groups)
        self.mask = np.isfinite(replay.y)
        engines = {} if engines is None else engines
        pnames = tuple(p.name for p in self.params)
        key = (structure.key(), pnames)
        from rventry_env.validation.replay.sensitivity import ReplayCache, SensitivityReplay

        if key not in engines:
            engines[key] = SensitivityReplay(replay, lambda v: build_model(setup, structure, v), pnames)
        self.engine = engines[key]
        self.replays = ReplayCache(2) if replays is None else replays
        self._cache_key = None
        self._cache = None
        self.nfev = 0

    # parameters <-> scaled unknowns z (theta = start + scale z)
    def theta(self, z: np.ndarray) -> np.ndarray:
        return self.start + self.scale * z

    def z(self, theta: np.ndarray) -> np.ndarray:
        return (np.asarray(theta, float) - self.start) / self.scale

    def model(self, theta: np.ndarray) -> EntryModel:
        """The physical model for parameters ``theta``."""
        values = {p.name: float(v) for p, v in zip(self.params, theta[self.n_init:])}
        return build_model(self.setup, self.structure, values)

    def _evaluate(self, z: np.ndarray):
        """(residual, Jacobian in z, prediction) at ``z``, from one replay with sensitivities (cached).

        A point other than the last counts as one replay, whether it is replayed or served from
        :attr:`replays` (the count bounds the search and does not depend on what was kept).
        """
        key = z.tobytes()
        if key != self._cache_key or self._cache[1] is None:
            if key != self._cache_key:
                self.nfev += 1  # one replay per point, whether or not its Jacobian is asked for
            th = self.theta(z)
            with np.errstate(all="ignore"):
                pred, jac = self.replays.evaluate(self.engine, th[: self.n_init], th[self.n_init:])
                r = (pred - self.replay.y) / self.sigma[None, :]
                j = jac / self.sigma[None, :, None] * self.scale[None, None, :]
            r = r[self.mask]
            j = j[self.mask]
            bad = ~np.isfinite(r) | ~np.all(np.isfinite(j), axis=1)
            r = np.where(bad, BAD_RESIDUAL, r)
            j[bad] = 0.0
            self._cache_key, self._cache = key, (r, j, pred)
        return self._cache

    def _residual(self, z: np.ndarray) -> np.ndarray:
        """The residual at ``z`` alone: a replay without sensitivities, unless the point's Jacobian is known.

        A trial point the solver rejects never needs its Jacobian; an accepted one gets it from
        :meth:`_evaluate` at the same point, whose residual is the same to the last bit (the
        replay's states are the same operations on the same values).
        """
        key = z.tobytes()
        if key != self._cache_key:
            th = self.theta(z)
            with np.errstate(all="ignore"):
                pred = self.replays.predict(self.engine, th[: self.n_init], th[self.n_init:])
                r = ((pred - self.replay.y) / self.sigma[None, :])[self.mask]
            r = np.where(np.isfinite(r), r, BAD_RESIDUAL)
            self.nfev += 1
            self._cache_key, self._cache = key, (r, None, pred)
        return self._cache[0]

    def solve(self, theta0: np.ndarray | None = None, max_nfev: int = 60) -> FitResult:
        """Fit from ``theta0`` (default: the current model, zero initial-state offsets)."""
        from scipy.optimize import least_squares

        theta0 = self.start if theta0 is None else np.asarray(theta0, float)
        lo, hi = self.z(self.lower), self.z(self.upper)
        width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
        z0 = np.clip(self.z(theta0), lo + 1e-7 * width, hi - 1e-7 * width)
        sol = least_squares(
            self._residual,
            z0,
            jac=lambda z: self._evaluate(z)[1],
            bounds=(lo, hi),
            method="trf",
            x_scale=1.0,
            # a relative cost change of 1e-10 is far below what moves BIC by one unit
            ftol=1e-10,
            xtol=1e-10,
            gtol=1e-10,
            max_nfev=max_nfev,
        )
        return self.result(sol.x, sol.message)

    def at_bound(self, theta: np.ndarray, first: int, last: int) -> list[str]:
        """Names of the parameters ``first:last`` that ended on a bound."""
        out = []
        for i in range(first, last):
            lo, hi = self.lower[i], self.upper[i]
            if not (np.isfinite(lo) and np.isfinite(hi)):
                continue
            if min(theta[i] - lo, hi - theta[i]) < BOUND_REL * (hi - lo):
                out.append(self.names[i])
        return out

    def linearized(self, theta: np.ndarray, subsets: dict[str, list[int]]) -> dict[str, dict]:
        """One Gauss-Newton step on each subset of the parameters, from the exact Jacobian at ``theta``.

        :return: per subset, the weighted RSS after the step, the step in parameter units and
            the parameters' standard errors (noise variance from the residual after the step).
        """
        res, jac, _ = self._evaluate(self.z(theta))
        out = {}
        for name, idx in subsets.items():
            js = jac[:, idx]
            step, *_ = np.linalg.lstsq(js, -res, rcond=None)
            r = res + js @ step
            rss = float(r @ r)
            s2 = rss / max(len(r) - len(idx), 1)
            cov = np.linalg.pinv(js.T @ js) * s2
            out[name] = {
                "chi2": rss,
                "step": step * self.scale[idx],
                "stderr": np.sqrt(np.clip(np.diag(cov), 0, None)) * self.scale[idx],
                "residual": r,
            }
        return out

    def rss_by_group(self, r_norm: np.ndarray) -> tuple[list, list]:
        """Residual sums of squares per observation group (physical units) of a normalised masked residual."""
        sig = np.broadcast_to(self.sigma, self.mask.shape)[self.mask]
        grp = np.broadcast_to(self.groups, self.mask.shape)[self.mask]
        e = r_norm * sig
        rss, nval = [], []
        for g in np.unique(self.groups):
            sel = grp == g
            rss.append(float(np.sum(e[sel] ** 2)))
            nval.append(int(np.count_nonzero(sel)))
        return rss, nval

    def result(self, z: np.ndarray, message: str = "") -> FitResult:
        """A :class:`FitResult` at scaled unknowns ``z``."""
        z = np.asarray(z, float)
        res, jac, pred = self._evaluate(z)
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
        with np.errstate(all="ignore"):
            try:
                cov_z = np.linalg.pinv(jac.T @ jac) * s2
                stderr = np.sqrt(np.clip(np.diag(cov_z), 0, None)) * self.scale
            except np.linalg.LinAlgError:
                stderr = np.full(len(z), np.nan)
        diverged = bool(np.any(res == BAD_RESIDUAL)) or not np.all(np.isfinite(pred[self.mask]))
        return FitResult(
            effects=self.structure.effects,
            names=self.names,
            values=theta,
            stderr=stderr,
            prediction=pred,
            residual=resid,
            rss_by_group=rss,
            n_by_group=nval,
            bic=bic(rss, nval, len(z)) if not diverged else float("inf"),
            model=self.model(theta),
            nfev=self.nfev,
            message=message,
            structure=self.structure,
            extra={
                "n_initial": self.n_init,
                "cost": 0.5 * float(res @ res),
                "knots": self.structure.density_knots,
                "at_bound": self.at_bound(theta, self.n_init, len(theta)),
                "initial_state_at_bound": self.at_bound(theta, 0, self.n_init),
                "diverged": diverged,
                "implausible": ["the replay diverged"] if diverged else [],
            },
        )


def j2_free_param() -> Param:
    """A free J2 (to check the value a record prefers against the known one); no bounds."""
    return Param("j2", "j2_gravity", EARTH_J2, 1e-4, -np.inf, np.inf)


__all__ = ["BAD_RESIDUAL", "FitResult", "OutputErrorProblem", "j2_free_param"]
