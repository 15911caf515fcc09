"""The sidecar against the record: does the declared entry state match the first samples?

A reduced record starts its replay from the sidecar's entry state, and the fit may move that
state only within the noise. A sidecar altitude in kilometres, a record altitude in feet, or an
inertial speed put in ``speed_rel_mps`` would otherwise be "explained" by whatever effect bends
the trajectory furthest. The declared state is replayed (nothing fitted) to the first observed
sample and compared with it:

* a mismatch beyond :data:`ERROR_SIGMAS` noise levels and beyond the absolute floors
  (:data:`ALTITUDE_FLOOR_M`, :data:`SPEED_FLOOR_MPS`) is an error naming the field, with the
  likely cause when the ratio or difference says so (feet, kilometres, inertial speed);
* a smaller mismatch beyond :data:`INIT_BOUND_SIGMAS` noise levels is a warning: the fitted
  initial state will end on its bound.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.intake.noise import INIT_BOUND_SIGMAS
from rventry_env.validation.record import RecordError

ERROR_SIGMAS = 20.0
ALTITUDE_FLOOR_M = 2000.0
SPEED_FLOOR_MPS = 50.0
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


def check_entry_state(replay, setup, sigma_by_group: dict) -> dict:
    """Compare the declared entry state, replayed to the first observed sample, with that sample.

    :param replay: the record's replay (a reduced record: it starts from the declared state).
    :param setup: the declared facts.
    :param sigma_by_group: noise per group (NaN or None where unknown).
    :return: the differences and any warnings; raises :class:`RecordError` on a gross mismatch.
    """
    es = setup.entry_state
    if replay.record.kind != "reduced" or es is None:
        return {}
    i = int(np.flatnonzero(np.all(np.isfinite(replay.y), axis=1))[0]) if np.any(
        np.all(np.isfinite(replay.y), axis=1)) else 0  # fmt: skip
    with np.errstate(all="ignore"):
        pred = replay.predict(setup.model, np.zeros((1, replay.init.size)))[i, :, 0]
    h_meas, v_meas = replay.y[i]
    dh, dv = float(h_meas - pred[0]), float(v_meas - pred[1])
    sh = sigma_by_group.get("altitude")
    sv = sigma_by_group.get("speed")
    sh = sh if sh and math.isfinite(sh) else None
    sv = sv if sv and math.isfinite(sv) else None
    t = float(replay.t_obs[i])
    row = replay.record.line_of(int(replay.rows[i]))
    out = {"t_s": t, "row": row, "altitude_difference_m": dh, "speed_difference_mps": dv, "warnings": []}
    if not (math.isfinite(dh) and math.isfinite(dv)):
        raise RecordError(f"sidecar: entry_state: the replay from the declared state fails before row {row}")
    near = abs(t - es.t) < 1.0
    if abs(dh) > max(ERROR_SIGMAS * (sh or 0.0), ALTITUDE_FLOOR_M):
        hint = _ratio_hint(es.altitude, h_meas, "altitude_m") if near else ""
        raise RecordError(
            f"sidecar: entry_state.altitude_m = {es.altitude:g} m, replayed to t_s = {t:g} (row {row}), is "
            f"{-dh:+.4g} m from the record's altitude_m {h_meas:g} m{hint}; fix the sidecar or the record"
        )
    if abs(dv) > max(ERROR_SIGMAS * (sv or 0.0), SPEED_FLOOR_MPS):
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
            f"sidecar: entry_state.speed_rel_mps = {es.speed:g} m/s, replayed to t_s = {t:g} (row {row}), is "
            f"{-dv:+.4g} m/s from the record's speed_rel_mps {v_meas:g} m/s{hint}"
        )
    for name, d, s, unit in (("altitude_m", dh, sh, "m"), ("speed_rel_mps", dv, sv, "m/s")):
        if s is not None and abs(d) > INIT_BOUND_SIGMAS * s:
            out["warnings"].append(
                f"sidecar: entry_state.{name} is {abs(d):.4g} {unit} ({abs(d) / s:.1f} noise levels) from the "
                f"record at t_s = {t:g}; the fitted entry state may move only {INIT_BOUND_SIGMAS:g} noise levels"
            )
    return out


__all__ = ["check_entry_state"]
