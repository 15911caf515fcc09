"""Math namespaces that let one physics function serve NumPy and CasADi.

Every physics function in rventry is written in plain arithmetic on *components*
(scalars, NumPy arrays of any shape, or CasADi ``SX``/``MX`` expressions) and takes
the few non-arithmetic operations it needs from a namespace argument ``ns``. The
same source line then evaluates batched on NumPy arrays for the environments and
symbolically on CasADi expressions for the collocation transcription.

Only operations that differ between the two libraries belong here.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np


def _np_where(cond, a, b):
    return np.where(cond, a, b)


_SCALAR_TYPES = (int, float, np.float64, np.float32, np.int64, np.int32)


def is_zero(x) -> bool:
    """True for a Python/NumPy scalar that is exactly zero (never for arrays or symbols)."""
    return type(x) in _SCALAR_TYPES and x == 0


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
    isfinite=np.isfinite,
)


# Plain Python floats: one vehicle stepped without NumPy's per-call overhead.
MATH = SimpleNamespace(
    name="math",
    sqrt=math.sqrt,
    exp=math.exp,
    log=math.log,
    sin=math.sin,
    cos=math.cos,
    tanh=math.tanh,
    arctan2=math.atan2,
    fabs=abs,
    fmax=max,
    fmin=min,
    where=lambda cond, a, b: a if cond else b,
    isfinite=math.isfinite,
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
    """a . b for 3-tuples of components."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def sparse(b) -> tuple:
    """The (index, value) pairs of ``b`` that are not literal zeros.

    Constant vectors such as the spin axis (0, 0, w) or point-mass gravity in A
    (g, 0, 0) would waste whole array operations on zeros; find the pattern once
    and dot against it with :func:`sparse_dot`.
    """
    return tuple([(j, bj) for j, bj in enumerate(b) if not (type(bj) in _SCALAR_TYPES and bj == 0)])


def sparse_dot(a, nz: tuple):
    """a . b where ``nz = sparse(b)``."""
    if not nz:
        return 0.0
    j, bj = nz[0]
    out = a[j] * bj
    for j, bj in nz[1:]:
        out = out + a[j] * bj
    return out


__all__ = ["NUMPY", "MATH", "casadi_ns", "dot3", "sparse", "sparse_dot", "is_zero"]
