"""The rv-Euler equations of motion (the paper's Section ``sect:Derivation1``).

State (10 components): ``r, eA1, eA2, eA3, etaA, v, eB1, eB2, eB3, etaB``.

* r, v: distance from the origin O and speed relative to the observation frame E;
* eA: Euler parameters of C_AE (frame A has a1 along r, omega_A1 = 0);
* eB: Euler parameters of C_BA (frame B has b1 along the E-relative velocity,
  omega_B1 = 0).

E rotates relative to the inertial frame N with angular velocity ``omega_e`` and
angular acceleration ``alpha_e`` (both in E components). The applied force enters
as the specific force (force per unit mass) in B components.

All functions here are pure arithmetic on components and take the non-arithmetic
operations from a namespace (see :mod:`rventry_env.core.backend`), so the same code
runs batched on NumPy arrays and on CasADi symbols.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

from rventry_env.core.backend import dot3, sparse
from rventry_env.core.euler_parameters import dcm, dcm_column

STATE_NAMES = ("r", "eA1", "eA2", "eA3", "etaA", "v", "eB1", "eB2", "eB3", "etaB")
ZERO3 = (0.0, 0.0, 0.0)


class Frames(NamedTuple):
    """Direction cosine matrices of one state, as 3x3 tuples of rows."""

    c_ae: tuple
    c_ba: tuple

    @property
    def c_be(self):
        """C_BE = C_BA C_AE."""
        return tuple(
            tuple(dot3(self.c_ba[i], (self.c_ae[0][j], self.c_ae[1][j], self.c_ae[2][j])) for j in range(3))
            for i in range(3)
        )


def frames(e_a: Sequence, e_b: Sequence) -> Frames:
    """C_AE and C_BA from the two Euler-parameter sets, Eqs. ``CAE-final`` and ``CBA-final``."""
    return Frames(dcm(*e_a), dcm(*e_b))


def omega_a(r, v, e_b):
    """(omega_A2, omega_A3): angular velocity of A relative to E, A components, Eq. ``kinematics-final-1``."""
    eb1, eb2, eb3, etab = e_b
    k = 2 * v / r
    return k * (etab * eb2 - eb1 * eb3), k * (etab * eb3 + eb1 * eb2)


def frame_rates_in_a(e_a, omega_e=ZERO3, alpha_e=ZERO3, c_ae=None):
    """omega_E and alpha_E (given in E components) carried into A: (C_AE omega_E, C_AE alpha_E).

    Only the columns of C_AE that meet a non-zero component are formed, so the
    planet's spin (0, 0, w) costs one column, not the whole matrix. A vector of
    literal zeros comes back as ``None`` (no such term).
    """
    out = []
    for vec in (omega_e, alpha_e):
        nz = sparse(vec)
        if not nz:
            out.append(None)
            continue
        acc = None
        for j, wj in nz:
            col = tuple(c_ae[i][j] for i in range(3)) if c_ae is not None else dcm_column(*e_a, j)
            term = tuple(ci * wj for ci in col)
            acc = term if acc is None else tuple(a + t for a, t in zip(acc, term))
        out.append(acc)
    return out[0], out[1]


def apparent_force(r, v, c_ba, accel_b, omega_e_a=None, alpha_e_a=None):
    """Apparent specific force f~/m in B components, Eq. ``F-apparent-3``.

    ``f~/m = f/m - 2 omega_E x v - alpha_E x r - omega_E x (omega_E x r)``. The
    paper writes each term with rows of C_BE = C_BA C_AE; here the frame's angular
    velocity and acceleration come already in A components (``omega_e_a = C_AE
    omega_E``, see :func:`frame_rates_in_a`), which is the same product regrouped
    and costs a third of the multiplications:

    * Coriolis 2 v [0; C_BE(3,:) w; -C_BE(2,:) w] = 2 v [0; w_B3; -w_B2], w_B = C_BA w_A;
    * Euler r C_BA [0; C_AE(3,:) alpha; -C_AE(2,:) alpha] = r C_BA [0; alpha_A3; -alpha_A2];
    * centrifugal r C_BE (w w^T - |w|^2 I) C_EA(:,1) = r C_BA (w_A w_A1 - |w|^2 e_1).

    ``accel_b`` is the applied f/m in B components; ``None`` for a frame rate means
    the frame does not rotate (or accelerate).
    """
    f1, f2, f3 = accel_b
    if omega_e_a is None and alpha_e_a is None:
        return f1, f2, f3
    # specific-force terms in A components, gathered before one C_BA product
    t1, t2, t3 = 0.0, 0.0, 0.0
    if omega_e_a is not None:
        w_a = omega_e_a
        w_sq = dot3(w_a, w_a)
        # -(w x (w x r)) = r (|w|^2 a1 - w_A w_A1), A components
        t1 = r * (w_sq - w_a[0] * w_a[0])
        t2 = -r * w_a[1] * w_a[0]
        t3 = -r * w_a[2] * w_a[0]
        w_b2 = dot3(c_ba[1], w_a)
        w_b3 = dot3(c_ba[2], w_a)
        f2 = f2 - 2 * v * w_b3
        f3 = f3 + 2 * v * w_b2
    if alpha_e_a is not None:
        t2 = t2 - r * alpha_e_a[2]
        t3 = t3 + r * alpha_e_a[1]
    t = (t1, t2, t3)
    return f1 + dot3(c_ba[0], t), f2 + dot3(c_ba[1], t), f3 + dot3(c_ba[2], t)


def omega_b(v, e_b, w_a2, w_a3, apparent_b):
    """(omega_B2, omega_B3): angular velocity of B relative to A, B components, Eq. ``dynamics-final-1``."""
    eb1, eb2, eb3, etab = e_b
    _, ft2, ft3 = apparent_b
    w_b2 = -ft3 / v - w_a2 * (1 - 2 * (eb1 * eb1 + eb3 * eb3)) - 2 * w_a3 * (eb2 * eb3 + eb1 * etab)
    w_b3 = ft2 / v - 2 * w_a2 * (eb2 * eb3 - eb1 * etab) - w_a3 * (1 - 2 * (eb1 * eb1 + eb2 * eb2))
    return w_b2, w_b3


def _no_twist_rates(e, w2, w3):
    """Euler-parameter rates with omega_1 = 0, Eqs. ``kinematics-final-2`` / ``dynamics-final-2``."""
    e1, e2, e3, eta = e
    return (
        0.5 * (w3 * e2 - w2 * e3),
        0.5 * (w2 * eta - w3 * e1),
        0.5 * (w2 * e1 + w3 * eta),
        -0.5 * (w2 * e2 + w3 * e3),
    )


class RvEulerRates(NamedTuple):
    """Time derivatives of the 10 rv-Euler parameters, plus the frame rates behind them."""

    r_dot: object
    e_a_dot: tuple
    v_dot: object
    e_b_dot: tuple
    omega_a: tuple  # (w_A2, w_A3)
    omega_b: tuple  # (w_B2, w_B3)

    def as_tuple(self):
        return (self.r_dot, *self.e_a_dot, self.v_dot, *self.e_b_dot)


def radial_rate(v, e_b):
    """dr/dt, Eq. kinematics-final-1: v (1 - 2 (eB2^2 + eB3^2)), from the state alone."""
    return v * (1 - 2 * (e_b[1] * e_b[1] + e_b[2] * e_b[2]))


def rv_euler_rates(
    r, e_a, v, e_b, accel_b, omega_e=ZERO3, alpha_e=ZERO3, c_ae=None, c_ba=None, omega_e_a=None, alpha_e_a=None
):
    """Derivatives of the rv-Euler parameters for an applied specific force.

    :param r: distance from O (m).
    :param e_a: (eA1, eA2, eA3, etaA).
    :param v: speed relative to E (m/s).
    :param e_b: (eB1, eB2, eB3, etaB).
    :param accel_b: applied force per unit mass in B components (m/s^2).
    :param omega_e: angular velocity of E relative to N, E components (rad/s).
    :param alpha_e: angular acceleration of E relative to N, E components (rad/s^2).
    :param c_ae: C_AE if the caller already has it (saves work).
    :param c_ba: C_BA if the caller already has it.
    :param omega_e_a: omega_E already in A components (then ``omega_e`` is ignored);
        pass it with ``alpha_e_a`` (``None`` for "no such term").
    :param alpha_e_a: alpha_E already in A components, or ``None``.
    :return: :class:`RvEulerRates`.
    """
    if omega_e_a is None and alpha_e_a is None:
        omega_e_a, alpha_e_a = frame_rates_in_a(e_a, omega_e, alpha_e, c_ae)
    if c_ba is None:
        c_ba = dcm(*e_b)
    # kinematics, Eq. kinematics-final-1 / -2 (omega_A1 = 0)
    r_dot = radial_rate(v, e_b)
    w_a2, w_a3 = omega_a(r, v, e_b)
    e_a_dot = _no_twist_rates(e_a, w_a2, w_a3)
    # kinetics, Eqs. F-apparent-3, dynamics-final-1 / -2 (omega_B1 = 0)
    ft = apparent_force(r, v, c_ba, accel_b, omega_e_a, alpha_e_a)
    w_b2, w_b3 = omega_b(v, e_b, w_a2, w_a3, ft)
    e_b_dot = _no_twist_rates(e_b, w_b2, w_b3)
    return RvEulerRates(r_dot, e_a_dot, ft[0], e_b_dot, (w_a2, w_a3), (w_b2, w_b3))


def rv_euler_rhs(x: Sequence, accel_b, omega_e=ZERO3, alpha_e=ZERO3):
    """The 10 derivatives of the state components ``x`` (a sequence of 10) as a tuple."""
    return rv_euler_rates(x[0], tuple(x[1:5]), x[5], tuple(x[6:10]), accel_b, omega_e, alpha_e).as_tuple()


def gravity_two_body_b(r, c_ba, mu):
    """Point-mass gravity as specific force in B: -mu/r^2 C_BA(:, 1) (Eq. ``Ex2-EOM-Ftot``)."""
    g = -mu / (r * r)
    return g * c_ba[0][0], g * c_ba[1][0], g * c_ba[2][0]


def two_body_rhs(x: Sequence, mu: float):
    """Example 1: the two-body problem in rv-Euler parameters (Eqs. ``Ex1-EOM-rvEuler``)."""
    e_b = tuple(x[6:10])
    c_ba = dcm(*e_b)
    accel = gravity_two_body_b(x[0], c_ba, mu)  # E = N here: no apparent-force terms
    return rv_euler_rates(x[0], tuple(x[1:5]), x[5], e_b, accel, c_ba=c_ba).as_tuple()


def cartesian_acceleration(x: Sequence, rates: RvEulerRates):
    """E-relative acceleration in E components implied by rv-Euler rates.

    d/dt(v b1) seen in E = v_dot b1 + v (omega_EB x b1), with omega_EB = omega_EA + omega_AB.
    Used to cross-check the rv-Euler equations against Newton's law in Cartesian form.
    """
    fr = frames(x[1:5], x[6:10])
    c_be = fr.c_be
    v = x[5]
    w_a2, w_a3 = rates.omega_a
    w_b2, w_b3 = rates.omega_b
    # omega_EA in B components: C_BA [0, w_A2, w_A3]
    c_ba = fr.c_ba
    w_eb = tuple(c_ba[i][1] * w_a2 + c_ba[i][2] * w_a3 for i in range(3))
    w_eb = (w_eb[0], w_eb[1] + w_b2, w_eb[2] + w_b3)
    # a_B = v_dot b1 + v (w x b1) = [v_dot, v w3, -v w2]
    a_b = (rates.v_dot, v * w_eb[2], -v * w_eb[1])
    return tuple(dot3((c_be[0][j], c_be[1][j], c_be[2][j]), a_b) for j in range(3))


__all__ = [
    "STATE_NAMES",
    "Frames",
    "frames",
    "omega_a",
    "radial_rate",
    "frame_rates_in_a",
    "apparent_force",
    "omega_b",
    "RvEulerRates",
    "rv_euler_rates",
    "rv_euler_rhs",
    "gravity_two_body_b",
    "two_body_rhs",
    "cartesian_acceleration",
]
