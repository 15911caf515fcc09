"""The evaluation plots: the conventional bank angle, overlapping flights named, readable axes."""

from __future__ import annotations

import numpy as np

from rventry_env.core import conversions as cv
from rventry_env.task import EntryTask
from rventry_env.evaluation.agents import load_agent
from rventry_env.evaluation.plots import coinciding, conventional_bank_deg, outcomes_figure, unwrapped_bank_deg
from rventry_env.evaluation.rollout import rollout
from rventry_env.reference import load_reference


def test_the_bank_angle_is_drawn_conventional_in_plus_minus_180_deg():
    ref = load_reference()
    x = ref.state(np.linspace(0, ref.tf * 0.97, 500))
    mu = conventional_bank_deg(x)
    shown = np.isfinite(mu)
    assert shown.sum() > 480 and np.all((mu[shown] >= -180) & (mu[shown] < 180))
    np.testing.assert_allclose(mu[shown], np.degrees(cv.conventional_bank(x, x[:, 11]))[shown], atol=1e-9)
    assert np.degrees(np.ptp(x[:, 11])) > 180  # the paper's sigma, unwrapped, spans more
    # a wrap leaves a gap instead of a line across the panel
    assert np.nanmax(np.abs(np.diff(mu))) < 180


def test_the_plotted_bank_angle_is_unwrapped_and_equals_the_conventional_one_modulo_360():
    ref = load_reference()
    x = ref.state(np.linspace(0, ref.tf * 0.97, 500))
    mu = conventional_bank_deg(x)
    unwrapped = unwrapped_bank_deg(x)
    shown = np.isfinite(unwrapped)
    assert shown.sum() > 480
    # no jump of a wrap anywhere: the roll flown, continuous
    assert np.nanmax(np.abs(np.diff(unwrapped[shown]))) < 30
    both = shown & np.isfinite(mu)
    np.testing.assert_allclose(np.mod(unwrapped[both] - mu[both] + 180, 360) - 180, 0, atol=1e-9)
    # a batch (time, episodes) is unwrapped along time, each episode on its own
    pair = unwrapped_bank_deg(np.stack([x, x], axis=1))
    np.testing.assert_array_equal(pair[:, 0], unwrapped)


def test_flights_on_top_of_one_another_are_found():
    lqr = rollout(load_agent("lqr"), 1, record_history=True)
    est = rollout(load_agent("lqr-est"), 1, record_history=True)
    ref = rollout(load_agent("reference"), 1, record_history=True)
    assert coinciding({"lqr": lqr, "lqr-est": est, "reference": ref}) == [["lqr", "lqr-est"]]


def test_outcome_tick_labels_do_not_overlap_and_each_law_has_its_own_row():
    import dataclasses

    batches = {name: rollout(load_agent(name), 12, dispersion="standard") for name in ("lqr", "reference")}
    # a law that lands within a decade (a log axis there once labelled its minor ticks on top of one another)
    narrow = dataclasses.replace(batches["lqr"], miss_km=np.linspace(0.3, 0.6, 12),
                                 vertical_error_deg=np.linspace(0.4, 1.8, 12))  # fmt: skip
    for case in (batches, {"narrow": narrow}):
        _check_outcomes_axes(outcomes_figure(case, EntryTask().success, "a title"), list(case))


def _check_outcomes_axes(fig, laws):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    grid = [fig.axes[i:i + 3] for i in range(0, len(fig.axes), 3)]
    assert len(grid) == len(laws)  # one row of three panels per law: no histogram hides another
    for row, law in zip(grid, laws):
        assert row[0].get_ylabel().splitlines()[0] == law and "12 ep." in row[0].get_ylabel()
        for ax in row:
            assert ax.get_legend() is None  # nothing drawn over the bars
            assert any(line.get_color() == "r" and line.get_linestyle() == "--" for line in ax.get_lines())
    for ax in grid[-1]:  # the bottom row carries the labels of its column
        boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
        boxes.sort(key=lambda b: b.x0)
        assert len(boxes) >= 3
        assert all(a.x1 <= b.x0 for a, b in zip(boxes, boxes[1:])), [t.get_text() for t in ax.get_xticklabels()]
    assert fig._suptitle.get_text().startswith("a title")
