"""The from-scratch throughput scan (benchmarks/scratch_scan.py): its variants are read and checked
before anything trains."""

import pytest

from rventry_agents.config import ConfigError
from tests.script_modules import load_script

scan = load_script("benchmarks/scratch_scan")


def test_a_variant_names_its_changes_as_toml_values_and_a_list_keeps_its_commas():
    name, one_core, changes = scan.parse_variant("net:ppo.hidden_layer_sizes=[32, 32],env.num_envs=1024")
    assert (name, one_core) == ("net", False)
    assert changes == {"ppo": {"hidden_layer_sizes": [32, 32]}, "env": {"num_envs": 1024}}
    assert scan.parse_variant("shipped@1") == ("shipped", True, {})


def test_a_variant_config_is_the_shipped_first_sections_with_the_changes_and_the_chunks_asked():
    cfg = scan.variant_config({"env": {"num_envs": 1024}}, chunks=3)
    assert cfg["env"]["num_envs"] == 1024 and cfg["ppo"]["num_steps"] == 64
    assert cfg["train"]["total_timesteps"] == 3 * cfg["train"]["chunk_timesteps"]
    assert cfg.get("stages", ()) in ((), [])


@pytest.mark.parametrize("text, says", [
    ("bad:num_envs=1024", "is not SECTION.KEY=VALUE"),
    ("bad:env.num_envs", "is not SECTION.KEY=VALUE"),
    ("bad:env.dtype=float32", "is not TOML"),
])  # fmt: skip
def test_a_malformed_variant_is_named(text, says):
    with pytest.raises(SystemExit, match=says):
        scan.parse_variant(text)


def test_a_variant_the_config_refuses_is_refused_before_anything_trains():
    with pytest.raises(SystemExit, match=r"no section \[envs\]"):
        scan.variant_config({"envs": {"num_envs": 8}}, chunks=2)
    with pytest.raises(ConfigError, match="num_minibatches"):
        scan.variant_config({"ppo": {"num_minibatches": 7}}, chunks=2)
