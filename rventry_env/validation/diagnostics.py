"""What remains after identification: the measured density, the declared entry state, time windows.

These checks use data the fits did not: a record's ``density_kgpm3`` column
(flight-derived, e.g. from stagnation pressure) is compared with the model
atmospheres and turned into a *measured* density correction, which then replaces
the atmosphere in a replay. If the residual's late drift shrinks, the
atmosphere explains it; if not, something else does.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.physics import DensityCorrection, EntryModel
from rventry_env.physics.atmosphere import piecewise_linear


def log_density_ratio(altitude: np.ndarray, density: np.ndarray, model: EntryModel) -> np.ndarray:
    """ln(rho_record / rho_model) at the record's altitudes."""
    return np.log(density / np.asarray(model.atmosphere.density(altitude, NUMPY), float))


def measured_density_correction(altitude: np.ndarray, density: np.ndarray, model: EntryModel,
                                n_knots: int = 6) -> DensityCorrection:  # fmt: skip
    """The :class:`DensityCorrection` of ``model``'s atmosphere that best matches measured densities.

    Linear least squares of ln(rho_record / rho_model) on the piecewise-linear
    (hat-function) basis of the correction, knots spread evenly over the
    measured altitudes (fewer if there are few measurements).

    :param altitude: altitudes of the measurements (m).
    :param density: measured densities (kg/m^3).
    :param model: the model whose atmosphere is corrected.
    :param n_knots: most knots.
    """
    lr = log_density_ratio(altitude, density, model)
    n = int(max(2, min(n_knots, len(altitude) // 4)))
    knots = tuple(float(k) for k in np.linspace(np.min(altitude), np.max(altitude), n))
    basis = np.stack(
        [piecewise_linear(altitude, knots, tuple(float(i == j) for j in range(n)), NUMPY) for i in range(n)], axis=1
    )
    coef, *_ = np.linalg.lstsq(basis, lr, rcond=None)
    return DensityCorrection(model.atmosphere, knots, tuple(float(c) for c in coef))


def base_atmosphere(model: EntryModel):
    """The atmosphere without an identified density correction."""
    atm = model.atmosphere
    while isinstance(atm, DensityCorrection):
        atm = atm.base
    return atm


def window_errors(t: np.ndarray, residual: np.ndarray, kind: str, n_windows: int = 3) -> list[dict]:
    """rms of the position (altitude) error in consecutive time windows (thirds by default)."""
    edges = np.linspace(t[0], t[-1], n_windows + 1)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (t >= a) & (t <= b)
        e = residual[sel]
        err = np.linalg.norm(e[:, :3], axis=1) if kind == "ecef" else e[:, 0]
        err = err[np.isfinite(err)]
        out.append({"t_from_s": float(a), "t_to_s": float(b),
                    "rms_m": float(np.sqrt(np.mean(err**2))) if err.size else None})  # fmt: skip
    return out


def with_atmosphere(setup, atmosphere):
    """A copy of a :class:`~rventry_env.validation.setup.ReplaySetup` whose model has ``atmosphere``."""
    return dataclasses.replace(setup, model=setup.model.replace(atmosphere=atmosphere))


__all__ = [
    "log_density_ratio",
    "measured_density_correction",
    "base_atmosphere",
    "window_errors",
    "with_atmosphere",
]
