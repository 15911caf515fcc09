"""Math namespaces that let one physics function serve NumPy, JAX and CasADi.

Every physics function in rventry is written in plain arithmetic on *components*
(scalars, NumPy arrays of any shape, or CasADi ``SX``/``MX`` expressions) and takes
the few non-arithmetic operations it needs from a namespace argument ``ns``. The
same source line then evaluates batched on NumPy arrays for the environments and
symbolically on CasADi expressions for the collocation transcription, and compiled
(``jax.jit``, CPU or GPU) on JAX arrays.

Only operations that differ between the libraries belong here. The array namespaces
(NUMPY, JAX) also carry the two control-flow forms the environment step needs, so one
source serves eager NumPy and traced JAX:

* ``while_loop(cond, body, carry)``: a Python loop for NumPy, ``lax.while_loop`` for JAX;
* ``known(flag)``: a Python bool that is True only where ``flag`` is a concrete True
  (NumPy: ``bool(flag)``; JAX: always False, since a traced value is never known), for
  shortcuts that skip work but never change a result;
* ``when(flag, fn)``: ``fn()`` where the scalar ``flag`` holds, else None (NumPy, floats); JAX:
  ``lax.cond``, whose untaken branch gives ``fn``'s result filled with zeros (under ``vmap`` both
  run and the zeros are selected where ``flag`` is False).

A namespace is typed (:class:`MathBackend`, and :class:`StepBackend` for the ones the
environment step runs on) and says what it can do in three flags, which callers test instead
of its name: ``array`` (elementwise on arrays, not one float or one symbol), ``concrete``
(values are known when the call runs: NumPy and floats, not JAX under tracing nor CasADi
symbols) and ``symbolic`` (CasADi expressions). ``name`` is for messages only.

Nothing here changes a process-wide setting when it is imported. :func:`jax_ns` with
``"float64"`` needs JAX's ``jax_enable_x64``; it turns it on when first called for that dtype
(an explicit request for 64-bit JAX arrays), and :func:`prefer_fused_cpu_runtime` sets
``XLA_FLAGS`` only when an entry point calls it (see docs/env.md).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np


def _py_while(cond, body, carry):
    while cond(carry):
        carry = body(carry)
    return carry


_SCALAR_TYPES = (int, float, np.float64, np.float32, np.int64, np.int32)


def is_zero(x) -> bool:
    """True for a Python/NumPy scalar that is exactly zero (never for arrays or symbols)."""
    return type(x) in _SCALAR_TYPES and x == 0


def _py_when(flag, fn):
    return fn() if flag else None


@dataclass(frozen=True, eq=False, slots=True)
class MathBackend:
    """The operations every physics function takes from its namespace: the transcendental functions,
    and the capabilities its callers test (see the module docstring)."""

    name: str  # for messages; never compared to choose a path
    key: str  # the namespace's name in :func:`_namespace`: what a pickle holds
    array: bool  # elementwise on arrays (NumPy, JAX), not one float or one symbol
    concrete: bool  # values known when the call runs (NumPy, floats), not traced (JAX) or symbolic (CasADi)
    symbolic: bool  # CasADi expressions
    sqrt: Callable
    exp: Callable
    log: Callable
    sin: Callable
    cos: Callable
    tanh: Callable
    arctan2: Callable
    fabs: Callable
    fmax: Callable
    fmin: Callable
    where: Callable  # where(cond, a, b)

    def __reduce__(self):
        """Pickled as a reference to the library's one namespace (an environment holding one pickles:
        its functions are never pickled, and the copy gets this process's namespace)."""
        return _namespace, (self.key,)


def _namespace(key):
    """The namespace ``key`` names: ``"numpy"``, ``"math"``, ``"casadi"`` or ``"jax-float64"`` / ``"jax-float32"``."""
    if key == "numpy":
        return NUMPY
    if key == "math":
        return MATH
    if key == "casadi":
        return casadi_ns()
    if key.startswith("jax-"):
        return jax_ns(key[4:])
    raise ValueError(f"no math namespace {key!r}")


@dataclass(frozen=True, eq=False, slots=True)
class StepBackend(MathBackend):
    """A namespace the environment step runs on (NumPy, floats, JAX): :class:`MathBackend` and the
    step's array and control-flow operations."""

    isfinite: Callable
    interp: Callable
    any: Callable
    all: Callable
    logical_not: Callable
    known: Callable  # known(flag): True only where flag is a concrete True
    while_loop: Callable  # while_loop(cond, body, carry)
    when: Callable  # when(flag, fn): fn() where flag holds
    int8: Callable | None = None  # arrays: x as int8
    index: Callable | None = None  # arrays: the integer part of x >= 0, for indexing
    zeros_int8: Callable | None = None  # arrays: int8 zeros shaped like ``like``
    take_rows: Callable | None = None  # traced arrays: values[n, i[n]] for each row n of an (N, K) table
    float_dtype: Any = None  # arrays: the float type of the state


def _array_namespace(xp, name: str, concrete: bool, index_dtype=np.intp, key: str | None = None,
                     **control) -> StepBackend:  # fmt: skip
    """The namespace of an array library with NumPy's API (NumPy itself, ``jax.numpy``)."""
    return StepBackend(
        name=name,
        key=key or name,
        array=True,
        concrete=concrete,
        symbolic=False,
        sqrt=xp.sqrt,
        exp=xp.exp,
        log=xp.log,
        sin=xp.sin,
        cos=xp.cos,
        tanh=xp.tanh,
        arctan2=xp.arctan2,
        fabs=xp.abs,
        fmax=xp.maximum,
        fmin=xp.minimum,
        where=xp.where,
        isfinite=xp.isfinite,
        interp=xp.interp,
        int8=lambda x: xp.asarray(x).astype(xp.int8),
        index=lambda x: xp.asarray(x).astype(index_dtype),  # integer part of x >= 0, for indexing
        zeros_int8=lambda like: xp.zeros(xp.shape(like), dtype=xp.int8),
        any=xp.any,
        all=xp.all,
        logical_not=xp.logical_not,
        **control,
    )


NUMPY = _array_namespace(np, "numpy", True, float_dtype=np.float64, known=bool, while_loop=_py_while, when=_py_when)


# Plain Python floats: one vehicle stepped without NumPy's per-call overhead. The transcendental
# functions are NumPy's, called on the float: on a CPU where NumPy dispatches them to SIMD kernels
# (AVX-512: exp, log, tanh, atan2 and others differ from the C library's by an ulp in a few per
# cent of arguments) the C library's would part the float path from the array path, which the
# vector env's copies take interchangeably. Outside each function's finite range the C library's
# is called instead, so that an overflow raises as before (the float path reports it as a
# non-finite state) rather than warn.
_np_exp, _np_log, _np_sin, _np_cos, _np_tanh, _np_atan2 = np.exp, np.log, np.sin, np.cos, np.tanh, np.arctan2


def _exp(x):
    return float(_np_exp(x)) if x < 709.0 else math.exp(x)


def _log(x):
    return float(_np_log(x)) if x > 0.0 else math.log(x)


def _sin(x):
    return float(_np_sin(x)) if math.isfinite(x) else math.sin(x)


def _cos(x):
    return float(_np_cos(x)) if math.isfinite(x) else math.cos(x)


def _tanh(x):
    return float(_np_tanh(x))


def _atan2(y, x):
    return float(_np_atan2(y, x))


MATH = StepBackend(
    name="math",
    key="math",
    array=False,
    concrete=True,
    symbolic=False,
    sqrt=math.sqrt,  # correctly rounded in both
    exp=_exp,
    log=_log,
    sin=_sin,
    cos=_cos,
    tanh=_tanh,
    arctan2=_atan2,
    fabs=abs,
    fmax=max,
    fmin=min,
    where=lambda cond, a, b: a if cond else b,
    isfinite=math.isfinite,
    interp=lambda x, xp, fp: float(np.interp(x, xp, fp)),
    any=bool,
    all=bool,
    logical_not=lambda b: not b,
    known=bool,
    while_loop=_py_while,
    when=_py_when,
)


def _casadi_namespace() -> MathBackend:
    import casadi as ca

    return MathBackend(
        name="casadi",
        key="casadi",
        array=False,
        concrete=False,
        symbolic=True,
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


_CASADI: MathBackend | None = None


def casadi_ns() -> MathBackend:
    """The CasADi namespace (imported lazily so NumPy users never load CasADi)."""
    global _CASADI
    if _CASADI is None:
        _CASADI = _casadi_namespace()
    return _CASADI


def _jax_namespace(dtype) -> StepBackend:
    import jax
    import jax.numpy as jnp

    def when(flag, fn):
        zeros = lambda: jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), jax.eval_shape(fn))  # noqa: E731
        return jax.lax.cond(flag, fn, zeros)

    # a traced value is never known while tracing: the shortcuts give way to the masked path
    def take_rows(values, i):  # values[n, i[n]] for each row n of an (N, K) table
        return jnp.take_along_axis(values, i[:, None], axis=1)[:, 0]

    return _array_namespace(jnp, "jax", False, index_dtype=jnp.int32, key=f"jax-{jnp.dtype(dtype).name}", float_dtype=dtype, known=lambda flag: False,
                            while_loop=jax.lax.while_loop, when=when, take_rows=take_rows)  # fmt: skip


_JAX: dict = {}
_XLA_CPU_FLAG = "--xla_cpu_use_thunk_runtime=false"


def prefer_fused_cpu_runtime() -> None:
    """Ask XLA's CPU backend for its fused (pre-thunk) runtime, before JAX first loads.

    Measured with jax 0.10.2 (docs/env.md): one control step of 8192 vehicles ran 2-3x faster
    on the CPU with it. It leaves GPUs alone. Skipped where JAX is already loaded, where
    ``XLA_FLAGS`` already names the option, or where jaxlib is 0.11 or newer (the option is
    deprecated there and may be gone).
    """
    import os
    import sys
    from importlib.metadata import PackageNotFoundError, version

    flags = os.environ.get("XLA_FLAGS", "")
    if "jax" in sys.modules or "xla_cpu_use_thunk_runtime" in flags:
        return
    try:
        major, minor = (int(p) for p in version("jaxlib").split(".")[:2])
    except (PackageNotFoundError, ValueError):
        return
    if (major, minor) < (0, 11):
        os.environ["XLA_FLAGS"] = f"{flags} {_XLA_CPU_FLAG}".strip()


def jax_ns(dtype: str = "float64") -> StepBackend:
    """The JAX namespace (imported lazily: JAX is the optional ``[jax]`` extra).

    :param dtype: ``"float64"`` (needs ``jax_enable_x64``, which this turns on) or ``"float32"``.
    :raises ImportError: naming the extra when JAX is not installed.
    """
    if dtype not in ("float64", "float32"):
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    if dtype not in _JAX:
        prefer_fused_cpu_runtime()
        try:
            import jax
        except ImportError as e:  # pragma: no cover - depends on the install
            raise ImportError('the JAX backend needs the optional extra: pip install "rventry[jax]"') from e
        if dtype == "float64":
            jax.config.update("jax_enable_x64", True)
        import jax.numpy as jnp

        _JAX[dtype] = _jax_namespace(jnp.float64 if dtype == "float64" else jnp.float32)
    return _JAX[dtype]


@contextlib.contextmanager
def jax_x64(enabled: bool):
    """JAX's 64-bit mode set to ``enabled`` inside the block and restored after it.

    The mode is one switch for the whole process, and :func:`jax_ns` turns it on for the float64
    backend. A float32 learner (rejax) must run with it off: with it on, JAX's default float is
    float64 and rejax's running statistics change type inside its training loop, which
    ``lax.scan`` refuses.
    """
    import jax

    before = bool(jax.config.jax_enable_x64)
    jax.config.update("jax_enable_x64", bool(enabled))
    try:
        yield
    finally:
        jax.config.update("jax_enable_x64", before)


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


__all__ = ["MathBackend", "StepBackend", "NUMPY", "MATH", "casadi_ns", "jax_ns", "jax_x64", "dot3", "sparse", "sparse_dot", "is_zero"]
