"""``learned``: the shipped learned policy that lands the most of the ``flight`` set, by a name
that stays when a better one is shipped.

Today that is ``ppo``: PPO fine-tuning of the flight-set DAgger student (``dagger-flight``), 0.79
of 200 held-out ``flight`` episodes against the student's 0.75 on the same ones (the README's
learned-policy section gives the figures and the command behind each).
"""

from __future__ import annotations

from rventry_env.task import EntryTask

LEARNED = "ppo"


def load_learned(name: str = "learned", task: EntryTask | None = None):
    """The policy ``learned`` names (entry point ``rventry.agents``)."""
    if name != "learned":
        raise ValueError(f"load_learned loads 'learned', not {name!r}")
    from rventry_agents.sb3_policy import load_shipped

    return load_shipped(LEARNED, task)


__all__ = ["LEARNED", "load_learned"]
