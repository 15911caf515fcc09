"""What a new user meets first: the version, default outputs, the env's time limit and feature
names as Gymnasium sees them, the glossary behind the printed words, and compare's tables."""

from __future__ import annotations

import json
from importlib.metadata import version

import gymnasium as gym
import numpy as np
import pytest

import rventry_env  # noqa: F401  (registers RvEntry-v0)
from rventry_env.cli import build_parser, main
from rventry_env.envs import MAX_EPISODE_STEPS
from rventry_env.envs.observation import feature_index, feature_names


def test_version_is_the_installed_distributions(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"rventry {version('rventry')}"


def test_the_registered_spec_knows_the_time_limit_and_the_env_ends_there_with_its_end_keys():
    assert gym.spec("RvEntry-v0").max_episode_steps == MAX_EPISODE_STEPS
    env = gym.make("RvEntry-v0", dt=0.1)  # 2000 steps of 0.1 s: 200 s, still gliding
    assert env.spec.max_episode_steps == MAX_EPISODE_STEPS
    env.reset(seed=0)
    for n in range(1, MAX_EPISODE_STEPS + 1):
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        if terminated or truncated:
            break
    # Gymnasium's TimeLimit and the environment's own limit cut at the same step; the env closes the episode
    assert (n, terminated, truncated) == (MAX_EPISODE_STEPS, False, True)
    assert info["failure"] == "time limit" and info["is_success"] is False and "miss_km" in info
    with pytest.raises(RuntimeError, match="after the episode ended"):
        env.unwrapped.step(np.zeros(2))


def test_a_shorter_limit_set_the_gymnasium_way_still_ends_like_any_other_episode():
    env = gym.make("RvEntry-v0", max_episode_steps=30)
    assert env.spec.max_episode_steps == 30
    env.reset(seed=1)
    for n in range(1, 100):
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        if terminated or truncated:
            break
    assert (n, truncated, info["failure"]) == (30, True, "time limit")
    # the next episode of the same env is cut at the same step (the limit is read at every reset)
    env.reset(seed=2)
    steps = 0
    while True:
        steps += 1
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        if terminated or truncated:
            break
    assert steps == 30 and info["failure"] == "time limit"


def test_the_vector_env_is_given_the_specs_limit():
    venv = gym.make_vec("RvEntry-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.unwrapped.max_episode_steps == MAX_EPISODE_STEPS
    assert venv.unwrapped.feature_names == feature_names()


def test_feature_names_are_on_the_env_in_observation_order():
    env = gym.make("RvEntry-v0")
    names = env.unwrapped.feature_names
    obs, _ = env.reset(seed=0)
    assert len(names) == obs.shape[0] == env.observation_space.shape[0] == 26
    assert names[feature_index("altitude")] == "altitude" and names[-1] == "load_factor"
    # the altitude feature is h / 40 km
    assert obs[names.index("altitude")] == pytest.approx(37e3 / 40e3, rel=1e-6)


def test_every_printed_term_has_a_glossary_entry_and_the_page_is_generated_from_them(capsys):
    from rventry_env.evaluation import cli as ev, compare_report
    from rventry_env.task.glossary import TERMS, glossary_markdown, term, terms_line

    for name in (*compare_report.TERMS, *ev.EVALUATE_TERMS, "load relief", "navigation", "flyable"):
        t = term(name)
        assert len(t.text) > 40 and t.anchor in glossary_markdown()
    page = glossary_markdown()
    assert all(f"({t.anchor})=" in page and f"## {t.name}" in page for t in TERMS)
    line = terms_line(["precision", "load relief"])
    assert "precision" in line and "load relief" in line and "glossary" in line
    assert main(["glossary", "Load", "Relief"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("load relief") and "12 g" in out
    assert main(["glossary", "no such word"]) == 2
    assert "entries: success" in capsys.readouterr().err


def test_the_glossarys_thresholds_are_the_tasks():
    from dataclasses import replace

    from rventry_env.task.glossary import term
    from rventry_env.task import SuccessThresholds

    assert "5 km" in term("success").text and "100 m" in term("precision").text
    assert replace(SuccessThresholds()).miss_km == 5.0


def test_evaluate_writes_its_report_where_the_default_says_and_names_its_terms(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--agent", "lqr", "--episodes", "2", "--dispersion", "standard", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "out" / "evaluate_lqr_standard.json").read_text())
    assert doc["agent"] == "lqr" and doc["n_episodes"] == 2
    assert "wrote out/evaluate_lqr_standard.json" in out and "terms (" in out and "precision" in out


def _small_compare_doc():
    """A compare report of two cheap laws on a few episodes, as ``rventry compare`` writes it."""
    from rventry_env.evaluation.cli import _document
    from rventry_env.evaluation.parallel import EvaluationJob, evaluate
    from rventry_env.evaluation.summary import summarize
    from rventry_env.reference import load_reference
    from rventry_env.task import EntryTask

    task, j = EntryTask(), float(load_reference().cost)
    runs = {}
    for case, d, n in (("nominal", "none", 1), ("dispersed", "standard", 3)):
        for agent in ("lqr", "reference"):
            batch = evaluate(EvaluationJob(agent, d, task), list(range(n)))
            summary = summarize(batch, j, task)
            runs[f"{case}/{agent}"] = _document(agent, n, d, 0, batch, summary)
    return {"agent": "lqr", "seed": 0, "dispersion_set": "standard", "episodes": {"lqr": 3, "reference": 3},
            "runs": runs}  # fmt: skip


def test_compare_tables_fit_100_columns_without_wrapping_and_the_markdown_says_the_same():
    from rich.console import Console

    from rventry_env.evaluation import compare_report as cr
    from rventry_env.evaluation.cli import print_compare

    doc = _small_compare_doc()
    console = Console(width=100, record=True)
    print_compare(doc, console)
    text = console.export_text()
    import re

    rows = [line for line in text.splitlines() if re.match(r"(lqr|reference)\s+(yes|no|\d)", line)]
    assert len(rows) == 4  # one line per law and table: no cell wrapped onto a second line
    assert "\u2026" not in text  # nor cut short
    assert max(len(line.rstrip()) for line in text.splitlines()) <= 100
    header, table = cr.dispersed_table(doc)
    md = cr.markdown_table(header, table)
    for row in table:  # every cell the terminal shows is in the Markdown table, as printed
        assert "| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" in md
        assert all(cell in text for cell in row)
    assert doc["runs"]["dispersed/lqr"]["summary"]["percentiles"]["miss_km"]["p50"] is not None
    best = cr.verdict(doc)[0]
    assert best.startswith("Best on the standard set: lqr") and "Why pick it:" in best


def test_the_cli_reference_lists_every_subcommand_and_option():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "docs" / "tools" / "cli_reference.py"
    spec = importlib.util.spec_from_file_location("cli_reference", path)
    cli_reference = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cli_reference)

    import argparse

    page = cli_reference.markdown(build_parser())
    sections = {s.split("`", 1)[0]: s for s in page.split("\n## `")[1:]}
    walked = list(cli_reference.walk(build_parser()))
    assert len(walked) > 15 and {" ".join(p) for p, _ in walked} == set(sections)
    for path, parser in walked:
        section = sections[" ".join(path)]  # each command's own section names each of its arguments
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name in action.choices:
                    assert f"`{' '.join((*path, name))}`" in section, (path, name)
                continue
            for flag in action.option_strings:
                assert f"`{flag}`" in section or f"`{flag} " in section, (path, flag)
            if not action.option_strings:
                assert f"`{action.metavar or action.dest}`" in section, (path, action.dest)
            text = cli_reference.help_text(parser, action)
            assert " ".join(text.split())[:40].replace("|", "\\|") in section, (path, action.dest)
