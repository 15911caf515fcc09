"""What every training command shares: reading a TOML configuration, and the algorithms by name.

The SB3 trainer (:mod:`rventry_agents.train`), DAgger (:mod:`rventry_agents.dagger`), the saved
policies (:mod:`rventry_agents.sb3_policy`) and ``ship`` read these; none of them imports another
for it.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ALGORITHMS = ("ppo", "recurrent_ppo", "sac")


def read_config(path: str | Path | dict | None, default: Path, sections: tuple[str, ...]) -> tuple[dict, str]:
    """A training configuration: a TOML file (``default`` when None) or an already-loaded dict,
    with every one of ``sections``; returns it and where it came from, for messages."""
    if isinstance(path, dict):
        cfg, where = path, "config"
    else:
        where = Path(path) if path is not None else default
        if where.is_dir():
            raise IsADirectoryError(f"the training config {where} is a directory; give a TOML file")
        if not where.is_file():
            raise FileNotFoundError(f"no training config at {where}")
        try:
            with open(where, "rb") as f:
                cfg = tomllib.load(f)
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{where} is not valid TOML: {exc}") from None
    for section in sections:
        if section not in cfg:
            raise ValueError(f"{where}: missing section [{section}]")
    return cfg, str(where)


def check_algorithm(algorithm: str) -> str:
    if algorithm not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algorithm!r}; known: {', '.join(ALGORITHMS)}")
    return algorithm


def algorithm_class(algorithm: str):
    """The stable-baselines3 (or sb3-contrib) class of ``algorithm``."""
    if check_algorithm(algorithm) == "recurrent_ppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    import stable_baselines3

    return getattr(stable_baselines3, algorithm.upper())


__all__ = ["ALGORITHMS", "algorithm_class", "check_algorithm", "read_config"]
