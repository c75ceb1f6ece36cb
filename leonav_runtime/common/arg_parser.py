"""The command line's argument parser: argparse with one-line errors.

argparse prints the whole usage block before its error; leonav's errors are one line
`leonav CMD: error: ...` (exit status 2, like every bad input), pointing at `--help`,
which is unchanged. Subcommand parsers inherit the class, so `leonav tle fetch` errors
name `leonav tle fetch`.
"""
from __future__ import annotations

import argparse
import sys
from typing import NoReturn

EXIT_BAD_INPUT = 2


class OneLineErrorParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr, exit status 2."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(str(message).split())   # argparse messages can wrap: keep one line
        sys.stderr.write(f"{self.prog}: error: {text} (see `{self.prog} --help`)\n")
        sys.exit(EXIT_BAD_INPUT)
