"""Statistics of the validation loop: noise level, information criterion, residual whiteness.

Noise is not declared in a record, so it is estimated twice, independently:

* from the record alone, by differencing: on a uniformly sampled smooth signal
  the k-th difference of the truth is negligible and that of white noise has
  variance C(2k, k) sigma^2. The rms of the 4th differences (after clipping
  outliers beyond 5 robust standard deviations) gives sigma without any model;
  its scatter is about 0.85 / sqrt(n) relative.
* from the fit, sigma_g^2 = RSS_g / n_g per observation group (profiled in BIC).

The first sets the least-squares weights when the record allows it (dense,
uniform sampling); the second is what BIC uses, so a record with no usable
difference estimate (sparse, irregular) is still handled.
"""

from __future__ import annotations

import math

import numpy as np

DIFF_ORDER = 4
MIN_DIFFERENCES = 20
MAD_TO_SIGMA = 1.4826  # the standard deviation of normal noise per median absolute deviation


def _differences(t: np.ndarray, y: np.ndarray, order: int) -> np.ndarray | None:
    """``order``-th differences over runs of consecutive finite samples at one spacing (None if too few)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    diffs = []
    start = 0
    n = len(t)
    while start < n:
        end = start + 1
        if np.isfinite(y[start]):
            dt0 = None
            while end < n and np.isfinite(y[end]):
                dt = t[end] - t[end - 1]
                if dt0 is None:
                    dt0 = dt
                elif abs(dt - dt0) > 1e-6 * max(dt0, 1e-9):
                    break
                end += 1
            run = y[start:end]
            if len(run) > order:
                diffs.append(np.diff(run, n=order))
        start = end
    if not diffs:
        return None
    d = np.concatenate(diffs)
    return d if d.size >= MIN_DIFFERENCES else None


def difference_noise(t: np.ndarray, y: np.ndarray, order: int = DIFF_ORDER) -> float:
    """Noise standard deviation of one channel from its ``order``-th differences, or NaN.

    Only runs of consecutive finite samples at one spacing are differenced (gaps
    and irregular steps break a run).

    :param t: sample times (s).
    :param y: samples, NaN in gaps.
    :param order: difference order.
    """
    d = _differences(t, y, order)
    if d is None:
        return math.nan
    dev = np.abs(d - np.median(d))
    robust = MAD_TO_SIGMA * np.median(dev)
    # rms rather than the MAD itself: a third less scatter; the clip keeps single outliers out
    kept = d[dev <= 5.0 * robust] if robust > 0 else d
    return float(np.sqrt(np.mean(kept**2)) / math.sqrt(math.comb(2 * order, order)))


def robust_difference_noise(t: np.ndarray, y: np.ndarray, order: int = DIFF_ORDER) -> float:
    """The noise's robust scale from its ``order``-th differences: 1.4826 MAD / sqrt(C(2k, k)), or NaN.

    For normal noise it is the standard deviation. For heavy-tailed noise (Student's t) it is
    the scale of the bulk, not inflated by the tails, and it is what :func:`robust_scale` of a
    residual is compared with in the adequacy test.
    """
    d = _differences(t, y, order)
    if d is None:
        return math.nan
    return float(robust_scale(d) / math.sqrt(math.comb(2 * order, order)))


def robust_scale(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation from the median of the finite values (NaN if none)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return math.nan
    return float(MAD_TO_SIGMA * np.median(np.abs(x - np.median(x))))


def bic(rss_by_group, n_by_group, n_params: int) -> float:
    """Bayesian information criterion with the noise variance of each group profiled out.

    BIC = sum_g n_g ln(RSS_g / n_g) + k ln(N), N = sum n_g (Gaussian, white,
    one unknown variance per observation group).

    :param rss_by_group: residual sums of squares (any consistent unit per group).
    :param n_by_group: number of scalar observations per group.
    :param n_params: number of fitted parameters (initial state included).
    """
    n_tot = 0
    out = 0.0
    for rss, n in zip(rss_by_group, n_by_group):
        out += n * math.log(max(rss, 1e-300) / n)
        n_tot += n
    return out + n_params * math.log(n_tot)


def effective_size(n: int, lag1: float | None) -> float:
    """Number of independent values in ``n`` serially correlated ones (AR(1) approximation).

    n_eff = n (1 - rho) / (1 + rho), rho the lag-1 autocorrelation clipped to [0, 0.98].
    BIC assumes white residuals; when even the best model leaves correlated ones
    (real data, unmodelled physics), counting every value as independent makes
    any extra parameter look significant.
    """
    rho = min(max(lag1 or 0.0, 0.0), 0.98)
    return n * (1.0 - rho) / (1.0 + rho)


def bic_effective(rss_by_group, n_by_group, n_params: int, n_eff: float) -> float:
    """:func:`bic` with the log-likelihood and the penalty counted on ``n_eff`` values.

    BIC_eff = (n_eff / N) sum_g n_g ln(RSS_g / n_g) + k ln(n_eff).
    """
    n_tot = sum(n_by_group)
    ll = sum(n * math.log(max(rss, 1e-300) / n) for rss, n in zip(rss_by_group, n_by_group))
    return (n_eff / n_tot) * ll + n_params * math.log(max(n_eff, 2.0))


def _autocorr(x: np.ndarray, lags: int) -> np.ndarray:
    x = x - np.mean(x)
    den = float(np.dot(x, x))
    if den == 0:
        return np.zeros(lags)
    return np.array([np.dot(x[:-k], x[k:]) / den for k in range(1, lags + 1)])


def whiteness(residual: np.ndarray, lags: int | None = None) -> dict:
    """Lag-1 autocorrelation and the Ljung-Box test of residual series.

    :param residual: ``(n, m)`` residuals, one column per channel, NaN in gaps
        (each channel's finite samples are taken in time order).
    :param lags: Ljung-Box lags; default min(10, n // 5).
    :return: ``lag1_autocorrelation`` (mean over channels), ``ljung_box_q`` (sum over
        channels), its degrees of freedom and ``ljung_box_p``. White noise has lag-1
        autocorrelation near 0 (within about 2/sqrt(n)) and p not small.
    """
    from scipy.stats import chi2

    residual = np.atleast_2d(np.asarray(residual, float))
    if residual.shape[0] == 1 and residual.shape[1] > 1:
        residual = residual.T
    r1, q, dof = [], 0.0, 0
    for col in residual.T:
        x = col[np.isfinite(col)]
        n = len(x)
        if n < 8:
            continue
        m = lags or max(1, min(10, n // 5))
        rho = _autocorr(x, m)
        r1.append(rho[0])
        q += n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, m + 1))))
        dof += m
    if not r1:
        return {"lag1_autocorrelation": None, "ljung_box_q": None, "ljung_box_dof": 0, "ljung_box_p": None}
    return {
        "lag1_autocorrelation": float(np.mean(r1)),
        "ljung_box_q": q,
        "ljung_box_dof": dof,
        "ljung_box_p": float(chi2.sf(q, dof)),
    }


__all__ = ["bic", "bic_effective", "difference_noise", "effective_size", "robust_difference_noise", "robust_scale",
           "whiteness"]
