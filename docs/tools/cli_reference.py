"""The manual's CLI reference, generated from the ``rventry`` argument parsers.

Walks :func:`rventry_env.cli.build_parser` (the library's commands and those installed packages
add through the ``rventry.commands`` entry points) and writes one section per command and
subcommand: its help, its usage and a table of its arguments with their defaults. The docs build
calls :func:`write` each time, so the page can never lag behind the parsers;
``tests/cli/test_first_hour.py`` checks that it names every subcommand and option.

    python docs/tools/cli_reference.py docs/reference/cli.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def walk(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("rventry",)):
    """Yield (command path, parser) for the parser and every subcommand below it, depth first; a
    subcommand's aliases (:func:`aliases`) are not walked again."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name in _helps(parser):
                yield from walk(action.choices[name], (*path, name))


def aliases(parser: argparse.ArgumentParser) -> dict[str, list[str]]:
    """Each subcommand's other names (argparse's ``aliases``), by its own name."""
    out: dict[str, list[str]] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name in _helps(parser):
                child = action.choices[name]
                out[name] = [a for a, c in action.choices.items() if c is child and a != name]
    return out


def _helps(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Each subcommand's one-line help, as its parent lists it."""
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                out[choice.dest] = choice.help or ""
    return out


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _argument(action: argparse.Action) -> str:
    if action.option_strings:
        if action.nargs == 0:
            return ", ".join(f"`{f}`" for f in action.option_strings)
        metavar = action.metavar or (action.dest.upper() if not action.choices else "{" + ",".join(map(str, action.choices)) + "}")
        if isinstance(metavar, tuple):
            metavar = " ".join(metavar)
        return ", ".join(f"`{f} {metavar}`" for f in action.option_strings)
    return f"`{action.metavar or action.dest}`"


def help_text(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """An argument's help as ``--help`` prints it (``%%`` and ``%(default)s`` expanded)."""
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    return parser._get_formatter()._expand_help(action)


def _default(action: argparse.Action) -> str:
    if action.nargs == 0 or action.default in (None, argparse.SUPPRESS) or action.required:
        return "required" if action.required and action.option_strings else ""
    return f"`{action.default}`"


def markdown(parser: argparse.ArgumentParser) -> str:
    """The whole reference page, in MyST Markdown."""
    lines = [
        "# Command line",
        "",
        "Every `rventry` command, subcommand and option, generated from the argument parsers each time",
        "the manual is built (`docs/tools/cli_reference.py`). Defaults that depend on the machine, such",
        "as the number of worker processes, are the building machine's. `rventry COMMAND --help` prints",
        "the same on your machine; the words the commands print are in the [glossary](glossary.md).",
        "",
    ]
    helps: dict[tuple[str, ...], str] = {}
    for path, p in walk(parser):
        for name, text in _helps(p).items():
            helps[(*path, name)] = text
    for path, p in walk(parser):
        subcommands = _helps(p)
        if len(path) > 1 and not subcommands and not [a for a in p._actions if not isinstance(a, argparse._HelpAction)]:
            continue
        title = " ".join(path)
        lines += [f"## `{title}`", ""]
        summary = helps.get(path) or p.description or ""
        if summary:
            lines += [_cell(summary[0].upper() + summary[1:]) + ("" if summary.endswith(".") else "."), ""]
        if p.description and p.description != summary:
            lines += [_cell(p.description), ""]
        usage = p.format_usage().strip()
        lines += ["```text", usage, "```", ""]
        rows = []
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                continue
            rows.append((_argument(action), _cell(help_text(p, action)), _default(action)))
        if rows:
            lines += ["| argument | meaning | default |", "|---|---|---|"]
            lines += [f"| {a} | {h} | {d} |" for a, h, d in rows]
            lines.append("")
        if subcommands:
            lines += ["| subcommand | what it does |", "|---|---|"]
            other = aliases(p)
            for n, h in subcommands.items():
                also = "".join(f" (also `{' '.join((*path, a))}`)" for a in other[n])
                lines.append(f"| [`{' '.join((*path, n))}`](#{_anchor((*path, n))}){also} | {_cell(h)} |")
            lines.append("")
        if p.epilog:
            lines += [_cell(p.epilog), ""]
    return "\n".join(lines)


def _anchor(path: tuple[str, ...]) -> str:
    """MyST's anchor of the section ``## `rventry a b```: its words, lower case, joined by hyphens."""
    return "-".join(path).lower().replace("_", "-")


def write(parser: argparse.ArgumentParser, path: Path) -> bool:
    """Write the page to ``path`` if it changed (so a rebuild does not re-read an unchanged page); True if written."""
    text = markdown(parser)
    path = Path(path)
    if path.exists() and path.read_text() == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return True


if __name__ == "__main__":
    from rventry_env.cli import build_parser

    write(build_parser(), Path(sys.argv[1] if len(sys.argv) > 1 else "docs/reference/cli.md"))
