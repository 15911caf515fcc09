"""The JAX stepper: the vector environment's step of all copies compiled by JAX.

``gym.make_vec("RvEntry-v0", num_envs=N, vectorization_mode="vector_entry_point",
backend="jax", dtype="float64")`` (or ``"float32"``). Everything a user sees is the
vector environment's (:class:`~rventry_env.envs.vector.RvEntryVectorEnv`, the one class for every
backend, which hands its episodes to this stepper): spaces, seeding, autoreset modes, infos, errors. Episodes are drawn on the
host with the same per-copy ``np_random`` generators and the same
:class:`~rventry_env.envs.uncertainty.VehicleErrors`, so the same seed flies the same
episodes as ``backend="numpy"``, every dispersion set included. The step of all copies
(:func:`~rventry_env.envs.transition.advance`, the NumPy environment's own code, and the
sensors and navigation of :func:`~rventry_env.envs.uncertainty.sense`) runs under
``jax.jit`` on the default JAX device (CPU, or a GPU where JAX finds one).

What keeps it fast: the episodes stay on the device between steps; one compiled call per
step returns everything the host needs in three arrays (observations, the float values
of the info and the outcome, and the flags), fetched in one transfer; the model's scalar
numbers are compiled in as constants and only its per-copy arrays (scale factors,
profiles) are arguments, sent when a reset changes them; the outcome is evaluated only on
steps where an episode ended. The accelerometer's white noise is the NumPy environment's
counter-based stream (:func:`~rventry_env.physics.sensors.white_noise`), evaluated on the
host and sent in.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from rventry_env.core.backend import NUMPY, jax_ns
from rventry_env.core.euler_parameters import dcm
from rventry_env.envs import common
from rventry_env.envs.functional import DTYPES, _structure
from rventry_env.envs.outcome import Outcome, TerminalMetrics, failure_name
from rventry_env.envs.propagation import Propagator
from rventry_env.envs.transition import advance, observe_episode, start_episode
from rventry_env.envs.uncertainty import SensorErrors, sense
from rventry_env.envs.steppers import StepSetup, Stepped, Stepper
from rventry_env.physics.model import numeric_leaves, scaled_model, with_numeric_leaves

# rows of the packed float output: the state, flight_info's values, then the step's numbers
_INFO_ROWS = (("r_ecef_m", 3), ("v_ecef_mps", 3), ("latitude_deg", 1), ("longitude_deg", 1), ("altitude_m", 1),
              ("speed_mps", 1), ("dynamic_pressure_pa", 1), ("load_factor_g", 1), ("sensed_accel_b", 3), ("cost", 1),
              ("time_s", 1))  # fmt: skip
_STEP_ROWS = ("reward", "max_load", "min_q", "miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg",
              "penalty", "steps")  # fmt: skip
_FLAGS = ("terminated", "truncated", "saturated", "violation", "success", "status")


def _row_slices(rows) -> dict:
    out, i = {}, 0
    for name, k in rows:
        out[name] = slice(i, i + k)
        i += k
    return out


class _Compiled:
    """The compiled step, restart and view of one model structure (its scalar numbers compiled in)."""

    def __init__(self, stepper: "JaxStepper", template, dynamic: tuple, sensing: bool, key: tuple):
        self.stepper, self.template, self.dynamic, self.sensing, self.key = stepper, template, dynamic, sensing, key
        leaves = numeric_leaves(template)
        self.scalars = [None if i in dynamic else float(v) for i, v in enumerate(leaves)]
        self.step = jax.jit(self._step)
        self.restart = jax.jit(self._restart)
        self.view = jax.jit(self._view)

    def model(self, dyn):
        it = iter(dyn)
        return with_numeric_leaves(self.template, iter([next(it) if v is None else v for v in self.scalars]))

    def _restart(self, carry, x0, t0, mask, dyn, errors):
        st = self.stepper
        fresh = start_episode(tuple(x0), self.model(dyn), st._jprop)._replace(t=t0)
        nav = (errors.dr, errors.dv) if self.sensing else None
        if carry is None:
            return fresh, nav
        episode = jax.tree.map(lambda new, old: jnp.where(mask, new, old), fresh, carry[0])
        return episode, nav if nav is None else jax.tree.map(lambda new, old: jnp.where(mask, new, old), nav, carry[1])

    def _seen(self, episode, c_ae, nav, errors, model, elapsed):
        """The state and features the observation is made of (the navigated ones where sensing errs)."""
        if not self.sensing:
            return episode, c_ae, None, None, nav
        seen = sense(episode.x, episode.forces, c_ae, nav[0], nav[1], errors, self.stepper.setup.model, elapsed,
                     self.stepper._ns)  # fmt: skip
        return episode._replace(x=seen.x, forces=seen.features), seen.c_ae, seen.x, seen.sensed_b, (seen.dr, seen.dv)

    def _pack(self, episode, c_ae, model, nav, errors, elapsed):
        st, ns = self.stepper, self.stepper._ns
        seen_episode, seen_c_ae, nav_x, sensed, nav = self._seen(episode, c_ae, nav, errors, model, elapsed)
        raw = jnp.stack(observe_episode(seen_episode, seen_c_ae, model, st._jprop, st._target)).astype(jnp.float32)
        lo, hi = st.setup.obs_low[:, None], st.setup.obs_high[:, None]
        clipped = jnp.any((raw < lo) | (raw > hi), axis=0)
        obs = jnp.clip(raw, lo, hi).T
        info = common.flight_info(episode.x, episode.forces, c_ae, episode.t, episode.cost, st.setup.radius, st.setup.g0, ns)
        if sensed is not None:
            info["sensed_accel_b"] = sensed
        rows = [*episode.x]
        for name, _ in _INFO_ROWS:
            v = info[name]
            rows.extend(v if isinstance(v, tuple) else (v,))
        if nav_x is not None:
            rows.extend(nav_x)
        n = episode.x[0].shape
        rows = jnp.stack([jnp.broadcast_to(jnp.asarray(r, ns.float_dtype), n) for r in rows])
        return obs, rows, clipped, nav

    def _view(self, carry, dyn, errors):
        episode, nav = carry
        model = self.model(dyn)
        obs, rows, clipped, _ = self._pack(episode, dcm(*episode.x[1:5]), model, nav, errors, None)
        return obs, rows, clipped

    def _step(self, carry, dyn, a, active, errors):
        st, ns = self.stepper, self.stepper._ns
        episode, nav = carry
        model = self.model(dyn)
        tr = advance(episode, (a[:, 0], a[:, 1]), model, st._jprop, st.setup.max_episode_steps, st._target, active)
        obs, rows, clipped, nav = self._pack(tr.episode, tr.c_ae, model, nav, errors, tr.out.elapsed)
        o = tr.outcome
        n = rows.shape[1]
        extra = jnp.stack([jnp.broadcast_to(jnp.asarray(v, ns.float_dtype), (n,)) for v in (
            tr.reward, tr.episode.max_load, tr.episode.min_q, *o.metrics, o.terminal_penalty, tr.episode.steps)])  # fmt: skip
        flags = jnp.stack([jnp.broadcast_to(jnp.asarray(v).astype(jnp.int8), (n,)) for v in (
            tr.terminated, tr.truncated, tr.out.alpha_saturated, o.constraint_violation, o.is_success, tr.out.status,
            clipped)])  # fmt: skip
        return (tr.episode, nav), obs, jnp.concatenate([rows, extra]), flags


class JaxStepper(Stepper):
    """All copies in one compiled call per step (see the module docstring).

    :param dtype: ``"float64"`` (default: agrees with NumPy to rounding) or ``"float32"``
        (faster; see the manual's JAX page for its error at impact).

    It flies every dispersion set, start states, shaping and every autoreset mode; it refuses
    rendering and footprint targets when the env is built, and ``true_forces`` when asked (its
    forces stay on the device).
    """

    name = "jax"

    def __init__(self, setup: StepSetup, dtype: str = "float64"):
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
        super().__init__(setup)
        self.dtype = dtype
        self._ns = jax_ns(dtype)
        self._jprop = Propagator(setup.task, self._ns, setup.reward)
        self._target = None
        self._carry = None
        self._fn: _Compiled | None = None
        self._compiled: dict = {}
        self._x0 = None  # (12, N) host: initial states of the current episodes
        self._rows = None  # host: the packed rows of the last step or view
        self._rows_at = _row_slices((("x", 12), *_INFO_ROWS, ("nav", 12)))

    def check_features(self, render_mode, targets) -> None:
        if render_mode is not None:
            raise self.refuse(f"render_mode={render_mode!r}", "use backend='numpy'")
        if targets != "fixed":
            raise self.refuse(f"targets={targets!r} (it flies the fixed target)", "use backend='numpy'")

    def __getstate__(self) -> dict:
        """Pickled without its compiled functions: the copy compiles its own (the episodes, on the
        device, travel as arrays)."""
        state = dict(self.__dict__)
        fn = state.pop("_fn")
        state["_compiled"] = {}
        state["_fn_made_of"] = None if fn is None else (fn.key, fn.template, fn.dynamic, fn.sensing)
        return state

    def __setstate__(self, state: dict) -> None:
        made_of = state.pop("_fn_made_of")
        self.__dict__.update(state)
        self._fn = None
        if made_of is not None:
            key, template, dynamic, sensing = made_of
            self._fn = self._compiled[key] = _Compiled(self, template, dynamic, sensing, key)

    @property
    def true_forces(self):
        raise self.refuse("true_forces", "the compiled step keeps its forces on the device; use backend='numpy'")

    @property
    def step_fn(self):
        """The compiled step of the current model structure (one compilation per structure)."""
        return self._fn.step

    @property
    def sensing(self) -> bool:
        """Whether the current model structure senses (its compiled step carries navigation errors)."""
        return self._fn.sensing

    @property
    def state(self) -> np.ndarray:
        return np.ascontiguousarray(self._rows[self._rows_at["x"]].T, dtype=np.float64)

    @property
    def steps(self) -> np.ndarray:
        return self._steps

    def begin(self) -> None:
        self._steps = np.zeros(self.setup.num_envs, dtype=np.int64)

    def restart(self, idx, x0, t0, started, errors, scales, target) -> None:
        s = self.setup
        self._target = target
        if self._x0 is None or self._carry is None or len(idx) == s.num_envs:
            self._x0 = np.empty((12, s.num_envs))
            self._t0 = np.zeros(s.num_envs)
        self._x0[:, idx] = x0.T
        self._t0[idx] = t0
        self._steps[idx] = 0
        mask = np.zeros(s.num_envs, bool)
        mask[idx] = True
        host = errors.model(*scales) if errors.any_model else scaled_model(s.model, *scales)
        if started.any():  # start states inside the path bounds, with each copy's own model (on the host)
            rows = idx[started]
            self._x0[0, rows] = common.within_path_bounds(tuple(self._x0), host, s.task, NUMPY)[0][rows]
        leaves = numeric_leaves(host)
        dynamic = tuple(i for i, v in enumerate(leaves) if np.ndim(v) > 0)
        sensing = bool(errors.any_sensing)
        key = (_structure(host), tuple(float(leaves[i]) for i in range(len(leaves)) if i not in dynamic), dynamic,
               sensing)  # fmt: skip
        fn = self._compiled.get(key)
        if fn is None:
            fn = self._compiled[key] = _Compiled(self, host, dynamic, sensing, key)
        f = self._ns.float_dtype
        self._sensor = self._sensor_errors(errors) if sensing else None
        if fn is not self._fn and self._carry is not None:
            # an autoreset drew a set of another structure (a reset's one-off dispersion before it): the
            # episodes go on; the navigation errors start from the host's (zero where nothing sensed before)
            nav = None
            if sensing:
                nav = self._carry[1] if self._fn.sensing else (self._sensor.dr, self._sensor.dv)
            self._carry = (self._carry[0], nav)
        self._fn = fn
        self._dyn = tuple(jnp.asarray(np.ascontiguousarray(leaves[i]), f) for i in dynamic)
        self._carry = fn.restart(self._carry, jnp.asarray(self._x0, f), jnp.asarray(self._t0, f), jnp.asarray(mask),
                                 self._dyn, self._sensor)  # fmt: skip

    def _sensor_errors(self, e) -> SensorErrors:
        """The copies' accelerometer errors, this sample's noise and the navigation fixes, on the device."""
        f = self._ns.float_dtype
        rows = lambda a: tuple(jnp.asarray(a[j], f) for j in range(3))  # noqa: E731
        return SensorErrors(self._columns(e.bias), self._columns(e.scale), self._columns(e.misalignment),
                            self._columns(e.noise_sample()), jnp.asarray(e.senses), rows(e.dr), rows(e.dv))  # fmt: skip

    def _columns(self, a: np.ndarray) -> tuple:
        """The 3 columns of an (N, 3) host array as device arrays."""
        return tuple(jnp.asarray(np.ascontiguousarray(a[:, j]), self._ns.float_dtype) for j in range(3))

    def view(self, errors):
        obs, rows, clipped = jax.device_get(self._fn.view(self._carry, self._dyn, self._sensor))
        self._set_rows(rows)
        return np.array(obs), np.asarray(clipped, bool), self._info_values()

    def _set_rows(self, rows) -> None:
        self._rows = rows
        if self._fn.sensing:
            self.nav = np.ascontiguousarray(rows[self._rows_at["nav"]].T, dtype=np.float64)
            self.sensed = np.ascontiguousarray(np.stack(self._info_values()["sensed_accel_b"], axis=-1),
                                               dtype=np.float64)  # fmt: skip
        else:
            self.nav = self.sensed = None

    def _info_values(self) -> dict:
        r = self._rows
        out = {}
        for name, k in _INFO_ROWS:
            v = r[self._rows_at[name]]
            out[name] = tuple(v) if k == 3 else v[0]
        return out

    def advance(self, a, active, errors) -> Stepped:
        f = self._ns.float_dtype
        sensor = None
        if self._fn.sensing:  # the noise sample of the step's end, the NumPy stepper's counter advanced alike
            errors.step += np.asarray(active, np.int64)
            sensor = self._sensor._replace(noise=self._columns(errors.noise_sample()))
        self._carry, obs, rows, flags = self._fn.step(self._carry, self._dyn, jnp.asarray(a, f), jnp.asarray(active),
                                                      sensor)  # fmt: skip
        obs, rows, flags = jax.device_get((obs, rows, flags))
        if self._fn.sensing:
            self._sensor = sensor
        n_info = self._rows_at["nav"].stop if self._fn.sensing else self._rows_at["nav"].start
        self._set_rows(rows[:n_info])
        step = dict(zip(_STEP_ROWS, rows[n_info:]))
        self._steps = step["steps"].astype(np.int64)
        flag = dict(zip(_FLAGS, flags[:-1]))
        terminated, truncated = flag["terminated"].astype(bool), flag["truncated"].astype(bool)
        ended = terminated | truncated
        outcome = None
        if ended.any():
            outcome = Outcome(
                TerminalMetrics(*(step[k] for k in TerminalMetrics._fields)), flag["violation"].astype(bool),
                flag["success"].astype(bool), step["penalty"], failure_name(flag["status"], terminated, NUMPY),
            )  # fmt: skip
        return Stepped(step["reward"].astype(np.float64), terminated, truncated, flag["saturated"].astype(bool),
                       np.array(obs), flags[-1].astype(bool), self._info_values(), outcome, step["max_load"],
                       step["min_q"])  # fmt: skip


__all__ = ["JaxStepper"]
