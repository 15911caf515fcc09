"""``rventry oracle``: the attainable ceiling of a dispersion set (:mod:`rventry_env.evaluation.oracle`)."""

from __future__ import annotations

import argparse
import time

from rventry_env.util.args import positive_int, seed
from rventry_env.util.files import check_writable, write_json

# the memory a draw holds until the report is written: its record, its call and future in the pool,
# and its share of the JSON text. Measured with tracemalloc over 20,000 records of the oracle's
# form: 7.1 kB per draw at the peak, rounded up
ORACLE_DRAW_BYTES = 8e3


def register(sub: argparse._SubParsersAction) -> None:
    from rventry_env.evaluation.cli import _parallel_arguments
    from rventry_env.task.dispersion import SET_CHOICES

    p = sub.add_parser("oracle", help="solve each draw of a dispersion set with perfect knowledge and fly it: "
                                      "the flyable fraction a guidance law is read against")  # fmt: skip
    p.add_argument("--dispersion", choices=SET_CHOICES, required=True, help="the dispersion set (docs/uncertainty.md)")
    p.add_argument("--episodes", type=positive_int, default=50, help="draws, seeds SEED .. SEED + N - 1 (default 50)")
    p.add_argument("--seed", type=seed, default=0, help="draw i uses seed SEED + i, as `rventry evaluate` (default 0)")
    p.add_argument("--json", required=True, metavar="PATH", help="write the summary and the per-draw records here")
    _parallel_arguments(p)
    p.set_defaults(func=_oracle)


def _oracle(args) -> int:
    from rventry_env.evaluation.cli import check_memory, progress_bar
    from rventry_env.task.glossary import terms_line
    from rventry_env.evaluation.oracle import OracleSettings, oracle
    from rventry_env.task import Dispersion, EntryTask

    check_memory(args.episodes, False, per_episode=ORACLE_DRAW_BYTES, unit="draw")
    check_writable(args.json)
    settings = OracleSettings()
    t0 = time.time()
    seeds = list(range(args.seed, args.seed + args.episodes))
    with progress_bar() as progress:
        job = progress.add_task(f"oracle, {args.dispersion}: {args.episodes} draw(s)", total=args.episodes)
        out = oracle(args.dispersion, seeds, EntryTask(), settings, workers=args.workers, cluster=args.cluster,
                     progress=lambda n: progress.advance(job, n))  # fmt: skip
    doc = {"dispersion_set": args.dispersion, "dispersion": Dispersion.parse(args.dispersion).describe(),
           "seed": args.seed, "settings": settings.__dict__, **out, "wall_time_s": time.time() - t0,
           "workers": None if args.cluster else args.workers}  # fmt: skip
    write_json(args.json, doc)
    s = out["summary"]
    print(f"oracle, {args.dispersion}: {s['draws']} draw(s): flyable {s['flyable_fraction']:.2f} "
          f"[{s['flyable_fraction_ci'][0]:.2f}, {s['flyable_fraction_ci'][1]:.2f}], precision "
          f"{s['precision_flyable_fraction']:.2f}, converged {s['converged']}, J p50 "
          + (f"{s['J']['p50']:.3f}" if s["J"] else "-"))  # fmt: skip
    print(terms_line(["flyable", "95 % CI", "precision", "J/J*", "dispersion set"]))
    return 0


__all__ = ["register"]
