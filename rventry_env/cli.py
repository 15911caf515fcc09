"""The ``rventry`` command line.

Each capability registers its own subcommands from its own module, so this file
only lists where they live. Commands from other installed packages (the learning
agents' ``rventry train``) arrive through the ``rventry.commands`` entry-point
group, so this library never imports them by name. Modules keep heavy imports
(CasADi, torch) inside the functions that run a command, so ``rventry --help``
stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from importlib.metadata import entry_points

# module -> it defines ``register(subparsers)`` adding one or more subcommands
COMMAND_MODULES = (
    "rventry_env.examples.orbit.cli",
    "rventry_env.reference.cli",
    "rventry_env.evaluation.cli",
    "rventry_env.evaluation.oracle_cli",
    "rventry_env.validation.cli",
    "rventry_env.task.glossary",
)
COMMAND_GROUP = "rventry.commands"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rventry",
        description="Entry guidance research on the rv-Euler parameterization (Miller & Rao).",
        epilog="The words the commands print are explained by `rventry glossary`.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        ep.load()(sub)
    _negative_numbers_are_values(parser)
    return parser


def _version() -> str:
    """The installed distribution's version (the package's own where it runs from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rventry")
    except PackageNotFoundError:
        from rventry_env import __version__

        return __version__


# argparse takes "-1e9" for an option (its own pattern knows "-1" and "-1.5" only) and answers
# "expected one argument"; with this one a negative number in any notation reaches the option's
# type, which names what is wrong with it
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)


def _negative_numbers_are_values(parser: argparse.ArgumentParser) -> None:
    parser._negative_number_matcher = _NEGATIVE_NUMBER
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _negative_numbers_are_values(child)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        print(f"rventry {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:
        from rventry_env.evaluation.parallel import WorkerLost

        if not isinstance(exc, WorkerLost):
            raise
        print(f"rventry {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"rventry {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
