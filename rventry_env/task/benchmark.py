"""The RvEntry-v0 benchmark's targets for a guidance law, and their check against measured figures.

``rventry compare`` keeps the checks in its JSON report as a record; the console shows the laws
against the success definition (:class:`~rventry_env.task.definition.SuccessThresholds`) instead.
"""

from __future__ import annotations

# the nominal flight's targets, on the evaluation summary's figures (km, deg, m/s, J/J*)
NOMINAL_TARGETS = {"miss_km": 1.0, "vertical_error_deg": 1.0, "abs_speed_error_mps": 50.0, "cost_ratio": 1.3}
# success under dispersions, per set (the nominal set is held to the standard set's), and the margin in
# success over TV-LQR without estimation, on the same episodes. The dispersed-success target exists for
# the sets a learned policy was first built for; the flight-grade sets are read against the oracle's
# ceiling instead (`rventry oracle`)
DISPERSED_SUCCESS_TARGETS = {"standard": 0.95, "wide": 0.90}
MARGIN_OVER_LQR = 0.10


def target_checks(nominal: dict, dispersed: dict, dispersion: str, lqr_dispersed: dict | None = None) -> dict:
    """Each target with the figure measured and whether it is met.

    :param nominal: the evaluation summary of the nominal flight; ``dispersed`` of the dispersed episodes.
    :param dispersion: the set flown.
    :param lqr_dispersed: TV-LQR's summary on the same dispersed episodes (None: no margin check).
    """
    checks = {
        f"nominal_{k}": {"target": v, "measured": nominal[k], "met": nominal[k] is not None and abs(nominal[k]) <= v}
        for k, v in NOMINAL_TARGETS.items()
    }
    success_target = DISPERSED_SUCCESS_TARGETS.get(dispersion)
    if success_target is not None:
        checks["dispersed_success_rate"] = {"target": success_target, "measured": dispersed["success_rate"],
                                            "met": dispersed["success_rate"] >= success_target}  # fmt: skip
        if lqr_dispersed is not None:
            gain = dispersed["success_rate"] - lqr_dispersed["success_rate"]
            checks["success_over_lqr"] = {"target": MARGIN_OVER_LQR, "measured": gain,
                                          "met": gain >= MARGIN_OVER_LQR - 1e-9}  # fmt: skip
    return checks


__all__ = ["NOMINAL_TARGETS", "DISPERSED_SUCCESS_TARGETS", "MARGIN_OVER_LQR", "target_checks"]
