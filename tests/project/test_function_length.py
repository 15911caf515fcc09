"""Functions fit on a screen: none over 80 lines, at most 10 over 60, across the packages.

A function's length is its ``end_lineno - lineno + 1`` (decorators not counted, docstring
counted); a nested function is counted on its own as well as within its parent. Run this file
as a script to print every function over 60 lines, longest first:
``python tests/project/test_function_length.py``.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("rventry_env", "rventry_agents")
LONG = 60  # lines: a function over this is long ...
MAX_LONG = 10  # ... and at most this many may be
LIMIT = 80  # lines: no function may be longer


def function_lengths(root: Path = ROOT) -> list[tuple[int, str]]:
    """Every function and method in the packages as ``(lines, "path:line name")``, longest first."""
    out = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            tree = ast.parse(path.read_text(), filename=str(path))
            for node in ast.walk(tree):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    lines = node.end_lineno - node.lineno + 1
                    out.append((lines, f"{path.relative_to(root)}:{node.lineno} {node.name}"))
    return sorted(out, key=lambda item: (-item[0], item[1]))


def test_no_function_over_the_limit():
    over = [f"{name} ({n} lines)" for n, name in function_lengths() if n > LIMIT]
    assert not over, f"functions over {LIMIT} lines: {over}"


def test_few_long_functions():
    long = [f"{name} ({n} lines)" for n, name in function_lengths() if n > LONG]
    assert len(long) <= MAX_LONG, f"{len(long)} functions over {LONG} lines (at most {MAX_LONG}): {long}"


def test_the_count_sees_a_long_function(tmp_path):
    """The count can fail: a planted 81-line function and a nested one are both found."""
    pkg = tmp_path / "rventry_env"
    pkg.mkdir()
    body = "\n".join(f"        x{i} = {i}" for i in range(78))
    (pkg / "m.py").write_text(f"def outer():\n    def inner():\n{body}\n        return 0\n    return inner\n")
    found = {name: n for n, name in function_lengths(tmp_path)}
    assert found == {"rventry_env/m.py:1 outer": 82, "rventry_env/m.py:2 inner": 80}


if __name__ == "__main__":
    lengths = function_lengths()
    for n, name in lengths:
        if n > LONG:
            print(f"{n:4d}  {name}")
    counts = [sum(n > k for n, _ in lengths) for k in (60, 80, 100)]
    print(f"over 60 / 80 / 100 lines: {counts[0]} / {counts[1]} / {counts[2]}")
