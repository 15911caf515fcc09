"""The sidecar against the record: does the declared entry state match the first samples?

A reduced record starts its replay from the sidecar's entry state. The declared state is
replayed (nothing fitted) over the first :data:`WINDOW_S` seconds (at least
:data:`MIN_WINDOW_SAMPLES` samples) and the differences from the record are fitted by a robust
straight line (Theil-Sen). Its value at the first sample is what the record says about the
sidecar, with the scatter of the window about the line (1.4826 MAD, never below the record's own
noise estimate) as the noise there. One sample never decides: a record digitised from a figure
may scatter by kilometres near entry.

A sidecar that disagrees with its record is a *finding*, not an error: an altitude read on
another reference (geodetic over the WGS-84 ellipsoid against a sphere,
:mod:`~rventry_env.validation.intake.references`), a state converted from another frame or
horizon, a reading error of a digitised figure. Only what cannot be physics is refused, with the
field named:

* a unit error: a ratio of a foot or a kilometre between the sidecar and the record (or between
  the record and the replay), and an inertial speed where an Earth-relative one belongs (either
  way round), when the difference has the size the error would make (within a quarter of it);
* a replay that cannot start (it fails before the window ends);
* a difference beyond the physical bound plus :data:`ERROR_SIGMAS` standard errors of the
  robust line: :data:`ALTITUDE_BOUND_M`, the largest difference between two altitude references
  on the WGS-84 Earth (geodetic height over the ellipsoid against a sphere of the equatorial
  radius: the polar flattening, 21.4 km), and :data:`SPEED_BOUND_MPS`, the largest difference
  between the speeds of two frames (the Earth's rotation at the equator, 465 m/s).

A difference within the bounds but beyond what the entry state may move (:data:`INIT_BOUND_SIGMAS`
noise levels) and beyond :data:`SIGNIFICANT` standard errors of the robust line is a warning,
and the fit's prior on that component is widened to the difference plus
:data:`INIT_BOUND_SIGMAS` noise levels and standard errors (``widen``), so the fit finds the entry
state; the report
gives the fitted offset with its standard error and the physical references it agrees with
(:func:`~rventry_env.validation.intake.references.explain_entry_offset`).
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.intake.noise import INIT_BOUND_SIGMAS
from rventry_env.validation.intake.references import ALTITUDE_REFERENCE_MAX_M, frame_speed_difference
from rventry_env.validation.record import INERTIAL_SPEED, RecordError

ERROR_SIGMAS = 5.0  # standard errors of the robust line beyond a physical bound before a sidecar is refused
ALTITUDE_BOUND_M = ALTITUDE_REFERENCE_MAX_M  # the polar flattening of WGS-84: the largest reference difference
SPEED_BOUND_MPS = 465.1  # the Earth's rotation speed at the equator (7.292115e-5 rad/s x 6378137 m)
HINT_TOLERANCE = 0.25  # a unit or frame error explains a difference within this fraction of it
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


def _speed_hint(setup, record, dv: float) -> str:
    """The frame error a speed difference has the size of (an inertial speed in the other's place), or ''."""
    es = setup.entry_state
    rot = frame_speed_difference(es.speed, es.altitude, es.latitude, es.flight_path, es.azimuth,
                                 setup.model.planet)  # fmt: skip
    if abs(dv + rot) < HINT_TOLERANCE * abs(dv):  # the replay starts too fast by the Earth's rotation
        if record.speed_frame == "inertial":
            return (f" (the Earth's rotation adds {rot:.4g} m/s here: the sidecar's speed_rel_mps looks like an "
                    f"inertial speed, or the record's {INERTIAL_SPEED} like an Earth-relative one)")
        return (f" (the Earth's rotation adds {rot:.4g} m/s here: the sidecar's speed_rel_mps looks like an "
                "inertial speed)")
    if abs(dv - rot) < HINT_TOLERANCE * abs(dv) and record.speed_frame == "earth":
        return (f" (the Earth's rotation adds {rot:.4g} m/s here: the record's speed_rel_mps looks like an inertial "
                f"speed; name that column {INERTIAL_SPEED})")
    return ""


def _refuse_gross_altitude(es, where: str, near: bool, dh: float, se_h: float, noise_h: float, h_meas: float,
                           h_replayed: float) -> None:  # fmt: skip
    """Refuse a declared entry altitude that differs from the record's by a unit's ratio or by more
    than any altitude reference explains, naming both values and the scatter."""
    significant_h = abs(dh) > ERROR_SIGMAS * noise_h and abs(dh) > SIGNIFICANT * se_h
    hint = _ratio_hint(es.altitude, h_meas, "altitude_m") if near else ""
    hint = hint or _ratio_hint(h_replayed, h_meas, "altitude_m (replayed)")
    beyond = abs(dh) - ERROR_SIGMAS * se_h > ALTITUDE_BOUND_M
    if significant_h and (hint or beyond):
        why = hint or (f"; beyond {ALTITUDE_BOUND_M:.0f} m, the largest difference two altitude references make on the "
                       "WGS-84 Earth, it is not an offset any reference explains: a unit, time or state error")
        raise RecordError(
            f"sidecar: entry_state.altitude_m = {es.altitude:g} m, replayed to {where}, is {-dh:+.4g} m from the "
            f"record's altitude_m {h_meas:g} m ({abs(dh) / max(noise_h, 1e-9):.1f} times the {noise_h:.3g} m "
            f"scatter of those samples){why}; fix the sidecar or the record"
        )


def _refuse_gross_speed(setup, record, where: str, near: bool, dv: float, se_v: float, noise_v: float,
                        v_meas: float) -> None:  # fmt: skip
    """Refuse a declared entry speed that differs from the record's by a unit's ratio, another frame's
    speed, or more than the Earth's rotation explains, naming both values and the scatter."""
    es = setup.entry_state
    significant_v = abs(dv) > ERROR_SIGMAS * noise_v and abs(dv) > SIGNIFICANT * se_v
    hint = _speed_hint(setup, record, dv)
    if not hint and near:
        hint = _ratio_hint(es.speed, v_meas, "speed_rel_mps")
    beyond = abs(dv) - ERROR_SIGMAS * se_v > SPEED_BOUND_MPS
    if significant_v and (hint or beyond):
        why = hint or (f"; beyond {SPEED_BOUND_MPS:.0f} m/s, the largest difference between two frames' speeds (the "
                       "Earth's rotation), it is not an offset any frame explains")
        speed_name = record.observation_names[1]
        raise RecordError(
            f"sidecar: entry_state.speed_rel_mps = {es.speed:g} m/s, replayed to {where}, is {-dv:+.4g} m/s from "
            f"the record's {speed_name} {v_meas:g} m/s ({abs(dv) / max(noise_v, 1e-9):.1f} times the "
            f"{noise_v:.3g} m/s scatter of those samples){why}"
        )


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
    _refuse_gross_altitude(es, where, near, dh, se_h, noise_h, h_meas, float(pred[0, 0]))
    _refuse_gross_speed(setup, replay.record, where, near, dv, se_v, noise_v, v_meas)
    for name, group, d, s, se, unit in (("altitude_m", "altitude", dh, sh, se_h, "m"),
                                        ("speed_rel_mps", "speed", dv, sv, se_v, "m/s")):  # fmt: skip
        if s is not None and abs(d) > INIT_BOUND_SIGMAS * s and abs(d) > SIGNIFICANT * se:
            # the offset the first samples show, and around it what the noise and the line's error allow
            half = abs(d) + INIT_BOUND_SIGMAS * (s + se)
            out["widen"][group] = half
            out["warnings"].append(
                f"sidecar: entry_state.{name} is {abs(d):.4g} {unit} ({abs(d) / s:.1f} noise levels) from a robust fit "
                f"of the record at {where}; a finding, not an error: the fitted entry state may move {half:.4g} "
                f"{unit} instead of {INIT_BOUND_SIGMAS * s:.4g} {unit}, and the report gives the offset it finds"
            )
    return out


__all__ = ["check_entry_state"]
