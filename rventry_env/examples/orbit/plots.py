"""The two panels of the paper's Fig. ``fig:Ex1-res`` as PNG files."""

from __future__ import annotations

from pathlib import Path

from rventry_env.examples.orbit.numerics import FORMS, CircularOrbit, OrbitRun
from rventry_env.util.files import save_figure


def plot_results(runs_1000: dict[str, OrbitRun], rows: list[dict], orbit: CircularOrbit, out_dir: str | Path) -> list[Path]:
    """Write the two panels of Fig. ``fig:Ex1-res`` as PNG files; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    labels = {"rv_euler": "rv-Euler", "spherical": "spherical"}
    paths = []

    fig, ax = plt.subplots(figsize=(6, 4))
    for form, run in runs_1000.items():
        ax.semilogy(run.t[1:], run.error[1:] / 1e3, label=labels[form])  # e_r(0) = 0
    for frac, name in ((0.25, "near South Pole"), (0.75, "near North Pole")):
        ax.axvline(frac * orbit.period, color="0.6", ls=":", lw=1)
        ax.text(frac * orbit.period, ax.get_ylim()[1], name, ha="center", va="bottom", fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("e_r (km)")
    ax.set_title(f"Position error, N = {next(iter(runs_1000.values())).n}", pad=14)
    ax.legend()
    paths.append(save_figure(fig, out_dir / "ex1_error_vs_time.png", dpi=120))

    fig, ax = plt.subplots(figsize=(6, 4))
    n = [row["n"] for row in rows]
    for form in FORMS:
        ax.loglog(n, [row[f"{form}_km"] for row in rows], "o-", ms=3, label=labels[form])
    ax.set_xlabel("N (steps per period)")
    ax.set_ylabel("e_r,max (km)")
    ax.set_title("Maximum position error over one period")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    paths.append(save_figure(fig, out_dir / "ex1_max_error_vs_n.png", dpi=120))
    return paths


__all__ = ["plot_results"]
