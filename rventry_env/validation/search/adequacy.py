"""Is the identified model adequate? The final residual against the measurement noise.

The loop can only name effects from its candidate set. When the record holds something else (a
Mach-dependent drag the candidates cannot shape, a clock offset, an atmosphere the profile
cannot bend to), the best candidate still lowers the residual, and "none" or a confident name
would be wrong. So after the final model the residual is tested against the noise: the declared
noise (``--noise`` or the sidecar's ``noise``) when there is one, else the record's difference
estimate.

* **Size**: per observation group, the residual's scale over the noise's, both *robust*
  (1.4826 x the median absolute deviation: the residual's own, and the record's differences',
  :func:`~rventry_env.validation.search.statistics.robust_difference_noise`; a declared noise is
  taken as the scale). Heavy-tailed noise (a few large errors, Student's t) then reads as
  noise: an rms test would compare a tail-inflated residual with an estimate whose outlier clip
  cut the tails, and call it an effect. The ratio's standard error is that of a MAD scale,
  :data:`MAD_SE` / sqrt(dof), with the estimate's :data:`MAD_DIFF_SE` / sqrt(n) added when the
  noise is estimated; a ratio more than :data:`Z_CRIT` standard errors above 1 is too large.
  The rms ratio is reported beside it. When the noise estimate is only an upper bound, the
  test is one-sided and still meaningful: a residual above an upper bound of the noise is not
  noise.
* **Whiteness**: the Ljung-Box test of the normalized residual; p below :data:`ALPHA` says the
  residual is correlated, which white measurement noise is not.
* **Entry state**: a fit whose initial state ends on its noise bound needed more than the noise
  allows at the start; the model does not explain the record from its first samples.

If any fails the report says ``"unexplained": true``, with the figures and a plain sentence.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.validation.search.statistics import robust_scale, whiteness

ALPHA = 1e-3
Z_CRIT = 3.3  # one-sided normal quantile of ALPHA
MAD_SE = 1.17  # standard error x sqrt(n) of a MAD scale of normal values (rms: 0.71)
MAD_DIFF_SE = 2.0  # the same of the 4th-difference MAD estimate (overlapping differences; conservative)


def _size_tests(fit, sigma_by_group: dict, source: str, group_names: list, groups: np.ndarray,
                robust_noise: dict | None) -> tuple[dict, bool]:  # fmt: skip
    """The size test per observation group: the residual's scale over the noise's (robust where the
    noise's robust scale is known, else rms), with its z against :data:`Z_CRIT`.

    :return: the figures per group, and whether every tested group is consistent with the noise.
    """
    n_tot = sum(fit.n_by_group)
    k = fit.n_params
    size = {}
    size_ok = True
    for i, g in enumerate(group_names):
        n = fit.n_by_group[i]
        s = sigma_by_group[g]
        if n == 0 or not (s and math.isfinite(s)):
            continue
        rms = math.sqrt(fit.rss_by_group[i] / n)
        dof = max(n - k * n / n_tot, 1.0)
        tested = source in ("declared", "estimated")
        s_rob = (robust_noise or {}).get(g)
        if s_rob is not None and math.isfinite(s_rob) and s_rob > 0:
            scale = robust_scale(fit.residual[:, groups == i])
            se = MAD_SE / math.sqrt(dof)
            if source == "estimated":
                se = math.hypot(se, MAD_DIFF_SE / math.sqrt(n))
            ratio = scale / s_rob
            entry = {"rms": rms, "noise": s, "rms_ratio": rms / s, "robust_scale": scale, "robust_noise": s_rob,
                     "ratio": ratio, "measure": "robust (MAD) scales"}  # fmt: skip
        else:
            se = math.sqrt(1.0 / (2.0 * dof))
            if source == "estimated":
                se = math.hypot(se, 0.85 / math.sqrt(n))
            ratio = rms / s
            entry = {"rms": rms, "noise": s, "ratio": ratio, "measure": "rms"}
        z = (ratio - 1.0) / se
        ok = (not tested) or z <= Z_CRIT
        size_ok &= ok
        size[g] = {**entry, "z": z if tested else None, "consistent": ok}
    return size, size_ok


def _reasons(fit, size: dict, source: str, w: dict, white_ok: bool, start_ok: bool) -> list[str]:
    """Why the model does not explain the record, one phrase per failed test."""
    p = w["ljung_box_p"]
    reasons = []
    for g, d in size.items():
        if not d["consistent"]:
            if d["measure"] == "rms":
                reasons.append(f"the {g} residual is {d['ratio']:.3g} times the {source} noise ({d['rms']:.4g} vs "
                               f"{d['noise']:.4g})")  # fmt: skip
            else:
                reasons.append(f"the {g} residual's robust scale is {d['ratio']:.3g} times the {source} noise's "
                               f"({d['robust_scale']:.4g} vs {d['robust_noise']:.4g}; rms {d['rms']:.4g})")  # fmt: skip
    if not white_ok:
        reasons.append(f"the residual is correlated (lag-1 autocorrelation {w['lag1_autocorrelation']:.2f}, "
                       f"Ljung-Box p = {p:.2g})")  # fmt: skip
    if not start_ok:
        reasons.append("the initial state ended on its noise bound ("
                       + ", ".join(fit.extra["initial_state_at_bound"]) + ")")  # fmt: skip
    return reasons


def adequacy(fit, sigma_by_group: dict, source: str, group_names: list, groups: np.ndarray, sigma: np.ndarray,
             estimated_is: dict | None = None, robust_noise: dict | None = None) -> dict:  # fmt: skip
    """Test the residual of ``fit`` against the noise.

    :param fit: the final :class:`~rventry_env.validation.search.fit.FitResult`.
    :param sigma_by_group: noise standard deviation per group.
    :param source: ``"declared"`` or ``"estimated"`` (from record differences) or
        ``"baseline residual"`` (no noise known: the size test is skipped).
    :param group_names: observation group names, in the order of ``fit.rss_by_group``.
    :param groups: group index per channel.
    :param sigma: noise per channel (the weights).
    :param estimated_is: per group, what the difference estimate is (noise or an upper bound).
    :param robust_noise: the noise's robust scale per group (declared, or the record's MAD
        estimate); without it the size test compares rms values.
    """
    size, size_ok = _size_tests(fit, sigma_by_group, source, group_names, groups, robust_noise)
    w = whiteness(fit.residual / sigma[None, :])
    p = w["ljung_box_p"]
    white_ok = p is None or p >= ALPHA
    start_ok = not fit.extra.get("initial_state_at_bound")
    unexplained = not (size_ok and white_ok and start_ok)
    reasons = _reasons(fit, size, source, w, white_ok, start_ok)
    if unexplained:
        statement = ("The identified model does not explain the record: " + "; ".join(reasons)
                     + ". An effect outside the candidate set remains (or the declared noise is too small).")  # fmt: skip
    else:
        statement = "The residual is consistent with the noise in size and white: nothing unexplained remains."
        if source == "baseline residual":
            statement = ("No noise level is known (declare one with --noise or the sidecar's 'noise'), so the "
                         "residual's size is not tested; it is white.")  # fmt: skip
    return {
        "unexplained": bool(unexplained),
        "noise_source": source,
        "noise_estimate_is": estimated_is or {},
        "size": size,
        "whiteness": w,
        "initial_state_at_bound": list(fit.extra.get("initial_state_at_bound", [])),
        "alpha": ALPHA,
        "statement": statement,
    }


__all__ = ["ALPHA", "MAD_DIFF_SE", "MAD_SE", "Z_CRIT", "adequacy"]
