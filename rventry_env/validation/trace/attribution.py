"""Trace what the identified model leaves unexplained to a force channel, a band and a size.

When the final residual is not noise, the effect the record needs is outside the candidate set.
The trace asks a weaker question the record can still answer: *which force, over which part of
the flight, and how large*. Each channel of :mod:`~rventry_env.validation.trace.forcing` (drag,
vertical lift, lateral lift, horizontal wind) gets a piecewise-linear correction over altitude
and, separately, over time. The replay's exact Jacobian with respect to all channels'
coefficients, the entry state and the identified effects' parameters is taken once at the
identified fit, at the finest knot count the record resolves (one replay with sensitivities);
the knot counts are nested, so every coarser profile is one of the finer ones and its Jacobian is
a linear map of that one, exactly. Every channel and every pair of channels at every knot count
is then a Gauss-Newton step on its columns, solved from one QR factorisation of the Jacobian per
count (the size of the parameters, not of the record). The knot count of each channel is chosen by BIC
(counted on the effective sample size, like the candidates), and the best single channel or pair
is kept only if it beats the identified model by the BIC threshold. It is then refined by full
Gauss-Newton iterations (a fresh Jacobian each), so the size and band are those of a converged fit.

The result names the channel(s), the axis, the *band* (where the correction is at least half its
peak), the *size* (its peak, signed, in the channel's unit), the Mach numbers flown in the band,
and the rivals within the threshold (what the record cannot tell apart from it). The named
physical effects follow from the channel and where it acts (:func:`points_to`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from rventry_env.core.backend import NUMPY
from rventry_env.validation.replay.sensitivity import SensitivityReplay
from rventry_env.validation.search.effects import WIND_MAX_MPS, build_model
from rventry_env.validation.search.statistics import bic, bic_effective, effective_size, whiteness
from rventry_env.validation.trace.forcing import CHANNELS, UNITS, ChannelForcing, channel_parameters, hat_values

# nested: (k - 1) divides 12, so every profile is one of the 13-knot profiles, and one replay with
# sensitivities at the finest count the record resolves gives the Jacobian of every coarser count
KNOT_COUNTS = (2, 3, 4, 7, 13)
MIN_ALTITUDE_SPACING = 1e3  # m between knots of an altitude profile
MIN_TIME_SPACING = 10.0  # s between knots of a time profile
VALUES_PER_PARAMETER = 8  # a fit needs at least this many measured values per parameter
REFINE_NFEV = 40  # replays with sensitivities per refined correction
# a refinement stops when a step lowers the cost by less than this fraction: on a record of n values the
# cost is about n, so 1e-6 is a change of n/1e6 in chi-square, far below the BIC threshold it is judged by
REFINE_FTOL = 1e-6
REFINE_BUDGET = 6  # refinements before the search stops (a pair's members count; the last pair may add its two)
AERO_MAX = 1.0  # an aerodynamic correction beyond 100 % of the drag is not a correction
BAND_FRACTION = 0.5  # the band: where the correction is at least this fraction of its peak
# the least time the record must spend in a correction's band: the trace's resolution in time. A force
# acting for less is an impulse: over the record's first seconds the fit cannot tell it from the entry state
# (which the record bounds to its noise), over its last seconds it moves almost no observation
MIN_BAND_TIME = MIN_TIME_SPACING


def _span(replay, axis: str) -> tuple[float, float]:
    if axis == "time":
        return float(replay.t0), float(replay.t_obs[-1])
    h = replay.record.altitude()[replay.rows]
    h = h[np.isfinite(h)]
    return float(np.min(h)), float(np.max(h))


def knot_counts(replay, axis: str, n_values: int) -> list[int]:
    """Knot counts the record resolves on an axis: not closer than the minimum spacing, enough values.

    The largest fit is a pair with the wind (three profiles of ``k`` coefficients) with the
    entry state: it needs :data:`VALUES_PER_PARAMETER` measured values per parameter.
    """
    lo, hi = _span(replay, axis)
    spacing = MIN_TIME_SPACING if axis == "time" else MIN_ALTITUDE_SPACING
    most = (n_values // VALUES_PER_PARAMETER - replay.init.size) // 3
    return [k for k in KNOT_COUNTS if k == 2 or ((hi - lo) / (k - 1) >= spacing and k <= most)]


def _knots(replay, axis: str, n: int) -> tuple:
    lo, hi = _span(replay, axis)
    if hi - lo < 1e-6:
        lo, hi = lo - 1.0, hi + 1.0
    return tuple(float(k) for k in np.linspace(lo, hi, n))


def _stage_times(replay) -> np.ndarray:
    g = replay.grid.nodes
    h = np.diff(g)
    return np.stack([g[:-1], g[:-1] + 0.5 * h, g[1:]])


class _Linearized:
    """One replay with sensitivities at the identified fit, all channels' corrections at zero."""

    def __init__(self, ctx, final, axis: str, n_knots: int, channels=CHANNELS, engines: dict | None = None,
                 residual: np.ndarray | None = None, finer: "_Linearized | None" = None):  # fmt: skip
        replay, setup = ctx.replay, ctx.setup
        self.replays = ctx.replays
        self.axis, self.knots = axis, _knots(replay, axis, n_knots)
        self.n0 = final.extra["n_initial"]
        self.effect_names = tuple(final.names[self.n0:])
        forcing = ChannelForcing(tuple(channels), axis, self.knots, _stage_times(replay), float(replay.grid.nodes[-1]))
        self.names = self.effect_names + tuple(forcing.names)
        self.channels = tuple(channels)
        self.sigma = ctx.sigma
        self.mask = np.isfinite(replay.y)
        self.y_obs = replay.y
        self.group_of = np.broadcast_to(ctx.groups, replay.y.shape)[self.mask]
        self.theta0 = np.concatenate([final.values, np.zeros(len(forcing.names))])
        self._qr = None
        if finer is not None:  # every profile on these knots is one on the finer knots: no replay needed
            self.engine = None
            self.r, self.jac = finer.r, finer.jac @ finer.embedding(self)
            return
        key = ("trace", final.structure.key(), self.effect_names, axis, self.knots, tuple(channels))
        engines = {} if engines is None else engines
        if key not in engines:
            st = final.structure
            engines[key] = SensitivityReplay(replay, lambda v: build_model(setup, st, v), self.names, forcing)
        self.engine = engines[key]
        if residual is None:  # the Jacobian at the identified fit (all channels: never asked for again, not kept)
            self.r, self.jac = self.evaluate(self.theta0, keep=False)
            ctx.nfev += 1
        else:  # the residual there is known (the corrections are zero): no replay needed
            self.r, self.jac = residual, None

    def serves(self, n_knots: int) -> bool:
        """Whether every profile through ``n_knots`` even knots is one through these (nested knots)."""
        return self.jac is not None and self.channels == CHANNELS and (len(self.knots) - 1) % (n_knots - 1) == 0

    def embedding(self, coarse: "_Linearized") -> np.ndarray:
        """The matrix taking ``coarse``'s parameters to these: identity on the entry state and the
        effects, and on every profile the finer hat coefficients of the coarser profile (its
        values at the finer knots, exact because the coarser knots are among the finer)."""
        t = hat_values(np.asarray(self.knots), coarse.knots).T  # (fine knots, coarse knots)
        n_base = self.n0 + len(self.effect_names)
        blocks = [np.eye(n_base)] + [t] * ((self.jac.shape[1] - n_base) // len(self.knots))
        from scipy.linalg import block_diag

        return block_diag(*blocks)

    def evaluate(self, theta: np.ndarray, keep: bool = True):
        """The normalized residual and its Jacobian at ``theta``; with ``keep``, through the context's
        kept replays (the covariance is taken at the point a refinement accepted last)."""
        with np.errstate(all="ignore"):
            if keep:
                y, j = self.replays.evaluate(self.engine, theta[: self.n0], theta[self.n0:])
            else:
                y, j = self.engine.evaluate(theta[: self.n0], theta[self.n0:])
        r = ((y - self.y_obs) / self.sigma[None, :])[self.mask]
        jac = (j / self.sigma[None, :, None])[self.mask]
        return r, jac

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """:meth:`evaluate`'s residual alone (the same to the last bit), from a replay without sensitivities."""
        with np.errstate(all="ignore"):
            y = self.replays.predict(self.engine, theta[: self.n0], theta[self.n0:])
        return ((y - self.y_obs) / self.sigma[None, :])[self.mask]

    def columns(self, channels) -> list[int]:
        """The entry state, the identified effects, and the channels' coefficients."""
        base = list(range(self.n0 + len(self.effect_names)))
        names = {n for c in channels for n in channel_parameters(c, len(self.knots))}
        return base + [i for i, n in enumerate(self.names, start=self.n0) if n in names]

    def screen(self, cols):
        """:meth:`step` from the screening Jacobian, for any subset of its columns, without refactoring it.

        The scaled Jacobian is factored once, J D = Q R; every subset S of its columns lies in the
        span of Q, so min |r + J_S s| is min |Q^T r + R_S s| (a problem of the size of the
        parameters, not of the record) plus the constant part of r outside that span. The step
        and the new residual are those of the least-squares fit on the subset's own columns.
        """
        if self._qr is None:
            scale = np.linalg.norm(self.jac, axis=0)
            scale[scale == 0] = 1.0
            from scipy.linalg import qr

            # R of [J D, r] holds R and Q^T r: Q itself (the size of the record) is never formed
            (rr,) = qr(np.column_stack([self.jac / scale, self.r]), mode="r", overwrite_a=True, check_finite=False)
            n = len(scale)
            self._qr = (scale, rr[:n, :n], rr[:n, n])
        scale, rr, qtr = self._qr
        s, *_ = np.linalg.lstsq(rr[:, cols], -qtr, rcond=np.finfo(float).eps * max(self.jac.shape))  # lstsq's own cutoff on J_S
        step = s / scale[cols]
        full = np.zeros(self.jac.shape[1])
        full[cols] = step
        return step, self.r + self.jac @ full

    def release(self, keep_jacobian: bool = False) -> None:
        """Drop the screening factors and, unless kept for coarser counts, the Jacobian (the
        refinement replays its own channels)."""
        self._qr = None
        if not keep_jacobian:
            self.jac = None

    def step(self, r, jac, cols):
        a = jac[:, cols]
        scale = np.linalg.norm(a, axis=0)
        scale[scale == 0] = 1.0
        step, *_ = np.linalg.lstsq(a / scale, -r, rcond=None)
        step = step / scale
        return step, r + a @ step


def _rss_by_group(r_norm: np.ndarray, sigma_entries: np.ndarray, group_of: np.ndarray, n_groups: int):
    e = r_norm * sigma_entries
    return [float(np.sum(e[group_of == g] ** 2)) for g in range(n_groups)], [
        int(np.count_nonzero(group_of == g)) for g in range(n_groups)
    ]


def _residual_matrix(lin: _Linearized, r_norm: np.ndarray) -> np.ndarray:
    out = np.full(lin.y_obs.shape, np.nan)
    out[lin.mask] = r_norm
    return out


def _profile_grid(lo: float, hi: float, n: int = 201) -> np.ndarray:
    return np.linspace(lo, hi, n)


def _band(s: np.ndarray, g: np.ndarray) -> tuple[float, float, float]:
    """Peak (signed) of a profile and the contiguous band around it where |g| >= BAND_FRACTION |peak|."""
    i = int(np.argmax(np.abs(g)))
    peak = float(g[i])
    keep = np.abs(g) >= BAND_FRACTION * abs(peak)
    a = i
    while a > 0 and keep[a - 1]:
        a -= 1
    b = i
    while b < len(g) - 1 and keep[b + 1]:
        b += 1
    return peak, float(s[a]), float(s[b])


def _channel_profile(lin: "_Linearized", theta: np.ndarray, channel: str, s: np.ndarray) -> np.ndarray:
    """One channel's correction on ``s`` (the wind's magnitude)."""
    k = len(lin.knots)
    coef = theta[[lin.n0 + lin.names.index(n) for n in channel_parameters(channel, k)]]
    if channel == "wind":
        return np.hypot(np.interp(s, lin.knots, coef[:k]), np.interp(s, lin.knots, coef[k:]))
    return np.interp(s, lin.knots, coef)


def band_time(replay, axis: str, lo: float, hi: float) -> float:
    """The time (s) the record spends in a band: its samples there times the record's median sampling interval."""
    s = replay.t_obs if axis == "time" else replay.record.altitude()[replay.rows]
    inside = np.count_nonzero(np.isfinite(s) & (s >= lo - 1e-9) & (s <= hi + 1e-9))
    dt = float(np.median(np.diff(replay.t_obs))) if len(replay.t_obs) > 1 else 0.0
    return inside * dt


def _unsupported(ctx, lin: "_Linearized", theta: np.ndarray, channels) -> list[str]:
    """Channels whose band the record flies through for less than :data:`MIN_BAND_TIME`.

    Such a correction acts as an impulse: at the record's start it stands in for an entry state
    beyond the bound the first samples give it (a 200 m/s wind over the top 0.5 km of a glide,
    the first 8 s), at its end it moves almost no observation. Neither is a finding about a force.
    """
    s = _profile_grid(lin.knots[0], lin.knots[-1])
    out = []
    for c in channels:
        _, a, b = _band(s, _channel_profile(lin, theta, c, s))
        if band_time(ctx.replay, lin.axis, a, b) < MIN_BAND_TIME:
            out.append(c)
    return out


def _mach_in(ctx, axis: str, lo: float, hi: float) -> tuple[list | None, dict | None]:
    """Mach numbers flown within a band, and whether the band is a Mach range (below or above a Mach number).

    A band is "below Mach M" when every sample outside it flies faster than every sample in it
    (within 0.05 Mach): then the record cannot tell a correction tied to the band from one tied
    to Mach.
    """
    rec, replay = ctx.replay.record, ctx.replay
    h = rec.altitude()[replay.rows]
    v = rec.speed()[replay.rows]
    s = replay.t_obs if axis == "time" else h
    ok = np.isfinite(h) & np.isfinite(v)
    inside = ok & (s >= lo - 1e-9) & (s <= hi + 1e-9)
    if not np.any(inside):
        return None, None
    m = np.full(len(h), np.nan)
    m[ok] = v[ok] / np.asarray(ctx.setup.model.atmosphere.speed_of_sound(h[ok], NUMPY), float)
    m_in, m_out = m[inside], m[ok & ~inside]
    rng = [float(np.min(m_in)), float(np.max(m_in))]
    bound = None
    if m_out.size and np.min(m_out) >= rng[1] - 0.05:
        bound = {"below": rng[1]}
    elif m_out.size and np.max(m_out) <= rng[0] + 0.05:
        bound = {"above": rng[0]}
    return rng, bound


def _lift_to_drag_in(ctx, model, axis: str, lo: float, hi: float) -> float | None:
    """The median lift-to-drag ratio of ``model`` over the record's samples within a band (None without lift)."""
    rec, replay = ctx.replay.record, ctx.replay
    h = rec.altitude()[replay.rows]
    v = rec.speed()[replay.rows]
    s = replay.t_obs if axis == "time" else h
    ok = np.isfinite(h) & np.isfinite(v) & (s >= lo - 1e-9) & (s <= hi + 1e-9)
    if not np.any(ok):
        return None
    mach = v[ok] / np.asarray(model.atmosphere.speed_of_sound(h[ok], NUMPY), float)
    alpha, _ = replay.controls.many(replay.t_obs[ok])
    cl, cd = model.vehicle.aerodynamics.coefficients(alpha, mach, NUMPY)
    ratio = np.asarray(cl, float) / np.asarray(cd, float)
    return float(np.median(ratio)) if np.any(ratio != 0) else None


def _describe(ctx, lin: _Linearized, theta: np.ndarray, cov: np.ndarray, channels, model=None) -> list[dict]:
    """One attribution entry per channel: band, size, profile, Mach in the band.

    A lateral entry also gives the force across the lift as a fraction of the drag at its peak,
    sin(g) L/D with the model's median L/D in the band (``across_over_drag``): the size a side
    force would have.
    """
    lo, hi = lin.knots[0], lin.knots[-1]
    s = _profile_grid(lo, hi)
    k = len(lin.knots)
    out = []
    for c in channels:
        names = channel_parameters(c, k)
        idx = [lin.n0 + lin.names.index(n) for n in names]
        coef = theta[idx]
        sub = cov[np.ix_(idx, idx)] if cov is not None else None
        parts = [("", coef)] if c != "wind" else [("east", coef[:k]), ("north", coef[k:])]
        if c == "wind":
            g_e, g_n = np.interp(s, lin.knots, coef[:k]), np.interp(s, lin.knots, coef[k:])
            g = np.hypot(g_e, g_n)
        else:
            g = np.interp(s, lin.knots, coef)
        peak, a, b = _band(s, g)
        stderr = None
        if sub is not None:
            se = np.sqrt(np.clip(np.diag(sub), 0, None))
            stderr = float(np.max(se))
        entry = {
            "channel": c,
            "axis": lin.axis,
            "band": [a, b],
            "band_unit": "m" if lin.axis == "altitude" else "s",
            "size": peak,
            "size_unit": UNITS[c],
            "knots": list(lin.knots),
            "coefficients": {label or "value": [float(x) for x in v] for label, v in parts},
            "coefficient_stderr_max": stderr,
            "mach_in_band": None,
            "mach_range_of_band": None,
            "whole_span": [float(lo), float(hi)],
        }
        entry["mach_in_band"], entry["mach_range_of_band"] = _mach_in(ctx, lin.axis, a, b)
        if c == "lateral_lift":
            entry["bank_offset_deg"] = math.degrees(peak)
            ld = _lift_to_drag_in(ctx, model, lin.axis, a, b) if model is not None else None
            entry["across_over_drag"] = None if ld is None else math.sin(peak) * ld
        if c == "wind":
            i = int(np.argmax(g))
            entry["direction"] = {"east_mps": float(np.interp(s[i], lin.knots, coef[:k])),
                                  "north_mps": float(np.interp(s[i], lin.knots, coef[k:]))}  # fmt: skip
            signs = np.sign(np.interp(s, lin.knots, coef[:k])), np.sign(np.interp(s, lin.knots, coef[k:]))
            entry["reverses"] = bool(any(np.any(x > 0) and np.any(x < 0) for x in signs))
        out.append(entry)
    return out


def _fmt_band(entry: dict) -> str:
    a, b = entry["band"]
    if entry["axis"] == "altitude":
        return f"{a / 1e3:.1f}-{b / 1e3:.1f} km altitude"
    return f"t = {a:.0f}-{b:.0f} s"


def _mach_text(entry: dict) -> str:
    m = entry.get("mach_in_band")
    return f" (Mach {m[0]:.1f}-{m[1]:.1f})" if m else ""


def _drag_and_lift_together(by: dict, alpha_dependent: bool) -> tuple[bool, list[str]]:
    """Whether drag and vertical lift are traced over overlapping bands, and what that points to:
    a mass change, the air density (or a trim offset) when they move the same way, a trim change
    when they move apart.
    """
    together = False
    out = []
    if "drag" in by and "vertical_lift" in by:
        d, v = by["drag"], by["vertical_lift"]
        together = d["band"][0] <= v["band"][1] and v["band"][0] <= d["band"][1]  # the bands overlap
    if together:
        if d["size"] * v["size"] > 0 and d["axis"] == "time":
            out.append(f"a mass change over {_fmt_band(d)}{_mach_text(d)}: drag and lift accelerations change "
                       f"together and with time (x {1 + d['size']:.3f}, a mass x {1 / (1 + d['size']):.3f}: "
                       "ablation, a jettison)")  # fmt: skip
        if d["size"] * v["size"] > 0:
            out.append(f"the air density over {_fmt_band(d)}{_mach_text(d)}: drag and lift change together "
                       f"(drag x {1 + d['size']:.3f}), as a density the atmosphere model lacks would make them"
                       + (", or an angle-of-attack (trim) offset, which moves this vehicle's C_D and C_L the same way"
                          if alpha_dependent else ""))  # fmt: skip
        else:
            out.append(f"a trim (angle-of-attack) change over {_fmt_band(d)}{_mach_text(d)}: drag and lift move in "
                       "opposite directions")  # fmt: skip
    return together, out


def _drag_effect(e: dict, where: str, mach_words: str, local: bool) -> str:
    """What a drag correction alone points to: C_D varying with Mach, altitude or flight condition, or time."""
    size = f"C_D x {1 + e['size']:.3f} at the peak"
    if mach_words:
        return (f"a drag coefficient that changes {mach_words} ({size}, over {where}): C_D varying with "
                "Mach in a shape the mach_drag candidate cannot take")  # fmt: skip
    if e["axis"] == "altitude" and local:
        return (f"a drag change confined to {where} ({size}) and not to a Mach range: a drag coefficient "
                "varying with Reynolds number (altitude) or with the angle of attack flown there")  # fmt: skip
    if e["axis"] == "altitude":
        return (f"a drag change over the altitudes flown ({size}) that the candidates cannot shape: C_D "
                "varying with flight condition")  # fmt: skip
    return (f"a drag change tied to time over {where} ({size}): a configuration or mass change "
            "(ablation, a jettison) rather than the atmosphere")  # fmt: skip


def _lift_effect(e: dict, where: str, mach_words: str, local: bool) -> str:
    """What a vertical-lift correction alone points to: C_L varying with Mach, altitude or angle of attack."""
    size = f"L/D {e['size']:+.3f} along the lift"
    if mach_words:
        return (f"a lift coefficient that changes {mach_words} ({size}, over {where}): C_L varying with "
                "Mach, not the atmosphere (which would move the drag too)")  # fmt: skip
    if local:
        return (f"a lift change confined to {where} ({size}) and not to a Mach range: an aerodynamic "
                "coefficient varying with Reynolds number (altitude) or the angle of attack flown there, "
                "not the atmosphere (which would move the drag too)")  # fmt: skip
    return (f"a lift change over the whole flight ({size}) with a shape the constant "
            "lift_coefficient cannot take: C_L varying with Mach or angle of attack")  # fmt: skip


def _lateral_effect(e: dict, where: str) -> str:
    """What a lateral-lift correction points to: a bank bias when steady, a side force when it varies."""
    coef = np.asarray(e["coefficients"]["value"], float)
    se = e.get("coefficient_stderr_max") or 0.0
    steady = float(np.ptp(coef)) <= max(3.0 * se, 0.1 * float(np.max(np.abs(coef))))
    deg = math.degrees(e["size"])
    if steady:
        return (f"a bank-angle bias of {deg:+.2f} deg over {where} (the lift rotated out of the plane of "
                "symmetry by a constant angle): an error in the bank record (a bias, a reference or sign "
                "convention), or a side force (sideslip, an asymmetric shape)")  # fmt: skip
    return (f"a force across the lift over {where} (the lift rotated by up to {deg:+.2f} deg out of the "
            "plane of symmetry, not constant): a side force (sideslip, an asymmetric shape) or an "
            "error in the bank record that varies")  # fmt: skip


def _wind_effect(e: dict, where: str) -> str:
    """What a wind correction points to: a wind (a shear when it reverses) the uniform candidate cannot shape."""
    kind = "that reverses with altitude (a shear)" if e.get("reverses") else "that varies along the flight"
    if e["axis"] == "time":
        kind += " (traced over time: a horizontal force or wind not tied to altitude)"
    return (f"a horizontal wind {kind}, peak {abs(e['size']):.0f} m/s over {where}; the uniform wind "
            "candidate cannot take its shape")  # fmt: skip


def points_to(attribution: list[dict], rivals: list[dict], alpha_dependent: bool = False) -> list[str]:
    """The physical effects a trace points to, in plain words (most specific first).

    :param alpha_dependent: the vehicle's coefficients depend on the angle of attack (a trim offset
        then moves drag and lift together, like the density).
    """
    if not attribution:
        return []
    by = {e["channel"]: e for e in attribution}
    whole = attribution[0]["whole_span"]
    span = whole[1] - whole[0]

    def local(e):
        return (e["band"][1] - e["band"][0]) < 0.8 * span

    together, out = _drag_and_lift_together(by, alpha_dependent)
    for c, e in by.items():
        where = f"{_fmt_band(e)}{_mach_text(e)}"
        mach = e.get("mach_range_of_band") or {}
        if "below" in mach:
            mach_words = f"below Mach {mach['below']:.1f}"
        elif "above" in mach:
            mach_words = f"above Mach {mach['above']:.1f}"
        else:
            mach_words = ""
        if c == "drag" and not together:
            out.append(_drag_effect(e, where, mach_words, local(e)))
        elif c == "vertical_lift" and not together:
            out.append(_lift_effect(e, where, mach_words, local(e)))
        elif c == "lateral_lift":
            out.append(_lateral_effect(e, where))
        elif c == "wind":
            out.append(_wind_effect(e, where))
    axes = {e["axis"] for e in attribution}
    tied_to_mach = any(e.get("mach_range_of_band") for e in attribution)
    if axes == {"time"} and not tied_to_mach and not any(r["axis"] == "altitude" for r in rivals):
        out.append("the correction is tied to time, not to altitude: look for an event or a timing error in the "
                   "record (a control or clock offset) as well")  # fmt: skip
    return out


def _screen_fits(ctx, final, sigma_entries, n_groups: int, say) -> list[dict]:
    """Screen every channel and channel pair over altitude and over time, at every knot count.

    Each is one linear step from the identified fit (`_Linearized.screen`); a coarser knot count
    reuses the Jacobian of a finer one that serves it.

    :return: one entry per (channels, axis, knots) with its step, residual, RSS by group and white BIC.
    """
    n_values = int(np.count_nonzero(np.isfinite(ctx.replay.y)))
    combos = [(c,) for c in CHANNELS] + list(itertools.combinations(CHANNELS, 2))
    fits = []  # (label channels, axis, k, lin, step, r_new, n_params)
    engines = ctx.engines
    for axis in ("altitude", "time"):
        replayed = []  # the screening replays of this axis, finest first
        for k in sorted(knot_counts(ctx.replay, axis, n_values), reverse=True):
            finer = next((f for f in replayed if f.serves(k)), None)
            say(f"trace: {axis}, {k} knots" + (f" (from the {len(finer.knots)}-knot Jacobian)" if finer else ""))
            lin = _Linearized(ctx, final, axis, k, CHANNELS, engines, finer=finer)
            if finer is None:
                replayed.append(lin)
            for combo in combos:
                cols = lin.columns(combo)
                step, r_new = lin.screen(cols)
                rss, nval = _rss_by_group(r_new, sigma_entries, lin.group_of, n_groups)
                fits.append({"channels": combo, "axis": axis, "knots": k, "lin": lin, "cols": cols, "step": step,
                             "r": r_new, "rss": rss, "n": nval, "k_params": len(cols),
                             "bic_white": bic(rss, nval, len(cols))})  # fmt: skip
            lin.release(keep_jacobian=finer is None)
        for lin in replayed:
            lin.release()
    return fits


def _eligible(f: dict, chosen: dict, threshold: float) -> bool:
    """Whether a fit may lead: refined, inside its physical bounds, every band flown long enough to tell
    it from the entry state, and (a pair) better than its members."""
    if not f.get("refined") or f["outside"] or f.get("unsupported"):
        return False
    # a pair must beat each of its members alone (same axis), refined alike, by the threshold too
    return len(f["channels"]) == 1 or all(
        chosen[((c,), f["axis"])].get("refined") and f["bic"] < chosen[((c,), f["axis"])]["bic"] - threshold
        for c in f["channels"])  # fmt: skip


def _refine_ranked(ctx, final, chosen: dict, threshold: float, sigma_entries, n_groups: int, n_eff: float,
                   cost_final: float, say) -> None:
    """Refine the screening's best corrections to convergence, in place (their BIC, residual, bounds).

    The screening is one linear step: a large residual is not linear, so its best are refined to
    convergence, the best of each axis first, then in the screening's order while an unrefined
    correction's screened BIC could still beat the best refined one or tie with it (within the
    threshold: a rival the record cannot tell apart is refined too, so the winner is decided between
    converged fits). A pair is compared with its members refined alike.
    """
    ranked = sorted(chosen.values(), key=lambda f: f["bic"])

    def refine(f) -> int:
        if f.get("refined"):
            return 0
        say(f"trace: refining {' + '.join(f['channels'])} over {f['axis']} ({f['knots']} knots)")
        theta, r, at_bound = _refine(ctx, f, final)
        rss, nval = _rss_by_group(r, sigma_entries, f["lin"].group_of, n_groups)
        f.update(theta=theta, r=r, rss=rss, bic=bic_effective(rss, nval, f["k_params"], n_eff), refined=True,
                 cost_ratio=float(r @ r) / cost_final)  # fmt: skip
        f["outside"] = sorted(set(_outside_bounds(f["lin"], theta, f["channels"])) | set(at_bound))
        f["unsupported"] = _unsupported(ctx, f["lin"], theta, f["channels"])
        return 1

    order = [next(f for f in ranked if f["axis"] == axis) for axis in ("altitude", "time")
             if any(f["axis"] == axis for f in ranked)]  # fmt: skip
    order += [f for f in ranked if f not in order]
    n_refined = 0
    for f in order:
        best_bic = min((g["bic"] for g in ranked if _eligible(g, chosen, threshold)), default=math.inf)
        if n_refined >= 2 and (f["bic_screened"] >= best_bic + threshold or n_refined >= REFINE_BUDGET):
            break
        n_refined += refine(f)
        for c in f["channels"] if len(f["channels"]) == 2 else ():
            n_refined += refine(chosen[((c,), f["axis"])])  # a pair is compared with its members refined alike


def trace_residual(ctx, final, threshold: float, say=lambda msg: None) -> dict:
    """Trace the residual of ``final`` to a force channel (see the module docstring).

    :param ctx: the fit context of the record.
    :param final: the identified fit.
    :param threshold: the BIC margin the trace must beat the identified model by.
    :return: the trace: ``attribution`` (a list of channel, axis, band, size, ...), the rivals,
        the fits tried, what the record would look like with it, and the effects it points to.
    """
    n_groups = int(np.max(ctx.groups)) + 1
    sigma_entries = np.broadcast_to(ctx.sigma, ctx.replay.y.shape)[np.isfinite(ctx.replay.y)]
    fits = _screen_fits(ctx, final, sigma_entries, n_groups, say)
    base_rss, base_n = final.rss_by_group, final.n_by_group
    best_raw = min(fits, key=lambda f: f["bic_white"])
    lag1 = whiteness(_residual_matrix(best_raw["lin"], best_raw["r"]))["lag1_autocorrelation"]
    n_eff = effective_size(sum(base_n), lag1)
    b_final = bic_effective(base_rss, base_n, final.n_params, n_eff)
    for f in fits:
        f["bic"] = bic_effective(f["rss"], f["n"], f["k_params"], n_eff)
    # per channel set and axis, the knot count BIC prefers
    chosen = {}
    for f in fits:
        key = (f["channels"], f["axis"])
        if key not in chosen or f["bic"] < chosen[key]["bic"]:
            chosen[key] = f
    r_final = (final.residual / ctx.sigma[None, :])[np.isfinite(ctx.replay.y)]
    cost_final = max(float(r_final @ r_final), 1e-300)
    for f in chosen.values():
        f["bic_screened"] = f["bic"]
    _refine_ranked(ctx, final, chosen, threshold, sigma_entries, n_groups, n_eff, cost_final, say)
    ranked = sorted(chosen.values(), key=lambda f: f["bic"])
    eligible_fits = [f for f in ranked if _eligible(f, chosen, threshold)]
    table = [{"channels": list(f["channels"]), "axis": f["axis"], "knots": f["knots"], "bic_gain": b_final - f["bic"],
              "screened_bic_gain": b_final - f["bic_screened"], "refined": bool(f.get("refined")),
              "cost_ratio": f.get("cost_ratio"), "refine_replays": f.get("refine_nfev"),
              "outside_bounds": f.get("outside") or [], "bands_too_brief": f.get("unsupported") or []}
             for f in ranked]  # fmt: skip
    out = {
        "method": "piecewise-linear corrections over altitude and over time per force channel, knots by BIC, "
        "fitted with the entry state and the identified effects (exact Jacobian of the replay)",
        "effective_samples": n_eff,
        "bic_threshold": threshold,
        "tried": table,
        "added_to_model": False,
    }
    best = eligible_fits[0] if eligible_fits else None
    if best is None:
        out.update({"attribution": [], "rivals": [], "points_to": [], "leading": None,
                    "statement": "No force channel explains the residual: every leading correction is outside its "
                                 "physical bounds or acts over a band the record flies through for less than "
                                 f"{MIN_BAND_TIME:g} s."})  # fmt: skip
        return out
    # a rival is a reading the record cannot tell from the winner: a fit refused (outside its bounds, a band
    # flown too briefly) is none
    rival_fits = [f for f in ranked if f is not best and f["bic"] - best["bic"] < threshold
                  and not (f.get("refined") and (f["outside"] or f.get("unsupported")))]  # fmt: skip
    rivals = [{"channels": list(f["channels"]), "axis": f["axis"], "knots": f["knots"],
               "bic_behind": f["bic"] - best["bic"]} for f in rival_fits]  # fmt: skip
    out["rival_fits"] = rival_fits  # not in the report
    # what the screening ranked above the result and the refinement budget left unrefined (normally none)
    out["unrefined_above_leading"] = sum(1 for f in ranked if not f.get("refined") and f["bic"] < best["bic"])
    out["fit"] = TraceFit(best, b_final, n_eff, sigma_entries, n_groups)  # for what follows; not in the report
    return describe_trace(ctx, final, out, threshold, rivals)


class TraceFit:
    """The trace's best correction, kept for the phases that follow (not written to the report).

    :param f: the refined correction (channels, axis, knots, its replay, columns, parameters, BIC).
    :param b_final: the BIC of the model it corrects, on the trace's effective sample size.
    :param n_eff: that effective sample size.
    """

    def __init__(self, f: dict, b_final: float, n_eff: float, sigma_entries, n_groups: int):
        self.f, self.b_final, self.n_eff = f, b_final, n_eff
        self.sigma_entries, self.n_groups = sigma_entries, n_groups

    @property
    def gain(self) -> float:
        return self.b_final - self.f["bic"]


def _describe_fit(ctx, f: dict, model) -> tuple[list[dict], np.ndarray]:
    """A refined correction in words and figures (its channels' bands, sizes and standard errors, from
    the Jacobian at its parameters: one replay), and its normalized residual."""
    lin, cols, theta = f["lin"], f["cols"], f["theta"]
    r, jac = lin.evaluate(theta)
    ctx.nfev += 1
    a = jac[:, cols]
    dof = max(len(r) - len(cols), 1)
    cov = np.zeros((len(theta), len(theta)))
    cov[np.ix_(cols, cols)] = np.linalg.pinv(a.T @ a) * float(r @ r) / dof
    return _describe(ctx, lin, theta, cov, f["channels"], model), r


def _bands_text(attribution: list[dict]) -> str:
    return "; ".join(f"{e['channel']} {e['size']:+.3g} +/- {e['coefficient_stderr_max']:.2g} {e['size_unit']} over "
                     f"{_fmt_band(e)}{_mach_text(e)}" for e in attribution)  # fmt: skip


def _describe_rivals(ctx, final, rivals: list, fits: list, alpha_dependent: bool) -> str:
    """Each refined rival's attribution and what it would point to, in place; the words that name the
    rivals (empty without one). A rival is what the record cannot tell apart from the result: naming
    it is part of the result."""
    words = []
    for rv, f in zip(rivals, fits):
        if not f.get("refined") or f.get("outside") or f.get("unsupported"):
            continue
        if "attribution" not in rv:
            rv["attribution"], _ = _describe_fit(ctx, f, final.model)
            rv["points_to"] = points_to(rv["attribution"], [], alpha_dependent)
        said = f"{' + '.join(rv['channels'])} over {rv['axis']} ({rv['bic_behind']:.1f} behind in BIC"
        # the closest rival's reading in full (the others' are in the report's rivals)
        words.append(said + (f": {rv['points_to'][0]})" if not words and rv["points_to"] else ")"))
    return (" The record cannot tell it from " + "; ".join(words) + ".") if words else ""


def describe_trace(ctx, final, out: dict, threshold: float, rivals: list) -> dict:
    """The attribution of ``out["fit"]`` (or its leading correction, when not significant), in words and figures."""
    tf = out["fit"]
    best, n_eff = tf.f, tf.n_eff
    gain = tf.gain
    lin = best["lin"]
    attribution, r = _describe_fit(ctx, best, final.model)
    resid = _residual_matrix(lin, r) * ctx.sigma[None, :]
    from rventry_env.physics import ConstantAerodynamics

    alpha_dependent = not isinstance(ctx.setup.lift_reference, ConstantAerodynamics)
    pts = points_to(attribution, rivals, alpha_dependent)
    from rventry_env.validation.report.diagnostics import error_metrics

    names = " + ".join(best["channels"])
    bands = _bands_text(attribution)
    after = error_metrics(resid, ctx.replay.record.kind)
    out["residual_after_trace"] = resid  # for the plot; not written to the report
    if not gain > threshold:
        # the leading correction is reported as such, not as an attribution
        out.update({"attribution": [], "rivals": [], "points_to": [],
                    "leading": {"attribution": attribution, "bic_gain": gain, "significant": False, "rivals": rivals,
                                "after_leading": after, "would_point_to": pts},
                    "statement": f"No force channel explains the residual significantly: the leading correction, "
                                 f"{names} over {best['axis']} ({bands}), gains {gain:.1f} in BIC on {n_eff:.1f} "
                                 f"effective samples, not more than {threshold:g}. Were it real, it would point to: "
                                 + "; ".join(pts) + "."})  # fmt: skip
        return out
    out.update({
        "attribution": attribution,
        "bic_gain": gain,
        "rivals": rivals,
        "after_trace": after,
        "points_to": pts,
        "leading": None,
        "statement": f"Traced to {names} over {best['axis']}: {bands}. It points to: " + "; ".join(pts) + "."
        + _describe_rivals(ctx, final, rivals, out.get("rival_fits", []), alpha_dependent),
    })  # fmt: skip
    return out


def refit_without(ctx, trace: dict, reduced, threshold: float) -> "TraceFit":
    """The trace's correction refitted on another identified model (one effect fewer), never worse than its start.

    :param trace: a trace whose ``fit`` is the correction to refit.
    :param reduced: the identified fit without the effect.
    :return: the refitted correction, its BIC counted on the trace's effective sample size.
    """
    tf = trace["fit"]
    old = tf.f
    r0 = (reduced.residual / ctx.sigma[None, :])[np.isfinite(ctx.replay.y)]
    screen = _Linearized(ctx, reduced, old["axis"], old["knots"], old["channels"], ctx.engines, residual=r0)
    cols = screen.columns(old["channels"])
    f = {"channels": old["channels"], "axis": old["axis"], "knots": old["knots"], "lin": screen, "cols": cols,
         "step": np.zeros(len(cols)), "k_params": len(cols)}  # fmt: skip
    theta, r, at_bound = _refine(ctx, f, reduced)
    rss, nval = _rss_by_group(r, tf.sigma_entries, f["lin"].group_of, tf.n_groups)
    f.update(theta=theta, r=r, rss=rss, bic=bic_effective(rss, nval, f["k_params"], tf.n_eff), refined=True,
             outside=sorted(set(_outside_bounds(f["lin"], theta, f["channels"])) | set(at_bound)),
             unsupported=_unsupported(ctx, f["lin"], theta, f["channels"]))  # fmt: skip
    b_reduced = bic_effective(reduced.rss_by_group, reduced.n_by_group, reduced.n_params, tf.n_eff)
    return TraceFit(f, b_reduced, tf.n_eff, tf.sigma_entries, tf.n_groups)


def _refine(ctx, f, final) -> tuple[np.ndarray, np.ndarray, list]:
    """The screened correction refitted to convergence, never worse than its start.

    The refinement replays only the fit's own channels (fewer sensitivity columns than the
    screening's all-channel replay); ``f["lin"]`` and ``f["cols"]`` become that replay's. It starts
    from the better of the screening's step and the identified model itself (no correction), and a
    bounded trust-region least-squares fit (SciPy's ``trf``, exact Jacobians) only accepts steps
    that lower the cost: the result is never worse than the model it corrects. The entry state
    keeps the bound the identification gave it, the identified effects their physical bounds, and
    the corrections theirs (:data:`AERO_MAX`, :data:`WIND_MAX_MPS`).

    :return: the parameters, the residual there, and the channels that ended on a bound.
    """
    from scipy.optimize import least_squares

    screen = f["lin"]
    screened = dict(zip(screen.names, screen.theta0[screen.n0:]))
    for i, s in zip(f["cols"], f["step"]):
        if i >= screen.n0:
            screened[screen.names[i - screen.n0]] += s
    lin = _Linearized(ctx, final, screen.axis, len(screen.knots), f["channels"], ctx.engines, residual=screen.r)
    cols = lin.columns(f["channels"])
    f["lin"], f["cols"] = lin, cols
    lower, upper = _bounds(ctx, final, lin)
    start = lin.theta0.copy()
    stepped = start.copy()
    stepped[: screen.n0] += f["step"][: screen.n0]  # the entry state's columns come first in both
    for j, name in enumerate(lin.names):
        stepped[lin.n0 + j] = screened[name]
    width = upper - lower
    inner = np.where(np.isfinite(width), 1e-9 * width, 0.0)
    stepped = np.clip(stepped, lower + inner, upper - inner)
    cache = {}  # the last point: its residual, and its Jacobian once asked for (a rejected trial never is)

    def evaluate(theta, jacobian=True):
        key = theta.tobytes()
        if key not in cache:
            ctx.nfev += 1
        if key not in cache or (jacobian and cache[key][1] is None):
            if jacobian:
                r, jac = lin.evaluate(theta)
            else:
                r, jac = lin.residual(theta), None
            bad = ~np.isfinite(r)
            cache.clear()
            cache[key] = (np.where(bad, 1e4, r), None if jac is None else np.where(bad[:, None], 0.0, jac))
        return cache[key]

    r_step, _ = evaluate(stepped, jacobian=False)
    x0 = stepped if float(r_step @ r_step) < float(lin.r @ lin.r) else start
    full = x0.copy()

    def put(x):
        full[cols] = x
        return full

    sol = least_squares(lambda x: evaluate(put(x), jacobian=False)[0], x0[cols],
                        jac=lambda x: evaluate(put(x))[1][:, cols],
                        bounds=(lower[cols], upper[cols]), method="trf", x_scale="jac", max_nfev=REFINE_NFEV,
                        ftol=REFINE_FTOL, xtol=1e-10, gtol=1e-10)  # fmt: skip
    f["refine_nfev"] = int(sol.nfev)
    theta = put(sol.x).copy()
    r, _ = evaluate(theta, jacobian=False)
    if float(r @ r) > float(lin.r @ lin.r):  # cannot happen with a descent method; never report worse than the start
        theta, r = start, lin.r
    on_bound = []
    k = len(lin.knots)
    for c in f["channels"]:
        idx = [lin.n0 + lin.names.index(n) for n in channel_parameters(c, k)]
        lo, hi = lower[idx], upper[idx]
        if np.any(np.minimum(theta[idx] - lo, hi - theta[idx]) < 1e-4 * (hi - lo)):
            on_bound.append(c)
    return theta, r, on_bound


def _bounds(ctx, final, lin) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of a trace fit's parameters: the entry state's and the effects' as identified, the corrections'."""
    from rventry_env.validation.search.effects import structure_parameters

    n0 = lin.n0
    half = np.full(n0, np.inf) if ctx.init_bound is None else np.asarray(ctx.init_bound, float)
    params = structure_parameters(ctx.setup, final.structure)
    lo = [-half, [p.lower for p in params]]
    hi = [half, [p.upper for p in params]]
    for name in lin.names[len(params):]:
        lim = WIND_MAX_MPS if name.startswith("trace_wind") else AERO_MAX
        lo.append([-lim])
        hi.append([lim])
    return np.concatenate(lo), np.concatenate(hi)


def _outside_bounds(lin, theta: np.ndarray, channels) -> list[str]:
    """Channels whose correction leaves its physical range (a coefficient x 0 .. 2, wind 200 m/s)."""
    out = []
    k = len(lin.knots)
    for c in channels:
        idx = [lin.n0 + lin.names.index(n) for n in channel_parameters(c, k)]
        v = theta[idx]
        if c == "wind":
            if np.max(np.hypot(v[:k], v[k:])) > WIND_MAX_MPS:
                out.append(c)
        elif np.max(np.abs(v)) > AERO_MAX:
            out.append(c)
    return out


__all__ = ["KNOT_COUNTS", "TraceFit", "describe_trace", "knot_counts", "points_to", "refit_without", "trace_residual"]
