"""`python -m leonav.codegen [--out DIR] [--check]`: regenerate (or check) leonav_runtime/gen/."""
from __future__ import annotations

import argparse
import sys

from leonav.codegen.cli import add_arguments, run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m leonav.codegen", description=__doc__)
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
