"""The README and the manual: their length, their generated tables against the records, and
every code block they show, run as a reader would run it.

A ``python`` or ``bash`` block runs in the fast tier unless the line before it says
``<!-- code: slow (why) -->`` (then in the slow tier), ``<!-- code: ci (why) -->`` (the README's
set-up commands, which make a virtual environment: ``.ci/run`` runs each verbatim, and a test
checks that it does) or ``<!-- code: skip (why) -->`` (only where it cannot run here: a GPU, a
cluster). The blocks of one page run in order in one scratch
folder, so a block may use what an earlier one wrote; a page's ``{include}`` of the README is
read as the included text, as the manual shows it.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOOLS = ROOT / "docs" / "tools"
RUN = ("python", "bash")
MARK = re.compile(r"^<!-- code: (slow|skip|ci) \((.+)\) -->$")
FENCE = re.compile(r"^```(\w[\w-]*)?\s*$")
INCLUDE = re.compile(r"^```\{include\} (\S+)\n((?::[\w-]+: .*\n)*)```$", re.M)


def tool(name: str):
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)
    spec.loader.exec_module(module)
    return module


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts)]


def _expand_includes(text: str, page: Path) -> str:
    def include(m):
        target = (page.parent / m.group(1)).resolve()
        body = target.read_text()
        opts = dict(re.findall(r":([\w-]+): (.*)", m.group(2)))
        if "start-after" in opts:
            body = body.split(opts["start-after"].strip('"'), 1)[1]
        if "end-before" in opts:
            body = body.split(opts["end-before"].strip('"'), 1)[0]
        return body

    return INCLUDE.sub(include, text)


def blocks(page: Path) -> list[dict]:
    """The page's code blocks in order: language, text, tier ("fast", "slow", "skip"), reason, line."""
    lines = _expand_includes(page.read_text(), page).split("\n")
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m and not lines[i].startswith("```{"):
            j = i + 1
            while j < len(lines) and lines[j].rstrip() != "```":
                j += 1
            mark = MARK.match(lines[i - 1].strip()) if i else None
            out.append({"lang": m.group(1) or "", "code": "\n".join(lines[i + 1 : j]), "line": i + 1,
                        "tier": mark.group(1) if mark else "fast", "why": mark.group(2) if mark else ""})  # fmt: skip
            i = j + 1
            continue
        i += 1
    return out


def _runnable(tier: str) -> list[Path]:
    return [p for p in pages() if any(b["lang"] in RUN and b["tier"] == tier for b in blocks(p))]


def _run_page(page: Path, tier: str, tmp_path: Path) -> None:
    """Run the page's blocks of ``tier`` (and the fast ones before them) in order, in one folder."""
    venv_bin = Path(sys.executable).parent
    env = dict(os.environ, PATH=f"{venv_bin}{os.pathsep}{os.environ.get('PATH', '')}", MPLBACKEND="Agg")
    order = ("fast",) if tier == "fast" else ("fast", "slow")
    # a block runs as from the repository root (it may name docs/tools/tables.py), but writes its
    # outputs (out/, ...) into the scratch folder
    for entry in ROOT.iterdir():
        if entry.name not in ("out", "runs", ".git", ".venv") and not (tmp_path / entry.name).exists():
            (tmp_path / entry.name).symlink_to(entry)
    for b in blocks(page):
        if b["lang"] not in RUN or b["tier"] not in order:
            continue
        if b["lang"] == "python":
            cmd = [sys.executable, "-c", b["code"]]
        else:
            cmd = ["bash", "-euo", "pipefail", "-c", b["code"]]
        done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1500)
        where = f"{page.relative_to(ROOT)}, line {b['line']}"
        assert done.returncode == 0, f"{where}:\n{b['code']}\n--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}"


@pytest.mark.parametrize("page", _runnable("fast"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_fast_code_blocks_run(page, tmp_path):
    _run_page(page, "fast", tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("page", _runnable("slow"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_slow_code_blocks_run(page, tmp_path):
    _run_page(page, "slow", tmp_path)


def test_every_block_is_run_or_says_why_not():
    for page in pages():
        for b in blocks(page):
            where = f"{page.relative_to(ROOT)}, line {b['line']}"
            if b["tier"] == "skip":
                assert b["why"] and b["lang"] in RUN, where
            if b["tier"] == "ci":  # run by CI itself, verbatim
                ci = (ROOT / ".ci" / "run").read_text().split("\n")
                assert all(line in ci for line in b["code"].split("\n")), where
            if b["lang"] in ("sh", "shell", "console", "py", "python3"):
                pytest.fail(f"{where}: say ```bash or ```python so that the block is run, or ```text for a synopsis")


def test_the_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text()
    lines = text.split("\n")
    assert len(lines) <= 200
    # on the first two screens (about 100 lines): gym.make, training and the headline results
    first = "\n".join(lines[:110])
    assert 'gym.make("RvEntry-v0"' in first and "model.learn(" in first and "<!-- table: compare-standard -->" in text
    assert text.index("<!-- table: compare-standard -->") < text.index("## The manual")
    # the set-up commands are the README's, and CI runs the test command verbatim
    bash = [b["code"] for b in blocks(ROOT / "README.md") if b["lang"] == "bash"]
    setup, tests = bash[0], bash[1]
    assert setup.startswith("python3 -m venv .venv") and setup.endswith("rventry compare")
    ci = (ROOT / ".ci" / "run").read_text()
    assert tests in ci.split("\n") and setup in ci.split("\n")


def test_results_tables_agree_with_their_records():
    tables = tool("tables")
    assert tables.problems() == []


def test_a_table_that_disagrees_with_its_record_is_caught(tmp_path, monkeypatch):
    tables = tool("tables")
    t = next(t for t in tables.TABLES if t.name == "mpc-benchmark")
    page = tmp_path / "page.md"
    body = tables.rendered(t)
    page.write_text(f"x\n<!-- table: mpc-benchmark -->\n{body.replace('6368', '6369')}\n<!-- end table -->\n")
    monkeypatch.setattr(tables, "ROOT", tmp_path)
    (tmp_path / "docs" / "results").mkdir(parents=True)
    for rec in t.records:
        (tmp_path / rec).write_text((ROOT / rec).read_text())
    (tmp_path / "README.md").write_text("")
    monkeypatch.setattr(tables, "TABLES", (tables.Table(t.name, t.records, t.render, ("page.md",)),))
    assert tables.problems() == ["page.md: table 'mpc-benchmark' differs from its records docs/results/bench_mpc_eval.json"]
    tables.write_all()
    assert tables.problems() == [] and "6368" in page.read_text()


def test_a_table_whose_record_is_missing_is_named(tmp_path, monkeypatch):
    tables = tool("tables")
    t = next(t for t in tables.TABLES if t.name == "mpc-benchmark")
    (tmp_path / "page.md").write_text("x\n<!-- table: mpc-benchmark -->\nold\n<!-- end table -->\n")
    (tmp_path / "README.md").write_text("")
    monkeypatch.setattr(tables, "ROOT", tmp_path)
    monkeypatch.setattr(tables, "TABLES", (tables.Table(t.name, t.records, t.render, ("page.md",)),))
    assert tables.problems() == ["table 'mpc-benchmark': no record docs/results/bench_mpc_eval.json"]


def test_the_glossary_page_is_the_glossarys():
    from rventry_env.task.glossary import glossary_markdown

    assert (ROOT / "docs" / "reference" / "glossary.md").read_text() == glossary_markdown()


def test_the_records_page_lists_every_record():
    """Each file or folder of docs/results/ is named on its page with the command that wrote it."""
    page = (ROOT / "docs" / "results" / "README.md").read_text()
    unlisted = [p.name for p in sorted((ROOT / "docs" / "results").iterdir())
                if p.name != "README.md" and f"`{p.name}" not in page]  # fmt: skip
    assert unlisted == [], f"docs/results/README.md does not name {unlisted}"
