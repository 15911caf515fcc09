"""``argparse`` types shared by every ``rventry`` command: one set of number checks.

Each type names what it expects, so a bad value gets a message such as
``argument --episodes: must be a positive integer, got '0'`` and exit code 2.
"""

from __future__ import annotations

import argparse
import math


def _number(text: str, kind) -> float | int:
    try:
        value = kind(text)
    except (TypeError, ValueError):
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1."""
    value = _number(text, int)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    value = _number(text, int)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text, float)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text, float)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def fraction(low: float = 0.0, high: float = 1.0, include_high: bool = False):
    """A number in [low, high) (or [low, high]) as an argparse type."""

    def check(text: str) -> float:
        value = _number(text, float)
        ok = low <= value <= high if include_high else low <= value < high
        if not ok:
            bracket = "]" if include_high else ")"
            raise argparse.ArgumentTypeError(f"must lie in [{low:g}, {high:g}{bracket}, got {text!r}")
        return value

    check.__name__ = "fraction"
    return check


def seed(text: str) -> int:
    """A random seed: an integer >= 0 (NumPy's generators take no negative seeds)."""
    value = _number(text, int)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0 (NumPy seeds are non-negative), got {text!r}")
    return value


__all__ = ["positive_int", "non_negative_int", "positive_float", "non_negative_float", "fraction", "seed"]
