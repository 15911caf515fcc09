"""``learned``: the shipped learned policy that lands the most of the ``flight`` set, by a name
that stays when a better one is shipped.

Today that is ``ppo-scratch-flight``: PPO learned from scratch, without a teacher (a reverse
curriculum on the standard set, then stages on the wide and flight-grade sets). On the same
held-out ``flight`` draws it lands more than ``ppo``, PPO fine-tuning of the flight-set DAgger
student, which held the name before it. Its figures, each beside its record and command, are on
the manual's learned-policies results page (``docs/benchmarks/learned_policies.md``); this
docstring quotes none, so that it cannot disagree with them.
"""

from __future__ import annotations

from rventry_env.task import EntryTask

LEARNED = "ppo-scratch-flight"


def load_learned(name: str = "learned", task: EntryTask | None = None):
    """The policy ``learned`` names (entry point ``rventry.agents``), loaded as that name's own entry point
    loads it, whatever kind of policy it is."""
    if name != "learned":
        raise ValueError(f"load_learned loads 'learned', not {name!r}")
    from rventry_env.evaluation.agents import load_agent

    return load_agent(LEARNED, task)


__all__ = ["LEARNED", "load_learned"]
