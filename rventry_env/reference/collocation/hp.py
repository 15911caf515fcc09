"""The hp mesh-refinement loop: transcribe, solve, estimate the error, refine (ph rule), repeat."""

from __future__ import annotations

import time
from dataclasses import dataclass

from rventry_env.reference.collocation.compiled import CompiledProblem
from rventry_env.reference.collocation.error_estimate import estimate_errors
from rventry_env.reference.collocation.guesses import TrajectoryLike
from rventry_env.reference.collocation.mesh import Mesh, refine_ph
from rventry_env.reference.collocation.ocp import OptimalControlProblem
from rventry_env.reference.collocation.progress import MeshIterationRecord, Progress
from rventry_env.reference.collocation.solution import CollocationSolution
from rventry_env.reference.collocation.transcription import SolverOptions, solve_on_mesh, transcribe


@dataclass
class CollocationResult:
    """Outcome of the hp loop: the last solution and one record per mesh pass."""

    solution: CollocationSolution
    records: list
    converged: bool
    total_time_s: float


def solve(
    problem: OptimalControlProblem | CompiledProblem,
    guess: TrajectoryLike,
    mesh: Mesh | None = None,
    options: SolverOptions | None = None,
    progress: Progress | None = None,
    label: str = "",
    warm_start: bool = False,
    parameters=None,
) -> CollocationResult:
    """Solve ``problem`` by LGR collocation with hp mesh refinement.

    :param problem: the problem (or its :class:`CompiledProblem`, to reuse the CasADi functions).
    :param guess: anything with ``t0``, ``tf``, ``state(t)``, ``control(t)`` (a
        :class:`SampledGuess`, a previous :class:`CollocationSolution`, ...).
    :param mesh: the first mesh (default: 10 intervals of ``n_min`` points).
    :param options: :class:`SolverOptions`.
    :param progress: called with a :class:`MeshIterationRecord` after each pass.
    :param label: appended to the pass number in the records (e.g. a continuation stage).
    :param warm_start: the guess is already a converged solution of a nearby
        problem: use the warm-start IPOPT options from the first pass.
    :param parameters: values of the problem's parameters (default: its defaults).
    :return: :class:`CollocationResult`; ``converged`` is true when the NLP
        succeeded and the mesh error met the tolerance.
    """
    opts = options or SolverOptions()
    cp = problem if isinstance(problem, CompiledProblem) else CompiledProblem(problem)
    mesh = mesh or Mesh.uniform(10, opts.n_min)
    records = []
    start = time.perf_counter()
    sol = None
    converged = False
    warm = warm_start

    def one_pass(it, warm, tag=""):
        t_pass = time.perf_counter()
        tr = transcribe(cp, mesh, opts, warm=warm)
        sol = solve_on_mesh(tr, guess, parameters)
        sol.errors = estimate_errors(cp, sol)
        rec = MeshIterationRecord(
            iteration=it, n_intervals=mesh.n_intervals, n_nodes=mesh.n_nodes, max_error=sol.max_error,
            status=sol.status, success=sol.success, nlp_iterations=sol.nlp_iterations,
            solve_time_s=time.perf_counter() - t_pass, cost=sol.cost, tf=sol.tf, label=label + tag,
        )  # fmt: skip
        records.append(rec)
        if progress is not None:
            progress(rec)
        return sol

    for it in range(opts.max_mesh_iterations):
        sol = one_pass(it, warm)
        if warm and opts.warm_ipopt and not sol.success:
            # the warm-start options trust the previous point; when IPOPT fails from it (an
            # "infeasible" verdict deep in a small barrier, say) the pass is solved again cold
            sol = one_pass(it, False, tag="c")
        if not sol.success and not opts.refine_after_failure:
            break
        if sol.success and sol.max_error <= opts.mesh_tolerance:
            converged = True
            break
        new = refine_ph(mesh, sol.errors, opts.mesh_tolerance, opts.n_min, opts.n_max)
        guess = sol
        mesh = new
        # far from converged the old point is no better than any guess: restart cold
        warm = sol.max_error <= opts.warm_start_error
    return CollocationResult(sol, records, converged, time.perf_counter() - start)


__all__ = ["CollocationResult", "solve"]
