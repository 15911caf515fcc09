"""A problem compiled to CasADi functions once, shared by every mesh of the hp loop.

``f(x, u, t)``, ``lagrange``, ``path``, ``invariants``, ``endpoint`` and ``mayer``
as ``casadi.Function`` objects, plus the scaled per-node functions the
transcription maps over the collocation points.
"""

from __future__ import annotations

import numpy as np

from rventry_env.reference.collocation.ocp import OptimalControlProblem


class CompiledProblem:
    """CasADi functions of one problem, built once and shared by every mesh.

    ``f(x, u, t, p)``, ``lagrange(x, u, t, p)``, ``path(x, u, t, p)``, ``invariants(x)``,
    ``endpoint(x0, xf, t0, tf)``, ``mayer(x0, xf, t0, tf)``; x, u, p are column vectors
    (p has no entries for a problem without parameters).
    """

    def __init__(self, problem: OptimalControlProblem):
        import casadi as ca

        self.problem = p = problem
        x = ca.SX.sym("x", p.n_x)
        u = ca.SX.sym("u", p.n_u)
        t = ca.SX.sym("t")
        x0 = ca.SX.sym("x0", p.n_x)
        xf = ca.SX.sym("xf", p.n_x)
        t0 = ca.SX.sym("t0")
        tf = ca.SX.sym("tf")
        xl = [x[i] for i in range(p.n_x)]
        ul = [u[i] for i in range(p.n_u)]
        x0l = [x0[i] for i in range(p.n_x)]
        xfl = [xf[i] for i in range(p.n_x)]
        par = ca.SX.sym("p", p.n_p)
        extra = ([[par[i] for i in range(p.n_p)]] if p.n_p else [])  # the fourth argument, if any

        rhs = list(p.dynamics(xl, ul, t, *extra))
        if len(rhs) != p.n_x:
            raise ValueError(f"dynamics returned {len(rhs)} derivatives for {p.n_x} states")
        self.f = ca.Function("f", [x, u, t, par], [ca.vertcat(*rhs)])
        lag = p.lagrange(xl, ul, t, *extra) if p.lagrange is not None else 0
        self.lagrange = ca.Function("L", [x, u, t, par], [ca.SX(lag)])
        path = [c.fn(xl, ul, t, *extra) for c in p.path_constraints]
        self.path = ca.Function("c", [x, u, t, par], [ca.vertcat(*path) if path else ca.SX(0, 1)])
        inv = [g.fn(xl) for g in p.invariants]
        self.invariants = ca.Function("g", [x], [ca.vertcat(*inv) if inv else ca.SX(0, 1)])
        end = [b.fn(x0l, xfl, t0, tf) for b in p.endpoint_constraints]
        self.endpoint = ca.Function("b", [x0, xf, t0, tf], [ca.vertcat(*end) if end else ca.SX(0, 1)])
        may = p.mayer(x0l, xfl, t0, tf) if p.mayer is not None else 0
        self.mayer = ca.Function("M", [x0, xf, t0, tf], [ca.SX(may)])
        self.path_scale = np.array([c.scale for c in p.path_constraints])
        self.path_lower = np.array([c.lower for c in p.path_constraints])
        self.path_upper = np.array([c.upper for c in p.path_constraints])
        self.end_scale = np.array([c.scale for c in p.endpoint_constraints])
        self.end_lower = np.array([c.lower for c in p.endpoint_constraints])
        self.end_upper = np.array([c.upper for c in p.endpoint_constraints])
        self.inv_scale = np.array([g.scale for g in p.invariants])

    def _scaled_symbols(self):
        import casadi as ca

        p = self.problem
        xs = ca.SX.sym("xs", p.n_x)
        x = xs * ca.DM(p.state_scale) + ca.DM(p.state_shift)
        return xs, x

    def node_function(self):
        """``(xs, us, s, h, tf, p) -> (f_scaled, path_scaled, lagrange)`` at one collocation point.

        xs, us are scaled; s is the normalised time, h the interval length (in s);
        f_scaled = (tf - t0) h / 2 f / state_scale is what the defect subtracts.
        """
        import casadi as ca

        if getattr(self, "_node", None) is None:
            p = self.problem
            xs, x = self._scaled_symbols()
            us = ca.SX.sym("us", p.n_u)
            u = us * ca.DM(p.control_scale) + ca.DM(p.control_shift)
            s, h, tf = ca.SX.sym("s"), ca.SX.sym("h"), ca.SX.sym("tf")
            par = ca.SX.sym("p", p.n_p)
            t = p.t0 + (tf - p.t0) * s
            f = self.f(x, u, t, par) * ((tf - p.t0) * h / 2) / ca.DM(p.state_scale)
            c = self.path(x, u, t, par) / ca.DM(self.path_scale) if self.path_scale.size else ca.SX(0, 1)
            self._node = ca.Function("node", [xs, us, s, h, tf, par], [f, c, self.lagrange(x, u, t, par)])
        return self._node

    def invariant_function(self):
        """``xs -> invariants / scale`` at one node (scaled state)."""
        import casadi as ca

        if getattr(self, "_inv", None) is None:
            xs, x = self._scaled_symbols()
            out = self.invariants(x) / ca.DM(self.inv_scale) if self.inv_scale.size else ca.SX(0, 1)
            self._inv = ca.Function("inv", [xs], [out])
        return self._inv

    def endpoint_function(self):
        """``(xs0, xsf, tf) -> endpoint / scale``."""
        import casadi as ca

        if getattr(self, "_end", None) is None:
            p = self.problem
            xs0, x0 = self._scaled_symbols()
            xsf, xf = self._scaled_symbols()
            tf = ca.SX.sym("tf")
            out = self.endpoint(x0, xf, p.t0, tf)
            out = out / ca.DM(self.end_scale) if self.end_scale.size else out
            self._end = ca.Function("end", [xs0, xsf, tf], [out])
        return self._end

    def mayer_function(self):
        """``(xs0, xsf, tf) -> terminal cost``."""
        import casadi as ca

        if getattr(self, "_may", None) is None:
            p = self.problem
            xs0, x0 = self._scaled_symbols()
            xsf, xf = self._scaled_symbols()
            tf = ca.SX.sym("tf")
            self._may = ca.Function("mayer", [xs0, xsf, tf], [self.mayer(x0, xf, p.t0, tf)])
        return self._may

    def rhs(self, x: np.ndarray, u: np.ndarray, t: np.ndarray, parameters=None) -> np.ndarray:
        """Batched numeric dynamics: ``x (n, n_x)``, ``u (n, n_u)``, ``t (n,)`` -> ``(n, n_x)``."""
        n = x.shape[0]
        par = self.problem.check_parameters(parameters)
        out = self.f.map(n)(x.T, u.T, np.reshape(t, (1, n)), np.repeat(par[:, None], n, axis=1))
        return np.asarray(out).T


__all__ = ["CompiledProblem"]
