"""A generic force correction in one or more channels, for the residual trace.

Each channel's correction is a continuous piecewise-linear function g(s) of altitude or of time
through ``knots`` (hat-function coefficients are the parameters), applied to the model's own
forces at every RK4 stage of the replay (the one :func:`~rventry_env.physics.entry_forces`):

============== ============================================ =============================
channel        added specific force                         size unit
============== ============================================ =============================
drag           -g D/m along the velocity (b1)               fraction of the drag
vertical_lift  g D/m along the lift (normal to v, in the     change of L/D
               vehicle's plane of symmetry, banked)
lateral_lift   the lift rotated out of the plane of          rad of bank
               symmetry by g: L/m ((cos g - 1) along the
               lift + sin g across it)
wind           a horizontal wind g_east, g_north (m/s)       m/s
============== ============================================ =============================

"Vertical" and "lateral" are the vehicle's: in and out of its plane of symmetry, which the bank
rolls about the velocity (at zero bank they are the local vertical plane and the horizontal). A
lift-coefficient change acts along the lift whatever the bank; a bank-angle error or a side force
acts across it. The drag and vertical-lift channels are scaled by the drag acceleration so that a
coefficient change (a C_D that varies with Mach, a lift change) is a smooth g, and so that they
act only where there is air. The lateral channel is a rotation of the lift about the velocity,
the bank angle's own degree of freedom: a bank-angle bias is a constant g, exactly, with the loss
of lift in the plane of symmetry that goes with it (1 - cos g: 0.06 % at 2 degrees, which over a
300 s glide moves the vehicle by hundreds of metres); a side force Y D/m across the lift is
g = asin(Y D / L), which varies with the lift-to-drag ratio. Without lift in the model nothing
can be traced across it. The wind enters the model's wind part, so it changes the air-relative
velocity exactly as a wind would. With ``axis="time"`` the hat functions' values at every RK4
stage time are known inputs of the step; with ``axis="altitude"`` they are functions of the state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rventry_env.physics import HorizontalWind, entry_forces
from rventry_env.physics.atmosphere import piecewise_linear

CHANNELS = ("drag", "vertical_lift", "lateral_lift", "wind")
AXES = ("altitude", "time")
UNITS = {"drag": "fraction of the drag", "vertical_lift": "L/D along the lift",
         "lateral_lift": "rad of bank (the lift rotated out of the plane of symmetry)", "wind": "m/s"}  # fmt: skip


def channel_parameters(channel: str, n_knots: int) -> list[str]:
    """Parameter names of one channel's correction (the wind has an east and a north profile)."""
    if channel == "wind":
        return [f"trace_wind_east_{i}" for i in range(n_knots)] + [f"trace_wind_north_{i}" for i in range(n_knots)]
    return [f"trace_{channel}_{i}" for i in range(n_knots)]


def hat_values(s: np.ndarray, knots) -> np.ndarray:
    """Values ``(len(knots), ...)`` of the piecewise-linear hat functions through ``knots`` at ``s``."""
    eye = np.eye(len(knots))
    return np.stack([np.interp(s, knots, eye[i]) for i in range(len(knots))])


@dataclass
class ChannelForcing:
    """Corrections in ``channels`` over ``axis``, through ``knots``, for one replay.

    :param channels: the channels with parameters.
    :param axis: ``"altitude"`` (knots in m) or ``"time"`` (knots in s).
    :param knots: increasing knot positions.
    :param stage_times: the replay's RK4 stage times ``(3, N)`` (for the time axis).
    :param end_time: the last node's time.
    """

    channels: tuple
    axis: str
    knots: tuple
    stage_times: np.ndarray
    end_time: float

    def __post_init__(self):
        if self.axis not in AXES:
            raise ValueError(f"trace axis must be one of {AXES}, got {self.axis!r}")
        unknown = [c for c in self.channels if c not in CHANNELS]
        if unknown:
            raise ValueError(f"unknown trace channel(s) {unknown}; choose from {CHANNELS}")
        if self.axis == "time":
            n, k = self.stage_times.shape[1], len(self.knots)
            self.stage_inputs = hat_values(self.stage_times, self.knots).transpose(1, 0, 2).reshape(3 * k, n)
            self.end_inputs = hat_values(np.array(self.end_time), self.knots).ravel()
        else:
            self.stage_inputs = np.zeros((0, self.stage_times.shape[1]))
            self.end_inputs = np.zeros(0)

    @property
    def n_inputs(self) -> int:
        return len(self.knots) if self.axis == "time" else 0

    @property
    def names(self) -> list[str]:
        return [n for c in self.channels for n in channel_parameters(c, len(self.knots))]

    def _profile(self, values: dict, prefix: str, s, inputs, ns):
        coeffs = [values[f"{prefix}_{i}"] for i in range(len(self.knots))]
        if self.axis == "altitude":
            return piecewise_linear(s, self.knots, coeffs, ns)
        return sum(c * b for c, b in zip(coeffs, inputs))

    def forces(self, x, model, values: dict, inputs, theta_u, ns):
        """The model (with the wind correction) and its forces with the aerodynamic corrections added."""
        h = x[0] - model.planet.radius

        def g(prefix):
            return self._profile(values, prefix, h, inputs, ns)

        if "wind" in self.channels:
            east, north = g("trace_wind_east"), g("trace_wind_north")
            if model.wind is not None:
                east, north = east + model.wind.east, north + model.wind.north
            model = model.replace(wind=HorizontalWind(east=east, north=north))
        f = entry_forces(x, model, ns)
        d = f.drag_accel
        add = [0.0, 0.0, 0.0]
        if "drag" in self.channels:
            add[0] = add[0] - g("trace_drag") * d
        sigma = x[11]  # the lift direction is cos(sigma) b2 + sin(sigma) b3
        cu, su = ns.cos(sigma), ns.sin(sigma)
        if "vertical_lift" in self.channels:
            gv = g("trace_vertical_lift") * d
            add[1], add[2] = add[1] + gv * cu, add[2] + gv * su
        if "lateral_lift" in self.channels:
            # the lift rotated about the velocity by gl: (cos gl - 1) along the lift, sin gl across it
            gl = g("trace_lateral_lift")
            along, across = (ns.cos(gl) - 1.0) * f.lift_accel, ns.sin(gl) * f.lift_accel
            add[1], add[2] = add[1] + along * cu - across * su, add[2] + along * su + across * cu
        accel = tuple(f.accel_b[i] + add[i] for i in range(3))
        aero = tuple(f.aero_b[i] + add[i] for i in range(3))
        return model, f._replace(accel_b=accel, aero_b=aero)


__all__ = ["CHANNELS", "AXES", "UNITS", "ChannelForcing", "channel_parameters", "hat_values"]
