"""Math namespaces that let one physics function serve NumPy and CasADi.

Every physics function in rventry is written in plain arithmetic on *components*
(scalars, NumPy arrays of any shape, or CasADi ``SX``/``MX`` expressions) and takes
the few non-arithmetic operations it needs from a namespace argument ``ns``. The
same source line then evaluates batched on NumPy arrays for the environments and
symbolically on CasADi expressions for the collocation transcription.

Only operations that differ between the two libraries belong here.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np


def _np_where(cond, a, b):
    return np.where(cond, a, b)


def is_zero(x) -> bool:
    """True for a Python/NumPy scalar that is exactly zero (never for symbols)."""
    return isinstance(x, (int, float, np.floating, np.integer)) and x == 0


NUMPY = SimpleNamespace(
    name="numpy",
    sqrt=np.sqrt,
    exp=np.exp,
    log=np.log,
    sin=np.sin,
    cos=np.cos,
    tanh=np.tanh,
    arctan2=np.arctan2,
    fabs=np.abs,
    fmax=np.maximum,
    fmin=np.minimum,
    where=_np_where,
)


def _casadi_namespace() -> SimpleNamespace:
    import casadi as ca

    return SimpleNamespace(
        name="casadi",
        sqrt=ca.sqrt,
        exp=ca.exp,
        log=ca.log,
        sin=ca.sin,
        cos=ca.cos,
        tanh=ca.tanh,
        arctan2=ca.atan2,
        fabs=ca.fabs,
        fmax=ca.fmax,
        fmin=ca.fmin,
        where=ca.if_else,
    )


_CASADI: SimpleNamespace | None = None


def casadi_ns() -> SimpleNamespace:
    """The CasADi namespace (imported lazily so NumPy users never load CasADi)."""
    global _CASADI
    if _CASADI is None:
        _CASADI = _casadi_namespace()
    return _CASADI


def dot3(a, b):
    """a . b for 3-tuples of components, skipping literal zeros (cheaper NumPy)."""
    terms = [x * y for x, y in zip(a, b) if not (is_zero(x) or is_zero(y))]
    if not terms:
        return 0.0
    out = terms[0]
    for t in terms[1:]:
        out = out + t
    return out


__all__ = ["NUMPY", "casadi_ns", "dot3", "is_zero"]
