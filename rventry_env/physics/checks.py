"""Construction-time checks of the force-model parts: every field named when it is wrong.

A part is checked when it is built, so a model that cannot be flown (a mass of zero, NaN or
a string, a zero scale height, a planet without standard gravity) is refused at once, naming
the part and the field, rather than failing at ``reset`` with ZeroDivisionError or flying NaN.

Fields may also hold per-vehicle NumPy arrays (the environments' dispersions) or CasADi
symbols (the identification's fitted parameters) or JAX arrays (the JAX environments'
params, traced): NumPy arrays are checked element by element; symbols and JAX arrays, whose
values are not known while tracing, pass (the JAX environments' params come from checked parts).
"""

from __future__ import annotations

import math
import numbers

import numpy as np


def _symbolic(value) -> bool:
    # CasADi symbols, and JAX arrays (traced inside jit: the JAX environments rebuild parts there)
    return type(value).__module__.split(".")[0] in ("casadi", "jax", "jaxlib")


def check_number(part, name: str, *, low: float | None = None, high: float | None = None,
                 low_open: bool = False, high_open: bool = False, optional: bool = False,
                 integer: bool = False) -> None:  # fmt: skip
    """Raise ValueError unless ``part.<name>`` is a finite number (or array of them) in the range.

    :param low: the smallest value allowed (exclusive when ``low_open``); ``high`` the largest
        (exclusive when ``high_open``).
    :param optional: None is allowed too (a setting that is off).
    :param integer: the value must be an ``int`` (not a bool).
    """
    value = getattr(part, name)
    where = f"{type(part).__name__}.{name}"
    if optional and value is None:
        return
    if _symbolic(value):
        return
    none = "None (off) or " if optional else ""
    if integer:
        if not isinstance(value, numbers.Integral) or isinstance(value, bool):
            raise ValueError(f"{where} must be {none}an integer, got {value!r} ({type(value).__name__})")
        values = np.asarray(int(value))
    elif isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        values = value
    elif isinstance(value, numbers.Real) and not isinstance(value, bool):
        values = np.asarray(float(value))
    else:
        raise ValueError(f"{where} must be {none}a number, got {value!r} ({type(value).__name__})")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{where} must be {none}finite, got {value!r}")
    bad = np.zeros(values.shape, bool)
    if low is not None:
        bad |= values <= low if low_open else values < low
    if high is not None:
        bad |= values >= high if high_open else values > high
    if np.any(bad):
        lo = "" if low is None else f"{'>' if low_open else '>='} {low:g}"
        hi = "" if high is None else f"{'<' if high_open else '<='} {high:g}"
        worst = values[bad].flat[0]
        raise ValueError(f"{where} must be {none}{' and '.join(p for p in (lo, hi) if p)}, got {worst:g}")


def check_flag(part, name: str) -> None:
    """Raise ValueError unless ``part.<name>`` is True or False."""
    value = getattr(part, name)
    if not isinstance(value, bool):
        raise ValueError(f"{type(part).__name__}.{name} must be True or False, got {value!r}")


def check_numbers(part, names, **limits) -> None:
    """:func:`check_number` for each field of ``names``."""
    for name in names:
        check_number(part, name, **limits)


def check_sequence(part, name: str) -> None:
    """Raise ValueError unless ``part.<name>`` is a sequence of finite numbers (or symbols)."""
    value = getattr(part, name)
    where = f"{type(part).__name__}.{name}"
    if _symbolic(value):
        return
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"{where} must be a sequence of numbers, got {value!r}") from None
    for item in items:
        if _symbolic(item):
            continue
        if not (isinstance(item, numbers.Real) and not isinstance(item, bool) and math.isfinite(item)):
            raise ValueError(f"{where} must hold finite numbers, got {value!r}")


def check_part(owner, name: str, *methods: str, optional: bool = False) -> None:
    """Raise ValueError unless ``owner.<name>`` is a part with the callable ``methods`` (or None if optional)."""
    value = getattr(owner, name)
    if value is None and optional:
        return
    if value is None or not all(callable(getattr(value, m, None)) for m in methods):
        need = " and ".join(f"{m}()" for m in methods)
        raise ValueError(
            f"{type(owner).__name__}.{name} must be a force-model part with {need}"
            f"{' or None' if optional else ''}, got {value!r:.80}"
        )


__all__ = ["check_number", "check_numbers", "check_flag", "check_sequence", "check_part"]
