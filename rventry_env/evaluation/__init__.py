"""Evaluate guidance policies on RvEntry-v0 against the collocation reference."""

from rventry_env.evaluation.rollout import EpisodeBatch, rollout
from rventry_env.evaluation.summary import summarize

__all__ = ["EpisodeBatch", "rollout", "summarize"]
