"""Plots of an identification (PNG, matplotlib's Agg backend): residuals, ranking, density."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from rventry_env.util.files import save_figure


def with_gap_breaks(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The finite samples of a series, with a NaN inserted wherever the line must not be drawn.

    A line is broken across missing values and across time steps longer than twice the
    median step (a data gap), so no segment joins samples the record does not connect.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    ok = np.isfinite(y)
    tt, yy = t[ok], y[ok]
    if tt.size < 2:
        return tt, yy
    idx = np.flatnonzero(ok)
    dt = np.diff(tt)
    med = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    brk = (np.diff(idx) > 1) | (dt > 2.0 * med)
    pos = np.flatnonzero(brk) + 1
    return np.insert(tt, pos, np.nan), np.insert(yy, pos, np.nan)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_residuals(ident, path: Path) -> Path:
    """Residual against time, before (current model) and after (identified model).

    Full-ECEF records: the norms of the position and velocity errors on a log
    scale, both fits on one axis. Reduced records: signed altitude and speed
    residuals, before and after side by side (their sizes differ by orders).
    """
    plt = _pyplot()
    t = ident.replay.t_obs
    rep = ident.report
    kind = rep["record"]["kind"]
    label_after = "after: " + (" + ".join(rep["effects"]) or "none")
    fits = ((ident.baseline, "before: current model", "C3"), (ident.final, label_after, "C0"))
    key = "position_rms_m" if kind == "ecef" else "altitude_rms_m"
    title = f"replayed - measured: rms {rep['before'][key]:.4g} m before, {rep['after'][key]:.4g} m after"
    if kind == "ecef":
        fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for fit, label, color in fits:
            e = fit.residual
            for ax, y in zip(axes, (np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1))):
                ax.plot(*with_gap_breaks(t, y), "-", color=color, label=label, lw=1)
        axes[0].set_ylabel("position error |dr| (m)")
        axes[1].set_ylabel("velocity error |dv| (m/s)")
        for ax in axes:
            ax.set_yscale("log")
        axes[1].set_xlabel("t (s)")
        axes[0].legend(loc="best", fontsize=8)
        axes[0].set_title(title, fontsize=10)
    else:
        fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
        for col, (fit, label, color) in enumerate(fits):
            for row, unit in enumerate(("altitude residual (m)", "speed residual (m/s)")):
                ax = axes[row, col]
                ax.plot(*with_gap_breaks(t, fit.residual[:, row]), ".-", color=color, lw=1, ms=3)
                ax.axhline(0.0, color="k", lw=0.5)
                ax.set_ylabel(unit)
            axes[0, col].set_title(label, fontsize=10)
            axes[1, col].set_xlabel("t (s)")
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


def plot_ranking(ident, path: Path) -> Path:
    """BIC improvement of every candidate over the current model (step 1), with the threshold."""
    plt = _pyplot()
    step = ident.report["steps"][0]
    rows = step["tried"]
    names = [r["effect"] + ("" if r["credible"] else " (not credible)") for r in rows][::-1]
    imp = np.array([r["improvement_over_current"] for r in rows][::-1], float)
    imp = np.where(np.isfinite(imp), imp, 0.0)
    fig, ax = plt.subplots(figsize=(7, 0.8 + 0.35 * len(rows)))
    colors = ["C2" if r["effect"] == step["accepted"] else ("C7" if r["credible"] else "C3")
              for r in rows][::-1]  # fmt: skip
    # symmetric log: improvements span from a few units to tens of thousands
    ax.barh(names, np.sign(imp) * np.log10(1 + np.abs(imp)), color=colors)
    thr = ident.report["bic_threshold"]
    ax.axvline(np.log10(1 + thr), color="k", ls="--", lw=1, label=f"threshold {thr:g}")
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("BIC improvement over the current model, sign(x) log10(1 + |x|)")
    # on lines short enough for the figure's width (a long effect name wraps, never runs off the edge)
    title = textwrap.wrap(f"candidates, step 1 (identified: {' + '.join(ident.report['effects']) or 'none'}); effective samples "
                          f"{step['effective_samples']:.0f}", 75) + [
        "green: accepted, grey: credible, red: on a bound or implausible"]  # fmt: skip
    fig.suptitle("\n".join(title), fontsize=9)  # centred on the figure, not on the axes beside the labels
    ax.legend(fontsize=8, loc="lower right")
    return save_figure(fig, path)


def plot_density(ident, path: Path) -> Path | None:
    """The record's density against the current model atmosphere, with the corrections (if measured)."""
    dc = ident.report.get("density_check")
    if not dc:
        return None
    from rventry_env.core.backend import NUMPY
    from rventry_env.physics.atmosphere import piecewise_linear

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 5))
    h = np.array(dc["altitude_m"])
    ax.plot(dc["current"]["log_ratio"], h / 1e3, "o", ms=4, label="record / current model")
    hh = np.linspace(h.min(), h.max(), 200)
    mc = dc.get("measured_correction")
    if mc:
        ax.plot(piecewise_linear(hh, mc["knots_m"], mc["log_factors"], NUMPY), hh / 1e3, "-", color="C1",
                label="correction fitted to the record's density")  # fmt: skip
    knots = ident.report.get("density_knots_m")
    if knots:
        lf = [v for k, v in ident.report["parameters"].items() if k.startswith("dlnrho_")]
        ax.plot(piecewise_linear(hh, knots, lf, NUMPY), hh / 1e3, "--", color="C2",
                label="density_profile identified from the trajectory")  # fmt: skip
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("ln(rho_record / rho_model)")
    ax.set_ylabel("altitude (km)")
    ax.legend(fontsize=8)
    ax.set_title("flight-derived density vs the model atmosphere", fontsize=10)
    return save_figure(fig, path)


def plot_trace(ident, path: Path) -> Path:
    """The residual trace: each attributed channel's correction over its axis, the band shaded,
    and the residual before and after the trace. Without an attribution, the leading correction
    is drawn, titled as not significant."""
    plt = _pyplot()
    rep = ident.report
    attribution, note, after_label = rep["attribution"], "", "after the trace"
    leading = (rep.get("trace") or {}).get("leading")
    if not attribution and leading:  # drawn as what it is: the leading correction, not an attribution
        attribution = leading["attribution"]
        note = (f"leading correction, NOT significant (BIC gain {leading['bic_gain']:.1f} <= threshold "
                f"{rep['bic_threshold']:g})\n")  # fmt: skip
        after_label = "after the leading correction (not significant)"
    fig, axes = plt.subplots(len(attribution) + 1, 1, figsize=(8, 2.8 * (len(attribution) + 1)))
    for ax, a in zip(axes, attribution):
        scale = 1e-3 if a["axis"] == "altitude" else 1.0
        unit = "km" if a["axis"] == "altitude" else "s"
        s = np.linspace(a["knots"][0], a["knots"][-1], 300)
        for label, coef in a["coefficients"].items():
            g = np.interp(s, a["knots"], coef)
            ax.plot(s * scale, g, label=f"{a['channel']} {label}" if label != "value" else a["channel"])
            ax.plot(np.asarray(a["knots"]) * scale, coef, "o", ms=3, color=ax.lines[-1].get_color())
        ax.axvspan(a["band"][0] * scale, a["band"][1] * scale, color="C1", alpha=0.15, label="band")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(f"{a['axis']} ({unit})")
        ax.set_ylabel(a["size_unit"])
        ax.legend(fontsize=8)
        m = a.get("mach_in_band")
        ax.set_title(f"{note}{a['channel']} over {a['axis']}: peak {a['size']:+.3g} +/- "
                     f"{a['coefficient_stderr_max']:.2g} {a['size_unit']}"
                     + (f", Mach {m[0]:.1f}-{m[1]:.1f} in the band" if m else ""), fontsize=10)  # fmt: skip
    ax = axes[-1]
    t = ident.replay.t_obs
    trace = ident.extra.get("trace") or {}
    kind = rep["record"]["kind"]
    for resid, label, color in ((ident.final.residual, "after identification", "C3"),
                                (trace.get("residual_after_trace"), after_label, "C0")):  # fmt: skip
        if resid is None:
            continue
        e = np.linalg.norm(resid[:, :3], axis=1) if kind == "ecef" else resid[:, 0]
        ax.plot(*with_gap_breaks(t, e), lw=0.7, color=color, label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("position error (m)" if kind == "ecef" else "altitude error (m)")
    ax.legend(fontsize=8)
    ax.set_title("replayed - measured", fontsize=10)
    return save_figure(fig, path)


def write_plots(ident, folder: str | Path) -> list[Path]:
    """Write every plot of an identification into ``folder`` (each file whole or not at all; inside an
    :func:`~rventry_env.util.files.output_set`, with the set's other files).

    :return: the destinations.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"--plots {folder}: exists and is not a folder")
    folder.mkdir(parents=True, exist_ok=True)
    plots = [("residuals.png", plot_residuals), ("ranking.png", plot_ranking)]
    if ident.report.get("density_check"):
        plots.append(("density.png", plot_density))
    if ident.report.get("attribution") or (ident.report.get("trace") or {}).get("leading"):
        plots.append(("trace.png", plot_trace))
    out = []
    for name, plot in plots:
        dest = folder / name
        plot(ident, dest)
        out.append(dest)
    return out


__all__ = ["plot_density", "plot_ranking", "plot_residuals", "plot_trace", "write_plots"]
