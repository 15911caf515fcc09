"""Shared test set-up: one BLAS thread, a shared cache of compiled XLA programs, a deterministic hypothesis
profile and a headless matplotlib."""

import os
import sys

# NumPy's BLAS reads its thread count once, when NumPy loads: set it before anything imports NumPy.
# Two pytest-xdist workers on a 2-core machine each get one thread instead of fighting over four.
NUMPY_LOADED_BEFORE_CONFTEST = "numpy" in sys.modules
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ["OMP_NUM_THREADS"])

# XLA's compiled programs kept on disk and shared by every test process (both tiers, their xdist workers
# and the CLI's subprocesses): the training tests build the same programs in run after run (one small
# training call took 105-119 s of a core compiling them, 14-28 s loading them). JAX keys each entry on the
# program, its compile options and flags, and the jax/jaxlib versions, so a changed program compiles
# afresh. A developer's own JAX_COMPILATION_CACHE_DIR is kept.
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                                                ".pytest_cache", "jax-compilation"))  # fmt: skip
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")
os.environ.setdefault("JAX_COMPILATION_CACHE_MAX_SIZE", str(2 * 1024**3))  # least recently used entries go first

# the JAX envs' CPU runtime, asked for as the `rventry` command asks for it, before anything loads JAX
from rventry_env.core.backend import prefer_fused_cpu_runtime  # noqa: E402

prefer_fused_cpu_runtime()

import matplotlib  # noqa: E402

matplotlib.use("Agg")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "rventry", derandomize=True, deadline=None, max_examples=200,
    suppress_health_check=[HealthCheck.too_slow],
)  # fmt: skip
settings.load_profile("rventry")
