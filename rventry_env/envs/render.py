"""rgb_array rendering: altitude and speed against time, and the ground track to the target."""

from __future__ import annotations

import math

import numpy as np


class Track:
    """The flown history of one vehicle, appended once per control step."""

    __slots__ = ("t", "h", "v", "lat", "lon")

    def __init__(self):
        self.t, self.h, self.v, self.lat, self.lon = [], [], [], [], []

    def append(self, t, h, v, lat, lon):
        self.t.append(float(t))
        self.h.append(float(h))
        self.v.append(float(v))
        self.lat.append(float(lat))
        self.lon.append(float(lon))


def render_tracks(tracks: list[Track], target_lat: float, target_lon: float, title: str = "RvEntry-v0") -> np.ndarray:
    """An RGB image (H, W, 3) uint8 of the tracks (matplotlib Agg, no screen needed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.2), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax_h, ax_v, ax_g = fig.subplots(1, 3)
    for tr in tracks:
        ax_h.plot(tr.t, np.array(tr.h) / 1e3, lw=1)
        ax_v.plot(tr.t, np.array(tr.v) / 1e3, lw=1)
        ax_g.plot(np.degrees(tr.lon), np.degrees(tr.lat), lw=1)
    ax_h.set(xlabel="t (s)", ylabel="altitude (km)")
    ax_v.set(xlabel="t (s)", ylabel="speed (km/s)")
    ax_g.plot([math.degrees(target_lon)], [math.degrees(target_lat)], "rx", ms=8, label="target")
    ax_g.set(xlabel="longitude (deg)", ylabel="latitude (deg)")
    ax_g.legend(loc="best", fontsize=7)
    for ax in (ax_h, ax_v, ax_g):
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
