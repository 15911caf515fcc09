"""The frontier study (studies/frontier.py): a run's policy flown from a window of starts, read back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script

SMALL = {"env": {"rung": "late", "num_envs": 32, "actions": "circular-commands"},
         "ppo": {"num_steps": 32, "num_minibatches": 4, "hidden_layer_sizes": [16, 16]},
         "curriculum": {"kind": "reverse", "first_window_s": 40.0, "frontier_episodes": 16},
         "train": {"total_timesteps": 1024, "chunk_timesteps": 1024, "select_episodes": 8}}  # fmt: skip


@pytest.mark.slow
def test_the_frontier_study_flies_what_the_runs_probe_flies_and_splits_the_miss_along_and_across(tmp_path):
    """From a short run's checkpoint: the study's episodes are the training's own probe's (the same
    starts, keys and actions: the same outcomes), the miss along and across the track from
    the last observation is the impact miss, and a bank read on the circle is never counted clipped
    while the clipped angle of attack's share is a share of the steps."""
    pytest.importorskip("rejax")
    import jax

    from rventry_agents.scratch import last_state, train_scratch

    study = load_script("studies/frontier")
    out = tmp_path / "run"
    train_scratch(json.loads(json.dumps(SMALL)), out=out, timesteps=1024, progress=lambda s: None)
    trainer, ts, steps = last_state(out)
    assert steps == 1024 and trainer.env.actions == "circular-commands"
    lo, hi = 30.0, 45.0
    o = study.fly(trainer, ts, lo, hi, 16, seed=3)
    probe = trainer.probe(ts, lo, hi, jax.random.PRNGKey(3))
    log_std = ts.actor_ts.params["params"]["action_log_std"]
    r = study.summarize(trainer, o, steps, lo, hi, log_std)
    # the same episodes: the same outcomes, to float32's rounding (two programs, fused apart)
    for key in ("success_rate", "miss_within_rate", "vertical_within_rate", "speed_within_rate", "violation_rate"):
        assert r[key] == probe[key], key
    for key in ("miss_km_p50", "vertical_error_deg_p50", "speed_error_mps_p50"):
        assert r[key] == pytest.approx(probe[key], rel=1e-4, abs=1e-3), key
    miss = np.asarray(o["miss_km"], float)
    assert np.all(miss > 0)
    from rventry_env.envs.observation import RANGE_SCALE, feature_index

    last = np.asarray(o["last_obs"], float)
    to_go = last[:, feature_index("range_to_go")] * RANGE_SCALE / 1e3
    split = np.hypot(to_go * last[:, feature_index("cos_heading_error")], to_go * last[:, feature_index("sin_heading_error")])
    assert np.allclose(split, miss, rtol=0.02, atol=0.05)
    assert r["miss_along_km"][0] <= r["miss_along_km"][1] <= r["miss_along_km"][2]
    share = np.asarray(o["clipped_share"], float)
    assert np.all(share[:, 1] == 0.0) and np.all((share[:, 0] >= 0) & (share[:, 0] <= 1))
    assert r["clipped"] == {"alpha": True, "bank": False} and len(r["log_std"]) == 2
    assert np.all(np.asarray(o["steps"]) > 0) and np.all(np.isfinite(np.asarray(o["output_mean"])))
    text = study.report(r)
    assert "bank output" in text and "read on the circle: not clipped" in text and "steps past its clip" in text
    # the first inputs are the first observations as the actor reads them, scaled by the run's statistics
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    params = trainer.params._replace(starts=trainer.env.base.start_params(trainer.curriculum.starts_between(lo, hi)))
    obs0 = np.stack([np.asarray(trainer.env.reset(k, params)[0], float) for k in keys])
    rms = ts.obs_rms_state
    z = (obs0 - np.asarray(rms.mean, float)) / np.sqrt(np.asarray(rms.var, float) + 1e-8)
    np.testing.assert_allclose(np.asarray(o["first_inputs"], float), z, rtol=1e-4, atol=1e-4)
    furthest = r["first_input_p50_furthest"]
    assert len(furthest) == 5 and list(furthest.values()) == sorted(furthest.values(), reverse=True)
    assert max(furthest.values()) == pytest.approx(np.max(np.median(np.abs(z), axis=0)), rel=1e-4)
    assert r["normalized_inputs"] and 0.0 <= r["saturated_share"][0] <= r["saturated_share"][2] <= 1.0
    assert "standard deviations of the run's observation statistics" in text and "past |pre-activation| 2" in text
    # a first layer scaled up a million times saturates every unit whose input is not exactly zero
    big = jax.tree_util.tree_map(lambda a: a, ts.actor_ts.params)
    layer = big["params"]["features"]["Dense_0"]
    layer["kernel"], layer["bias"] = layer["kernel"] * 1e6, layer["bias"] * 0 + 1e6
    loud = study.fly(trainer, ts.replace(actor_ts=ts.actor_ts.replace(params=big)), lo, hi, 4, seed=3)
    assert np.all(np.asarray(loud["saturated_share"]) == 1.0)
    assert np.all(np.asarray(o["saturated_share"]) < 1.0)
    # the last chunk's policy exported (studies/last_policy.py): here the run's one chunk, the one it selected
    exported = load_script("studies/last_policy").export_last(out, tmp_path / "last")
    assert exported["timesteps"] == 1024 and exported["provenance"]["chunk"].startswith("the run's last")
    with np.load(out / "policy.npz") as selected, np.load(tmp_path / "last" / "policy.npz") as last:
        assert sorted(selected.files) == sorted(last.files)
        for key in selected.files:
            np.testing.assert_array_equal(selected[key], last[key], err_msg=key)


def test_the_curves_study_reads_a_runs_best_last_and_lowest_chunks_and_writes_its_plot_with_them(tmp_path):
    """studies/curves.py: the best chunk is the first of equals (as the run's selection ranks them),
    the lowest point leaves out the stage's first chunks, the plot and the record are written together."""
    study = load_script("studies/curves")
    run = tmp_path / "run"
    run.mkdir()
    success = [0.7, 0.0, 0.5, 0.9, 0.6, 0.3, 0.9, 0.8, 0.4, 0.7, 0.6, 0.5]
    hist = [{"timesteps": 1000 * (i + 1), "select": {"success_rate": s}} for i, s in enumerate(success)]
    (run / "evaluations.json").write_text(json.dumps(hist))
    r = study.summary(*study.curve(run, start=1000))  # the first chunk left out: a stage from its step
    assert r["chunks"] == 11 and r["best"] == 0.9 and r["best_at"] == 4000
    assert r["last"] == 0.5 and r["last_at"] == 12000
    assert r["last10_mean"] == pytest.approx(np.mean(success[2:])) and r["last10_min"] == 0.3
    assert r["min_after_settling"] == 0.4  # 0.0 and 0.3 lie in the first five chunks
    with pytest.raises(ValueError, match="no chunk past 12,000 steps"):
        study.curve(run, start=12000)
    study.plot({"a s1": study.curve(run)}, tmp_path / "c.png", "t")
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_the_curves_study_reads_where_a_curriculum_first_took_each_window_and_refuses_a_run_without_one(tmp_path):
    """studies/curves.py --window: each window's first chunk (its step and wall time), the chunks of a
    stage past ``start`` alone, and a clear error for a chunk with no curriculum window."""
    study = load_script("studies/curves")
    run = tmp_path / "run"
    run.mkdir()
    window = [60.0, 60.0, 75.0, 75.0, 75.0, 94.0, 117.0, 117.0]
    hist = [{"timesteps": 1000 * (i + 1), "wall_s": 10.0 * (i + 1), "select": {"success_rate": 0.0},
             "curriculum": {"window_s": w}} for i, w in enumerate(window)]  # fmt: skip
    (run / "evaluations.json").write_text(json.dumps(hist))
    steps, w, first = study.windows(run)
    assert steps.tolist() == [1000.0 * (i + 1) for i in range(8)] and w.tolist() == window
    assert [(f["window_s"], f["timesteps"], f["wall_s"]) for f in first] == [
        (60.0, 1000, 10.0), (75.0, 3000, 30.0), (94.0, 6000, 60.0), (117.0, 7000, 70.0)]
    _, _, first = study.windows(run, start=3000)  # a stage from that step: its first chunk is a window's first
    assert [(f["window_s"], f["timesteps"]) for f in first] == [(75.0, 4000), (94.0, 6000), (117.0, 7000)]
    study.plot({"a s1": study.curve(run)}, tmp_path / "w.png", "t", windows={"a s1": study.windows(run)[:2]})
    assert (tmp_path / "w.png").stat().st_size > 1000
    hist[4]["curriculum"] = None  # a stage without the curriculum
    (run / "evaluations.json").write_text(json.dumps(hist))
    with pytest.raises(ValueError, match="no curriculum window in the chunk at 5,000 steps"):
        study.windows(run)
