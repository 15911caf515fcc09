"""Gross outliers in a record: found without a model, rejected, and reported by row.

One bad row (a 30 km jump in a position, a digit dropped in a speed) must not decide which
effect the loop names. Each observation channel is checked against a local cubic through its
neighbours (three on each side, the sample itself left out): a sample whose deviation exceeds
:data:`OUTLIER_SIGMAS` robust standard deviations of all such deviations (1.4826 x the median
absolute deviation) is an outlier. The largest is removed first and the check repeated, so an
outlier does not make its neighbours look bad. On a smooth trajectory the cubic follows the
signal and the deviations are the noise; on a sparse table they include the signal's curvature,
which the robust scale then absorbs, so only gross errors stand out.

A rejected sample removes its observation group in that row (all of a position, all of a
velocity); the report lists every rejected row with its file line and the deviation.
"""

from __future__ import annotations

import numpy as np

OUTLIER_SIGMAS = 12.0
HALF_WINDOW = 3
MAX_PASSES = 50
MIN_SAMPLES = 2 * HALF_WINDOW + 2


def _loo_deviation(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Deviation of every sample from a cubic through its neighbours (itself left out)."""
    n = len(t)
    dev = np.full(n, np.nan)
    if n < MIN_SAMPLES:
        return dev
    idx = np.arange(n)
    # the 2 HALF_WINDOW + 1 consecutive samples around each (shifted inward at the ends), itself left out
    centre = np.clip(idx, HALF_WINDOW, n - 1 - HALF_WINDOW)
    win = centre[:, None] + np.arange(-HALF_WINDOW, HALF_WINDOW + 1)[None, :]
    nb = win[win != idx[:, None]].reshape(n, 2 * HALF_WINDOW)
    tc = t[nb] - t[idx][:, None]
    scale = np.max(np.abs(tc), axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    x = tc / scale
    basis = np.stack([np.ones_like(x), x, x * x, x * x * x], axis=-1)  # (n, w, 4)
    a = np.einsum("nwi,nwj->nij", basis, basis)
    b = np.einsum("nwi,nw->ni", basis, y[nb])
    try:
        coef = np.linalg.solve(a + 1e-12 * np.eye(4), b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return dev
    return y - coef[:, 0]  # the cubic at the sample itself (x = 0)


def find_outliers(t: np.ndarray, y: np.ndarray) -> list[tuple[int, float, float]]:
    """Outliers of one channel: (sample index, deviation, robust sigmas), largest first.

    :param t: sample times.
    :param y: samples, NaN in gaps.
    """
    t = np.asarray(t, float)
    yorig = np.asarray(y, float)
    y = yorig.copy()
    found = []
    for _ in range(MAX_PASSES):
        ok = np.flatnonzero(np.isfinite(y))
        if ok.size < MIN_SAMPLES:
            break
        dev = _loo_deviation(t[ok], y[ok])
        good = np.isfinite(dev)
        if not np.any(good):
            break
        scale = 1.4826 * float(np.median(np.abs(dev[good] - np.median(dev[good]))))
        if scale <= 0:
            break
        k = int(np.nanargmax(np.abs(dev)))
        z = abs(dev[k]) / scale
        if z <= OUTLIER_SIGMAS:
            break
        found.append((int(ok[k]), float(dev[k]), float(z), scale))
        y[ok[k]] = np.nan
    # confirm each against the cleaned channel: an early find can have made a neighbour look bad
    confirmed = []
    for i, dev, z, scale in found:
        y[i] = float(np.asarray(yorig)[i])
        ok = np.flatnonzero(np.isfinite(y))
        d = _loo_deviation(t[ok], y[ok])[np.searchsorted(ok, i)]
        y[i] = np.nan
        if np.isfinite(d) and abs(d) > OUTLIER_SIGMAS * scale:
            confirmed.append((i, float(d), float(abs(d) / scale)))
    return sorted(confirmed, key=lambda c: -c[2])


def reject_outliers(replay, groups: dict) -> list[dict]:
    """Find gross outliers in a replay's observations, blank their groups, and describe them.

    Only channels whose sampling resolves the signal are screened (their difference noise
    estimate is noise, not an upper bound): on a sparse table a local cubic does not follow the
    trajectory, and a real sample would be called an outlier.

    :param replay: the record's replay (its ``y`` is modified in place).
    :param groups: group name -> (unit, column indices) of the channels to screen.
    :return: one entry per rejected row and group: file line, time, columns, deviation.
    """
    rec = replay.record
    out = []
    for name, (unit, cols) in groups.items():
        rows = {}
        for c in cols:
            for i, dev, z in find_outliers(replay.t_obs, replay.y[:, c]):
                prev = rows.get(i)
                if prev is None or z > prev[2]:
                    rows[i] = (c, dev, z)
        for i, (c, dev, z) in sorted(rows.items()):
            replay.y[i, list(cols)] = np.nan
            out.append({
                "row": rec.line_of(int(replay.rows[i])),
                "t_s": float(replay.t_obs[i]),
                "group": name,
                "columns": [rec.observation_names[j] for j in cols],
                "deviation": dev,
                "unit": unit,
                "robust_sigmas": z,
            })  # fmt: skip
    return out


__all__ = ["OUTLIER_SIGMAS", "find_outliers", "reject_outliers"]
