"""Two policies on the same episodes, episode by episode: where one lands and the other does not.

Takes two ``rventry evaluate --json`` reports flown on the same set and seeds (say a fine-tuned
policy and the policy it started from) and draws, per episode, the first policy's figures against
the second's: miss, vertical-impact error, peak load factor and minimum dynamic pressure, each
episode coloured by which of the two succeeded. Prints the paired counts (both, only A, only B,
neither), a two-sided sign test on the discordant episodes, and each policy's failures by
criterion.

Run: ``python studies/compare_episodes.py out/ppo_flight.json out/student_flight.json
--labels ppo dagger-flight --png out/ppo_vs_student.png [--json out/ppo_vs_student.json]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rventry_env.util.provenance import start_run, write_record

# what each panel shows: (episode key, axis label, log axis, the success rule's bound in those units)
PANELS = (("miss_km", "miss (km)", True, 5.0), ("vertical_error_deg", "vertical-impact error (deg)", True, 5.0),
          ("max_load_factor_g", "peak load factor (g)", False, None),
          ("min_dynamic_pressure_pa", "minimum dynamic pressure (kPa)", False, None))  # fmt: skip


def load_report(path: str) -> dict:
    doc = json.loads(Path(path).read_text())
    if not isinstance(doc, dict) or not isinstance(doc.get("episodes"), list) or not doc["episodes"]:
        raise ValueError(f"{path} is not an `rventry evaluate --json` report with episodes")
    return doc


def successes(report: dict) -> np.ndarray:
    """Each episode's basic success, in the report's order."""
    return np.array([bool(e["success"]) for e in report["episodes"]])


def paired(a: dict, b: dict) -> dict:
    """The paired success counts of two reports on the same episodes, and the sign test on the discordant ones."""
    sa = [(e["seed"], e["dispersion"]) for e in a["episodes"]]
    sb = [(e["seed"], e["dispersion"]) for e in b["episodes"]]
    if sa != sb:
        raise ValueError("the two reports did not fly the same episodes (seeds and draws differ)")
    from scipy.stats import binomtest

    x, y = successes(a), successes(b)
    only_a, only_b = int(np.sum(x & ~y)), int(np.sum(~x & y))
    n = only_a + only_b
    p = binomtest(only_a, n, 0.5).pvalue if n else 1.0  # the exact sign test on the discordant episodes
    return {"episodes": len(x), "both": int(np.sum(x & y)), "only_a": only_a, "only_b": only_b,
            "neither": int(np.sum(~x & ~y)), "sign_test_p": p}  # fmt: skip


def failures(report: dict) -> dict:
    """A report's failures by the success rule's criteria (one episode can fail several)."""
    th = report["summary"]["success_thresholds"]
    bad = [e for e in report["episodes"] if not e["success"]]
    return {
        "failures": len(bad), "miss": sum(e["miss_km"] > th["miss_km"] for e in bad),
        "vertical": sum(e["vertical_error_deg"] > th["vertical_error_deg"] for e in bad),
        "speed": sum(abs(e["speed_error_mps"]) > th["speed_error_mps"] for e in bad),
        "path_bound": sum(bool(e["constraint_violation"]) for e in bad),
    }  # fmt: skip


def plot(a: dict, b: dict, labels: tuple[str, str], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rventry_env.util.files import save_figure

    sa, sb = successes(a), successes(b)
    groups = ((sa & sb, "both land", "0.7"), (sa & ~sb, f"only {labels[0]}", "C2"),
              (~sa & sb, f"only {labels[1]}", "C3"), (~sa & ~sb, "neither", "k"))  # fmt: skip
    fig, axes = plt.subplots(1, len(PANELS), figsize=(4.2 * len(PANELS), 4.2))
    for ax, (key, name, log, bound) in zip(axes, PANELS):
        scale = 1e-3 if key.endswith("_pa") else 1.0
        va = np.array([e[key] for e in a["episodes"]], float) * scale
        vb = np.array([e[key] for e in b["episodes"]], float) * scale
        for mask, label, color in groups:
            ax.scatter(vb[mask], va[mask], s=9, color=color, label=f"{label} ({mask.sum()})", alpha=0.8)
        lo, hi = np.nanmin(np.r_[va, vb]), np.nanmax(np.r_[va, vb])
        ax.plot([lo, hi], [lo, hi], lw=0.8, color="C0")
        if bound is not None:
            ax.axhline(bound, ls="--", lw=0.8, color="r")
            ax.axvline(bound, ls="--", lw=0.8, color="r")
        if log:
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set(xlabel=f"{labels[1]}: {name}", ylabel=f"{labels[0]}: {name}")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize="small")
    fig.suptitle(f"{labels[0]} against {labels[1]}, episode by episode ({len(sa)} episodes of "
                 f"{a.get('dispersion_set', 'the set')}, seed {a.get('seed', '?')}); dashed: the success bounds")  # fmt: skip
    save_figure(fig, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a", help="the first policy's report (rventry evaluate --json)")
    ap.add_argument("b", help="the second policy's report, flown on the same episodes")
    ap.add_argument("--labels", nargs=2, metavar=("A", "B"), help="names for the two (default: their agents)")
    ap.add_argument("--png", required=True)
    ap.add_argument("--json", help="write the counts here")
    args = ap.parse_args(argv)
    start_run(None if argv is None else ["python", __file__, *argv])
    from rventry_env.util.files import check_writable, output_set

    check_writable(args.png, args.json)
    a, b = load_report(args.a), load_report(args.b)
    labels = tuple(args.labels) if args.labels else (str(a.get("agent", "A")), str(b.get("agent", "B")))
    pair = paired(a, b)
    out = {"labels": labels, "paired": pair, "failures": {labels[0]: failures(a), labels[1]: failures(b)}}
    with output_set():
        plot(a, b, labels, args.png)
        if args.json:
            write_record(args.json, out)
    print(f"{pair['episodes']} episodes: both land {pair['both']}, only {labels[0]} {pair['only_a']}, "
          f"only {labels[1]} {pair['only_b']}, neither {pair['neither']}; sign test on the discordant "
          f"ones p = {pair['sign_test_p']:.3f}")  # fmt: skip
    for name, f in out["failures"].items():
        print(f"{name}: {f['failures']} failures: miss {f['miss']}, vertical {f['vertical']}, speed {f['speed']}, "
              f"path bound {f['path_bound']}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
