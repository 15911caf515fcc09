"""Statistics over training seeds (rliable): IQM, mean, intervals, performance profiles."""

import numpy as np
import pytest

from rventry_env.evaluation.seeds import performance_profiles, plot_performance_profiles, seed_statistics


def _iqm(x):
    """The interquartile mean written out independently: the mean of the middle half of the pooled
    scores (scipy's trimmed mean, 25 % cut from each end)."""
    from scipy.stats import trim_mean

    return trim_mean(np.asarray(x, float).ravel(), 0.25)


def test_iqm_and_mean_against_an_independent_formula():
    rng = np.random.default_rng(3)
    s = rng.uniform(0.2, 1.0, size=(8, 4))
    stats = seed_statistics({"a": s}, reps=500)["a"]
    assert stats["runs"] == 8 and stats["tasks"] == 4
    assert stats["iqm"] == pytest.approx(_iqm(s), rel=1e-12)
    assert stats["mean"] == pytest.approx(s.mean(), rel=1e-12)
    for k in ("iqm", "mean"):
        lo, hi = stats[f"{k}_ci"]
        assert lo <= stats[k] <= hi and lo < hi


def test_iqm_ignores_one_collapsed_seed_that_the_mean_does_not():
    """The reason for the IQM: one seed that collapsed moves the mean, not the middle half."""
    good = np.full((7, 3), 0.95)
    bad = np.vstack([good, [[0.0, 0.0, 0.0]]])
    st = seed_statistics({"good": good, "bad": bad}, reps=500)
    assert st["bad"]["iqm"] == pytest.approx(0.95)
    assert st["bad"]["mean"] < st["good"]["mean"] - 0.1


def test_intervals_are_seeded_and_leave_the_global_rng_alone():
    s = {"a": np.random.default_rng(1).uniform(size=(5, 2)), "b": np.random.default_rng(2).uniform(size=(5, 2))}
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    one, two = seed_statistics(s, reps=300, seed=7), seed_statistics(s, reps=300, seed=7)
    assert one == two
    assert np.array_equal(np.random.get_state()[1], before)
    other = seed_statistics(s, reps=300, seed=8)
    assert other["a"]["iqm_ci"] != one["a"]["iqm_ci"]


def test_identical_seeds_give_a_point_interval():
    st = seed_statistics({"a": np.full((4, 2), 0.5)}, reps=200)["a"]
    assert st["iqm_ci"] == pytest.approx([0.5, 0.5]) and st["mean_ci"] == pytest.approx([0.5, 0.5])


def test_performance_profile_is_the_fraction_above_each_threshold(tmp_path):
    s = np.array([[0.1, 0.5], [0.9, 0.7], [0.3, 1.0]])
    taus = np.linspace(0.0, 1.0, 11)
    p = performance_profiles({"a": s}, taus, reps=200)["a"]
    expected = [(s > t).mean() for t in taus]
    assert p["fraction"] == pytest.approx(expected)
    assert all(lo <= f + 1e-12 and f <= hi + 1e-12 for lo, f, hi in zip(p["low"], p["fraction"], p["high"]))
    out = plot_performance_profiles({"a": p}, tmp_path / "profiles.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("scores, match", [
    ({}, "at least one method"),
    ({"a": np.ones(3)}, r"'a' must be a \(runs, tasks\) matrix.*\(3,\)"),
    ({"a": np.ones((0, 2))}, "at least one of each"),
    ({"a": np.array([[0.5, np.nan]])}, "'a' hold NaN"),
])  # fmt: skip
def test_bad_scores_are_named(scores, match):
    with pytest.raises(ValueError, match=match):
        seed_statistics(scores, reps=10)


def test_bad_thresholds_are_named():
    with pytest.raises(ValueError, match="increasing thresholds"):
        performance_profiles({"a": np.ones((2, 2))}, [0.5, 0.2])
