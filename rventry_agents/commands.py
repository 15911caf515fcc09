"""Attitude commands: a policy that asks for an angle of attack and a bank angle, flown by a one-step tracker.

The environment's action is a pair of *rates* (fractions of the rate limits). A policy that
outputs rates must integrate them into the attitude it wants, and its exploration noise
integrates too: white noise of 0.1 on the bank rate is a random walk of 3 deg per second of
bank, 30 deg over 100 s, which moves the impact by hundreds of kilometres. A policy that
outputs the *attitude* it wants explores around it without drift, and its noise costs only the
rates that jitter needs. DeepMimic's policies output PD targets for the same reason.

:func:`command_rates` turns a command into the environment's action from what the vehicle
measures (the observation): alpha_cmd = (c0 + 1) / 2 alpha_max, and the conventional bank
mu_cmd = c1 pi (0 = lift up, positive = lift to the right of the flight direction), approached
at the rate (command - attitude) / tau within the rate limits, the bank the short way round.
With tau = dt the command is reached in one step where the limits allow; a longer tau turns the
exploration noise of a command into a smaller rate, which the paper's cost charges (the noise's
cost falls as 1 / tau^2), at the price of a slower response. The map is part of the policy:
training flies it inside the environment step, evaluation inside the law, with the same code for
NumPy and JAX (``xp`` is ``numpy`` or ``jax.numpy``).

``"circular-commands"`` takes the bank command as the angle it is: c1 is any real number and
mu_cmd = c1 pi is read on the circle (c1 = 1.25 is mu = -135 deg), where ``"commands"`` clips c1
to [-1, 1]. The clip is a trap for a Gaussian policy: lift down (mu = 180 deg) is c1 = +-1, the
ends of the interval, and a policy whose bank mean drifts past 1 with a small exploration noise
flies exactly lift down on every sample. The bank then has no gradient, and the crossrange it
would steer is lost. A run of ``commands`` on seed 5 stood 31 chunks (130M steps) that way with
its window 94 s from impact: its bank mean was 1.25 on every step, with noise 0.028, and every
impact 6.6-8.0 km to the side. On the circle the mean moves through lift down as through any
other bank. The angle of attack is bounded by the vehicle and stays clipped in both.
"""

from __future__ import annotations

import math

from rventry_env.envs.observation import feature_index
from rventry_env.task import EntryTask

# what a policy outputs: the environment's own rates, or attitude commands (the bank clipped, or on the circle)
ACTIONS = ("rates", "commands", "circular-commands")
_ALPHA, _LIFT_UP, _LIFT_RIGHT = (feature_index(n) for n in ("alpha", "lift_up", "lift_right"))


def command_rates(observation, command, task: EntryTask, xp, tau: float | None = None, circular: bool = False):
    """The environment's actions (rate fractions in [-1, 1], (..., 2)) that fly ``command`` (..., 2)
    from the attitude in ``observation`` (..., 26), approached with time constant ``tau`` (s; default
    and at least the control step). Each command is clipped to [-1, 1], except a ``circular`` bank."""
    p = task.problem
    dt = task.dt if tau is None else max(float(tau), task.dt)
    c0 = xp.clip(command[..., 0], -1.0, 1.0)
    c1 = command[..., 1] if circular else xp.clip(command[..., 1], -1.0, 1.0)
    alpha = 0.5 * (observation[..., _ALPHA] + 1.0) * p.alpha_max
    mu = xp.arctan2(observation[..., _LIFT_RIGHT], observation[..., _LIFT_UP])
    alpha_cmd = 0.5 * (c0 + 1.0) * p.alpha_max
    turn = c1 * math.pi - mu
    turn = xp.arctan2(xp.sin(turn), xp.cos(turn))  # the short way round
    return xp.stack([xp.clip((alpha_cmd - alpha) / (dt * p.u_alpha_max), -1.0, 1.0),
                     xp.clip(turn / (dt * p.u_sigma_max), -1.0, 1.0)], axis=-1)  # fmt: skip


def output_bounds(actions: str) -> tuple[float, float]:
    """Where a policy's outputs are clipped before they are flown (each output alike): [-1, 1], or
    nowhere for circular commands (:func:`command_rates` clips their angle of attack itself)."""
    return (-math.inf, math.inf) if check_actions(actions) == "circular-commands" else (-1.0, 1.0)


def clipped_outputs(actions: str) -> tuple[bool, bool]:
    """Which of a policy's two outputs its action map clips to [-1, 1]: the angle of attack (or its
    rate) always; the bank (or its rate) unless circular commands read it on the circle."""
    return True, check_actions(actions) != "circular-commands"


def policy_actions(observation, output, actions: str, task: EntryTask, xp, tau: float | None = None):
    """The environment's actions for a policy's ``output`` (..., 2) on ``observation``: the output
    itself (clipped) for ``"rates"``, else the attitude commands it asks, flown by :func:`command_rates`
    (each output clipped as :func:`clipped_outputs` says)."""
    if actions == "rates":
        return xp.clip(output, -1.0, 1.0)
    return command_rates(observation, output, task, xp, tau, circular=not clipped_outputs(actions)[1])


def check_actions(actions: str) -> str:
    if actions not in ACTIONS:
        raise ValueError(f"actions must be one of {ACTIONS}, got {actions!r}")
    return actions


__all__ = ["ACTIONS", "check_actions", "clipped_outputs", "command_rates", "output_bounds", "policy_actions"]
