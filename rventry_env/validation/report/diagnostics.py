"""What remains after identification: the measured density, the declared entry state, time windows.

A record's ``density_kgpm3`` column (flight-derived, e.g. from stagnation pressure) is
compared with the model atmospheres and turned into a *measured* density correction, the
atmosphere of the ``measured_density`` candidate. Reduced records are also replayed from the
declared entry state with nothing fitted (like-for-like with published reconstructions), and
the residual is summarised in thirds of the record.
"""

from __future__ import annotations

import numpy as np

from rventry_env.physics import EntryModel
from rventry_env.validation.record import FlightRecord
from rventry_env.validation.replay.record_replay import TIME_OFFSET, Replay
from rventry_env.validation.search.effects import Structure, build_model, log_density_ratio
from rventry_env.validation.search.fit import FitResult
from rventry_env.validation.search.selection import FitContext


def _rms(x: np.ndarray):
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def _max(x: np.ndarray):
    x = np.abs(x[np.isfinite(x)])
    return float(np.max(x)) if x.size else None


def error_metrics(residual: np.ndarray, kind: str) -> dict:
    """rms and max position (or altitude) error, rms and max velocity (or speed) error.

    :param residual: replayed - measured ``(n, m)``, NaN in gaps.
    :param kind: ``"ecef"`` or ``"reduced"``.
    :return: the figures, None where a group has no value.
    """
    e = residual
    if kind == "ecef":
        with np.errstate(over="ignore", invalid="ignore"):
            pos = np.linalg.norm(e[:, :3], axis=1)
            vel = np.linalg.norm(e[:, 3:], axis=1)
        return {
            "position_rms_m": _rms(pos),
            "position_max_m": _max(pos),
            "velocity_rms_mps": _rms(vel),
            "velocity_max_mps": _max(vel),
        }
    return {
        "altitude_rms_m": _rms(e[:, 0]),
        "altitude_max_m": _max(e[:, 0]),
        "speed_rms_mps": _rms(e[:, 1]),
        "speed_max_mps": _max(e[:, 1]),
    }


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


def fixed_state_errors(replay: Replay, model: EntryModel, kind: str, time_offset: float = 0.0) -> dict:
    """Errors of a replay from the declared (or first measured) initial state, nothing fitted (the record's
    time offset, when one is identified, applied)."""
    pred = replay.predict(model, np.zeros((1, replay.init.size)), time_offset)[..., 0]
    return error_metrics(pred - replay.y, kind)


def run_diagnostics(
    record: FlightRecord, ctx: FitContext, base: FitResult, current: FitResult, chosen, kind: str, first: dict
) -> dict:
    """Checks on what remains (see :mod:`rventry_env.validation.report.diagnostics`)."""
    replay, setup = ctx.replay, ctx.setup
    t = replay.t_obs
    out = {"windows": {"before": window_errors(t, base.residual, kind),
                       "after": window_errors(t, current.residual, kind)}}  # fmt: skip
    if kind == "reduced":
        # like-for-like with replays that keep the declared entry state (e.g. published reconstructions)
        declared = (build_model(setup, Structure(("lift_coefficient",)), {"cl_scale": 1.0})
                    if setup.start == "drag-only" else setup.model)  # fmt: skip
        out["declared_entry_state"] = {
            "current_model": fixed_state_errors(replay, setup.model, kind),
            "declared_vehicle": fixed_state_errors(replay, declared, kind),
            "identified_model": fixed_state_errors(replay, current.model, kind,
                                                   current.parameters().get(TIME_OFFSET, 0.0)),
        }
    if record.density is None:
        return out
    alt = record.altitude()
    ok = np.isfinite(alt) & np.isfinite(record.density) & (record.density > 0)
    if ok.sum() < 3:
        return out
    h, rho = alt[ok], record.density[ok]
    lr_cur = log_density_ratio(h, rho, setup.model)
    lr_id = log_density_ratio(h, rho, current.model)
    corr = setup.measured_atmosphere
    out["density_check"] = {
        "altitude_m": h.tolist(),
        "current": {"log_ratio": lr_cur.tolist(), "rms_log_ratio": float(np.sqrt(np.mean(lr_cur**2)))},
        "identified": {"log_ratio": lr_id.tolist(), "rms_log_ratio": float(np.sqrt(np.mean(lr_id**2)))},
        "measured_correction": {"knots_m": list(corr.knots), "log_factors": list(corr.log_factors)}
        if corr is not None else None,
    }
    md = first.get("measured_density")
    if md is not None:
        out["density_check"]["replay_with_measured_density"] = {
            "effects": list(md.effects),
            "errors": error_metrics(md.residual, kind),
            "windows": window_errors(t, md.residual, kind),
        }
    return out


__all__ = [
    "error_metrics",
    "fixed_state_errors",
    "run_diagnostics",
    "window_errors",
]
