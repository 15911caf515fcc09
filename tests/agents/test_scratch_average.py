"""The averaged actor of a from-scratch run (``[train] policy_average``): its arithmetic, how a chunk
that carries one ranks and what it offers, its place in the checkpoint, and its setting's checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rventry_agents.config import ConfigError
from rventry_agents.scratch_config import load_config


def _sel(success: float, miss: float) -> dict:
    return {"success_rate": success, "miss_km_p50": miss}


def test_the_average_weighs_the_average_before_by_b_and_starts_at_the_first_chunks_actor():
    pytest.importorskip("jax")
    from rventry_agents.scratch import _averaged

    first = {"params": {"w": np.array([1.0, 2.0]), "b": np.array(4.0)}}
    second = {"params": {"w": np.array([3.0, -2.0]), "b": np.array(0.0)}}
    assert _averaged(None, first, 0.75) is first
    avg = _averaged(first, second, 0.75)
    np.testing.assert_allclose(avg["params"]["w"], [1.5, 1.0])  # 0.75 * before + 0.25 * the chunk's
    np.testing.assert_allclose(avg["params"]["b"], 3.0)
    again = _averaged(avg, second, 0.75)  # the weight of the first chunk's actor shrinks by b a chunk
    np.testing.assert_allclose(again["params"]["w"], 0.75**2 * np.array([1.0, 2.0]) + (1 - 0.75**2) * np.array([3.0, -2.0]))


def test_a_chunk_ranks_by_the_better_of_its_own_actor_and_its_average_and_a_tie_goes_to_its_own():
    from rventry_agents.scratch import _best, chunk_rank, selected_evaluation

    plain = {"select": _sel(0.5, 2.0)}
    better_average = {"select": _sel(0.5, 2.0), "average": {"select": _sel(0.75, 3.0)}}
    worse_average = {"select": _sel(0.5, 2.0), "average": {"select": _sel(0.25, 1.0)}}
    tied = {"select": _sel(0.5, 2.0), "average": {"select": _sel(0.5, 2.0)}}
    assert selected_evaluation(plain) is plain["select"]
    assert selected_evaluation(better_average) is better_average["average"]["select"]
    assert selected_evaluation(worse_average) is worse_average["select"]
    assert selected_evaluation(tied) is tied["select"]
    assert chunk_rank(better_average) > chunk_rank(plain) == chunk_rank(worse_average) == chunk_rank(tied)
    # the run's best chunk is the one whose better policy ranks first: here the one by its average
    assert _best([plain, better_average, worse_average], "standard") is better_average
    closer = {"select": _sel(0.75, 2.5)}  # the same success nearer the target beats the average's
    assert _best([better_average, closer], "standard") is closer


def test_the_checkpoint_keeps_the_average_and_gives_it_back_or_none_or_refuses_another_shape(tmp_path):
    pytest.importorskip("flax")
    from rventry_agents.scratch import _restored_average
    from rventry_agents.scratch_state import AVERAGE, CHECKPOINT, Checkpoint

    actor = {"params": {"Dense_0": {"kernel": np.arange(6.0).reshape(2, 3), "bias": np.zeros(3)}}}
    state = {"actor": actor, "step": np.array(7)}
    Checkpoint.write(tmp_path, state, 60.0, [{"timesteps": 7, "stage": 1}], 1.0, 7, average=actor)
    point = Checkpoint.read(tmp_path)
    zeros = {"params": {"Dense_0": {"kernel": np.zeros((2, 3)), "bias": np.ones(3)}}}
    back = point.average(zeros)
    np.testing.assert_array_equal(back["params"]["Dense_0"]["kernel"], actor["params"]["Dense_0"]["kernel"])
    np.testing.assert_array_equal(back["params"]["Dense_0"]["bias"], np.zeros(3))

    class TS:  # what _resumed_average reads of a training state
        class actor_ts:
            params = zeros

    assert _restored_average(point, TS, point.history, "standard")["params"]["Dense_0"]["kernel"][1, 2] == 5.0
    # its last chunk flew another rung (another selection set) than the run goes on with: afresh
    assert _restored_average(point, TS, [{"timesteps": 7, "rung": "standard"}], "wide") is None
    assert _restored_average(None, TS, [], "standard") is None
    wider = {"params": {"Dense_0": {"kernel": np.zeros((2, 4)), "bias": np.zeros(4)}}}
    with pytest.raises(ConfigError, match=r"averaged actor's .*bias.* has shape \(3,\) and this config's \(4,\)"):
        point.average(wider)
    (tmp_path / CHECKPOINT / AVERAGE).write_bytes(b"not msgpack")
    with pytest.raises(ConfigError, match="is not an average of this config's actor"):
        point.average(zeros)
    Checkpoint.write(tmp_path, state, 60.0, [], 1.0, 7)  # a run without an average writes none
    assert not (tmp_path / CHECKPOINT / AVERAGE).exists() and Checkpoint.read(tmp_path).average(zeros) is None
    assert json.loads((tmp_path / CHECKPOINT / "state.json").read_text())["timesteps"] == 7


@pytest.mark.parametrize("value", [0.0, 1.0, -0.5, float("nan")])
def test_a_policy_average_outside_0_to_1_is_refused_by_name(value):
    with pytest.raises(ConfigError, match=r"\[train\] policy_average must be a finite number > 0 and < 1"):
        load_config({"train": {"policy_average": value}})


def test_a_policy_average_is_a_setting_a_stage_may_turn_on_and_left_out_of_a_config_without_it():
    cfg = load_config({"stages": [{"when_select_success": 0.5, "train": {"policy_average": 0.5}}]})
    assert [c.train.policy_average for _, c in cfg.stage_configs()] == [None, 0.5]
    # a config without it writes no key, so runs recorded before the setting existed resume under it
    assert "policy_average" not in load_config().to_dict()["train"]
