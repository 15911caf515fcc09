"""PNG plots of evaluated episodes: altitude, speed, ground track, alpha and sigma against the reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rventry_env.core.conversions import cartesian_from_rv_euler, lift_up_angle, wrap_angle
from rventry_env.evaluation.rollout import EpisodeBatch
from rventry_env.physics.entry import IDX
from rventry_env.util.files import save_figure

R_E = 6378137.0
NEAR_VERTICAL = np.sin(np.radians(2.0)) ** 2  # the squared horizontal share of "lift up" 2 deg from vertical flight


def _ground_track(x: np.ndarray):
    ok = np.isfinite(x[..., IDX.r])
    lat = np.full(x.shape[:-1], np.nan)
    lon = np.full(x.shape[:-1], np.nan)
    r, _ = cartesian_from_rv_euler(np.where(ok[..., None], x, np.array([R_E + 1, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, 0])))
    a1 = r / np.linalg.norm(r, axis=-1, keepdims=True)
    lat[ok] = np.degrees(np.arcsin(np.clip(a1[..., 2], -1, 1)))[ok]
    lon[ok] = np.degrees(np.arctan2(a1[..., 1], a1[..., 0]))[ok]
    return lat, lon


def conventional_bank_deg(x: np.ndarray) -> np.ndarray:
    """The conventional bank angle mu (0 = lift up, positive to the right) in degrees, in [-180, 180),
    of states ``x (..., 12)``; NaN where it means nothing (within 2 deg of vertical flight, where
    it is undefined at the end and swings freely just before; padding) and where it wraps, so that
    a line drawn through it does not cross the plot at each wrap."""
    e_b = np.moveaxis(np.where(np.isfinite(x[..., 6:10]), x[..., 6:10], 0.0), -1, 0)
    theta_u, n2 = lift_up_angle(e_b)
    mu = np.degrees(wrap_angle(x[..., 11] - theta_u))
    mu = np.where((n2 > NEAR_VERTICAL) & np.isfinite(x[..., 11]), mu, np.nan)
    wraps = np.abs(np.diff(mu, axis=0)) > 180.0
    mu[1:][wraps] = np.nan
    return mu


def unwrapped_bank_deg(x: np.ndarray) -> np.ndarray:
    """The conventional bank angle mu in degrees like :func:`conventional_bank_deg`, but unwrapped
    along time (a roll through 180 deg reads 190, not -170), so that a line through it is the roll
    flown; NaN where it means nothing (near vertical flight, padding). ``x`` is (T, ...) with time first."""
    e_b = np.moveaxis(np.where(np.isfinite(x[..., 6:10]), x[..., 6:10], 0.0), -1, 0)
    theta_u, n2 = lift_up_angle(e_b)
    mu = wrap_angle(x[..., 11] - theta_u)
    shown = (n2 > NEAR_VERTICAL) & np.isfinite(x[..., 11])
    flat_mu = mu.reshape(mu.shape[0], -1)
    flat_shown = shown.reshape(shown.shape[0], -1)
    out = np.full(flat_mu.shape, np.nan)
    for j in range(flat_mu.shape[1]):
        k = np.flatnonzero(flat_shown[:, j])
        if k.size:
            out[k, j] = np.unwrap(flat_mu[k, j])
    return np.degrees(out).reshape(mu.shape)


def coinciding(batches: dict[str, EpisodeBatch], altitude_m: float = 100.0, bank_deg: float = 1.0) -> list[list[str]]:
    """Groups of single-episode batches whose flights lie on top of one another: altitude within
    ``altitude_m`` and conventional bank within ``bank_deg`` at every common step."""
    single = {k: b for k, b in batches.items() if b.history_x is not None and b.history_x.shape[1] == 1}
    groups: list[list[str]] = []
    for name, b in single.items():
        for g in groups:
            other = single[g[0]]
            n = min(b.history_x.shape[0], other.history_x.shape[0])
            xa, xb = b.history_x[:n, 0], other.history_x[:n, 0]
            dh = np.nanmax(np.abs(xa[:, 0] - xb[:, 0]))
            dmu = np.abs(wrap_angle(np.radians(conventional_bank_deg(xa) - conventional_bank_deg(xb))))
            if dh <= altitude_m and np.nanmax(np.degrees(dmu), initial=0.0) <= bank_deg:
                g.append(name)
                break
        else:
            groups.append([name])
    return [g for g in groups if len(g) > 1]


def _words(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _draw_reference(ax: dict, reference) -> None:
    """The collocation reference in black, dashed, on every panel of :func:`plot_trajectories`."""
    tr = np.linspace(0, reference.tf, 2000)
    xr = reference.state(tr)
    lat, lon = _ground_track(xr)
    kw = dict(color="k", lw=1.2, ls="--", zorder=4)
    ax["h"].plot(tr, (xr[:, IDX.r] - R_E) / 1e3, **kw)
    ax["v"].plot(tr, xr[:, IDX.v] / 1e3, **kw)
    ax["track"].plot(lon, lat, **kw)
    ax["alpha"].plot(tr, np.degrees(xr[:, IDX.alpha]), **kw)
    ax["sigma"].plot(tr, unwrapped_bank_deg(xr), **kw)
    ax["legend"].plot([], [], label="collocation reference (optimal)", **kw)


def _finish_trajectory_axes(ax: dict, axes, groups, target_deg) -> None:
    """The target, the axes' labels, the legend and the note on overlapping flights of :func:`plot_trajectories`."""
    import matplotlib

    ax["track"].plot([target_deg[1]], [target_deg[0]], "rx", ms=10, mew=2, zorder=5)
    ax["legend"].plot([], [], "rx", ms=10, mew=2, label="target")
    ax["h"].set(xlabel="t (s)", ylabel="altitude (km)")
    ax["v"].set(xlabel="t (s)", ylabel="speed (km/s)")
    ax["track"].set(xlabel="longitude (deg)", ylabel="latitude (deg)", title="ground track")
    ax["alpha"].set(xlabel="t (s)", ylabel="angle of attack (deg)")
    ax["sigma"].set(xlabel="t (s)", ylabel="bank angle (deg, 0 = lift up, + right)",
                    title="bank angle, unwrapped (a roll through 180 deg continues)")  # fmt: skip
    ax["sigma"].yaxis.set_major_locator(matplotlib.ticker.MultipleLocator(90))
    ax["legend"].axis("off")
    ax["legend"].legend(loc="center", fontsize=10, frameon=False)
    notes = [f"{_words(g)} fly within 100 m of altitude\nand 1 deg of bank of one another: their lines overlap"
             for g in groups]  # fmt: skip
    if notes:
        ax["legend"].text(0.5, 0.0, "\n".join(notes), ha="center", va="bottom", fontsize=9, style="italic",
                          wrap=True, transform=ax["legend"].transAxes)  # fmt: skip
    for a in axes.ravel()[:5]:
        a.grid(alpha=0.3)


def _draw_flights(ax: dict, batches: dict, order: list, color: dict, styles: dict, headline, banks: dict) -> None:
    """Every episode of every batch on the trajectory panels, in ``order``: the headline thick and on
    top, the others fainter, thinner the more episodes a batch holds."""
    for label in order:
        b = batches[label]
        c, ls = color[label], styles.get(label, "-")
        t, x = b.history_t, b.history_x
        n = x.shape[1]
        top = label == headline
        if n == 1:
            lw, alpha = (2.4, 1.0) if top else (1.4, 0.9 if headline is None else 0.7)
        else:
            lw, alpha = (0.9, max(0.15, min(0.8, 20.0 / n))) if top else (0.5, max(0.03, min(0.5, 4.0 / n)))
        kw = dict(color=c, lw=lw, alpha=alpha, ls=ls, zorder=3 if top else 2)
        lat, lon = _ground_track(x)
        ax["h"].plot(t, (x[..., IDX.r] - R_E) / 1e3, **kw)
        ax["v"].plot(t, x[..., IDX.v] / 1e3, **kw)
        ax["track"].plot(lon, lat, **kw)
        ax["alpha"].plot(t, np.degrees(x[..., IDX.alpha]), **kw)
        ax["sigma"].plot(t, banks[label], **kw)


def plot_trajectories(
    batches: dict[str, EpisodeBatch], path: str | Path, reference=None, target_deg=(0.0, 25.15), title: str = "",
    headline: str | None = None,
) -> Path:
    """Altitude, speed, ground track, alpha and the bank angle (deg, unwrapped) of every episode of every batch.

    :param batches: label -> batch recorded with ``record_history=True``.
    :param path: PNG file to write.
    :param reference: a loaded reference solution to draw in black (its own time grid).
    :param target_deg: (latitude, longitude) of the target in degrees.
    :param title: the figure's title (say the set and the episode count).
    :param headline: the label drawn on top of the others, bold; the others fainter beneath it.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(14, 7.5))
    ax = dict(zip(("h", "v", "track", "alpha", "sigma", "legend"), axes.ravel()))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for label, b in batches.items():
        if b.history_x is None:
            raise ValueError(f"batch {label!r} was not recorded with record_history=True")
    if headline is not None and headline not in batches:
        raise ValueError(f"headline {headline!r} is not among the batches {list(batches)}")
    groups = coinciding(batches)
    # flights on top of one another: the second of a group dashed, the third dotted, ... to tell them apart
    styles = {name: ("-", "--", ":", "-.")[i % 4] for g in groups for i, name in enumerate(g)}
    color = {label: colors[k % len(colors)] for k, label in enumerate(batches)}
    # the headline last, so that it is drawn over the others
    order = [k for k in batches if k != headline] + ([headline] if headline is not None else [])
    banks = {label: unwrapped_bank_deg(batches[label].history_x) for label in batches}
    _draw_flights(ax, batches, order, color, styles, headline, banks)
    # the bank panel's range: where nearly all of the drawn bank angles lie, so that a few vehicles
    # spinning at the end do not squeeze every other line flat
    every = np.concatenate([v[np.isfinite(v)] for v in banks.values()] or [np.zeros(1)])
    if every.size:
        lo, hi = np.percentile(every, [0.5, 99.5])
        ax["sigma"].set_ylim(min(lo, -185.0) - 10.0, max(hi, 185.0) + 10.0)
    for label in batches:  # the legend in the order of the batches, the headline first where it is
        n = batches[label].history_x.shape[1]
        text = f"{label} ({n} episode{'s' if n > 1 else ''})" + (": drawn on top" if label == headline else "")
        ax["legend"].plot([], [], color=color[label], lw=3 if label == headline else 2, ls=styles.get(label, "-"),
                          label=text)  # fmt: skip
    if reference is not None:
        _draw_reference(ax, reference)
    _finish_trajectory_axes(ax, axes, groups, target_deg)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_outcomes(batches: dict[str, EpisodeBatch], path: str | Path, thresholds, title: str = "") -> Path:
    """Histograms of miss, vertical-impact error and speed error with the success thresholds, one row per law, as a PNG."""
    return save_figure(outcomes_figure(batches, thresholds, title), path, tight=False)


def _shared_bins(pooled: np.ndarray, thr: float, positive: bool) -> np.ndarray:
    """40 bins over every law's values and the threshold: logarithmic for a positive quantity."""
    if positive:
        lo = max(pooled.min(), 1e-3) if pooled.size else 1e-3
        hi = max(pooled.max(), 10 * lo) if pooled.size else 1.0
        bins = np.logspace(np.log10(lo), np.log10(hi), 40)
    else:
        lo, hi = (pooled.min(), pooled.max()) if pooled.size > 1 else (-thr, thr)
        lo, hi = min(lo, -thr), max(hi, thr)
        bins = np.linspace(lo, hi, 40)
    return bins


def _outcome_histogram(ax, v: np.ndarray, bins: np.ndarray, thr: float, positive: bool, row: int) -> None:
    """One law's histogram of one outcome, heights a fraction of its episodes, the threshold dashed in red."""
    from matplotlib import ticker

    if v.size:
        ax.hist(np.clip(v, bins[0], bins[-1]) if positive else v, bins=bins, color=f"C{row % 10}",
                weights=np.full(v.size, 1.0 / v.size), histtype="stepfilled", alpha=0.8)  # fmt: skip
    ax.axvline(thr, color="r", ls="--", lw=1)
    if not positive:
        ax.axvline(-thr, color="r", ls="--", lw=1)
    ax.set_ylim(0, 1.05)
    ax.yaxis.set_major_locator(ticker.FixedLocator([0, 0.5, 1]))
    ax.tick_params(labelsize=8)
    ax.grid(alpha=0.3)
    if positive:
        ax.set_xscale("log")


def outcomes_figure(batches: dict[str, EpisodeBatch], thresholds, title: str = ""):
    """The figure of :func:`plot_outcomes`: a row of three histograms per law (miss, vertical-impact
    error, speed error) on bins shared down each column, each row's heights a fraction of that law's
    own episodes, the success threshold dashed in red, and the law, its episode count and success
    rate written beside its row, so that nothing covers a bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    specs = (
        ("miss_km", "miss (km)", thresholds.miss_km, True),
        ("vertical_error_deg", "vertical-impact error (deg)", thresholds.vertical_error_deg, True),
        ("speed_error_mps", "speed error (m/s)", thresholds.speed_error_mps, False),
    )
    names = list(batches)
    rows = max(1, len(names))
    fig, axes = plt.subplots(rows, 3, figsize=(13, 1.2 + 1.15 * rows), sharex="col", squeeze=False)
    for col, (key, label, thr, positive) in enumerate(specs):
        values = {name: np.asarray(getattr(b, key), float) for name, b in batches.items()}
        values = {name: v[np.isfinite(v)] for name, v in values.items()}
        pooled = np.concatenate([v for v in values.values()]) if values else np.zeros(0)
        # one set of bins for every law, so the rows compare; heights are fractions of each law's episodes
        bins = _shared_bins(pooled, thr, positive)
        unit = label.rsplit("(", 1)[-1].rstrip(")")
        axes[0, col].set_title(f"{label}\ndashed: success within {'' if positive else '+/-'}{thr:g} {unit}", fontsize=10)
        for row, name in enumerate(names):
            _outcome_histogram(axes[row, col], values[name], bins, thr, positive, row)
        bottom = axes[-1, col]
        bottom.set_xlabel(label)
        if positive:  # whole labels at 1, 2, 5 per decade, none on the minor ticks: no overlap
            bottom.set_xlim(min(bins[0], thr) / 1.2, max(bins[-1], thr) * 1.2)
            subs = (1.0, 2.0, 5.0) if _decades(bottom) < 3 else (1.0,)
            bottom.xaxis.set_major_locator(ticker.LogLocator(base=10, subs=subs))
            bottom.xaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            bottom.xaxis.set_minor_formatter(ticker.NullFormatter())
    for row, name in enumerate(names):
        b = batches[name]
        n = int(np.size(b.is_success))
        share = f"{np.mean(b.is_success):.3f}"
        share = share[:-1] if share.endswith("0") else share  # 0.995, 1.00, 0.74: as the tables print it
        axes[row, 0].set_ylabel(f"{name}\n{n} ep., success {share}" if n else name, fontsize=9,
                                rotation=0, ha="right", va="center")  # fmt: skip
    fig.suptitle((title + "\n" if title else "") + "bar heights: the fraction of each law's own episodes", fontsize=11)
    fig.tight_layout()
    return fig


def _decades(ax) -> float:
    lo, hi = ax.get_xlim()
    return float(np.log10(hi / lo))
