"""Docstrings as autodoc reads them: the package's Markdown habits made into reStructuredText.

The docstrings are written for ``help()`` and for reading in the source: tables in Markdown (the
environment's observation table, as Gymnasium's own environments do) and absolute values as
``|x|``. reStructuredText reads a ``|`` as a substitution or a line block, so the docs build
(``autodoc-process-docstring``) turns each Markdown table into a ``list-table`` and escapes every
other ``|`` outside literals. Nothing in the code changes for the manual.
"""

from __future__ import annotations

import re

_SEPARATOR = re.compile(r"^\|\s*:?-{2,}:?\s*(\|\s*:?-{2,}:?\s*)*\|$")
_LITERAL = re.compile(r"(``.+?``)")
_GLUED = re.compile(r"[^\s.,;:!?)\]}'\"/\\-]")  # a character that may not follow a literal's end


def _is_row(line: str) -> bool:
    s = line.strip()
    return len(s) > 1 and s.startswith("|") and s.endswith("|")


def _cells(line: str) -> list[str]:
    s = line.strip()[1:-1]
    # split on | not escaped by a backslash
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", s)]


def _escape(text: str) -> str:
    """Escape every ``|`` outside ````literal```` spans, and end a literal that a character such as
    ``^`` follows (``wind_sigma``^2) with an escaped space, as reStructuredText asks."""
    parts = _LITERAL.split(text)
    out = []
    for i, p in enumerate(parts):
        if i % 2:  # a literal (split keeps the captured group at the odd places)
            nxt = parts[i + 1] if i + 1 < len(parts) else ""
            out.append(p + ("\\ " if nxt and _GLUED.match(nxt) else ""))
        else:
            out.append(p.replace("|", "\\|"))
    return "".join(out)


def _table(rows: list[str], indent: str) -> list[str]:
    header, body = _cells(rows[0]), [_cells(r) for r in rows[2:]]
    out = [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
    for row in [header, *body]:
        row = row + [""] * (len(header) - len(row))
        for j, cell in enumerate(row[: len(header)]):
            mark = "* -" if j == 0 else "  -"
            out.append(f"{indent}   {mark} {_escape(cell) if cell else ' '}".rstrip() if cell else f"{indent}   {mark}")
    out.append("")
    return out


def rst_lines(lines: list[str]) -> list[str]:
    """The docstring's lines with Markdown tables as ``list-table`` and the other ``|`` escaped."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if _is_row(line) and i + 1 < len(lines) and _SEPARATOR.match(lines[i + 1].strip()):
            j = i + 2
            while j < len(lines) and _is_row(lines[j]):
                j += 1
            indent = line[: len(line) - len(line.lstrip())]
            if out and out[-1].strip():
                out.append("")
            out += _table(lines[i:j], indent)
            i = j
            continue
        out.append(_escape(line))
        i += 1
    return out


def process_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    """The ``autodoc-process-docstring`` hook: rewrite ``lines`` in place."""
    lines[:] = rst_lines(lines)
