"""LGR transcription of a problem on one mesh to an NLP, and its solution by IPOPT through CasADi.

Transcription (Garg et al. 2010; GPOPS-II, Patterson & Rao 2014), differential
form: with the node layout of :class:`~.mesh.Mesh`, on interval k

    D_k X_k = (tf - t0) (b_k - a_k) / 2 * f(X_j, U_j, t_j),  j the interval's LGR points,

the Lagrange cost is the Radau quadrature of the running cost, and path
constraints hold at the collocation points. The whole NLP is one CasADi ``SX``
graph, so IPOPT gets exact first and second derivatives by automatic
differentiation (``hessian_approximation = exact``).

Scaling: every NLP variable is ``(value - shift) / scale`` with the problem's
state and control scales, tf is divided by ``time_scale``; each defect row is
divided by its state's scale (it then reads "scaled state change per unit
normalised time"), path and endpoint constraints by their own scales, the cost
by ``cost_scale``. IPOPT's own gradient-based scaling stays on top.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rventry_env.reference.collocation.compiled import CompiledProblem
from rventry_env.reference.collocation.guesses import TrajectoryLike
from rventry_env.reference.collocation.lgr import differentiation_matrix, lgr_weights
from rventry_env.reference.collocation.mesh import Mesh
from rventry_env.reference.collocation.ocp import OptimalControlProblem
from rventry_env.reference.collocation.solution import CollocationSolution


@dataclass
class Transcription:
    """The NLP of one problem on one mesh, with its packing helpers."""

    cp: CompiledProblem
    mesh: Mesh
    solver: Any
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    g_groups: dict  # name -> slice into g
    build_time_s: float

    @property
    def problem(self) -> OptimalControlProblem:
        return self.cp.problem

    def pack(self, x: np.ndarray, u: np.ndarray, tf: float) -> np.ndarray:
        """Scaled decision vector from ``x (n_nodes, n_x)``, ``u (n_col, n_u)`` and tf."""
        p = self.problem
        xs = (x - p.state_shift) / p.state_scale
        us = (u - p.control_shift) / p.control_scale
        parts = [xs.ravel(), us.ravel()]
        if p.free_final_time:
            parts.append(np.full(self.mesh.n_nodes, tf / p.time_scale))
        return np.concatenate(parts)

    def bounds_with_initial_state(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Variable bounds (scaled) with the first node fixed at ``x0`` (a re-solve from a new state)."""
        p = self.problem
        x0s = (np.asarray(x0, dtype=float) - p.state_shift) / p.state_scale
        lbx, ubx = self.lbx.copy(), self.ubx.copy()
        lbx[: p.n_x] = ubx[: p.n_x] = x0s
        return lbx, ubx

    def unpack(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Inverse of :meth:`pack`."""
        p, m = self.problem, self.mesh
        z = np.asarray(z, dtype=float).ravel()
        nxz = m.n_nodes * p.n_x
        nuz = m.n_collocation * p.n_u
        x = z[:nxz].reshape(m.n_nodes, p.n_x) * p.state_scale + p.state_shift
        u = z[nxz : nxz + nuz].reshape(m.n_collocation, p.n_u) * p.control_scale + p.control_shift
        tf = float(z[-1] * p.time_scale) if p.free_final_time else float(p.tf_lower)
        return x, u, tf


def _block_matrices(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Global D (n_col x n_nodes, sparse), per-column interval length and weight, node times s."""
    import scipy.sparse as sp

    rows, cols, vals = [], [], []
    h = np.empty(mesh.n_collocation)
    w = np.empty(mesh.n_collocation)
    for k, (n, off) in enumerate(zip(mesh.degrees, mesh.offsets)):
        n, off = int(n), int(off)
        d = differentiation_matrix(n)
        r, c = np.nonzero(np.ones_like(d))
        rows.append(off + r)
        cols.append(off + c)
        vals.append(d[r, c])
        h[off : off + n] = mesh.breaks[k + 1] - mesh.breaks[k]
        w[off : off + n] = lgr_weights(n)
    big = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(mesh.n_collocation, mesh.n_nodes),
    )
    return big, h, w, mesh.nodes()


def _dm_sparse(m):
    import casadi as ca

    m = m.tocsc()
    sp = ca.Sparsity(m.shape[0], m.shape[1], m.indptr.tolist(), m.indices.tolist())
    return ca.DM(sp, m.data.tolist())


# A refined mesh starts from the previous solution, which is optimal to within the
# error estimate: start the barrier small and do not push the point off its bounds.
WARM_START_IPOPT = {
    "mu_init": 1e-6,
    "warm_start_init_point": "yes",
    "warm_start_bound_push": 1e-9,
    "warm_start_bound_frac": 1e-9,
    "warm_start_slack_bound_push": 1e-9,
    "warm_start_slack_bound_frac": 1e-9,
    "warm_start_mult_bound_push": 1e-9,
}


@dataclass
class SolverOptions:
    """Options of the hp loop and of IPOPT.

    :param mesh_tolerance: target max relative error per interval.
    :param max_mesh_iterations: mesh passes before giving up.
    :param n_min: LGR points of a new subinterval (ph rule).
    :param n_max: LGR points beyond which an interval is split.
    :param nlp_tolerance: IPOPT ``tol``.
    :param max_nlp_iterations: IPOPT ``max_iter`` per pass.
    :param ipopt: extra IPOPT options (``{"mu_strategy": "adaptive"}``, ...).
    :param print_ipopt: show IPOPT's own iteration log.
    :param refine_after_failure: whether to refine the mesh after an NLP failure
        (GPOPS-II does; off by default because the error estimate of a failed
        NLP point is meaningless).
    :param warm_ipopt: IPOPT options for the passes after the first, which start
        from the previous mesh's solution: a small initial barrier parameter and
        tiny bound pushes keep IPOPT from walking away from a nearly optimal point.
        A warm-started pass that IPOPT fails is solved again with the cold options
        (Betts' shuttle at mesh tolerance 1e-7: a warm second pass from a point with
        error 2.5e-3 is declared infeasible after 351 iterations; cold, it succeeds).
    :param warm_start_error: use ``warm_ipopt`` only when the previous pass's max
        error is below this (a coarse solution is not "nearly optimal").
    :param graph: ``"mx"`` (default) evaluates the node functions through
        ``Function.map``, so building the NLP and its exact Hessian costs the same
        for any mesh size; ``"sx"`` inlines everything into one scalar graph
        (faster evaluations, slower to build).
    """

    mesh_tolerance: float = 1e-6
    max_mesh_iterations: int = 10
    n_min: int = 4
    n_max: int = 10
    nlp_tolerance: float = 1e-9
    max_nlp_iterations: int = 3000
    ipopt: dict = field(default_factory=dict)
    print_ipopt: bool = False
    refine_after_failure: bool = False
    graph: str = "mx"
    warm_ipopt: dict = field(default_factory=lambda: dict(WARM_START_IPOPT))
    warm_start_error: float = 1e-2

    def __post_init__(self):
        if self.graph not in ("mx", "sx"):
            raise ValueError(f"graph must be 'mx' or 'sx', got {self.graph!r}")
        if not self.mesh_tolerance > 0:
            raise ValueError(f"mesh_tolerance must be positive, got {self.mesh_tolerance}")
        if self.max_mesh_iterations < 1:
            raise ValueError(f"max_mesh_iterations must be >= 1, got {self.max_mesh_iterations}")
        if not 1 <= self.n_min <= self.n_max:
            raise ValueError(f"need 1 <= n_min <= n_max, got {self.n_min}, {self.n_max}")
        if not self.nlp_tolerance > 0:
            raise ValueError(f"nlp_tolerance must be positive, got {self.nlp_tolerance}")


def _nlp_variables(sym, p, nn: int, nc: int):
    """The NLP's decision variables, scaled: the states at every node, the controls at every
    collocation point and, with a free final time, one copy of tf per node.

    :return: ``(xs, us, tfs, zs, tf_nodes)``: the state and control matrices (column = node),
        the tf copies (``None`` for a fixed final time), the vectors stacked into the NLP's
        ``x`` and the final time at every node, unscaled.
    """
    import casadi as ca

    nx, nu = p.n_x, p.n_u
    xs = sym.sym("X", nx, nn)  # scaled, column = node
    us = sym.sym("U", nu, nc)
    zs = [ca.vec(xs), ca.vec(us)]  # column-major vec = node-major, matching pack()
    tfs = None
    if p.free_final_time:
        # one copy of tf per node, chained by equalities: a single tf variable would
        # couple every defect and make the KKT matrix's tf row and column dense
        # (twice the factorisation time, and many more colours for the MX Hessian)
        tfs = sym.sym("tf", 1, nn)
        zs.append(ca.vec(tfs))
        tf_nodes = tfs * p.time_scale
    else:
        tf_nodes = ca.repmat(sym(p.tf_lower), 1, nn)
    return xs, us, tfs, zs, tf_nodes


def _nlp_constraints(cp: CompiledProblem, xs, tfs, tf, c_sc, defect, nn: int, nc: int):
    """The NLP's constraint rows, in order: the defects, the links of the tf copies, the path
    constraints, the invariants and the endpoint constraints (scaled).

    :return: ``(g, lbg, ubg, groups)``: the rows and their bounds as lists of blocks, and each
        group's slice of the rows.
    """
    import casadi as ca

    p = cp.problem
    nx = p.n_x
    g = [ca.vec(defect)]
    groups = {"defects": slice(0, nx * nc)}
    lbg = [np.zeros(nx * nc)]
    ubg = [np.zeros(nx * nc)]
    pos = nx * nc

    def add(name, expr, lo, hi):
        nonlocal pos
        n = expr.numel()
        if n == 0:
            return
        g.append(ca.vec(expr))
        lbg.append(np.asarray(lo, dtype=float).ravel())
        ubg.append(np.asarray(hi, dtype=float).ravel())
        groups[name] = slice(pos, pos + n)
        pos += n

    if p.free_final_time:
        add("time_links", (tfs[0, 1:] - tfs[0, : nn - 1]), np.zeros(nn - 1), np.zeros(nn - 1))
    n_path = len(p.path_constraints)
    if n_path:
        add("path", c_sc, np.repeat((cp.path_lower / cp.path_scale)[:, None], nc, 1).T,
            np.repeat((cp.path_upper / cp.path_scale)[:, None], nc, 1).T)  # fmt: skip
    n_inv = len(p.invariants)
    if n_inv:
        gi = cp.invariant_function().map(nn - 1)(xs[:, 1:])
        add("invariants", gi, np.zeros((nn - 1, n_inv)), np.zeros((nn - 1, n_inv)))
    if p.endpoint_constraints:
        b = cp.endpoint_function()(xs[:, 0], xs[:, nn - 1], tf)
        add("endpoint", b, cp.end_lower / cp.end_scale, cp.end_upper / cp.end_scale)
    return g, lbg, ubg, groups


def _variable_bounds(p, nn: int, nc: int) -> tuple[list, list]:
    """The scaled bounds of the NLP's variables (states, controls, tf copies), as lists of blocks."""
    xl = np.tile(p.state_lower, (nn, 1))
    xu = np.tile(p.state_upper, (nn, 1))
    xl[0], xu[0] = p.initial_lower, p.initial_upper
    xl[-1], xu[-1] = p.final_lower, p.final_upper
    lbx = [((xl - p.state_shift) / p.state_scale).ravel()]
    ubx = [((xu - p.state_shift) / p.state_scale).ravel()]
    lbx.append(((np.tile(p.control_lower, (nc, 1)) - p.control_shift) / p.control_scale).ravel())
    ubx.append(((np.tile(p.control_upper, (nc, 1)) - p.control_shift) / p.control_scale).ravel())
    if p.free_final_time:
        lbx.append(np.full(nn, p.tf_lower / p.time_scale))
        ubx.append(np.full(nn, p.tf_upper / p.time_scale if math.isfinite(p.tf_upper) else math.inf))
    return lbx, ubx


def _ipopt_options(opts: SolverOptions, warm: bool) -> dict:
    """IPOPT's options: the defaults here, then the warm-start ones when ``warm``, then the user's."""
    ipopt = {
        "tol": opts.nlp_tolerance,
        "max_iter": opts.max_nlp_iterations,
        "print_level": 5 if opts.print_ipopt else 0,
        "sb": "yes",
        "linear_solver": "mumps",
        "hessian_approximation": "exact",
    }
    if warm:
        ipopt.update(opts.warm_ipopt)
    ipopt.update(opts.ipopt)
    return ipopt


def transcribe(
    cp: CompiledProblem, mesh: Mesh, options: SolverOptions | None = None, warm: bool = False
) -> Transcription:
    """Build the NLP (and its IPOPT solver) of ``cp`` on ``mesh``.

    :param warm: use ``options.warm_ipopt`` on top of the IPOPT options (the guess
        is a converged solution on a nearby mesh).
    """
    import casadi as ca

    opts = options or SolverOptions()
    start = time.perf_counter()
    p = cp.problem
    nn, nc = mesh.n_nodes, mesh.n_collocation
    big_d, h_col, w_col, s_nodes = _block_matrices(mesh)

    sym = ca.MX if opts.graph == "mx" else ca.SX
    xs, us, tfs, zs, tf_nodes = _nlp_variables(sym, p, nn, nc)
    tf = tf_nodes[0, nn - 1]
    tf_col = tf_nodes[0, :nc]
    t0 = p.t0
    node = cp.node_function()
    # one mapped call evaluates dynamics, path constraints and running cost at every
    # collocation point; its derivatives are those of one node, reused nc times
    par = sym.sym("P", p.n_p)  # the problem's parameters: NLP parameters, set per solve
    f_sc, c_sc, lag = node.map(nc)(
        xs[:, :nc], us, ca.DM(s_nodes[:nc]).T, ca.DM(h_col).T, tf_col, ca.repmat(par, 1, nc)
    )  # fmt: skip
    # defects, D X = (tf - t0) h / 2 f, divided by the state scale
    defect = ca.mtimes(xs, _dm_sparse(big_d).T) - f_sc
    g, lbg, ubg, groups = _nlp_constraints(cp, xs, tfs, tf, c_sc, defect, nn, nc)

    cost = ca.mtimes((tf_col - t0) * 0.5 * lag, ca.DM(h_col * w_col))  # Radau quadrature
    cost = cost + cp.mayer_function()(xs[:, 0], xs[:, nn - 1], tf)
    nlp = {"x": ca.vertcat(*zs), "f": cost / p.cost_scale, "g": ca.vertcat(*g), "p": par}

    lbx, ubx = _variable_bounds(p, nn, nc)

    ipopt = _ipopt_options(opts, warm)
    solver = ca.nlpsol(
        "lgr", "ipopt", nlp,
        {"ipopt": ipopt, "print_time": False, "error_on_fail": False},
    )  # fmt: skip
    return Transcription(
        cp, mesh, solver,
        np.concatenate(lbx), np.concatenate(ubx), np.concatenate(lbg), np.concatenate(ubg),
        groups, time.perf_counter() - start,
    )  # fmt: skip


def _violations(tr: Transcription, z: np.ndarray, gval: np.ndarray, lbx, ubx, lbg, ubg) -> tuple[float, dict]:
    """Largest violation of the (scaled) NLP constraints and bounds, overall and per group."""
    def excess(v, lo, hi):
        if v.size == 0:
            return 0.0
        return float(np.max(np.maximum(np.maximum(lo - v, v - hi), 0.0)))

    out = {name: excess(gval[sl], lbg[sl], ubg[sl]) for name, sl in tr.g_groups.items()}
    out["bounds"] = excess(z, lbx, ubx)
    return max(out.values()), out


def initial_point(tr: Transcription, guess: TrajectoryLike, lbx=None, ubx=None) -> np.ndarray:
    """The scaled NLP starting point: the guess interpolated onto the mesh nodes, within the bounds."""
    p, mesh = tr.problem, tr.mesh
    tf_guess = float(np.clip(guess.tf, p.tf_lower, p.tf_upper))
    s = mesh.nodes()
    # guess given on its own time axis: map normalised time onto it
    tg = guess.t0 + (guess.tf - guess.t0) * s
    x0 = np.asarray(guess.state(tg), dtype=float).reshape(mesh.n_nodes, p.n_x)
    u0 = np.asarray(guess.control(tg[:-1]), dtype=float).reshape(mesh.n_collocation, p.n_u)
    return np.clip(tr.pack(x0, u0, tf_guess), tr.lbx if lbx is None else lbx, tr.ubx if ubx is None else ubx)


def solve_from(tr: Transcription, z0: np.ndarray, parameters=None, lbx=None, ubx=None, lam_x0=None,
               lam_g0=None, lbg=None, ubg=None) -> CollocationSolution:  # fmt: skip
    """Solve the transcribed NLP from the scaled point ``z0``.

    :param parameters: the problem's parameter values (default: its defaults).
    :param lbx: variable bounds replacing the transcription's (to fix a new initial state, say).
    :param lam_x0: bound multipliers to warm-start from (with ``lam_g0``, the constraint multipliers).
    :param lbg: constraint bounds replacing the transcription's (``tr.g_groups`` names their
        rows: per-node path bounds, say), with ``ubg``.
    """
    p, mesh = tr.problem, tr.mesh
    par = p.check_parameters(parameters)
    lbx = tr.lbx if lbx is None else lbx
    ubx = tr.ubx if ubx is None else ubx
    lbg = tr.lbg if lbg is None else lbg
    ubg = tr.ubg if ubg is None else ubg
    args = dict(x0=z0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, p=par)
    if lam_x0 is not None and lam_g0 is not None:
        args.update(lam_x0=lam_x0, lam_g0=lam_g0)
    start = time.perf_counter()
    res = tr.solver(**args)
    elapsed = time.perf_counter() - start
    stats = tr.solver.stats()
    z = np.asarray(res["x"]).ravel()
    x, u, tf = tr.unpack(z)
    worst, groups = _violations(tr, z, np.asarray(res["g"]).ravel(), lbx, ubx, lbg, ubg)
    s = mesh.nodes()
    return CollocationSolution(
        problem=p, mesh=mesh, t0=p.t0, tf=tf, t=p.t0 + (tf - p.t0) * s, x=x, u=u,
        cost=float(res["f"]) * p.cost_scale, status=str(stats.get("return_status", "?")),
        success=bool(stats.get("success", False)), nlp_iterations=int(stats.get("iter_count", -1)),
        solve_time_s=elapsed, build_time_s=tr.build_time_s, max_violation=worst, violations=groups,
        parameters=par, z=z, lam_x=np.asarray(res["lam_x"]).ravel(), lam_g=np.asarray(res["lam_g"]).ravel(),
    )  # fmt: skip


def solve_on_mesh(tr: Transcription, guess: TrajectoryLike, parameters=None) -> CollocationSolution:
    """Solve the transcribed NLP from a guess interpolated onto the mesh nodes."""
    return solve_from(tr, initial_point(tr, guess), parameters)


__all__ = ["Transcription", "SolverOptions", "WARM_START_IPOPT", "transcribe", "initial_point", "solve_from", "solve_on_mesh"]
