"""The shipped reference: its file format, writer and reader (NumPy only to read).

Format version 1, two files side by side:

``entry_reference_v1.npz``
    ``t (n,)`` state-node times (the collocation points and tf), ``x (n, 12)``
    states, ``u (n, 2)`` (u_alpha, u_sigma) at the nodes (the last row is the
    last interval's control polynomial at tf), ``u_extra (n, k)`` the
    formulation's extra controls (lambda_A, lambda_B), ``mesh_breaks (K+1,)``
    normalised breakpoints, ``mesh_degrees (K,)`` LGR points per interval,
    ``t0``, ``tf``, ``cost``, ``format_version``. With the mesh, the collocation
    polynomials are rebuilt exactly (:class:`Reference`).
``entry_reference_v1.json``
    the summary: J*, tf, final-mesh error, constraint violation, solver statistics,
    diagnostics and the problem constants.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from rventry_env.physics.entry import CONTROL_NAMES, ENTRY_STATE_NAMES
from rventry_env.reference.collocation.interpolation import PiecewiseLGR
from rventry_env.reference.collocation.mesh import Mesh

FORMAT_VERSION = 1
DATA_DIR = Path(__file__).resolve().parent / "data"
DEFAULT_PATH = DATA_DIR / f"entry_reference_v{FORMAT_VERSION}.npz"
GUIDANCE_PATH = DATA_DIR / f"guidance_reference_v{FORMAT_VERSION}.npz"


class Reference:
    """The optimal entry trajectory of the paper's Example 2 as shipped.

    :param t: node times ``(n,)``.
    :param x: states at the nodes ``(n, 12)`` (state order of docs/conventions.md).
    :param u: (u_alpha, u_sigma) at the nodes ``(n, 2)``.
    :param mesh: the final collocation mesh.
    :param cost: J*.
    :param summary: the JSON summary.
    :param u_extra: the formulation's extra controls at the nodes.
    """

    state_names = ENTRY_STATE_NAMES
    control_names = CONTROL_NAMES

    def __init__(self, t, x, u, mesh: Mesh, cost: float, summary: dict, u_extra=None):
        self.t = np.asarray(t, dtype=float)
        self.x = np.asarray(x, dtype=float)
        self.u = np.asarray(u, dtype=float)
        self.u_extra = None if u_extra is None else np.asarray(u_extra, dtype=float)
        n = self.t.size
        if self.x.shape != (n, len(ENTRY_STATE_NAMES)) or self.u.shape != (n, len(CONTROL_NAMES)):
            shapes = f"t {self.t.shape}, x {self.x.shape}, u {self.u.shape}"
            raise ValueError(f"reference arrays disagree: {shapes}")
        if mesh.n_nodes != n:
            raise ValueError(f"mesh has {mesh.n_nodes} nodes but the reference has {n}")
        self.mesh = mesh
        self.cost = float(cost)
        self._summary = dict(summary)
        self._poly = PiecewiseLGR(mesh, float(self.t[0]), float(self.t[-1]), self.x, self.u)
        const = self._summary.get("constants", {})
        prob = const.get("problem", {})
        if "u_alpha_max" in prob:  # format 1 since the constants moved to rventry_env.task.problem (rad)
            bounds = [prob["u_alpha_max"], prob["u_sigma_max"]]
        else:  # files written before that (deg)
            bounds = [np.radians(b) if b is not None else None for b in (const.get("u_alpha_max_deg"), const.get("u_sigma_max_deg"))]
        self._u_max = np.array([b if b is not None else np.inf for b in bounds])
        for arr in (self.t, self.x, self.u):
            arr.setflags(write=False)  # shared by every caller of the cached loader

    @property
    def t0(self) -> float:
        return float(self.t[0])

    @property
    def tf(self) -> float:
        """Final (impact) time (s)."""
        return float(self.t[-1])

    def state(self, t) -> np.ndarray:
        """States at ``t`` (s; scalar or array, clamped to [t0, tf]) from the collocation polynomials."""
        return self._poly.state(t)

    def control(self, t) -> np.ndarray:
        """(u_alpha, u_sigma) at ``t`` (rad/s; t clamped to [t0, tf]) from the control polynomials.

        Collocation enforces the rate bounds of Eq. ``Ex2-path`` at the collocation
        points only; where a bound is active (the final pitch-down) the polynomial
        overshoots it slightly between points, so the values are clipped to the
        bounds: every returned control is admissible.
        """
        return np.clip(self._poly.control(t), -self._u_max, self._u_max)

    def summary(self) -> dict:
        """The JSON summary (a copy)."""
        return json.loads(json.dumps(self._summary))

    def __repr__(self) -> str:
        return f"Reference(n={self.t.size}, tf={self.tf:.3f} s, cost={self.cost:.6g})"


def write_reference(
    path: str | Path, t, x, u, u_extra, mesh: Mesh, cost: float, summary: dict
) -> tuple[Path, Path]:
    """Write the ``.npz`` and its ``.json`` summary, each whole or not at all; returns both paths."""
    from rventry_env.util.files import atomic_write, dumps_json

    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"the reference file must end in .npz, got {path.name}")
    arrays = dict(
        format_version=FORMAT_VERSION,
        t=np.asarray(t, float), x=np.asarray(x, float), u=np.asarray(u, float),
        u_extra=np.asarray(u_extra, float), mesh_breaks=mesh.breaks, mesh_degrees=mesh.degrees,
        t0=float(t[0]), tf=float(t[-1]), cost=float(cost),
    )  # fmt: skip
    json_path = path.with_suffix(".json")
    # the summary first: a reader takes the .npz as the file, the .json as its description
    atomic_write(json_path, dumps_json(summary, indent=2))
    atomic_write(path, lambda tmp: np.savez_compressed(tmp, **arrays))
    return path, json_path


def read_reference(path: str | Path) -> Reference:
    """Read a reference written by :func:`write_reference` (never with pickle)."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{path} is a directory; give a reference .npz file")
    if not path.exists():
        raise FileNotFoundError(f"no reference file at {path}; run `rventry reference solve` to create it")
    keys = ("format_version", "t", "x", "u", "u_extra", "mesh_breaks", "mesh_degrees", "cost")
    not_reference = f"{path} is not an rventry reference file (a NumPy .npz written by `rventry reference solve`)"
    try:
        d = np.load(path, allow_pickle=False)
    except (OSError, EOFError, ValueError) as exc:
        raise ValueError(f"{not_reference}: {exc.__class__.__name__}") from None
    if not isinstance(d, np.lib.npyio.NpzFile):
        raise ValueError(f"{not_reference}: it holds a single array")
    with d:
        missing = [k for k in keys if k not in d.files]
        if missing:
            raise ValueError(f"{not_reference}: it lacks {', '.join(missing)}")
        version = int(d["format_version"])
        if version != FORMAT_VERSION:
            raise ValueError(f"{path.name} has format version {version}; this code reads {FORMAT_VERSION}")
        mesh = Mesh(d["mesh_breaks"], d["mesh_degrees"])
        arrays = {k: d[k].copy() for k in ("t", "x", "u", "u_extra")}
        cost = float(d["cost"])
    json_path = path.with_suffix(".json")
    summary = {}
    if json_path.exists():
        try:
            summary = json.loads(json_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"the reference summary {json_path} is not valid JSON ({exc})") from None
    return Reference(arrays["t"], arrays["x"], arrays["u"], mesh, cost, summary, arrays["u_extra"])


@lru_cache(maxsize=4)
def _cached(path: str) -> Reference:
    return read_reference(path)


def load_guidance_reference() -> Reference:
    """The shipped *guidance* reference: Example 2 re-solved with path-constraint margins.

    ``rventry reference solve --q-margin 0.30 --load-margin 0.06 --ship guidance``:
    q >= 15.6 kPa and a load
    factor <= 11.28 g, so that a guidance law tracking it under dispersions has room
    before the true bounds (a -5 % density error alone takes 5 % off q). Its cost is
    higher than J*; :func:`load_reference` stays the optimum the paper's problem
    asks for.
    """
    return _cached(str(GUIDANCE_PATH))


def load_reference(path: str | Path | None = None) -> Reference:
    """The shipped reference (cached per path; the arrays are read-only).

    :param path: a reference ``.npz`` (default: the packaged ``entry_reference_v1.npz``).
    """
    return _cached(str(Path(path).resolve() if path is not None else DEFAULT_PATH))


__all__ = [
    "FORMAT_VERSION",
    "DEFAULT_PATH",
    "Reference",
    "write_reference",
    "read_reference",
    "load_reference",
    "load_guidance_reference",
    "GUIDANCE_PATH",
]
