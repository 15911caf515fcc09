"""``rventry reference {solve,show,export,plot}``.

The shipped data files (the optimum and the guidance reference) are written only by
``solve --ship``, only after a converged solve, and atomically; every other output
goes where ``--out`` says. Heavy imports (CasADi, matplotlib) happen inside the
command functions so that ``rventry --help`` stays fast.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from rventry_env.util.args import interval, positive_float, positive_int
from rventry_env.util.files import atomic_write, check_writable, write_json

# a shipped file is replaced only by a solve whose cost is no higher than this, relative (a cold solve may
# converge to a local optimum: docs/reference.md)
SHIP_COST_RTOL = 1e-6
# the shipped files, and the margins each must be solved with
SHIPPED = {"optimum": (0.0, 0.0), "guidance": (0.30, 0.06)}
MAX_EXPORT_ROWS = 2_000_000


def register(subparsers) -> None:
    """Add ``reference`` and its subcommands to the ``rventry`` parser."""
    ref = subparsers.add_parser("reference", help="the collocation reference (paper Example 2)")
    sub = ref.add_subparsers(dest="reference_command", metavar="SUBCOMMAND")
    ref.set_defaults(func=lambda args: (ref.print_help(), 2)[1])

    p = sub.add_parser("solve", help="solve Example 2 from a cold start and write the data file")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=None,
                       help="output .npz, written after a converged solve (default: reference.npz here)")
    where.add_argument("--ship", choices=tuple(SHIPPED),
                       help="replace a packaged file instead: 'optimum' (no margins) or 'guidance' "
                            "(--q-margin 0.30 --load-margin 0.06); only after convergence")  # fmt: skip
    p.add_argument("--mesh-tolerance", type=positive_float, default=1e-6, help="target max relative error")
    p.add_argument("--first-mesh", type=positive_int, nargs=2, metavar=("INTERVALS", "POINTS"), default=(39, 6),
                   help="uniform part of the first mesh (default 39 intervals of 6 LGR points)")
    p.add_argument("--end-fraction", type=interval(0.0, 1.0, high_open=True), default=0.025,
                   help="last fraction of the time meshed finer in the first mesh (0.025; 0 for none)")
    p.add_argument("--max-mesh-iterations", type=positive_int, default=15, help="mesh passes per stage (15)")
    p.add_argument("--norm-mode", choices=("projection", "paper", "none"), default="projection",
                   help="how the quaternion norms are kept (see docs/reference.md)")  # fmt: skip
    p.add_argument("--q-margin", type=interval(0.0, 0.5, high_open=True), default=0.0, metavar="FRACTION",
                   help="solve with q >= q_min (1 + FRACTION): a guidance reference with room for dispersions (0)")
    p.add_argument("--load-margin", type=interval(0.0, 0.5, high_open=True), default=0.0, metavar="FRACTION",
                   help="solve with the load factor <= a_max (1 - FRACTION) (0)")
    p.add_argument("--quiet", action="store_true", help="no per-pass table")
    p.set_defaults(func=_solve)

    p = sub.add_parser("show", help="print the summary of the reference")
    p.add_argument("--json", type=Path, default=None, metavar="PATH", help="also write the summary here")
    p.add_argument("--file", type=Path, default=None, help="a reference .npz (default: the packaged one)")
    p.set_defaults(func=_show)

    p = sub.add_parser("export", help="write the reference on a uniform time grid as CSV")
    p.add_argument("--csv", type=Path, required=True, metavar="PATH", help="output CSV")
    p.add_argument("--dt", type=positive_float, default=0.1, metavar="SECONDS", help="grid step (0.1 s)")
    p.add_argument("--file", type=Path, default=None, help="a reference .npz (default: the packaged one)")
    p.set_defaults(func=_export)

    p = sub.add_parser("plot", help="write the panels of the paper's Fig. fig:Ex2-sol-1 as PNG")
    p.add_argument("dir", type=Path, metavar="DIR", help="output directory")
    p.add_argument("--file", type=Path, default=None, help="a reference .npz (default: the packaged one)")
    p.set_defaults(func=_plot)


def _load(path):
    from rventry_env.reference import load_reference

    return load_reference(path)


def _solve(args) -> int:
    from rventry_env.task.problem import EntryProblem
    from rventry_env.reference.collocation.progress import RichMeshTable
    from rventry_env.reference.data_file import DEFAULT_PATH, GUIDANCE_PATH
    from rventry_env.reference.entry_ocp import EntryOcpConfig
    from rventry_env.reference.pipeline import ReferenceOptions, save_reference, solve_reference

    paths = {"optimum": DEFAULT_PATH, "guidance": GUIDANCE_PATH}
    if args.ship is not None:
        want = SHIPPED[args.ship]
        if (args.q_margin, args.load_margin) != want:
            raise ValueError(
                f"--ship {args.ship} is the reference solved with --q-margin {want[0]:g} --load-margin {want[1]:g}, "
                f"not {args.q_margin:g} / {args.load_margin:g}; use --out for any other solve"
            )
        out = paths[args.ship]
    else:
        out = args.out if args.out is not None else Path("reference.npz")
    if out.suffix != ".npz":
        raise ValueError(f"--out must name a .npz file, got {out}")
    check_writable(out, out.with_suffix(".json"))
    opts = ReferenceOptions(
        first_mesh=tuple(args.first_mesh), end_fraction=args.end_fraction, mesh_tolerance=args.mesh_tolerance,
        max_mesh_iterations=args.max_mesh_iterations,
    )  # fmt: skip
    base = EntryProblem()
    problem = EntryProblem(q_min=base.q_min * (1 + args.q_margin), a_max_g=base.a_max_g * (1 - args.load_margin))
    title = "LGR collocation, paper Example 2 (rv-Euler, exact vertical impact)"
    if args.q_margin or args.load_margin:
        title += f", path margins q +{args.q_margin:.0%} load -{args.load_margin:.0%}"
    progress = None if args.quiet else RichMeshTable(title)
    rs = solve_reference(EntryOcpConfig(problem=problem, norm_mode=args.norm_mode), opts, progress)
    sol = rs.solution
    print(
        f"J* = {sol.cost:.6f}   tf = {sol.tf:.3f} s   mesh error = {sol.max_error:.2e}   "
        f"max violation = {sol.max_violation:.1e}   solve time = {rs.timings['solve_time_s']:.1f} s"
    )
    if not rs.converged:
        why = f"IPOPT: {sol.status}" if not sol.success else f"mesh error {sol.max_error:.2e} > {args.mesh_tolerance:g}"
        print(f"rventry reference solve: the solve did not converge ({why}); nothing written", file=sys.stderr)
        return 1
    # the problem of a shipped file (its margins): a cost above that file's is a local optimum of it
    shipped_path = next((paths[k] for k, m in SHIPPED.items() if m == (args.q_margin, args.load_margin)), None)
    if shipped_path is not None and shipped_path.exists():
        shipped = _load(shipped_path).cost
        if sol.cost > shipped * (1 + SHIP_COST_RTOL):
            local = (f"rventry reference solve: J* = {sol.cost:.6f} is above the shipped file's {shipped:.6f} for the "
                     "same problem: a local optimum, not the optimum (a cold first pass is fragile: docs/reference.md)")  # fmt: skip
            if args.ship is not None:
                print(f"{local}; {out} not replaced", file=sys.stderr)
                return 1
            print(f"warning: {local}; written to {out} as solved", file=sys.stderr)
    npz, js = save_reference(rs, out)
    print(f"wrote {npz} and {js}")
    from rventry_env.task.glossary import terms_line

    print(terms_line(["J*", "mesh error", "max violation"]))
    return 0


def _show(args) -> int:
    ref = _load(args.file)
    s = ref.summary()
    keys = (
        "tf_s", "cost", "mesh_error", "max_constraint_violation", "solve_time_s", "solve_cpu_s",
        "n_nodes", "n_intervals", "nlp_iterations_per_pass", "rss_peak_mb", "norm_mode",
    )  # fmt: skip
    for k in keys:
        if k in s:
            print(f"{k:28s} {s[k]}")
    for k, v in s.get("diagnostics", {}).items():
        print(f"{'diagnostics.' + k:28s} {v}")
    if args.json is not None:
        print(f"wrote {write_json(args.json, s, indent=2)}")
    from rventry_env.task.glossary import terms_line

    print(terms_line(["J*", "mesh error", "max violation"]))
    return 0


def export_grid(ref, dt: float):
    """Uniform times from 0 with step ``dt`` ending exactly at tf, and the interpolated rows."""
    import numpy as np

    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"--dt must be a positive number of seconds, got {dt}")
    span = ref.tf - ref.t0
    if span / dt > MAX_EXPORT_ROWS:
        raise ValueError(
            f"--dt {dt:g} s would export {span / dt:.3g} rows; the limit is {MAX_EXPORT_ROWS:,} "
            f"(--dt >= {span / MAX_EXPORT_ROWS:.2g} s)"
        )
    n = int(math.floor(span / dt + 1e-9))
    t = ref.t0 + dt * np.arange(n + 1)
    if ref.tf - t[-1] > 1e-9 * max(1.0, ref.tf):
        t = np.append(t, ref.tf)
    else:
        t[-1] = ref.tf
    return t, ref.state(t), ref.control(t)


def _export(args) -> int:
    import numpy as np

    ref = _load(args.file)
    t, x, u = export_grid(ref, args.dt)
    header = ",".join(("t_s", *ref.state_names, *ref.control_names))
    # %.17g round-trips every double: the last row is tf exactly
    rows = np.column_stack([t, x, u])
    atomic_write(args.csv, lambda tmp: np.savetxt(tmp, rows, delimiter=",", header=header, comments="", fmt="%.17g"))
    print(f"wrote {t.size} rows to {args.csv}")
    return 0


def _plot(args) -> int:
    from rventry_env.reference.plots import plot_reference

    ref = _load(args.file)
    paths = plot_reference(ref, args.dir)
    for p in paths:
        print(f"wrote {p}")
    return 0


__all__ = ["register", "export_grid"]
