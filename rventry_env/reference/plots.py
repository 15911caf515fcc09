"""The panels of the paper's Fig. ``fig:Ex2-sol-1`` from a reference (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.util.files import save_figure

PANELS = ("altitude", "speed", "c_ae_euler_parameters", "c_ba_euler_parameters", "alpha", "sigma")


def plot_reference(ref, out_dir: str | Path, n: int = 4000) -> list[Path]:
    """Write one PNG per panel (altitude, speed, C_AE and C_BA Euler parameters, alpha, sigma).

    Curves are the collocation polynomials on a fine grid; dots mark the nodes.

    :param ref: a :class:`~rventry_env.reference.data_file.Reference`.
    :param out_dir: directory for the PNG files (created).
    :param n: points of the fine grid.
    :return: the written paths, in :data:`PANELS` order.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    t = np.linspace(ref.t0, ref.tf, n)
    x = ref.state(t)
    re = float(ref.summary().get("constants", {}).get("model", {}).get("planet", {}).get("radius", 6378137.0))
    specs = [
        ("altitude", "Altitude h (km)", [((x[:, IDX.r] - re) / 1e3, (ref.x[:, IDX.r] - re) / 1e3, "h")]),
        ("speed", "Earth-relative speed v (km/s)", [(x[:, IDX.v] / 1e3, ref.x[:, IDX.v] / 1e3, "v")]),
        ("c_ae_euler_parameters", "C_AE Euler parameters",
         [(x[:, i], ref.x[:, i], name) for i, name in zip(range(1, 5), ("e_A1", "e_A2", "e_A3", "eta_A"))]),
        ("c_ba_euler_parameters", "C_BA Euler parameters",
         [(x[:, i], ref.x[:, i], name) for i, name in zip(range(6, 10), ("e_B1", "e_B2", "e_B3", "eta_B"))]),
        ("alpha", "Angle of attack alpha (deg)", [(np.degrees(x[:, IDX.alpha]), np.degrees(ref.x[:, IDX.alpha]), "alpha")]),
        ("sigma", "Bank angle sigma (deg, paper's definition)",
         [(np.degrees(x[:, IDX.sigma]), np.degrees(ref.x[:, IDX.sigma]), "sigma")]),
    ]  # fmt: skip
    paths = []
    for name, ylabel, curves in specs:
        fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
        for fine, nodes, label in curves:
            (line,) = ax.plot(t, fine, lw=1.2, label=label)
            ax.plot(ref.t, nodes, ".", ms=2.5, color=line.get_color())
        ax.set_xlabel("time t (s)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        if len(curves) > 1:
            ax.legend(loc="best", fontsize=8)
        paths.append(save_figure(fig, out / f"{name}.png", dpi=120))
    return paths


__all__ = ["PANELS", "plot_reference"]
