"""Shared test set-up: one BLAS thread, a deterministic hypothesis profile and a headless matplotlib."""

import os
import sys

# NumPy's BLAS reads its thread count once, when NumPy loads: set it before anything imports NumPy.
# Two pytest-xdist workers on a 2-core machine each get one thread instead of fighting over four.
NUMPY_LOADED_BEFORE_CONFTEST = "numpy" in sys.modules
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ["OMP_NUM_THREADS"])

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
