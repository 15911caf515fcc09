"""PNG plots of evaluated episodes: altitude, speed, ground track, alpha and sigma against the reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.core.conversions import cartesian_from_rv_euler
from rventry_env.evaluation.rollout import EpisodeBatch
from rventry_env.util.files import save_figure

R_E = 6378137.0


def _ground_track(x: np.ndarray):
    ok = np.isfinite(x[..., IDX.r])
    lat = np.full(x.shape[:-1], np.nan)
    lon = np.full(x.shape[:-1], np.nan)
    r, _ = cartesian_from_rv_euler(np.where(ok[..., None], x, np.array([R_E + 1, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, 0])))
    a1 = r / np.linalg.norm(r, axis=-1, keepdims=True)
    lat[ok] = np.degrees(np.arcsin(np.clip(a1[..., 2], -1, 1)))[ok]
    lon[ok] = np.degrees(np.arctan2(a1[..., 1], a1[..., 0]))[ok]
    return lat, lon


def plot_trajectories(
    batches: dict[str, EpisodeBatch], path: str | Path, reference=None, target_deg=(0.0, 25.15), title: str = ""
) -> Path:
    """Altitude, speed, ground track, alpha and sigma (deg) of every episode of every batch.

    :param batches: label -> batch recorded with ``record_history=True``.
    :param path: PNG file to write.
    :param reference: a loaded reference solution to draw in black (its own time grid).
    :param target_deg: (latitude, longitude) of the target in degrees.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(14, 7.5))
    ax = dict(zip(("h", "v", "track", "alpha", "sigma", "legend"), axes.ravel()))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, b) in enumerate(batches.items()):
        if b.history_x is None:
            raise ValueError(f"batch {label!r} was not recorded with record_history=True")
        c = colors[k % len(colors)]
        t, x = b.history_t, b.history_x
        n = x.shape[1]
        lw, alpha = (1.6, 1.0) if n == 1 else (0.6, max(0.08, min(0.6, 8.0 / n)))
        lat, lon = _ground_track(x)
        ax["h"].plot(t, (x[..., IDX.r] - R_E) / 1e3, color=c, lw=lw, alpha=alpha)
        ax["v"].plot(t, x[..., IDX.v] / 1e3, color=c, lw=lw, alpha=alpha)
        ax["track"].plot(lon, lat, color=c, lw=lw, alpha=alpha)
        ax["alpha"].plot(t, np.degrees(x[..., IDX.alpha]), color=c, lw=lw, alpha=alpha)
        ax["sigma"].plot(t, np.degrees(x[..., IDX.sigma]), color=c, lw=lw, alpha=alpha)
        ax["legend"].plot([], [], color=c, lw=2, label=f"{label} ({n} episode{'s' if n > 1 else ''})")
    if reference is not None:
        tr = np.linspace(0, reference.tf, 2000)
        xr = reference.state(tr)
        lat, lon = _ground_track(xr)
        kw = dict(color="k", lw=1.2, ls="--")
        ax["h"].plot(tr, (xr[:, IDX.r] - R_E) / 1e3, **kw)
        ax["v"].plot(tr, xr[:, IDX.v] / 1e3, **kw)
        ax["track"].plot(lon, lat, **kw)
        ax["alpha"].plot(tr, np.degrees(xr[:, IDX.alpha]), **kw)
        ax["sigma"].plot(tr, np.degrees(xr[:, IDX.sigma]), **kw)
        ax["legend"].plot([], [], label="collocation reference (optimal)", **kw)
    ax["track"].plot([target_deg[1]], [target_deg[0]], "rx", ms=10, mew=2)
    ax["legend"].plot([], [], "rx", ms=10, mew=2, label="target")
    ax["h"].set(xlabel="t (s)", ylabel="altitude (km)")
    ax["v"].set(xlabel="t (s)", ylabel="speed (km/s)")
    ax["track"].set(xlabel="longitude (deg)", ylabel="latitude (deg)", title="ground track")
    ax["alpha"].set(xlabel="t (s)", ylabel="angle of attack (deg)")
    ax["sigma"].set(xlabel="t (s)", ylabel="bank angle sigma (deg, paper's)")
    ax["legend"].axis("off")
    ax["legend"].legend(loc="center", fontsize=10, frameon=False)
    for a in axes.ravel()[:5]:
        a.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_outcomes(batches: dict[str, EpisodeBatch], path: str | Path, thresholds) -> Path:
    """Histograms of miss, vertical-impact error and speed error with the success thresholds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    specs = (
        ("miss_km", "miss (km)", thresholds.miss_km, True),
        ("vertical_error_deg", "vertical-impact error (deg)", thresholds.vertical_error_deg, True),
        ("speed_error_mps", "speed error (m/s)", thresholds.speed_error_mps, False),
    )
    for ax, (key, label, thr, positive) in zip(axes, specs):
        values = {name: np.asarray(getattr(b, key), float) for name, b in batches.items()}
        values = {name: v[np.isfinite(v)] for name, v in values.items()}
        pooled = np.concatenate([v for v in values.values()]) if values else np.zeros(0)
        # one set of bins for every law, so the bars compare; heights are fractions of each law's episodes
        if positive:
            lo = max(pooled.min(), 1e-3) if pooled.size else 1e-3
            hi = max(pooled.max(), 10 * lo) if pooled.size else 1.0
            bins = np.logspace(np.log10(lo), np.log10(hi), 40)
            ax.set_xscale("log")
        else:
            bins = np.linspace(pooled.min(), pooled.max(), 40) if pooled.size > 1 else 10
        for name, v in values.items():
            if v.size:
                ax.hist(np.clip(v, bins[0], bins[-1]) if positive else v, bins=bins, alpha=0.5,
                        weights=np.full(v.size, 1.0 / v.size), label=f"{name} ({v.size})", histtype="stepfilled")
        ax.axvline(thr, color="r", ls="--", lw=1)
        if not positive:
            ax.axvline(-thr, color="r", ls="--", lw=1)
        ax.set(xlabel=label, ylabel="fraction of episodes")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    return save_figure(fig, path)
