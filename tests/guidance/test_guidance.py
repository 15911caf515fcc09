"""Classical guidance on the reference: the margined guidance reference and the TV-LQR law."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from rventry_env.task import Dispersion
from rventry_env.guidance.reference_replay import ReferencePolicy
from rventry_env.evaluation.rollout import rollout
from rventry_env.guidance.tvlqr import NeighboringOptimalGuidance
from rventry_env.physics import EntryModel, entry_forces
from rventry_env.reference import load_guidance_reference, load_reference


@pytest.fixture(scope="module")
def lqr():
    return NeighboringOptimalGuidance()


def test_guidance_reference_keeps_its_margins_at_the_nodes():
    ref, opt = load_guidance_reference(), load_reference()
    solved = ref.summary()["constants"]["problem"]  # the tightened bounds it was solved with
    assert solved["q_min"] > 12e3 and solved["a_max_g"] < 12.0
    f = entry_forces(tuple(ref.x.T), EntryModel())
    assert f.dynamic_pressure.min() >= solved["q_min"] * (1 - 1e-6)
    assert (f.aero_accel / 9.80665).max() <= solved["a_max_g"] * (1 + 1e-6)
    assert ref.x[-1, 6] == 0.0 and ref.x[-1, 9] == 0.0  # still an exact vertical impact
    assert opt.cost < ref.cost < 2.0 * opt.cost  # margins cost something
    np.testing.assert_array_equal(ref.x[0, :10], opt.x[0, :10])


def test_lqr_linearization_matches_finite_differences(lqr):
    """The gains come from exact Jacobians of the env's own step: check one against differences."""
    from rventry_env.core.integrate import rk4_step
    from rventry_env.physics import entry_rhs

    k = 500
    x0, u0 = lqr.x_ref[k], lqr.u_ref[k]
    a, b = lqr._jacobians(x0[None], u0[None])

    def step(x, u):
        return rk4_step(lambda _t, y: np.array(entry_rhs(list(y), tuple(u), lqr.model)), 0.0, x, lqr.task.dt)

    # absolute steps per component: 1 m of radius, 1e-7 of Euler parameters and angles, 1 mm/s
    eps = np.array([1.0, *[1e-7] * 4, 1e-3, *[1e-7] * 4, 1e-7, 1e-7])
    fd = np.column_stack([(step(x0 + e, u0) - step(x0 - e, u0)) / (2 * e[i]) for i, e in enumerate(np.diag(eps))])
    # each row against its own scale (r's round-off, 6e6 m x 1e-16 / 1e-7, sets row 0's noise floor)
    row_scale = np.abs(fd).max(axis=1, keepdims=True)
    assert np.all(np.abs(a[0] - fd) <= 1e-6 * row_scale + 1e-9)
    du = 1e-5
    fd_u = np.column_stack([(step(x0, u0 + e) - step(x0, u0 - e)) / (2 * du) for e in np.eye(2) * du])
    assert np.all(np.abs(b[0] - fd_u) <= 1e-5 * np.abs(fd_u).max(axis=1, keepdims=True) + 1e-9)


def test_lqr_flies_the_nominal_case_to_success_within_the_cost_budget(lqr):
    b = rollout(lqr, 1)
    assert b.is_success[0] and b.miss_km[0] < 0.1 and b.vertical_error_deg[0] < 2.0
    assert b.cost[0] <= 1.5 * load_reference().cost  # the benchmark's nominal J/J* target


@pytest.mark.slow
def test_lqr_beats_the_open_loop_reference_under_dispersions(lqr):
    closed = rollout(lqr, 24, seed=7, dispersion=Dispersion.standard())
    open_ = rollout(ReferencePolicy(), 24, seed=7, dispersion=Dispersion.standard())
    assert np.median(closed.miss_km) < 0.1 * np.median(open_.miss_km)


def test_lqr_rejects_bad_weights():
    with pytest.raises(ValueError, match="r_weight > 0"):
        NeighboringOptimalGuidance(r_weight=0.0)


@pytest.mark.parametrize("flag", ["--q-margin", "--load-margin"])
def test_solve_rejects_a_bad_margin(flag, tmp_path):
    cmd = [sys.executable, "-m", "rventry_env.cli", "reference", "solve", flag, "0.7", "--out", str(tmp_path / "x.npz")]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 2 and "must lie in [0, 0.5)" in res.stderr
