#!/usr/bin/env python
"""Right-hand-side throughput and operation counts of the translational-motion forms.

Forms: the two-body problem in rv-Euler parameters (Eqs. ``Ex1-EOM-rvEuler``),
spherical coordinates (Eq. ``Ex1-EOM-Geo``) and Cartesian coordinates, plus the
full entry dynamics (``entry_rhs``: rv-Euler with lift, drag, gravity and a
rotating Earth, 12 states).

Throughput: states per second, for one state given as plain Python floats
(``scalar``: the ``MATH`` namespace, the way the single environment steps one vehicle) and for
NumPy batches of 1 to 1e5 states (component arrays of shape ``(B,)``).

Operation count: each form is built once on CasADi SX with ``casadi_ns()`` and the
instructions of the resulting ``casadi.Function`` are counted by type. The count
is of the expression graph CasADi keeps (it folds constants and drops x*1, x+0);
``--cse`` first merges common subexpressions. ``sq`` (x^2) and ``twice`` (2x)
count as one multiply, ``inv`` (1/x) as one divide, ``neg`` is listed apart.

The paper (Section ``sect:Discussion``) argues rv-Euler needs fewer floating-point
operations because it has no trigonometry, pricing sin x at 14 flops (Eq.
``sin(x)``). The table prints raw counts and that weighted total.

Run:  python benchmarks/rhs_forms.py            (about a minute on a quiet machine)
      python benchmarks/rhs_forms.py --quick    (smaller batches, shorter timing)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from typing import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from rventry_env.core.backend import MATH, NUMPY, casadi_ns  # noqa: E402
from rventry_env.core.cartesian import two_body_cartesian_rhs  # noqa: E402
from rventry_env.core.conversions import rv_euler_from_cartesian, spherical_from_cartesian  # noqa: E402
from rventry_env.core.eom import two_body_rhs  # noqa: E402
from rventry_env.core.spherical import two_body_spherical_rhs  # noqa: E402
from rventry_env.physics import EntryModel, entry_rhs  # noqa: E402

from rventry_env.util.provenance import start_run, write_record

MU = 3.986004418e14
BATCHES = (1, 10, 100, 1_000, 10_000, 100_000)
SIN_FLOPS = 14  # the paper's price of one sin evaluation, Eq. sin(x)



# ---------------------------------------------------------------------------------
# the forms: (number of states, rhs(components, ns) -> tuple)

def _entry_form():
    model = EntryModel()
    return lambda x, ns: entry_rhs(x, (0.01, 0.02), model, ns)


FORMS: dict[str, tuple[int, Callable]] = {
    "rv-Euler": (10, lambda x, ns: two_body_rhs(x, MU)),
    "spherical": (6, lambda x, ns: two_body_spherical_rhs(x, MU, ns)),
    "Cartesian": (6, lambda x, ns: two_body_cartesian_rhs(x, MU, ns)),
    "entry (rv-Euler)": (12, None),  # filled lazily: building the model is cheap but keep imports honest
}
TWO_BODY = ("rv-Euler", "spherical", "Cartesian")


def _form(name: str):
    n, f = FORMS[name]
    return n, (_entry_form() if f is None else f)


def random_states(name: str, batch: int, seed: int = 0) -> np.ndarray:
    """Physically sensible random states ``(n_state, batch)`` for one form."""
    rng = np.random.default_rng(seed)
    if name == "entry (rv-Euler)":
        radius, speed = 6378137.0 + rng.uniform(20e3, 70e3, batch), rng.uniform(2e3, 7e3, batch)
    else:
        radius, speed = rng.uniform(6.6e6, 8e6, batch), rng.uniform(6e3, 9e3, batch)
    # directions away from the poles and from vertical flight so spherical states exist
    lat, lon = rng.uniform(-1.2, 1.2, batch), rng.uniform(-np.pi, np.pi, batch)
    a1 = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
    d = rng.normal(size=(batch, 3))
    d -= 0.9 * np.sum(d * a1, -1, keepdims=True) * a1  # mostly horizontal
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    r_e, v_e = radius[:, None] * a1, speed[:, None] * d
    if name == "Cartesian":
        x = np.concatenate([r_e, v_e], -1)
    elif name == "spherical":
        x = spherical_from_cartesian(r_e, v_e)
    else:
        x = rv_euler_from_cartesian(r_e, v_e)
        if name == "entry (rv-Euler)":
            x = np.concatenate([x, rng.uniform(0.05, 0.3, (batch, 1)), rng.uniform(-3, 3, (batch, 1))], -1)
    return np.ascontiguousarray(x.T)


def _rate(call: Callable[[], object], min_time: float) -> float:
    """Calls per second: best of 3 timed runs of >= min_time / 3 each."""
    call()  # warm-up
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            call()
        dt = time.perf_counter() - t0
        if dt >= min_time / 3:
            break
        n *= 2 if dt == 0 else max(2, int(min_time / 3 / dt * 1.2))
    best = dt
    for _ in range(2):
        t0 = time.perf_counter()
        for _ in range(n):
            call()
        best = min(best, time.perf_counter() - t0)
    return n / best


def throughput(name: str, batches=BATCHES, min_time: float = 0.3) -> dict:
    """States per second: ``{"scalar": ..., 1: ..., 10: ...}`` for one form."""
    _, f = _form(name)
    out = {}
    xs = random_states(name, 1)[:, 0].tolist()
    out["scalar"] = _rate(lambda: f(xs, MATH), min_time)
    for b in batches:
        x = tuple(random_states(name, b))  # component arrays of shape (b,)
        out[b] = b * _rate(lambda x=x: f(x, NUMPY), min_time)
    return out


# ---------------------------------------------------------------------------------
# operation counts


def _op_classes():
    import casadi as ca

    return {
        "add/sub": (ca.OP_ADD, ca.OP_SUB, ca.OP_TWICE),
        "mul": (ca.OP_MUL, ca.OP_SQ),
        "div": (ca.OP_DIV, ca.OP_INV),
        "neg": (ca.OP_NEG,),
        "sqrt": (ca.OP_SQRT,),
        "trig": (ca.OP_SIN, ca.OP_COS, ca.OP_TAN, ca.OP_ASIN, ca.OP_ACOS, ca.OP_ATAN, ca.OP_ATAN2),
        "exp/log/pow": (ca.OP_EXP, ca.OP_LOG, ca.OP_POW, ca.OP_CONSTPOW, ca.OP_TANH),
        "ignored": (ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_PARAMETER),
    }


def op_count(name: str, cse: bool = False) -> dict:
    """Instruction counts by class for one form built on CasADi SX."""
    import casadi as ca

    n, f = _form(name)
    x = ca.SX.sym("x", n)
    out = f([x[i] for i in range(n)], casadi_ns())
    fun = ca.Function("rhs", [x], [ca.vertcat(*out)], {"cse": True} if cse else {})
    by_op = Counter(fun.instruction_id(k) for k in range(fun.n_instructions()))
    counts = {cls: 0 for cls in _op_classes()}
    names = {getattr(ca, a): a for a in dir(ca) if a.startswith("OP_")}
    other = []
    for op, k in by_op.items():
        for cls, ops in _op_classes().items():
            if op in ops:
                counts[cls] += k
                break
        else:
            other.append(f"{names.get(op, op)} x{k}")
    counts.pop("ignored")
    counts["other"] = ", ".join(sorted(other))
    counts["arithmetic"] = counts["add/sub"] + counts["mul"] + counts["div"] + counts["neg"]
    counts["weighted"] = counts["arithmetic"] + counts["sqrt"] + SIN_FLOPS * counts["trig"]
    return counts


# ---------------------------------------------------------------------------------


def _fmt_rate(x: float) -> str:
    return f"{x:.3g}"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="batches up to 1e4 and shorter timing")
    p.add_argument("--min-time", type=float, default=None, help="seconds of timing per cell (default 0.6)")
    p.add_argument("--cse", action="store_true", help="also count with common-subexpression elimination")
    p.add_argument("--json", metavar="PATH", help="write all figures as JSON")
    args = p.parse_args(argv)
    batches = BATCHES[:-1] if args.quick else BATCHES
    min_time = args.min_time if args.min_time is not None else (0.15 if args.quick else 0.6)
    if min_time <= 0:
        p.error("--min-time must be positive")
    start_run(None if argv is None else ["python", __file__, *argv])

    print(f"numpy {np.__version__}, python {sys.version.split()[0]}, OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}")
    print("\nRight-hand-side throughput, states per second (best of 3)")
    cols = ["scalar"] + list(batches)
    head = f"{'form':<18}" + "".join(f"{('B=' + str(c)) if c != 'scalar' else 'scalar':>11}" for c in cols)
    print(head)
    rates = {}
    for name in FORMS:
        rates[name] = throughput(name, batches, min_time)
        print(f"{name:<18}" + "".join(f"{_fmt_rate(rates[name][c]):>11}" for c in cols), flush=True)
    print("scalar = one state as Python floats (MATH namespace); B = NumPy component arrays of length B")

    counts = {}
    for cse in (False, True) if args.cse else (False,):
        label = "with CSE" if cse else "as built"
        print(f"\nOperations per evaluation, CasADi SX instruction count ({label})")
        keys = ["add/sub", "mul", "div", "neg", "arithmetic", "sqrt", "trig", "exp/log/pow", "weighted"]
        print(f"{'form':<18}" + "".join(f"{k:>12}" for k in keys) + "  other")
        for name in FORMS:
            c = op_count(name, cse)
            counts.setdefault(label, {})[name] = c
            print(f"{name:<18}" + "".join(f"{c[k]:>12}" for k in keys) + f"  {c['other'] or '-'}")
        print(f"weighted = arithmetic + sqrt + {SIN_FLOPS} x trig (the paper's price of sin, Eq. sin(x))")

    if args.json:
        data = {
            "throughput_states_per_s": {k: {str(b): v for b, v in r.items()} for k, r in rates.items()},
            "op_counts": counts,
            "numpy": np.__version__,
        }
        write_record(args.json, data, indent=2)
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
