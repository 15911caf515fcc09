"""One control step of whole episodes, written once for NumPy and JAX.

:func:`advance` is the environment's step without its bookkeeping of resets and
infos: it propagates (:mod:`~rventry_env.envs.propagation`, impact located inside the
step), forms C_AE once, accumulates the episode's time, cost, peak load factor and
least dynamic pressure, pays the reward, decides termination and truncation, and on
an ending evaluates the outcome rule (:mod:`~rventry_env.envs.outcome`) and charges
its terminal penalty. The NumPy vector environment calls it on arrays
(:data:`~rventry_env.core.backend.NUMPY`); the JAX environments call the same code
under ``jax.jit`` (:func:`~rventry_env.core.backend.jax_ns`), where an :class:`EpisodeState`
is a pytree.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from rventry_env.core.euler_parameters import dcm
from rventry_env.envs.observation import observe
from rventry_env.envs.outcome import Outcome, episode_outcome
from rventry_env.envs.propagation import FLYING, Propagator, StepOutcome
from rventry_env.physics.entry import EntryForces
from rventry_env.physics.model import EntryModel


class EpisodeState(NamedTuple):
    """What an episode carries from step to step (floats, arrays of one shape, or JAX arrays)."""

    x: tuple  # the 12 state components, order of docs/conventions.md
    forces: EntryForces  # at x
    t: Any  # time (s)
    steps: Any  # control steps taken
    cost: Any  # running cost so far
    max_load: Any  # largest load factor flown (g)
    min_q: Any  # least dynamic pressure flown (Pa)


class Transition(NamedTuple):
    episode: EpisodeState
    c_ae: tuple  # C_AE at the new state
    out: StepOutcome
    reward: Any  # running cost and path penalty, and the terminal penalty where an episode terminated
    terminated: Any
    truncated: Any
    outcome: Outcome | None  # None where no episode ended (NumPy); zeros there (JAX)


def start_episode(x0: tuple, model: EntryModel, prop: Propagator) -> EpisodeState:
    """An episode's state at its start, from its initial state components ``x0``."""
    forces = prop.forces(x0, model)
    zero = 0.0 * x0[0]
    return EpisodeState(x0, forces, zero, zero, zero, forces.aero_accel / model.planet.g0, forces.dynamic_pressure)


def advance(episode: EpisodeState, actions: tuple, model: EntryModel, prop: Propagator, max_steps: int | None, target_e,
            active=None) -> Transition:  # fmt: skip
    """One control step of every episode in ``episode``.

    :param actions: the (alpha, sigma) rate fractions, each in [-1, 1] (already clipped).
    :param max_steps: the time limit in control steps (truncation), or None.
    :param active: arrays: the episodes stepped (the others stay as they are and neither
        terminate nor truncate); None: all.
    """
    ns, task = prop.ns, prop.task
    p = task.problem
    out = prop.step(episode.x, episode.forces, actions[0] * p.u_alpha_max, actions[1] * p.u_sigma_max, model, active)
    stepped = 1 if active is None else active
    new = EpisodeState(
        out.x, out.forces, episode.t + out.elapsed, episode.steps + stepped, episode.cost + out.cost,
        ns.fmax(episode.max_load, out.max_load_g), ns.fmin(episode.min_q, out.min_q),
    )  # fmt: skip
    c_ae = dcm(*out.x[1:5])
    terminated = out.status != FLYING
    truncated = ns.logical_not(terminated)
    if active is not None:
        terminated = terminated & active
        truncated = truncated & active
    if max_steps is None:
        truncated = truncated & False
    else:
        truncated = truncated & (new.steps >= max_steps)
    ended = terminated | truncated
    reward = -(out.cost + out.path_penalty)
    # the outcome only where an episode ended (JAX: a branch taken at run time; zeros otherwise)
    outcome = ns.when(ns.any(ended), lambda: episode_outcome(
        out.x, c_ae, out.status, terminated, new.max_load, new.min_q, task, prop.weights, target_e,
        model.planet.radius, ns,
    ))  # fmt: skip
    if outcome is not None:
        reward = reward - ns.where(ended, outcome.terminal_penalty, 0.0)
    return Transition(new, c_ae, out, reward, terminated, truncated, outcome)


def observe_episode(episode: EpisodeState, c_ae: tuple, model: EntryModel, prop: Propagator, target_e) -> tuple:
    """The observation features (unclipped) of the episodes."""
    planet = model.planet
    return observe(episode.x, episode.forces, c_ae, episode.t, prop.task, target_e, planet.radius, planet.g0, prop.ns)


__all__ = ["EpisodeState", "Transition", "start_episode", "advance", "observe_episode"]
