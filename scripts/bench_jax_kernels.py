"""How the compiled JAX step is cut into GPU kernels, and what that costs: variants of one scan.

The functional env's step (``bench_jax.py``'s ``functional_speed``: ``jit`` of ``lax.scan`` over
``vmap``-ed gymnax steps with autoreset, the standard set) compiled in variants:

* ``base``: as the package compiles it;
* ``unroll1``: XLA's loop-fusion unrolling off (``xla_gpu_experimental_max_unroll_factor = 1``);
* ``stages``: a fusion barrier after each right-hand side (``kernel_cuts=("stages",)``), so that
  a step is a kernel per RK4 stage rather than one kernel holding the whole step;
* ``reset``: a fusion barrier on the reset's outputs (``kernel_cuts=("reset",)``), so that
  gymnax's autoreset selection does not take the whole reset into its kernel;
* ``stages+reset``: both.

For each variant and size it prints vehicle-steps/s (float64, and float32 with ``--float32``) and
the largest difference of the final state from ``base`` (the variants compute the same function;
only fusion, and with it rounding, may differ). With ``--ptxas`` (a GPU, and CUDA's ``ptxas`` on
the PATH or in /usr/local/cuda/bin) it dumps each float64 variant's PTX at the first size and
runs ``ptxas -v`` on it: each kernel's registers per thread, spill bytes and launch bounds.

Run: ``python scripts/bench_jax_kernels.py --sizes 1048576 4194304 --ptxas --json PATH``
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

UNROLL_OPTIONS = ("xla_gpu_experimental_max_unroll_factor", "xla_gpu_max_kernel_unroll_factor")
VARIANTS = ("base", "reset", "stages", "stages+reset", "unroll1")


def accepted_option(names) -> str | None:
    """The first of ``names`` this jaxlib takes as a compile option (names move between versions)."""
    import jax
    import jax.numpy as jnp

    for name in names:
        try:
            jax.jit(lambda x: x + 1.0, compiler_options={name: 1})(jnp.ones(2))
            return name
        except Exception:  # noqa: BLE001 - "No such compile option"
            continue
    return None


def ptxas_report(dump_dir: str, ptxas: str) -> list[dict]:
    """``ptxas -v`` over every PTX file XLA dumped: per kernel, registers, spills and launch bounds."""
    rows = []
    for path in sorted(glob.glob(os.path.join(dump_dir, "*.ptx"))):
        text = Path(path).read_text()
        arch = re.search(r"^\.target\s+(\w+)", text, re.M)
        bounds = {k: re.findall(rf"\.{k}\s+([\d, ]+)", text) for k in ("reqntid", "maxntid", "minnctapersm", "maxnreg")}
        res = subprocess.run([ptxas, "-v", f"-arch={arch.group(1) if arch else 'sm_90'}", path, "-o", os.devnull],
                             capture_output=True, text=True)  # fmt: skip
        kernel = None
        for line in (res.stdout + res.stderr).splitlines():
            m = re.search(r"Compiling entry function '([^']+)'", line)
            if m:
                kernel = {"file": os.path.basename(path), "kernel": m.group(1), "ptx_lines": text.count("\n"),
                          "bounds": {k: v for k, v in bounds.items() if v}}  # fmt: skip
                rows.append(kernel)
            m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
            if m and kernel is not None:
                kernel.update(stack=int(m.group(1)), spill_stores=int(m.group(2)), spill_loads=int(m.group(3)))
            m = re.search(r"Used (\d+) registers", line)
            if m and kernel is not None:
                kernel["registers"] = int(m.group(1))
        if res.returncode != 0:
            rows.append({"file": os.path.basename(path), "ptxas_error": res.stderr[-400:]})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[8192])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--float32", action="store_true", help="also float32, each variant at the largest size")
    ap.add_argument("--ptxas", action="store_true", help="dump the PTX and report ptxas -v per kernel")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()

    from rventry_env.core.backend import jax_ns, prefer_fused_cpu_runtime

    prefer_fused_cpu_runtime()
    import jax

    jax_ns("float64")  # float64 on, as the float64 env turns it on
    from bench_jax import functional_speed

    from rventry_env.task import EntryTask
    from rventry_env.util.files import write_json

    dev = jax.devices()[0]
    unroll = accepted_option(UNROLL_OPTIONS)
    ptxas = shutil.which("ptxas") or ("/usr/local/cuda/bin/ptxas" if os.path.exists("/usr/local/cuda/bin/ptxas") else None)
    res = {"device": f"{dev} ({dev.device_kind})", "jax": jax.__version__, "unroll_option": unroll, "runs": [],
           "ptxas": {}}  # fmt: skip
    print(f"JAX {jax.__version__} on {dev} ({dev.device_kind}); unroll option: {unroll}; ptxas: {ptxas}", flush=True)
    substeps = EntryTask().substeps

    def options(variant, dump=None):
        opts = {}
        if "unroll1" in variant:
            if unroll is None:
                return None
            opts[unroll] = 1
        if dump:
            opts["xla_dump_to"] = dump
        return opts

    base_state = {}
    jobs = [(v, n, "float64") for n in args.sizes for v in args.variants]
    if args.float32:
        jobs += [(v, max(args.sizes), "float32") for v in args.variants]
    for variant, n, dtype in jobs:
        dump = None
        if args.ptxas and ptxas and dtype == "float64" and n == args.sizes[0]:
            dump = tempfile.mkdtemp(prefix=f"xla_{variant.replace('+', '_')}_")
        opts = options(variant, dump)
        if opts is None:
            print(f"{variant}: this jaxlib takes none of {UNROLL_OPTIONS}; skipped", flush=True)
            continue
        t0 = time.perf_counter()
        f = functional_speed(n, dtype, args.steps, substeps, compiler_options=opts, keep_state=True,
                             kernel_cuts=[c for c in ("stages", "reset") if c in variant])  # fmt: skip
        leaves = [np.asarray(x, dtype=np.float64) for x in jax.tree.leaves(f.pop("state"))]
        f.pop("rewards")
        key = (n, dtype)
        if variant == "base":
            base_state[key] = leaves
        diff = None
        if key in base_state:
            diff = max(float(np.nanmax(np.abs(a - b), initial=0.0)) for a, b in zip(leaves, base_state[key]))
        row = {"variant": variant, **f, "compiler_options": {k: v for k, v in opts.items() if k != "xla_dump_to"},
               "max_state_diff_from_base": diff, "wall_s": time.perf_counter() - t0}  # fmt: skip
        res["runs"].append(row)
        print(f"{variant:>14} {dtype} N = {n:>9,}: {f['vehicle_steps_per_s']:>15,.0f} vehicle-steps/s, compile "
              f"{f['first_call_s']:.1f} s; final state vs base: {diff}", flush=True)  # fmt: skip
        if dump:
            rep = ptxas_report(dump, ptxas)
            res["ptxas"][variant] = rep
            big = sorted((r for r in rep if "registers" in r), key=lambda r: -r["ptx_lines"])[:4]
            for r in big:
                print(f"    kernel {r['kernel'][:40]:40} {r['ptx_lines']:>7} PTX lines, {r['registers']:>3} registers, "
                      f"spill {r.get('spill_stores', 0)}/{r.get('spill_loads', 0)} B, stack {r.get('stack', 0)} B, "
                      f"bounds {r['bounds']}", flush=True)  # fmt: skip
            print(f"    {len(rep)} kernels in {len(glob.glob(os.path.join(dump, '*.ptx')))} PTX files", flush=True)
            shutil.rmtree(dump, ignore_errors=True)
        if args.json:
            write_json(args.json, res)


if __name__ == "__main__":
    main()
