"""``rventry compare`` and ``rventry evaluate`` end to end, on a few episodes."""

from __future__ import annotations

import json

import pytest

from rventry_env.cli import main


@pytest.mark.slow
def test_compare_on_a_few_episodes_writes_the_report_and_plots(tmp_path, capsys):
    out, plots = tmp_path / "c.json", tmp_path / "plots"
    assert main(["compare", "--episodes", "2", "--seed", "5", "--json", str(out), "--plots", str(plots)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc["runs"]) == {f"{case}/{name}" for case in ("nominal", "dispersed")
                                for name in ("ppo", "TV-LQR", "reference (open loop)")}  # fmt: skip
    assert doc["runs"]["dispersed/TV-LQR"]["n_episodes"] == 2 and doc["dispersion_set"] == "standard"
    assert [e["dispersion"]["density"] != 0 for e in doc["runs"]["dispersed/TV-LQR"]["episodes"]] == [True, True]
    # the nominal TV-LQR flight tracks the guidance reference to a success
    assert doc["runs"]["nominal/TV-LQR"]["summary"]["success_rate"] == 1.0
    for key, check in doc["targets"].items():
        assert set(check) == {"target", "measured", "met"}, key
    assert sorted(p.name for p in plots.iterdir()) == ["dispersed_outcomes.png", "dispersed_trajectories.png",
                                                       "nominal_trajectories.png"]  # fmt: skip
    printed = capsys.readouterr().out
    assert "2 dispersed episodes (standard set)" in printed and "benchmark's targets" in printed


def test_compare_checks_its_destinations_before_flying(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["compare", "--episodes", "1", "--json", str(tmp_path / "c.json"), "--plots", str(blocker)]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert not (tmp_path / "c.json").exists()


def test_dispersed_is_a_synonym_that_cannot_contradict(tmp_path, capsys):
    args = ["evaluate", "--agent", "reference", "--dispersed", "--dispersion", "wide", "--json", str(tmp_path / "e.json")]
    assert main(args) == 2
    assert "--dispersed means --dispersion standard" in capsys.readouterr().err
