"""Which guidance laws ``rventry evaluate`` and ``rventry compare`` can fly, by name.

The classical laws are built in. Other packages add theirs through entry points,
so this library never imports them by name:

* group ``rventry.agents``: ``name = "package.module:loader"``, called as
  ``loader(name, task)``; the learning agents register ``learned``, ``dagger``, ``ppo`` and their baselines there;
* group ``rventry.agent_files``: loaders tried in turn for an agent given as a
  path (a saved model), called as ``loader(path, task)``;
* group ``rventry.agent_cards``: ``package = "package.module:CARDS"``, a sequence of
  :class:`AgentCard`: what each agent says of itself (why a user would pick it, whether and where
  ``rventry compare`` shows it, whether it re-plans in flight). The module should be light: the
  commands read the cards without loading any policy.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Callable

from rventry_env.task import EntryTask

AGENT_GROUP = "rventry.agents"
FILE_GROUP = "rventry.agent_files"
CARD_GROUP = "rventry.agent_cards"


@dataclass(frozen=True)
class AgentCard:
    """What an agent declares about itself to the commands that list and compare laws.

    :param name: the agent's name (as ``--agent`` takes it).
    :param why: why a user would pick it, in words (``rventry compare``'s verdict); figures come from the run.
    :param compare_label: its column in ``rventry compare``; None: compared only when named by ``--agent``.
    :param compare_order: its place among the compared columns (smaller first).
    :param replans: it re-plans in flight, seconds of CPU per decision: ``rventry compare`` flies it
        ``--mpc-episodes`` dispersed episodes instead of ``--episodes``.
    """

    name: str
    why: str
    compare_label: str | None = None
    compare_order: int = 0
    replans: bool = False


def _reference(task, **options):
    from rventry_env.guidance.reference_replay import ReferencePolicy

    return ReferencePolicy(task, **options)


def _lqr(task, **options):
    from rventry_env.guidance.tvlqr import NeighboringOptimalGuidance

    return NeighboringOptimalGuidance(task=task, **options)


def _lqr_est(task, **options):
    from rventry_env.guidance.tvlqr import NeighboringOptimalGuidance

    return NeighboringOptimalGuidance(task=task, estimate=True, **options)


def _mpc(task, **options):
    from rventry_env.guidance.replanning import ReplanningGuidance

    return ReplanningGuidance(task=task, **options)


def _mpc_flight(task, **options):
    from rventry_env.guidance.estimation import FlightEstimatorSettings
    from rventry_env.guidance.replanning import ReplanningGuidance, ReplanningSettings

    preset = {"settings": ReplanningSettings.flight_grade(), "estimator_settings": FlightEstimatorSettings.flight_grade()}
    return ReplanningGuidance(task=task, **(preset | options))


# the peer set's density is one constant factor: a single Gauss-Markov band over every altitude flown, with a
# correlation length far beyond the flight
_CONSTANT_BAND = (100_000.0, 1e8)


def peer_settings():
    """:class:`~rventry_env.guidance.replanning.ReplanningSettings` of ``mpc-flight`` with its margins sized by
    the ``peer`` set's published statistics (:meth:`~rventry_env.task.Dispersion.peer`) instead of the
    ``flight`` set's: the density a constant factor (one band of its rms), and the q bound carrying the drag
    scale's share that is C_D (its rms). Chosen against ``mpc-flight`` on seeds 1000-1019 of ``peer``."""
    from rventry_env.guidance.replanning import ReplanningSettings
    from rventry_env.task import Dispersion

    d = Dispersion.peer()
    return ReplanningSettings.flight_grade(density_bands=((_CONSTANT_BAND[0], d.density, _CONSTANT_BAND[1]),),
                                           drag_rms=d.drag)  # fmt: skip


def _mpc_peer(task, **options):
    return _mpc_flight(task, **({"settings": peer_settings()} | options))


# name -> (description, factory(task, **options))
BUILTIN: dict[str, tuple[str, Callable]] = {
    "reference": ("open-loop replay of the optimal collocation reference", _reference),
    "lqr": ("time-varying LQR around the margined guidance reference", _lqr),
    "lqr-est": ("the same TV-LQR with online estimation of the aerodynamic scales", _lqr_est),
    "mpc": ("re-planning on the LGR transcription every 30 s, with online estimation", _mpc),
    "mpc-flight": ("the same re-planning with flight-grade estimation (scales as processes in altitude and Mach, "
                   "the wind) and margins: load relief, and margins from the density's "
                   "and the aerodynamics' uncertainty", _mpc_flight),
    "mpc-peer": ("mpc-flight with its margins sized by the peer set's published statistics (density a constant "
                 "factor of 25 % rms, C_D 20 % rms)", _mpc_peer),
}


# what the built-in laws declare of themselves
BUILTIN_CARDS = (
    AgentCard("lqr", "it is the cheapest feedback law, exact nominally, but it tracks a fixed reference and cannot "
              "re-plan", "TV-LQR", 40),
    AgentCard("lqr-est", "it is TV-LQR with the estimated aerodynamic scales fed forward: estimation alone",
              "TV-LQR + estimation", 50),
    AgentCard("mpc", "it re-plans the optimum from where the vehicle is every 30 s: the most precise law, at seconds "
              "of CPU per decision", "re-planning (mpc)", 60, replans=True),
    AgentCard("mpc-flight", "it is mpc with flight-grade estimation and margins", replans=True),
    AgentCard("mpc-peer", "it is mpc-flight with its margins sized by the peer set's statistics", replans=True),
    AgentCard("reference", "it is the optimum flown open loop: the cost floor nominally, no feedback under "
              "dispersions", "reference (open loop)", 70),
)  # fmt: skip


def agent_cards() -> dict[str, AgentCard]:
    """Every agent's card by name: the built-in laws' and those installed packages declare
    (entry-point group ``rventry.agent_cards``)."""
    cards = {c.name: c for c in BUILTIN_CARDS}
    for ep in sorted(entry_points(group=CARD_GROUP), key=lambda e: e.name):
        for card in ep.load():
            if not isinstance(card, AgentCard):
                raise TypeError(f"entry point {ep.name} ({CARD_GROUP}) holds {card!r}, not an AgentCard")
            cards.setdefault(card.name, card)
    return cards


def compared_agents() -> list[AgentCard]:
    """The cards of the agents ``rventry compare`` shows by default, in their order."""
    return sorted((c for c in agent_cards().values() if c.compare_label is not None), key=lambda c: c.compare_order)


def plugin_agents() -> dict:
    """Agent names registered by installed packages (entry-point group ``rventry.agents``)."""
    return {ep.name: ep for ep in entry_points(group=AGENT_GROUP)}


def agent_names() -> list[str]:
    """Every agent name ``load_agent`` accepts (besides paths)."""
    return [*BUILTIN, *sorted(set(plugin_agents()) - set(BUILTIN))]


def check_agent(spec: str) -> None:
    """Refuse at once, loading nothing, an agent that is neither a known name nor an existing path.

    :raises ValueError: an unknown name. :raises FileNotFoundError: a path that does not exist.
    """
    if spec in BUILTIN or spec in plugin_agents():
        return
    path = Path(spec)
    if not (path.suffix or path.exists() or "/" in spec):
        raise ValueError(f"unknown agent {spec!r}: choose one of {', '.join(agent_names())}, or give a saved model's path")
    if not path.exists():
        raise FileNotFoundError(f"no saved policy at {path}")


def load_agent(spec: str, task: EntryTask | None = None, **options):
    """The guidance law called ``spec``, or the saved policy at the path ``spec``.

    :param options: keyword arguments for a built-in law (``settings=...`` for ``mpc``, say).

    :raises ValueError: an unknown name, or a path no installed loader can read.
    :raises FileNotFoundError: a path that does not exist.
    """
    task = EntryTask() if task is None else task
    if spec in BUILTIN:
        return BUILTIN[spec][1](task, **options)
    if options:
        raise ValueError(f"options {sorted(options)} apply to the built-in laws only, not to {spec!r}")
    plugins = plugin_agents()
    if spec in plugins:
        return plugins[spec].load()(spec, task)
    check_agent(spec)
    path = Path(spec)
    loaders = sorted(entry_points(group=FILE_GROUP), key=lambda e: e.name)
    if not loaders:
        raise ValueError(f"no installed package reads saved policies such as {path} (entry-point group {FILE_GROUP})")
    errors = []
    for ep in loaders:
        try:
            return ep.load()(str(path), task)
        except (ValueError, FileNotFoundError) as exc:
            errors.append(f"{ep.name}: {exc}")
    raise ValueError(f"cannot load a policy from {path}: " + "; ".join(errors))


__all__ = ["AGENT_GROUP", "FILE_GROUP", "CARD_GROUP", "AgentCard", "BUILTIN", "BUILTIN_CARDS", "agent_cards", "agent_names",
           "check_agent", "compared_agents", "load_agent", "plugin_agents"]
