"""What the learning agents declare of themselves to ``rventry compare`` and the agent listings
(entry-point group ``rventry.agent_cards``). Light on purpose: reading the cards loads no policy."""

from __future__ import annotations

from rventry_env.evaluation.agents import AgentCard

# `learned` is the learned policy that lands the most of the flight set (today `ppo-scratch-flight`, learned
# from scratch); `dagger-flight`, the flight-set student of `mpc-flight`, and `dagger`, the student of `mpc`
# built for the standard and wide sets, are shown beside it
CARDS = (
    AgentCard("learned", "it is the learned policy that lands the most of the flight-grade set, learned from scratch "
              "without a teacher; trained to land rather than to fly the optimum, it gives up nominal precision "
              "and cost"),
    AgentCard("ppo", "it is PPO fine-tuning of the flight-set student, flown with its q floor"),
    AgentCard("dagger-flight", "it flies mpc-flight's flight-grade margins at a network's cost per decision",
              "DAgger of mpc-flight", 10),
    AgentCard("dagger", "it lands like mpc on the standard and wide sets, at a network's cost per decision",
              "DAgger of mpc", 20),
    AgentCard("ppo-scratch", "it is PPO learned from scratch with a reverse curriculum, no teacher: it lands the whole "
              "flight on the standard set, not yet the wide and flight-grade sets"),
    AgentCard("ppo-scratch-wide", "it is ppo-scratch trained further on the wide set, still without a teacher: the "
              "from-scratch policy that lands the most of the wide set"),
    AgentCard("ppo-scratch-flight", "it is ppo-scratch-wide trained further on the flight-grade set, still without a "
              "teacher: the from-scratch policy that lands the most of the flight-grade set"),
    AgentCard("ppo-scratch-2h", "it is PPO learned from scratch in two hours on one CPU core, from one config file and "
              "step 0, no teacher: it lands the standard set, not yet the wide and flight-grade sets"),
    AgentCard("ppo-plain", "it is what off-the-shelf RL learns from scratch on the raw reward: a baseline, not a law "
              "to fly", "plain PPO", 30),
)  # fmt: skip

__all__ = ["CARDS"]
