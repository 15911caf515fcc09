"""scripts/bench_rhs.py: the op counts behind the README's no-trigonometry discussion."""

import importlib.util
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "scripts" / "bench_rhs.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_rhs", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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


def test_throughput_runs_on_scalars_and_batches(bench):
    rates = bench.throughput("spherical", batches=(1, 7), min_time=0.003)
    assert set(rates) == {"scalar", 1, 7} and all(v > 0 for v in rates.values())


def test_random_states_are_valid(bench):
    for name in bench.FORMS:
        n, _ = bench._form(name)
        x = bench.random_states(name, 5)
        assert x.shape == (n, 5)
