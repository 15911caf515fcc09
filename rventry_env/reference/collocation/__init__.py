"""Legendre-Gauss-Radau collocation with hp mesh refinement (IPOPT through CasADi).

* :mod:`.lgr` - points, weights, differentiation and integration matrices;
* :mod:`.ocp` - a general single-phase optimal-control problem (OCP);
* :mod:`.compiled` - the problem compiled to CasADi functions once;
* :mod:`.mesh` - the mesh and the ph raise-degree-or-split rule;
* :mod:`.guesses` - initial guesses;
* :mod:`.transcription` - the NLP on one mesh and its IPOPT solve;
* :mod:`.solution` - the solution on one mesh and its collocation polynomials;
* :mod:`.error_estimate` - the per-interval error estimate;
* :mod:`.hp` - the refinement loop;
* :mod:`.interpolation` - the collocation polynomials as an interpolant (NumPy only);
* :mod:`.progress` - per-pass records and reporters.

CasADi is imported only when a problem is compiled or transcribed.
"""

from rventry_env.reference.collocation.compiled import CompiledProblem
from rventry_env.reference.collocation.error_estimate import estimate_errors
from rventry_env.reference.collocation.guesses import SampledGuess, TrajectoryLike
from rventry_env.reference.collocation.hp import CollocationResult, solve
from rventry_env.reference.collocation.mesh import Mesh, refine_ph
from rventry_env.reference.collocation.ocp import (
    EndpointConstraint,
    Invariant,
    OptimalControlProblem,
    PathConstraint,
)
from rventry_env.reference.collocation.progress import MeshIterationRecord, RecordingProgress, RichMeshTable
from rventry_env.reference.collocation.solution import CollocationSolution
from rventry_env.reference.collocation.transcription import (
    WARM_START_IPOPT,
    SolverOptions,
    Transcription,
    initial_point,
    solve_from,
    solve_on_mesh,
    transcribe,
)

__all__ = [
    "CompiledProblem",
    "CollocationResult",
    "CollocationSolution",
    "EndpointConstraint",
    "Invariant",
    "Mesh",
    "MeshIterationRecord",
    "OptimalControlProblem",
    "PathConstraint",
    "RecordingProgress",
    "RichMeshTable",
    "SampledGuess",
    "SolverOptions",
    "TrajectoryLike",
    "Transcription",
    "WARM_START_IPOPT",
    "estimate_errors",
    "initial_point",
    "solve_from",
    "refine_ph",
    "solve",
    "solve_on_mesh",
    "transcribe",
]
