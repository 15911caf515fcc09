"""Legendre-Gauss-Radau collocation with hp mesh refinement (IPOPT through CasADi).

* :mod:`.lgr` - points, weights, differentiation and integration matrices;
* :mod:`.problem` - a general single-phase optimal-control problem;
* :mod:`.mesh` - the mesh and the ph raise-degree-or-split rule;
* :mod:`.solver` - transcription, IPOPT, error estimate, the refinement loop;
* :mod:`.interpolation` - the collocation polynomials as an interpolant (NumPy only);
* :mod:`.progress` - per-pass records and reporters.

CasADi is imported only when a problem is compiled or transcribed.
"""

from rventry_env.reference.collocation.mesh import Mesh, refine_ph
from rventry_env.reference.collocation.problem import (
    EndpointConstraint,
    Invariant,
    OptimalControlProblem,
    PathConstraint,
)
from rventry_env.reference.collocation.progress import MeshIterationRecord, RecordingProgress, RichMeshTable

__all__ = [
    "Mesh",
    "refine_ph",
    "OptimalControlProblem",
    "PathConstraint",
    "EndpointConstraint",
    "Invariant",
    "MeshIterationRecord",
    "RecordingProgress",
    "RichMeshTable",
]
