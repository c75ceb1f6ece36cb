"""The `leonav` command line.

Each subcommand lives in its own module under `leonav_runtime/commands/` and exposes
`register(subparsers) -> None`, which adds a parser whose `func(args) -> int` does the
work. Modules are discovered here, so adding a command never edits this file.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from leonav_runtime import commands as _commands_pkg


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every discovered subcommand."""
    parser = argparse.ArgumentParser(
        prog="leonav",
        description=(
            "LEO-aided 9D navigation (position, velocity, attitude): IMU + GPS + passive "
            "Starlink Doppler-rate in a generated-C error-state EKF, with its PCRB."
        ),
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(_commands_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{_commands_pkg.__name__}.{info.name}")
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `leonav` console script; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except UserInputError as exc:  # bad file/field/value: one clear line, no traceback
        print(f"leonav {args.command}: error: {exc}", file=sys.stderr)
        return 2


from leonav_runtime.errors import UserInputError  # noqa: E402  (after main for readability)

if __name__ == "__main__":
    sys.exit(main())
