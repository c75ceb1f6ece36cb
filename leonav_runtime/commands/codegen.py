"""`leonav codegen [--out DIR] [--check]`: regenerate the C filter from the symbolic models.

Needs casadi (a development dependency of the models); the runtime itself never imports it.
"""
from __future__ import annotations

import argparse


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "codegen",
        help="regenerate leonav_runtime/gen/ (C, headers, state layout) from models/",
        description="Regenerate the generated C filter and state layout from the CasADi models, "
        "or with --check verify that the committed files are up to date (exit 1 if not).",
    )
    from leonav.codegen.cli import add_arguments

    add_arguments(parser)
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from leonav.codegen.cli import run

    return run(args)
