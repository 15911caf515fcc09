"""``RvEntry-v0``: guide a hypersonic glide vehicle to a vertical impact on a target."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from rventry_env.core.backend import MATH
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import MAX_EPISODE_STEPS, common
from rventry_env.envs.observation import features, observe
from rventry_env.envs.outcome import episode_outcome
from rventry_env.envs.propagation import FLYING
from rventry_env.envs.render import Track, render_tracks
from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.shaping import PotentialShaping
from rventry_env.envs.uncertainty import Sensed, VehicleErrors
from rventry_env.task import Dispersion, EntryTask, apply_state_dispersion, draw_dispersion, draw_extras
from rventry_env.task.starts import StartStates
from rventry_env.physics.model import EntryModel

class RvEntryEnv(common.EntryEnvSetup, gym.Env):
    """
    ## Description

    The entry problem of Miller & Rao's Example 2 as a control task. A CAV-H glide
    vehicle starts at 37 km altitude flying east at 7138 m/s over (0 deg, 0 deg)
    and must hit a target 2800 km downrange (25.15 deg E, 0 deg N) *vertically*, at
    1219 m/s, with zero angle of attack, while spending as little control effort as
    the paper's cost (Eq. ``Ex2-Cost``) allows and respecting its path constraints
    (load factor <= 12 g, dynamic pressure >= 12 kPa).

    The dynamics are the rv-Euler equations of motion (Eqs. ``Ex2-EOM`` to
    ``Ex2-EOM-Ftot``) on a rotating spherical Earth, evaluated by
    :func:`rventry_env.physics.entry_rhs` -- the same function the collocation
    reference and the identification tool use. The state has no singularity in
    vertical flight, which is what makes the vertical-impact task well posed.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: the angle-of-attack and bank-angle *rates*
    as fractions of their limits, held constant over the control step ``dt``:

    | index | action | maps to |
    |---|---|---|
    | 0 | angle-of-attack rate | u_alpha = a0 * u_alpha_max (10 deg/s) |
    | 1 | bank-angle rate | u_sigma = a1 * u_sigma_max (30 deg/s) |

    Out-of-range actions are clipped to [-1, 1] (the rate limits of Eq.
    ``Ex2-path``) and ``info["action_clipped"]`` says so. An action of the wrong
    shape or with NaN/inf raises ``ValueError``. alpha saturates at [0, alpha_max]:
    in a substep where the commanded rate would carry alpha past a bound the
    applied rate is reduced so alpha lands on the bound, and held there
    (``info["alpha_saturated"]``); the cost charges the *commanded* rate.

    ## Observation Space

    ``Box(low, high, (26,), float32)``, every feature bounded by construction or by
    the episode-end rules:

    | index | name | meaning | min | max |
    |---|---|---|---|---|
    {obs_table}

    mu is the conventional bank angle (0 = lift up, positive = lift to the right),
    gamma the flight-path angle relative to the Earth. A feature outside its bound is
    clipped into the Box and ``info["observation_clipped"]`` is set. That happens in three
    cases only: from an unusual user-supplied state or model; at the last step of an episode
    flown with coarse control steps (dt of 10 s and more), where one RK4 step can carry the
    state past the stall, skip-out or impact bounds before the episode ends; and with
    navigation errors (the ``flight`` set, or any dispersion with accelerometer or navigation errors), where
    the observation is built from the navigated state: in the last seconds of a flight the
    navigation can put the vehicle more than 400 m below the ground, and the altitude
    feature is then held at its bound -0.01. On 2000 ``flight`` episodes flown by the
    reference, 27 % of the episodes had such steps, 0.4 per thousand steps; no other feature
    left the Box, and no step of the sets without navigation errors did (docs/env.md).

    ## Rewards

    Each step pays minus the paper's running cost (Eq. ``Ex2-Cost``, k1 = k2 = k3
    = 1) integrated exactly over the step, minus a path penalty (10 x relative
    excess of the load factor over 12 g, 10 x relative deficit of q under 12 kPa,
    each beyond the 1 % margin that decides success, per second, sampled at every
    RK4 node). The terminal step also pays minus

        0.2 x miss [km] + 0.2 x vertical error [deg] + 0.02 x |v - 1219 m/s| + 0.1 x |alpha(t_f)| [deg]

    and, if the episode ended without impact, a failure penalty of 200. All
    weights are :class:`~rventry_env.envs.reward.RewardWeights` fields. Along the
    optimal collocation reference the summed reward is -J* with a near-zero
    terminal penalty.

    ## Starting State

    The paper's Table ``tab:Ex2-BCs``: r = R_e + 37 km, eA = (0, 0, 0, 1),
    v = 7138 m/s, eB = (0, 0, sqrt(2)/2, sqrt(2)/2); alpha and sigma (free in the
    paper) default to the shipped collocation reference's initial values.
    Dispersions (constructor ``dispersion=`` or ``reset(options={"dispersion": ...})``,
    a :class:`~rventry_env.task.Dispersion`, a dict of its fields or a set's name:
    ``"standard"``, ``"wide"``, ``"flight"``, ``"peer"``, ``"peer-0.1"``) draw from
    ``self.np_random``: density and C_L/C_D scale factors, initial altitude, speed,
    flight-path angle, heading, alpha, sigma (uniform or clipped Gaussian), and for the
    flight-grade sets the mass, density and wind profiles in altitude, Mach-dependent
    C_L/C_D errors, accelerometer and navigation errors (docs/uncertainty.md).
    ``reset(options={"state": x})`` starts from any valid 12-state.

    ## Episode End

    ``terminated`` on impact (r = R_e, located inside the step by root-finding on
    the RK4 map; the returned state is the state at impact), on skip-out (altitude
    above 80 km), on a non-finite state, or on stall (v < 50 m/s); the last three
    set ``info["failure"]``. ``truncated`` at the time limit, ``max_episode_steps``
    = 2000 by default (2000 s at the default dt). A shorter limit set with
    ``gym.make("RvEntry-v0", max_episode_steps=N)`` (Gymnasium's ``TimeLimit``, which
    records it in ``env.spec.max_episode_steps``) is read at ``reset``, so that episode
    too ends with the end keys below, and a further ``step`` raises.

    ## Info

    Every step: ``r_ecef_m``, ``v_ecef_mps``, ``latitude_deg``, ``longitude_deg``,
    ``altitude_m``, ``speed_mps``, ``dynamic_pressure_pa``, ``load_factor_g``,
    ``sensed_accel_b`` (what an accelerometer measures: the aerodynamic specific
    force in B components, m/s^2, so ``-sensed[0]`` is the drag acceleration and
    ``sensed[1:]`` the lift's; the navigation state plus this is all a guidance law
    may know), ``navigation_state`` (the 12-state the vehicle's navigation gives: the
    truth unless the dispersion has sensor or navigation errors; the observation is
    built from it), ``cost`` (running cost J so far), ``time_s``, ``action_clipped``,
    ``alpha_saturated``. The last step also: ``miss_km``, ``vertical_error_deg``,
    ``speed_error_mps``, ``alpha_final_deg``, ``max_load_factor_g``,
    ``min_dynamic_pressure_pa``, ``constraint_violation`` (load > 12 g or q < 12 kPa
    by more than 1 %), ``terminal_penalty``, ``failure`` ("" on impact) and
    ``is_success``: impact with miss <= 5 km, vertical error <= 5 deg,
    |speed error| <= 100 m/s and no constraint violation
    (:class:`~rventry_env.task.SuccessThresholds`). At reset, ``dispersion_draw``: the
    episode's draw, for evaluation only (a guidance law is never given it).

    ## Arguments

    ``gym.make("RvEntry-v0", model=None, task=None, reward=None, dt=None, substeps=None,
    dispersion=None, render_mode=None, targets=None)``

    * ``model``: an :class:`~rventry_env.physics.EntryModel` (gravity, atmosphere,
      vehicle/aerodynamics, wind parts); default: the documented defaults (docs/conventions.md).
    * ``task``: an :class:`~rventry_env.task.EntryTask` (problem constants,
      success thresholds, dt, substeps, ceiling).
    * ``reward``: :class:`~rventry_env.envs.reward.RewardWeights` (see Rewards).
    * ``dt``: control step, default 1 s; ``substeps``: RK4 substeps per control
      step, default 1.
    * ``dispersion``: see Starting State.
    * ``render_mode``: ``"rgb_array"`` draws altitude and speed against time and
      the ground track toward the target.
    * ``targets``: ``"fixed"`` (the task's default: the paper's target) or ``"footprint"``:
      each episode draws its target within +/-300 km downrange and +/-150 km crossrange of the
      paper's (:class:`~rventry_env.task.Footprint`), after the dispersion's draws. The
      observation's target features follow it, and ``info["target_e"]`` tells it (unit vector
      in E components) at reset and every step.

    ``env.unwrapped.state`` is the float64 (12,) state in the documented order (docs/conventions.md);
    ``env.unwrapped.dt`` the control step.

    ## Vectorized environment

    ``gym.make_vec("RvEntry-v0", num_envs=N, vectorization_mode="vector_entry_point")``
    returns :class:`~rventry_env.envs.vector.RvEntryVectorEnv`, which steps all
    copies in one array operation through the same propagation code.

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        model: EntryModel | None = None,
        task: EntryTask | None = None,
        reward: RewardWeights | None = None,
        dt: float | None = None,
        substeps: int | None = None,
        dispersion: Dispersion | dict | str | None = None,
        render_mode: str | None = None,
        targets: str | None = None,
        max_episode_steps: int | None = MAX_EPISODE_STEPS,
        starts: StartStates | None = None,
        shaping: PotentialShaping | None = None,
    ):
        self.observation_space, self.action_space = self._configure(
            model, task, reward, dt, substeps, dispersion, render_mode, MATH, targets, starts, shaping
        )
        self.max_episode_steps = common.check_max_steps(max_episode_steps)
        self._limit = self.max_episode_steps  # this episode's: the own limit or a shorter outer one
        self._ended = False

    # ------------------------------------------------------------------ state
    @property
    def state(self) -> np.ndarray:
        """The 12-component state, float64, state order of docs/conventions.md (a copy)."""
        if self._x is None:
            raise RuntimeError("the environment has no state before reset()")
        return np.array(self._x, dtype=np.float64)

    @property
    def episode_model(self) -> EntryModel:
        """The episode's truth model (the drawn profiles, aerodynamics and mass), for evaluation
        such as the attainable ceiling (``rventry oracle``); a guidance law is never given it."""
        if self._x is None:
            raise RuntimeError("the environment has no episode before reset()")
        return self._episode_model

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=common.check_seed(seed))
        self._limit = common.outer_time_limit(self, self.max_episode_steps)
        options = common.reset_options(options)
        dispersion = Dispersion.parse(options["dispersion"]) if "dispersion" in options else self.dispersion
        self.task.check_dispersion(dispersion)
        x0 = common.check_state(options["state"], self._radius, self.task) if "state" in options else self._nominal
        d = draw_dispersion(self.np_random, dispersion)
        extras = draw_extras(self.np_random, dispersion, self.task.problem)
        target = self.task.draw_target(self.np_random, self._radius)
        self._target = self._nominal_target if target is None else tuple(float(c) for c in target)
        start = None if self.starts is None or "state" in options else self.starts.draw(self.np_random, self.task.problem.alpha_max)
        self._errors = VehicleErrors(1, self.model)
        self._errors.assign(0, dispersion, extras)
        if start is not None:  # a start state: the table's perturbation replaces the initial state's
            x0 = start[1]
        elif not dispersion.is_zero:
            x0 = apply_state_dispersion(x0, d)
        if not dispersion.is_zero:
            # Python floats, not NumPy scalars: the single env works on floats (overflow raises, and is caught)
            self._episode_model = self._errors.model(float(1 + d[0]), float(1 + d[1]), float(1 + d[2]), single=True)
        else:
            self._episode_model = self.model
        self.dispersion_draw = d
        self._x = tuple(float(c) for c in x0)
        if start is not None:
            self._x = common.within_path_bounds(self._x, self._episode_model, self.task, MATH)
        self._forces = self._prop.forces(self._x, self._episode_model)
        self._c_ae = dcm(*self._x[1:5])
        self._t = 0.0 if start is None else start[0]
        self._steps = 0
        self._cost = 0.0
        self._max_load = self._forces.aero_accel / self._g0
        self._min_q = self._forces.dynamic_pressure
        self._ended = False
        self._phi = self._potential(self._x, self._c_ae, MATH)
        self._track = Track() if self.render_mode else None
        self._measure()
        obs, clipped = self._observe()
        info = self._info(False, False, clipped)
        # the draws, for evaluation only: a guidance law is never given them
        info["dispersion_draw"] = self._errors.draw_info(d[None], [extras], single=True)
        self._record()
        return obs, info

    def step(self, action):
        if self._x is None:
            raise RuntimeError("call reset() before step()")
        if self._ended:
            raise RuntimeError("step() called after the episode ended (terminated or truncated); call reset() first")
        a = common.real_actions(action, (2,), "action")
        a0, a1 = float(a[0]), float(a[1])
        if not (math.isfinite(a0) and math.isfinite(a1)):
            raise ValueError(f"action contains NaN or inf: {a.tolist()}")
        clipped = not (-1.0 <= a0 <= 1.0 and -1.0 <= a1 <= 1.0)
        a0, a1 = min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)
        p = self.task.problem
        out = self._prop.step(self._x, self._forces, a0 * p.u_alpha_max, a1 * p.u_sigma_max, self._episode_model)
        self._x, self._forces = out.x, out.forces
        self._c_ae = dcm(*self._x[1:5])  # once per step, for the observation and info
        self._t += out.elapsed
        self._steps += 1
        self._cost += out.cost
        self._max_load = max(self._max_load, out.max_load_g)
        self._min_q = min(self._min_q, out.min_q)
        reward = -(out.cost + out.path_penalty)
        terminated = out.status != FLYING
        truncated = not terminated and self._limit is not None and self._steps >= self._limit
        if self.shaping is not None:
            phi = self._potential(self._x, self._c_ae, MATH)
            reward += self.shaping.reward(self._phi, phi, terminated, MATH)
            self._phi = phi
        self._measure(out.elapsed)
        info_obs, obs_clipped = self._observe()
        info = self._info(clipped, out.alpha_saturated, obs_clipped)
        if terminated or truncated:
            reward -= self._finish(info, out.status, terminated)
        self._ended = terminated or truncated
        self._record()
        return info_obs, float(reward), bool(terminated), bool(truncated), info

    def end_at_time_limit(self, info: dict) -> None:
        """End the episode because a time limit outside the env cut it: add the end keys to ``info``.

        Gymnasium's ``TimeLimit`` wrapper (added by ``gym.make(..., max_episode_steps=N)``)
        truncates without telling the environment. Wrapping it in
        :class:`~rventry_env.envs.wrappers.EndAtTimeLimit` calls this, so that such an
        episode too carries ``failure = "time limit"``, ``is_success`` and the terminal
        metrics like any other ending, and a further ``step`` is refused. Idempotent.
        """
        if self._x is None or self._ended:
            return
        self._finish(info, FLYING, False)
        self._ended = True

    def render(self):
        if self.render_mode is None:
            gym.logger.warn('render() needs render_mode="rgb_array" at construction')
            return None
        if self._track is None:
            raise RuntimeError("call reset() before render()")
        p = self.task.problem
        return render_tracks([self._track], p.target_latitude, p.target_longitude)

    # ------------------------------------------------------------------ helpers
    def _measure(self, elapsed=None) -> None:
        """What the vehicle's sensors and navigation make of the truth (the truth itself where
        the set has no sensor or navigation errors)."""
        if self._errors.any_sensing:
            nav, sensed, feats, _ = self._errors.sense(self._x, self._forces, self._c_ae, self._g0,
                                                       None if elapsed is None else [elapsed])  # fmt: skip
            nav_x = tuple(float(c) for c in nav[0])
            self._nav = nav[0]
            self._sensed = sensed[0]
            seen = Sensed(dcm(*nav_x[6:10]), float(feats.dynamic_pressure[0]), float(feats.aero_accel[0]))
            self._seen = (nav_x, seen, dcm(*nav_x[1:5]))
        else:
            self._nav = None
            self._sensed = None
            self._seen = (self._x, self._forces, self._c_ae)

    def _observe(self):
        x, forces, c_ae = self._seen
        raw = observe(x, forces, c_ae, self._t, self.task, self._target, self._radius, self._g0, MATH)
        obs, clipped = common.clip_observation(np.array(raw, dtype=np.float32), self._obs_low, self._obs_high)
        return obs, bool(clipped)

    def _info(self, action_clipped, alpha_saturated, obs_clipped) -> dict:
        f = self._forces
        r_e, v_e, a1 = common.position_velocity_e(self._c_ae, f.c_ba, self._x[0], self._x[5])
        lat, lon = common.latitude_longitude(a1, MATH)
        return {
            "r_ecef_m": np.array(r_e),
            "v_ecef_mps": np.array(v_e),
            "latitude_deg": lat * common.RAD2DEG,
            "longitude_deg": lon * common.RAD2DEG,
            "altitude_m": self._x[0] - self._radius,
            "speed_mps": self._x[5],
            "dynamic_pressure_pa": f.dynamic_pressure,
            "load_factor_g": f.aero_accel / self._g0,
            "sensed_accel_b": np.array(f.aero_b, dtype=np.float64) if self._sensed is None else self._sensed.copy(),
            "navigation_state": np.array(self._x, dtype=np.float64) if self._nav is None else self._nav.copy(),
            "cost": self._cost,
            "time_s": self._t,
            "action_clipped": action_clipped,
            "alpha_saturated": bool(alpha_saturated),
            "observation_clipped": obs_clipped,
            "target_e": np.array(self._target),
        }

    def _finish(self, info: dict, status: int, terminated: bool) -> float:
        """Add the end-of-episode keys to ``info``; return the terminal penalty (:mod:`.outcome`)."""
        o = episode_outcome(
            self._x, self._c_ae, status, terminated, self._max_load, self._min_q, self.task, self.reward, self._target,
            self._radius, MATH,
        )  # fmt: skip
        info.update(
            **o.metrics._asdict(),
            max_load_factor_g=self._max_load,
            min_dynamic_pressure_pa=self._min_q,
            constraint_violation=bool(o.constraint_violation),
            terminal_penalty=o.terminal_penalty,
            failure=o.failure,
            is_success=bool(o.is_success),
        )
        return o.terminal_penalty

    def _record(self):
        if self._track is not None:
            lat, lon = common.latitude_longitude(self._c_ae[0], MATH)
            self._track.append(self._t, self._x[0] - self._radius, self._x[5], lat, lon)


def _obs_table() -> str:
    from rventry_env.task import EntryTask as _T

    rows = features(_T(), 6378137.0)
    return "\n    ".join(f"| {i} | {f.name} | {f.meaning} | {f.low:g} | {f.high:.3g} |" for i, f in enumerate(rows))


RvEntryEnv.__doc__ = RvEntryEnv.__doc__.replace("{obs_table}", _obs_table())
