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

    from rventry_agents.scratch import train_scratch

    study = load_script("studies/frontier")
    out = tmp_path / "run"
    train_scratch(json.loads(json.dumps(SMALL)), out=out, timesteps=1024, progress=lambda s: None)
    trainer, ts, steps = study.restore(out)
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
