"""The sidecar against the record: does the declared entry state match the first samples?

A reduced record starts its replay from the sidecar's entry state, and the fit may move that
state only within the noise. A sidecar altitude in kilometres, a record altitude in feet, or an
inertial speed put in ``speed_rel_mps`` would otherwise be "explained" by whatever effect bends
the trajectory furthest. The declared state is replayed (nothing fitted) over the first
:data:`WINDOW_S` seconds (at least :data:`MIN_WINDOW_SAMPLES` samples) and the differences from
the record are fitted by a robust straight line (Theil-Sen). Its value at the first sample is
what the record says about the sidecar, with the scatter of the window about the line (1.4826
MAD, never below the record's own noise estimate) as the noise there. One sample never decides:
a record digitised from a figure may scatter by kilometres near entry.

* a difference beyond :data:`ERROR_SIGMAS` of those noise levels *and* beyond the absolute floors
  (:data:`ALTITUDE_FLOOR_M`, :data:`SPEED_FLOOR_MPS`) is grossly inconsistent: an error naming
  the field, with the likely cause when the ratio or difference says so (feet, kilometres,
  inertial speed);
* a smaller difference beyond what the entry state may move (:data:`INIT_BOUND_SIGMAS` noise
  levels) and beyond :data:`SIGNIFICANT` standard errors of the robust line is a warning, and the fit's prior on that component is widened to the difference
  plus :data:`INIT_BOUND_SIGMAS` standard errors of the robust line (``widen``).
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.intake.noise import INIT_BOUND_SIGMAS
from rventry_env.validation.record import RecordError

ERROR_SIGMAS = 5.0  # noise levels of the early samples' scatter beyond which a sidecar is refused
ALTITUDE_FLOOR_M = 2000.0
SPEED_FLOOR_MPS = 50.0
WINDOW_S = 30.0  # the first seconds of the record compared with the declared state
MIN_WINDOW_SAMPLES = 8
MAD_TO_SIGMA = 1.4826
SIGNIFICANT = 3.0  # a difference is warned about only beyond this many standard errors of the robust line
FEET = 0.3048


def _ratio_hint(declared: float, measured: float, what: str) -> str:
    if declared <= 0 or measured <= 0:
        return ""
    r = measured / declared
    for factor, text in ((1 / FEET, "the record in feet?"), (FEET, f"the sidecar's {what} in feet?"),
                         (1000.0, f"the sidecar's {what} in kilometres?"), (1e-3, "the record in kilometres?")):
        if abs(r / factor - 1.0) < 0.03:
            return f" (ratio {r:.4g}: {text})"
    return ""


def _robust_line(t: np.ndarray, d: np.ndarray, t_at: float, floor: float | None) -> tuple[float, float, float]:
    """Theil-Sen line through (t, d): its value at ``t_at``, that value's standard error, the scatter about it."""
    from scipy.stats import theilslopes

    ok = np.isfinite(d)
    t, d = t[ok], d[ok]
    if t.size == 1:
        s = floor or 0.0
        return float(d[0]), s, s
    slope, intercept, *_ = theilslopes(d, t)
    resid = d - (intercept + slope * t)
    scatter = MAD_TO_SIGMA * float(np.median(np.abs(resid - np.median(resid))))
    scatter = max(scatter, floor or 0.0)
    tc = t - t.mean()
    sxx = float(tc @ tc)
    # a robust line is about 1.25 times less efficient than least squares on normal noise
    se = 1.25 * scatter * math.sqrt(1.0 / t.size + ((t_at - t.mean()) ** 2 / sxx if sxx > 0 else 0.0))
    return float(intercept + slope * t_at), se, scatter


def check_entry_state(replay, setup, sigma_by_group: dict) -> dict:
    """Compare the declared entry state, replayed over the first seconds, with a robust fit of the record there.

    :param replay: the record's replay (a reduced record: it starts from the declared state).
    :param setup: the declared facts.
    :param sigma_by_group: noise per group (NaN or None where unknown).
    :return: the differences, the noise levels they were judged by, any warnings, and the
        half-widths (``widen``) the entry state's prior needs; raises :class:`RecordError` on a
        grossly inconsistent sidecar.
    """
    es = setup.entry_state
    if replay.record.kind != "reduced" or es is None:
        return {}
    full = np.all(np.isfinite(replay.y), axis=1)
    if not np.any(full):
        return {}
    first = int(np.flatnonzero(full)[0])
    t_first = float(replay.t_obs[first])
    idx = np.flatnonzero(full & (replay.t_obs <= t_first + WINDOW_S))
    if idx.size < MIN_WINDOW_SAMPLES:
        idx = np.flatnonzero(full)[:MIN_WINDOW_SAMPLES]
    with np.errstate(all="ignore"):
        pred = replay.predict(setup.model, np.zeros((1, replay.init.size)))[idx, :, 0]
    row = replay.record.line_of(int(replay.rows[first]))
    if not np.all(np.isfinite(pred)):
        raise RecordError(f"sidecar: entry_state: the replay from the declared state fails before row "
                          f"{replay.record.line_of(int(replay.rows[idx[-1]]))}")  # fmt: skip
    t = replay.t_obs[idx]
    sh = sigma_by_group.get("altitude")
    sv = sigma_by_group.get("speed")
    sh = sh if sh and math.isfinite(sh) else None
    sv = sv if sv and math.isfinite(sv) else None
    dh, se_h, noise_h = _robust_line(t, replay.y[idx, 0] - pred[:, 0], t_first, sh)
    dv, se_v, noise_v = _robust_line(t, replay.y[idx, 1] - pred[:, 1], t_first, sv)
    h_meas, v_meas = float(pred[0, 0] + dh), float(pred[0, 1] + dv)
    out = {"t_s": t_first, "row": row, "window_s": [t_first, float(t[-1])], "window_samples": int(idx.size),
           "altitude_difference_m": dh, "speed_difference_mps": dv,
           "altitude_noise_m": noise_h, "speed_noise_mps": noise_v,
           "altitude_difference_stderr_m": se_h, "speed_difference_stderr_mps": se_v,
           "warnings": [], "widen": {}}  # fmt: skip
    near = abs(t_first - es.t) < 1.0
    where = f"t_s = {t_first:g} (row {row}; a robust line through {idx.size} samples to t_s = {t[-1]:g})"
    if abs(dh) > max(ERROR_SIGMAS * noise_h, ALTITUDE_FLOOR_M):
        hint = _ratio_hint(es.altitude, h_meas, "altitude_m") if near else ""
        raise RecordError(
            f"sidecar: entry_state.altitude_m = {es.altitude:g} m, replayed to {where}, is {-dh:+.4g} m from the "
            f"record's altitude_m {h_meas:g} m ({abs(dh) / max(noise_h, 1e-9):.1f} times the {noise_h:.3g} m "
            f"scatter of those samples){hint}; fix the sidecar or the record"
        )
    if abs(dv) > max(ERROR_SIGMAS * noise_v, SPEED_FLOOR_MPS):
        hint = ""
        # inertial speed of the measured state with the declared direction: |v_E + w x r|
        w = setup.model.planet.omega
        r = setup.model.planet.radius + h_meas
        east = v_meas * math.cos(es.flight_path) * math.sin(es.azimuth) + w * r * math.cos(es.latitude)
        north = v_meas * math.cos(es.flight_path) * math.cos(es.azimuth)
        up = v_meas * math.sin(es.flight_path)
        v_inertial = math.sqrt(east * east + north * north + up * up)
        if abs(es.speed - v_inertial) < 0.25 * abs(dv):
            hint = (f" (the Earth-fixed speed plus the Earth's rotation is {v_inertial:.6g} m/s: "
                    "the sidecar's speed_rel_mps looks like an inertial speed)")  # fmt: skip
        elif near:
            hint = _ratio_hint(es.speed, v_meas, "speed_rel_mps")
        raise RecordError(
            f"sidecar: entry_state.speed_rel_mps = {es.speed:g} m/s, replayed to {where}, is {-dv:+.4g} m/s from "
            f"the record's speed_rel_mps {v_meas:g} m/s ({abs(dv) / max(noise_v, 1e-9):.1f} times the "
            f"{noise_v:.3g} m/s scatter of those samples){hint}"
        )
    for name, group, d, s, se, unit in (("altitude_m", "altitude", dh, sh, se_h, "m"),
                                        ("speed_rel_mps", "speed", dv, sv, se_v, "m/s")):  # fmt: skip
        if s is not None and abs(d) > INIT_BOUND_SIGMAS * s and abs(d) > SIGNIFICANT * se:
            half = abs(d) + INIT_BOUND_SIGMAS * se
            out["widen"][group] = half
            out["warnings"].append(
                f"sidecar: entry_state.{name} is {abs(d):.4g} {unit} ({abs(d) / s:.1f} noise levels) from a robust fit "
                f"of the record at {where}; the fitted entry state may move {half:.4g} {unit} instead of "
                f"{INIT_BOUND_SIGMAS * s:.4g} {unit}"
            )
    return out


__all__ = ["check_entry_state"]
