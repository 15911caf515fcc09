"""Legendre-Gauss-Radau (LGR) points, weights, differentiation and integration matrices.

On the reference interval tau in [-1, 1] the N LGR points are -1 and the N - 1
roots of P_{N-1}(tau) + P_N(tau) divided by (1 + tau) (Jacobi P^{(0,1)}_{N-1}).
The state is approximated by the Lagrange polynomial of degree N through the N
LGR points *and* the non-collocated end tau = +1; its derivative at the N LGR
points gives the N x (N + 1) differentiation matrix (Garg et al. 2010; GPOPS-II,
Patterson & Rao 2014). The N-point Radau rule integrates polynomials of degree
2N - 2 exactly.

Everything here is plain NumPy and cached per N: these matrices are built once
per degree and reused by every mesh interval.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.special import eval_legendre, roots_jacobi

MAX_DEGREE = 60  # beyond this the barycentric matrices lose digits; no mesh needs more


def _check_n(n: int) -> int:
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool):
        raise TypeError(f"the number of LGR points must be an int, got {type(n).__name__}")
    if n < 1 or n > MAX_DEGREE:
        raise ValueError(f"the number of LGR points must be in [1, {MAX_DEGREE}], got {n}")
    return int(n)


@lru_cache(maxsize=None)
def _lgr(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n == 1:
        return np.array([-1.0]), np.array([2.0])
    interior, _ = roots_jacobi(n - 1, 0.0, 1.0)
    tau = np.concatenate([[-1.0], np.sort(interior)])
    w = np.empty(n)
    w[0] = 2.0 / n**2
    p = eval_legendre(n - 1, tau[1:])
    w[1:] = (1.0 - tau[1:]) / (n**2 * p**2)
    return tau, w


def lgr_points(n: int) -> np.ndarray:
    """The ``n`` LGR points on [-1, 1), ascending, the first at -1."""
    return _lgr(_check_n(n))[0].copy()


def lgr_weights(n: int) -> np.ndarray:
    """Quadrature weights of the ``n``-point LGR rule (exact to degree 2n - 2)."""
    return _lgr(_check_n(n))[1].copy()


def barycentric_weights(s: np.ndarray) -> np.ndarray:
    """Barycentric weights 1 / prod_{k != j} (s_j - s_k) of distinct support points ``s``."""
    s = np.asarray(s, dtype=float)
    diff = s[:, None] - s[None, :]
    np.fill_diagonal(diff, 1.0)
    if np.any(diff == 0.0):
        raise ValueError("interpolation support points must be distinct")
    # scale rows to avoid overflow for large n; only ratios matter
    return 1.0 / np.prod(diff * (2.0 / max(np.ptp(s), 1e-300)), axis=1)


def support_points(n: int) -> np.ndarray:
    """The state-approximation support: the ``n`` LGR points and +1."""
    return np.append(lgr_points(n), 1.0)


@lru_cache(maxsize=None)
def _diff_matrix(n: int) -> np.ndarray:
    s = support_points(n)
    w = barycentric_weights(s)
    m = n + 1
    d = np.zeros((m, m))
    for i in range(m):
        for j in range(m):
            if i != j:
                d[i, j] = (w[j] / w[i]) / (s[i] - s[j])
        d[i, i] = -np.sum(d[i, :])
    return d[:n, :]


def differentiation_matrix(n: int) -> np.ndarray:
    """The ``n x (n + 1)`` LGR differentiation matrix.

    Row i gives the derivative at LGR point i of the degree-n polynomial through
    the values at the n LGR points and +1 (:func:`support_points`).
    """
    return _diff_matrix(_check_n(n)).copy()


@lru_cache(maxsize=None)
def _int_matrix(n: int) -> np.ndarray:
    d = _diff_matrix(n)
    # D [x0; x] = f with rows of D summing to zero gives x = x0 + D[:, 1:]^{-1} f
    return np.linalg.inv(d[:, 1:])


def integration_matrix(n: int) -> np.ndarray:
    """The ``n x n`` LGR integration matrix A.

    ``x(s_{i+1}) = x(-1) + sum_j A_ij f(tau_j)`` where s are :func:`support_points`
    and f is the derivative at the LGR points: the integral form of LGR
    collocation (equivalent to the differential form with :func:`differentiation_matrix`).
    """
    return _int_matrix(_check_n(n)).copy()


def lagrange_matrix(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Matrix ``P (len(t), len(s))`` with ``P @ y`` the interpolant through ``(s, y)`` at ``t``.

    Barycentric form of the second kind; exact at the support points.
    """
    s = np.asarray(s, dtype=float)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    w = barycentric_weights(s)
    diff = t[:, None] - s[None, :]
    exact = diff == 0.0
    diff = np.where(exact, 1.0, diff)
    k = w[None, :] / diff
    p = k / np.sum(k, axis=1, keepdims=True)
    hit = np.any(exact, axis=1)
    if np.any(hit):
        p[hit] = exact[hit].astype(float)
    return p


__all__ = [
    "MAX_DEGREE",
    "lgr_points",
    "lgr_weights",
    "barycentric_weights",
    "support_points",
    "differentiation_matrix",
    "integration_matrix",
    "lagrange_matrix",
]
