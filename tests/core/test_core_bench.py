"""benchmarks/rhs_forms.py: the op counts behind the README's no-trigonometry discussion."""


import numpy as np
import pytest
from script_modules import load_script  # (tests/ is on the path)


@pytest.fixture(scope="module")
def bench():
    return load_script("benchmarks/rhs_forms")


def test_op_counts_separate_trigonometry(bench):
    rv, sph, cart = (bench.op_count(name) for name in ("rv-Euler", "spherical", "Cartesian"))
    assert rv["trig"] == 0 and rv["sqrt"] == 0  # Eqs. Ex1-EOM-rvEuler: plain arithmetic
    assert sph["trig"] == 6  # sin and cos of gamma, psi and latitude, each once
    assert cart["sqrt"] == 1 and cart["trig"] == 0
    # rv-Euler needs more arithmetic than spherical coordinates (measured 95 vs 15)
    assert rv["arithmetic"] > 3 * sph["arithmetic"]
    assert bench.op_count("rv-Euler", cse=True)["arithmetic"] <= rv["arithmetic"]
    entry = bench.op_count("entry (rv-Euler)")
    assert entry["trig"] == 2 and entry["exp/log/pow"] >= 3  # cos/sin of the bank; density and aero exps
    assert not any(c["other"] for c in (rv, sph, cart, entry))


@pytest.mark.parametrize("name", ["rv-Euler", "spherical", "Cartesian", "entry (rv-Euler)"])
def test_throughput_times_the_same_function_on_scalars_and_batches(bench, name):
    """The scalar (Python floats) and batched (NumPy) timings evaluate identical rates: a fair race."""
    from rventry_env.core.backend import MATH, NUMPY

    _, f = bench._form(name)
    x = bench.random_states(name, 7)
    batched = np.array(np.broadcast_arrays(*f(tuple(x), NUMPY), np.zeros(7))[:-1])
    for j in range(7):
        scalar = np.array(f(x[:, j].tolist(), MATH), dtype=float)
        np.testing.assert_allclose(scalar, batched[:, j], rtol=1e-13, atol=1e-13 * np.abs(batched[:, j]).max())
    rates = bench.throughput(name, batches=(1, 7), min_time=0.002)
    assert set(rates) == {"scalar", 1, 7} and all(np.isfinite(v) and v > 0 for v in rates.values())


def test_random_states_are_one_physical_state_in_every_form(bench):
    """With one seed, the rv-Euler, spherical and Cartesian draws are the same positions and velocities."""
    from rventry_env.core.conversions import cartesian_from_rv_euler, cartesian_from_spherical

    cart = bench.random_states("Cartesian", 6).T
    rv = bench.random_states("rv-Euler", 6).T
    sph = bench.random_states("spherical", 6).T
    for r_e, v_e in (cartesian_from_rv_euler(rv), cartesian_from_spherical(sph)):
        np.testing.assert_allclose(r_e, cart[:, :3], rtol=1e-12)
        np.testing.assert_allclose(v_e, cart[:, 3:], rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(rv[:, 1:5], axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(rv[:, 6:10], axis=1), 1.0, atol=1e-14)
    radius = np.linalg.norm(cart[:, :3], axis=1)
    assert np.all((radius >= 6.6e6) & (radius <= 8e6))
    entry = bench.random_states("entry (rv-Euler)", 6).T
    assert entry.shape == (6, 12) and np.all((entry[:, 10] >= 0.05) & (entry[:, 10] <= 0.3))
