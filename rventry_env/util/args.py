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


def _at_least(kind, low, strict: bool, phrase: str):
    """An argparse type: a number of ``kind`` above ``low`` (or at least ``low``), else "must be <phrase>"."""

    def check(text: str):
        value = _number(text, kind)
        if value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(f"must be {phrase}, got {text!r}")
        return value

    return check


positive_int = _at_least(int, 1, False, "a positive integer")
non_negative_int = _at_least(int, 0, False, "an integer >= 0")
positive_float = _at_least(float, 0.0, True, "a positive finite number")
non_negative_float = _at_least(float, 0.0, False, "a finite number >= 0")


def seed(text: str) -> int:
    """A random seed: an integer >= 0 (NumPy's generators take no negative seeds)."""
    value = _number(text, int)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0 (NumPy seeds are non-negative), got {text!r}")
    return value


def agent_spec(text: str) -> str:
    """An agent's name or a saved policy's path: not empty."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError(f"must name an agent or the path of a saved policy, got {text!r}")
    return str(text)


def interval(low: float, high: float, *, low_open: bool = False, high_open: bool = False):
    """A finite number between ``low`` and ``high`` (each end open or closed) as an argparse type."""

    def check(text: str) -> float:
        value = _number(text, float)
        ok_low = value > low if low_open else value >= low
        ok_high = value < high if high_open else value <= high
        if not (ok_low and ok_high):
            lb, hb = "(" if low_open else "[", ")" if high_open else "]"
            raise argparse.ArgumentTypeError(f"must lie in {lb}{low:g}, {high:g}{hb}, got {text!r}")
        return value

    check.__name__ = "interval"
    return check


def number_list(item, min_len: int = 1, max_len: int | None = None, what: str = "numbers"):
    """Comma-separated numbers, each checked by the argparse type ``item`` (e.g. ``positive_float``)."""

    def check(text: str) -> tuple:
        parts = [p.strip() for p in str(text).split(",")]
        n_max = max_len if max_len is not None else len(parts)
        if not min_len <= len(parts) <= n_max:
            count = f"{min_len}" if min_len == n_max else f"{min_len} to {n_max}"
            raise argparse.ArgumentTypeError(f"expected {count} comma-separated {what}, got {text!r}")
        out = []
        for p in parts:
            try:
                out.append(item(p))
            except argparse.ArgumentTypeError as exc:
                raise argparse.ArgumentTypeError(f"{exc} (in {text!r})") from None
        return tuple(out)

    check.__name__ = "number_list"
    return check


__all__ = [
    "positive_int",
    "non_negative_int",
    "positive_float",
    "non_negative_float",
    "seed",
    "agent_spec",
    "interval",
    "number_list",
]
