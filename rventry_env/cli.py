"""The ``rventry`` command line.

Each capability registers its own subcommands from its own module, so this file
only lists where they live. Modules keep heavy imports (CasADi, torch) inside the
functions that run a command, so ``rventry --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# module -> it defines ``register(subparsers)`` adding one or more subcommands
COMMAND_MODULES = (
    "rventry_env.examples.orbit",
    "rventry_env.reference.cli",
    "agents.cli",
    "rventry_env.validation.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rventry",
        description="Entry guidance research on the rv-Euler parameterization (Miller & Rao).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and name.startswith(exc.name):
                continue  # capability not installed in this build
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"rventry {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
