"""Euler parameters (unit quaternions): the paper's Section ``sect:Review``.

Conventions follow the paper exactly. A set ``(e1, e2, e3, eta)`` describes the
direction cosine matrix ``C_BA`` that maps components in frame A to components in
frame B (Eq. ``C_BA-Quat``); the rows of ``C_BA`` are b1, b2, b3 written in A.
Angular velocities are those of B relative to A, in B components.

Two layers:

* component functions (``dcm``, ``rates_from_omega`` ...) do plain arithmetic on
  scalars, NumPy arrays or CasADi expressions;
* array functions (``dcm_from_quaternion`` ...) take NumPy arrays whose last axis
  holds the 4 parameters (or 3 vector components) and are batched over every
  leading axis.
"""

from __future__ import annotations

import numpy as np

# ---------------------------------------------------------------------------------
# component layer (NumPy or CasADi)


def dcm(e1, e2, e3, eta):
    """Direction cosine matrix C_BA as a 3x3 tuple of rows, Eq. ``C_BA-Quat``."""
    return (
        (1 - 2 * (e2 * e2 + e3 * e3), 2 * (e1 * e2 + e3 * eta), 2 * (e1 * e3 - e2 * eta)),
        (2 * (e2 * e1 - e3 * eta), 1 - 2 * (e3 * e3 + e1 * e1), 2 * (e2 * e3 + e1 * eta)),
        (2 * (e3 * e1 + e2 * eta), 2 * (e3 * e2 - e1 * eta), 1 - 2 * (e1 * e1 + e2 * e2)),
    )


def dcm_column(e1, e2, e3, eta, j: int):
    """Column ``j`` (0-based) of C_BA, Eq. ``C_BA-Quat``: the j-th basis vector of A written in B."""
    if j == 0:
        return 1 - 2 * (e2 * e2 + e3 * e3), 2 * (e2 * e1 - e3 * eta), 2 * (e3 * e1 + e2 * eta)
    if j == 1:
        return 2 * (e1 * e2 + e3 * eta), 1 - 2 * (e3 * e3 + e1 * e1), 2 * (e3 * e2 - e1 * eta)
    if j == 2:
        return 2 * (e1 * e3 - e2 * eta), 2 * (e2 * e3 + e1 * eta), 1 - 2 * (e1 * e1 + e2 * e2)
    raise ValueError(f"column index must be 0, 1 or 2, got {j}")


def rates_from_omega(e1, e2, e3, eta, w1, w2, w3):
    """Euler-parameter rates from the angular velocity in B components, Eq. ``QuatRate``."""
    return (
        0.5 * (eta * w1 - e3 * w2 + e2 * w3),
        0.5 * (e3 * w1 + eta * w2 - e1 * w3),
        0.5 * (-e2 * w1 + e1 * w2 + eta * w3),
        -0.5 * (e1 * w1 + e2 * w2 + e3 * w3),
    )


def omega_from_rates(e1, e2, e3, eta, de1, de2, de3, deta):
    """Angular velocity (B components) from Euler parameters and rates, Eq. ``QuatRate-2-Om``."""
    return (
        2 * (eta * de1 - deta * e1 + e3 * de2 - de3 * e2),
        2 * (eta * de2 - deta * e2 - e3 * de1 + de3 * e1),
        2 * (eta * de3 - deta * e3 + e2 * de1 - de2 * e1),
    )


# ---------------------------------------------------------------------------------
# array layer (NumPy, batched over leading axes)


def _as_last(x, n: int, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] != n:
        raise ValueError(f"{name} must have {n} components on its last axis, got shape {x.shape}")
    return x


def dcm_from_quaternion(q) -> np.ndarray:
    """C_BA for Euler parameters ``q[..., 4]`` as an array of shape ``(..., 3, 3)``."""
    q = _as_last(q, 4, "q")
    rows = dcm(q[..., 0], q[..., 1], q[..., 2], q[..., 3])
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def quaternion_rates(q, omega) -> np.ndarray:
    """Euler-parameter rates ``(..., 4)`` from ``q (..., 4)`` and ``omega (..., 3)``, Eq. ``QuatRate``."""
    q = _as_last(q, 4, "q")
    omega = _as_last(omega, 3, "omega")
    return np.stack(rates_from_omega(*np.moveaxis(q, -1, 0), *np.moveaxis(omega, -1, 0)), axis=-1)


def omega_from_quaternion_rates(q, q_dot) -> np.ndarray:
    """Angular velocity ``(..., 3)`` from ``q`` and its rate ``q_dot``, Eq. ``QuatRate-2-Om``."""
    q = _as_last(q, 4, "q")
    q_dot = _as_last(q_dot, 4, "q_dot")
    return np.stack(omega_from_rates(*np.moveaxis(q, -1, 0), *np.moveaxis(q_dot, -1, 0)), axis=-1)


def normalize(q) -> np.ndarray:
    """Scale Euler parameters to unit norm; raises on a zero or non-finite set."""
    q = _as_last(q, 4, "q")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    bad = ~np.isfinite(norm) | (norm < 1e-12)
    if np.any(bad):
        raise ValueError(
            "cannot normalize Euler parameters with zero or non-finite norm "
            f"(at index {np.argwhere(bad[..., 0])[0].tolist()})"
        )
    return q / norm


def quaternion_from_dcm(c) -> np.ndarray:
    """Euler parameters ``(..., 4)`` of a rotation matrix C_BA ``(..., 3, 3)``.

    Shepperd's method: the largest of eta^2, e1^2, e2^2, e3^2 is taken from the
    trace, the others from the off-diagonal sums and differences, so the result
    is accurate for every rotation. The sign is fixed so that eta >= 0.
    """
    c = np.asarray(c, dtype=float)
    if c.shape[-2:] != (3, 3):
        raise ValueError(f"a DCM must have shape (..., 3, 3), got {c.shape}")
    tr = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    # 4 * (square of each parameter), from the diagonal
    sq4 = np.stack(
        [1 + 2 * c[..., 0, 0] - tr, 1 + 2 * c[..., 1, 1] - tr, 1 + 2 * c[..., 2, 2] - tr, 1 + tr],
        axis=-1,
    )
    d1 = c[..., 1, 2] - c[..., 2, 1]  # 4 e1 eta
    d2 = c[..., 2, 0] - c[..., 0, 2]  # 4 e2 eta
    d3 = c[..., 0, 1] - c[..., 1, 0]  # 4 e3 eta
    s12 = c[..., 0, 1] + c[..., 1, 0]  # 4 e1 e2
    s13 = c[..., 0, 2] + c[..., 2, 0]  # 4 e1 e3
    s23 = c[..., 1, 2] + c[..., 2, 1]  # 4 e2 e3
    k = np.argmax(sq4, axis=-1)
    sq_k = np.maximum(np.take_along_axis(sq4, k[..., None], -1)[..., 0], 0.0)  # 4 p_k^2
    big = 2 * np.sqrt(sq_k)  # 4 |p_k|; every row of cand is 4 p_k (e1, e2, e3, eta)
    q = np.empty(c.shape[:-2] + (4,))
    cand = [
        (sq_k, s12, s13, d1),  # k = 0: e1 largest
        (s12, sq_k, s23, d2),  # k = 1
        (s13, s23, sq_k, d3),  # k = 2
        (d1, d2, d3, sq_k),  # k = 3: eta largest
    ]
    for i, cols in enumerate(cand):
        mask = k == i
        if np.any(mask):
            q[mask] = np.stack([col[mask] for col in cols], axis=-1) / big[mask][..., None]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)


__all__ = [
    "dcm",
    "dcm_column",
    "rates_from_omega",
    "omega_from_rates",
    "dcm_from_quaternion",
    "quaternion_rates",
    "omega_from_quaternion_rates",
    "normalize",
    "quaternion_from_dcm",
]
