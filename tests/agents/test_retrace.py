"""studies/retrace.py: two runs' chunk histories compared to the bit."""

import json

import pytest
from script_modules import load_script  # (tests/ is on the path)


@pytest.fixture(scope="module")
def retrace():
    return load_script("studies/retrace")


def _chunk(steps, success=0.5, std=(0.1, 0.2)):
    return {"timesteps": steps, "exploration_std": list(std),
            "select": {"success_rate": success, "miss_km_p50": 2.0},
            "curriculum": {"window_s": 60.0, "frontier_success": 0.5}}  # fmt: skip


def _write(path, chunks):
    path.write_text(json.dumps(chunks))
    return str(path)


def test_identical_shared_chunks_pass_and_a_differing_one_is_named(retrace, tmp_path, capsys):
    a = _write(tmp_path / "a.json", [_chunk(1), _chunk(2), _chunk(3)])
    b = _write(tmp_path / "b.json", [_chunk(1), _chunk(2)])  # a run that stopped earlier
    assert retrace.main([a, b, "--json", str(tmp_path / "same.json")]) == 0
    assert "2 of 2 shared chunks identical, through 2 steps" in capsys.readouterr().out
    same = json.loads((tmp_path / "same.json").read_text())
    assert (same["identical"], same["shared_chunks"], same["through_steps"], same["first_difference_steps"]) == (True, 2, 2, None)
    # the last bit of one noise figure differs at the second chunk
    c = _write(tmp_path / "c.json", [_chunk(1), _chunk(2, std=(0.1, 0.2 + 2 ** -52)), _chunk(3, success=0.0)])
    assert retrace.main([a, c, "--json", str(tmp_path / "parted.json")]) == 1
    assert "the runs part at 2 steps (chunk 2 of 3 shared)" in capsys.readouterr().out
    parted = json.loads((tmp_path / "parted.json").read_text())
    assert (parted["identical"], parted["first_difference_steps"]) == (False, 2)
    d = _write(tmp_path / "d.json", [_chunk(7)])
    assert retrace.main([a, d]) == 1
    assert "share no chunk" in capsys.readouterr().err


def test_the_shipped_history_retraces_itself_and_a_malformed_file_is_named(retrace, tmp_path, capsys):
    assert retrace.main([str(retrace.SHIPPED)]) == 0
    assert "176 of 176 shared chunks identical, through 738,197,504 steps" in capsys.readouterr().out
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([{"timesteps": 1, "select": {}}]))
    with pytest.raises(SystemExit) as exc:
        retrace.main([str(bad)])
    assert exc.value.code == 2
    assert "is not a ppo-scratch run's evaluations.json (KeyError" in capsys.readouterr().err
