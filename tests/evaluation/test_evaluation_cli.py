"""``rventry compare`` and ``rventry evaluate`` end to end, on a few episodes."""

from __future__ import annotations

import json

import pytest

from rventry_env.cli import main


@pytest.mark.slow
def test_compare_on_a_few_episodes_writes_the_report_and_plots(tmp_path, capsys):
    out, plots = tmp_path / "c.json", tmp_path / "plots"
    args = ["compare", "--episodes", "2", "--mpc-episodes", "1", "--seed", "5", "--workers", "1", "--json", str(out),
            "--plots", str(plots)]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(out.read_text())
    names = ("learned", "DAgger of mpc-flight", "DAgger of mpc", "plain PPO", "TV-LQR", "TV-LQR + estimation", "re-planning (mpc)",
             "reference (open loop)")
    assert set(doc["runs"]) == {f"{case}/{name}" for case in ("nominal", "dispersed") for name in names}
    assert doc["runs"]["dispersed/TV-LQR"]["n_episodes"] == 2 and doc["dispersion_set"] == "standard"
    mpc = doc["runs"]["dispersed/re-planning (mpc)"]
    assert mpc["n_episodes"] == 1 and mpc["episodes"][0]["replans"] >= 10
    assert mpc["summary"]["replanning"]["solve_time_s"]["p50"] > 0
    assert [e["dispersion"]["density"] != 0 for e in doc["runs"]["dispersed/TV-LQR"]["episodes"]] == [True, True]
    # the nominal TV-LQR flight tracks the guidance reference to a success
    assert doc["runs"]["nominal/TV-LQR"]["summary"]["success_rate"] == 1.0
    for key, check in doc["targets"].items():
        assert set(check) == {"target", "measured", "met"}, key
    # the learned policy's margin over TV-LQR without estimation, on the same episodes
    gain = doc["targets"]["success_over_lqr"]
    runs = doc["runs"]
    assert gain["target"] == 0.10 and gain["measured"] == pytest.approx(
        runs["dispersed/learned"]["summary"]["success_rate"] - runs["dispersed/TV-LQR"]["summary"]["success_rate"])
    assert doc["targets"]["dispersed_success_rate"]["target"] == 0.95  # the standard set's
    assert sorted(p.name for p in plots.iterdir()) == ["dispersed_outcomes.png", "dispersed_trajectories.png",
                                                       "nominal_trajectories.png"]  # fmt: skip
    printed = capsys.readouterr().out
    assert "Standard set, seeds 5-6: 2 episodes per law (mpc: 1)" in printed and "Best on the standard set: " in printed
    assert "NOT met" not in printed and doc["verdict"][0].startswith("Best on the standard set: ")
    # the tables fit a 100-column terminal, every cell on one line: one table line per law
    assert max(len(line) for line in printed.splitlines() if "─" in line) <= 100
    import re

    for law in ("learned", "dagger-flight", "dagger", "ppo-plain", "lqr", "lqr-est", "mpc", "reference"):
        rows = [line for line in printed.splitlines() if re.match(rf"{re.escape(law)}\s+(yes|no|\d)", line)]
        assert len(rows) == 2, (law, rows)


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


def test_evaluate_reports_the_precision_tier_and_intervals_on_a_new_set(tmp_path, capsys):
    out = tmp_path / "e.json"
    assert main(["evaluate", "--agent", "reference", "--episodes", "3", "--dispersion", "peer-0.1", "--workers", "1",
                 "--json", str(out)]) == 0  # fmt: skip
    doc = json.loads(out.read_text())
    s = doc["summary"]
    lo, hi = s["success_rate_ci"]
    assert 0.0 <= lo <= s["success_rate"] <= hi <= 1.0
    lo, hi = s["precision_success_rate_ci"]
    assert 0.0 <= lo <= s["precision_success_rate"] <= hi <= 1.0 and s["precision_success_rate"] <= s["success_rate"]
    assert s["miss_m"]["p50"] <= s["miss_m"]["p95"] <= s["miss_m"]["p99"]
    assert s["precision_thresholds"] == {"miss_m": 100.0, "vertical_error_deg": 2.0, "alpha_final_deg": 2.0,
                                         "speed_error_mps": 25.0}  # fmt: skip
    assert doc["dispersion"]["shape"] == "gaussian" and doc["dispersion"]["mass"] == pytest.approx(0.005)
    assert all(e["dispersion"]["mass"] != 0 for e in doc["episodes"])
    assert "precision" in capsys.readouterr().out


def test_several_jobs_on_one_pool_fly_what_each_flies_alone():
    """``rventry compare`` flies every law on one pool: each job gets exactly its own episodes, in its seeds' order."""
    import numpy as np

    from rventry_env.evaluation.parallel import EvaluationJob, evaluate, evaluate_many
    from rventry_env.task import EntryTask

    task = EntryTask()
    jobs = [(EvaluationJob("lqr", "standard", task), [5, 3, 4]), (EvaluationJob("reference", "none", task), [0])]
    seen = []
    together = evaluate_many(jobs, workers=2, progress=lambda j, k: seen.append((j, k)))
    assert sorted(seen) == [(0, 3), (1, 1)]
    for (job, seeds), batch in zip(jobs, together):
        alone = evaluate(job, seeds)
        assert batch.seeds.tolist() == seeds
        for key in ("miss_km", "vertical_error_deg", "speed_error_mps", "cost"):
            np.testing.assert_array_equal(getattr(batch, key), getattr(alone, key))
    with pytest.raises(ValueError, match="no episodes to evaluate"):
        evaluate_many([(jobs[0][0], [])])


def test_compare_reads_its_columns_and_episode_counts_from_the_agents_cards(monkeypatch):
    """The library names no learning agent: the installed package declares its cards, and a law that
    re-plans in flight says so itself. A card that is not an AgentCard is refused with its entry point."""
    from rventry_env.evaluation import agents
    from rventry_env.evaluation.compare_report import _why

    cards = agents.agent_cards()
    compared = [c.name for c in agents.compared_agents()]
    assert compared == ["dagger-flight", "dagger", "ppo-plain", "lqr", "lqr-est", "mpc", "reference"]
    assert set(compared) <= set(agents.agent_names())  # every column is an agent load_agent knows
    assert [n for n, c in cards.items() if c.replans] == ["mpc", "mpc-flight", "mpc-peer"]
    assert _why("lqr").startswith("it is the cheapest feedback law") and _why("x.zip") == "it is the policy x.zip"

    class Point:
        name = "bad"

        def load(self):
            return ("not a card",)

    monkeypatch.setattr(agents, "entry_points", lambda group: [Point()])
    with pytest.raises(TypeError, match="entry point bad .* not an AgentCard"):
        agents.agent_cards()


def test_every_command_offers_the_named_dispersion_sets_from_one_table():
    from rventry_env.evaluation.cli import DISPERSIONS
    from rventry_env.task import NAMED_SETS, SET_CHOICES, Dispersion

    assert DISPERSIONS == SET_CHOICES == ("none", *NAMED_SETS)
    assert [Dispersion.named(n).name for n in NAMED_SETS] == list(NAMED_SETS)  # each set knows its own name
    assert Dispersion.named("peer-0.1") == Dispersion.peer(0.1) and Dispersion.named("none").is_zero
    with pytest.raises(ValueError, match="no dispersion set 'narrow'; named sets: .*'peer-0.1'"):
        Dispersion.named("narrow")
