"""The singularity study: Example 2 posed in spherical coordinates.

States ``r, lon, lat, v, gamma, psi, alpha, mu`` (psi the azimuth from north
toward east, mu the *conventional* bank angle: 0 lift up, positive to the right),
controls ``u_alpha, u_mu``. Rotating spherical Earth, point-mass gravity (Vinh,
Busemann & Culp, *Hypersonic and Planetary Entry Flight Mechanics*, 1980, Ch. 2)::

    dr/dt     = v sin(gamma)
    dlon/dt   = v cos(gamma) sin(psi) / (r cos(lat))
    dlat/dt   = v cos(gamma) cos(psi) / r
    dv/dt     = -D/m - g sin(gamma) + w^2 r cos(lat) (sin(gamma) cos(lat) - cos(gamma) sin(lat) cos(psi))
    dgamma/dt = [L cos(mu)/m - g cos(gamma) + v^2 cos(gamma)/r + 2 w v cos(lat) sin(psi)
                 + w^2 r cos(lat) (cos(gamma) cos(lat) + sin(gamma) sin(lat) cos(psi))] / v
    dpsi/dt   = L sin(mu) / (m v cos(gamma)) + v cos(gamma) sin(psi) tan(lat) / r
                - 2 w (tan(gamma) cos(psi) cos(lat) - sin(lat))
                + w^2 r sin(psi) sin(lat) cos(lat) / (v cos(gamma))          (Eq. Ex2-azidot)

The azimuth equation divides by cos(gamma): it is undefined in vertical flight,
which is exactly the terminal condition gamma(tf) = -90 deg of Example 2.

The bank angle differs from the paper's sigma (docs/conventions.md): sigma = mu + theta_u,
theta_u the angle of "lift up" in the no-twist B frame. theta_u turns at a rate
of about -tan(gamma) times the lateral acceleration over v, so the two bank rates
(and the u_sigma and u_mu cost terms) differ where the flight is steep and the
lift has a lateral part; elsewhere they agree. The force model (atmosphere,
aerodynamics, planet) is the same :class:`~rventry_env.physics.model.EntryModel`
parts as the rv-Euler problem; only the kinematics are re-written here, since
they are what the study compares.
"""

from __future__ import annotations

import math

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.core.backend import NUMPY, casadi_ns
from rventry_env.physics.gravity import PointMassGravity
from rventry_env.reference.collocation.ocp import (
    EndpointConstraint,
    OptimalControlProblem,
    PathConstraint,
)
from rventry_env.reference.entry_ocp import DEG, EntryOcpConfig

STATE_NAMES = ("r", "lon", "lat", "v", "gamma", "psi", "alpha", "mu")
CONTROL_NAMES = ("u_alpha", "u_mu")


def _check_model(config: EntryOcpConfig) -> None:
    model = config.model
    if model.wind is not None:
        raise ValueError("the spherical study supports still air only (model.wind must be None)")
    if not isinstance(model.gravity, PointMassGravity):
        raise ValueError("the spherical study supports point-mass gravity only")


def aero_accelerations(x, model, ns=NUMPY):
    """(L/m, D/m, q) from the spherical state (SI)."""
    r, v, alpha = x[0], x[3], x[6]
    h = r - model.planet.radius
    rho = model.atmosphere.density(h, ns)
    q = 0.5 * rho * v * v
    mach = v / model.atmosphere.speed_of_sound(h, ns)
    cl, cd = model.vehicle.aerodynamics.coefficients(alpha, mach, ns)
    k = model.vehicle.reference_area / model.vehicle.mass
    return q * k * cl, q * k * cd, q


def spherical_rhs(x, u, model, ns=NUMPY):
    """The eight derivatives (module docstring) on components (NumPy or CasADi)."""
    r, _, lat, v, gamma, psi, _, mu = x
    lift, drag, _ = aero_accelerations(x, model, ns)
    w = model.planet.omega
    g = model.gravity.mu / (r * r)
    sg, cg = ns.sin(gamma), ns.cos(gamma)
    sp, cp = ns.sin(psi), ns.cos(psi)
    sl, cl = ns.sin(lat), ns.cos(lat)
    sm, cm = ns.sin(mu), ns.cos(mu)
    return (
        v * sg,
        v * cg * sp / (r * cl),
        v * cg * cp / r,
        -drag - g * sg + w * w * r * cl * (sg * cl - cg * sl * cp),
        (lift * cm - g * cg + v * v * cg / r + 2 * w * v * cl * sp
         + w * w * r * cl * (cg * cl + sg * sl * cp)) / v,
        lift * sm / (v * cg) + v * cg * sp * sl / (r * cl) - 2 * w * (sg / cg * cp * cl - sl)
        + w * w * r * sp * sl * cl / (v * cg),
        u[0],
        u[1],
    )  # fmt: skip


def _spherical_boundary(config: EntryOcpConfig, final_gamma_deg: float, relaxed: bool):
    """The initial and final state bounds of Table tab:Ex2-BCs in spherical coordinates, and the
    final flight-path angle: a final-state bound, or an endpoint inequality when ``relaxed``.

    :return: ``(initial_lower, initial_upper, final_lower, final_upper, endpoint_constraints)``.
    """
    re = config.model.planet.radius
    # the rv-Euler initial state of Table tab:Ex2-BCs is horizontal flight due east at (0, 0)
    x0 = np.array([re + config.problem.initial_altitude, 0.0, 0.0, config.problem.initial_speed, 0.0, 90 * DEG, 0.0, 0.0])
    init_lo, init_hi = x0.copy(), x0.copy()
    init_lo[6:8] = (0.0, -4 * math.pi)
    init_hi[6:8] = (config.alpha_max, 4 * math.pi)
    fin_lo = np.full(8, -math.inf)
    fin_hi = np.full(8, math.inf)
    fin_lo[0] = fin_hi[0] = re + config.problem.final_altitude
    fin_lo[1] = fin_hi[1] = config.problem.target_longitude
    fin_lo[2] = fin_hi[2] = config.problem.target_latitude
    fin_lo[3] = fin_hi[3] = config.problem.final_speed
    fin_lo[6] = fin_hi[6] = config.problem.final_alpha
    endpoint = []
    if relaxed:
        limit = final_gamma_deg * DEG
        endpoint.append(EndpointConstraint("final_gamma", lambda a, b, t0, tf: b[4], upper=limit))
    else:
        fin_lo[4] = fin_hi[4] = final_gamma_deg * DEG
    return init_lo, init_hi, fin_lo, fin_hi, endpoint


def spherical_problem(config: EntryOcpConfig | None = None, final_gamma_deg: float | None = -90.0,
                      relaxed: bool = False) -> OptimalControlProblem:  # fmt: skip
    """Example 2 in spherical coordinates.

    :param config: the same constants as the rv-Euler problem.
    :param final_gamma_deg: the terminal flight-path angle (deg).
    :param relaxed: impose gamma(tf) <= final_gamma_deg (an inequality) instead of equality.
    """
    config = config or EntryOcpConfig()
    _check_model(config)
    if final_gamma_deg is None or not -90.0 <= final_gamma_deg < 0.0:
        raise ValueError(f"final_gamma_deg must lie in [-90, 0), got {final_gamma_deg}")
    ns = casadi_ns()
    model = config.model
    re = model.planet.radius
    uam, usm = config.u_alpha_max, config.u_sigma_max

    def lagrange(x, u, t):
        return config.problem.cost_integrand(x[6], u[0], u[1])

    def aero_norm(x, u, t):
        lift, drag, _ = aero_accelerations(x, model, ns)
        return ns.sqrt(lift * lift + drag * drag)

    path = [
        PathConstraint("aero_accel", aero_norm, upper=config.a_max, scale=config.a_max),
        PathConstraint("dynamic_pressure", lambda x, u, t: aero_accelerations(x, model, ns)[2],
                       lower=config.problem.q_min, scale=1e5),
    ]  # fmt: skip
    init_lo, init_hi, fin_lo, fin_hi, endpoint = _spherical_boundary(config, final_gamma_deg, relaxed)
    return OptimalControlProblem(
        name=f"spherical-entry-gamma{final_gamma_deg:g}{'-relaxed' if relaxed else ''}",
        state_names=STATE_NAMES,
        control_names=CONTROL_NAMES,
        dynamics=lambda x, u, t: spherical_rhs(x, u, model, ns),
        state_lower=[re - 1.0, -math.pi, -80 * DEG, 50.0, -90 * DEG, -4 * math.pi, 0.0, -4 * math.pi],
        state_upper=[re + 150e3, math.pi, 80 * DEG, 8000.0, 90 * DEG, 4 * math.pi, config.alpha_max,
                     4 * math.pi],
        control_lower=[-uam, -usm],
        control_upper=[uam, usm],
        initial_lower=init_lo,
        initial_upper=init_hi,
        final_lower=fin_lo,
        final_upper=fin_hi,
        tf_lower=config.tf_bounds[0],
        tf_upper=config.tf_bounds[1],
        lagrange=lagrange,
        path_constraints=path,
        endpoint_constraints=endpoint,
        state_scale=[1e5, 1, 1, 1e4, 1, 1, 0.5, math.pi],
        state_shift=[re, 0, 0, 0, 0, 0, 0, 0],
        control_scale=[uam, usm],
        control_shift=[0.0, 0.0],
        time_scale=500.0,
        cost_scale=10.0,
    )


def spherical_from_entry_states(x: np.ndarray) -> np.ndarray:
    """Spherical states (8) from rv-Euler entry states (12), mu = conventional bank.

    Where the azimuth (vertical flight) or the bank is undefined the value of the
    nearest defined sample is used, so a vertical final point stays finite.
    """
    from rventry_env.core.conversions import lift_up_angle, spherical_from_rv_euler, wrap_angle

    x = np.asarray(x, dtype=float)
    sph = spherical_from_rv_euler(x[:, :10], on_singular="nan", tol=1e-7)
    theta_u, n2 = lift_up_angle(np.moveaxis(x[:, IDX.e_b], -1, 0))
    mu = np.where(n2 > 1e-14, wrap_angle(x[:, IDX.sigma] - theta_u), np.nan)
    out = np.column_stack([sph, x[:, IDX.alpha], mu])
    for j in (5, 7):  # azimuth and bank: fill undefined samples from the last defined one
        col = out[:, j]
        good = np.isfinite(col)
        if not good.all():
            idx = np.where(good, np.arange(col.size), 0)
            np.maximum.accumulate(idx, out=idx)
            out[:, j] = col[idx]
        out[:, j] = np.unwrap(out[:, j])
    return out


__all__ = [
    "STATE_NAMES",
    "CONTROL_NAMES",
    "aero_accelerations",
    "spherical_rhs",
    "spherical_problem",
    "spherical_from_entry_states",
]


def spherical_guess_from_reference(reference, config: EntryOcpConfig | None = None):
    """The rv-Euler reference, converted, as a guess for the spherical problem.

    Controls: u_alpha as is; u_mu = d(mu)/dt by differentiating the converted bank
    angle (it differs from u_sigma by the turn rate of the lift-up direction).
    """
    from rventry_env.reference.collocation import SampledGuess

    t = np.asarray(reference.t, dtype=float)
    s = spherical_from_entry_states(reference.x)
    u_mu = np.gradient(s[:, 7], t)
    return SampledGuess(t, s, np.column_stack([reference.u[:, 0], u_mu]))


def solve_spherical(final_gamma_deg: float, guess, config: EntryOcpConfig | None = None, mesh=None,
                    options=None, progress=None, relaxed: bool = False) -> dict:  # fmt: skip
    """Solve the spherical problem with gamma(tf) = ``final_gamma_deg`` and report what happened.

    :return: a dict with the NLP status, success, J, tf, mesh error, passes, wall
        time, whether non-finite values appeared, and the final flight-path angle.
    """
    import time

    from rventry_env.reference.collocation.mesh import Mesh
    from rventry_env.reference.collocation import SolverOptions, solve

    config = config or EntryOcpConfig()
    prob = spherical_problem(config, final_gamma_deg, relaxed=relaxed)
    options = options or SolverOptions(max_mesh_iterations=8)
    mesh = mesh or Mesh.uniform(40, 6)
    start = time.perf_counter()
    try:
        res = solve(prob, guess, mesh, options, progress=progress, label=f"[{final_gamma_deg:g}]")
    except (RuntimeError, ValueError) as exc:  # CasADi raises on non-finite evaluations in some paths
        return {"final_gamma_deg": final_gamma_deg, "status": f"error: {exc}", "success": False,
                "time_s": time.perf_counter() - start}  # fmt: skip
    sol = res.solution
    finite = bool(np.all(np.isfinite(sol.x)) and np.all(np.isfinite(sol.u)))
    return {
        "final_gamma_deg": final_gamma_deg,
        "relaxed": relaxed,
        "status": sol.status,
        "success": bool(sol.success),
        "converged": bool(res.converged),
        "cost": sol.cost,
        "tf_s": sol.tf,
        "mesh_error": sol.max_error,
        "n_nodes": sol.mesh.n_nodes,
        "passes": len(res.records),
        "nlp_iterations": [r.nlp_iterations for r in res.records],
        "finite": finite,
        "gamma_tf_deg": float(sol.x[-1, 4] / DEG),
        "max_abs_psi_rate_deg_s": float(np.max(np.abs(np.gradient(sol.x[:, 5], sol.t))) / DEG),
        "time_s": time.perf_counter() - start,
    }


__all__ += ["spherical_guess_from_reference", "solve_spherical"]
