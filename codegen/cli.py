"""Shared argument handling of `python -m leonav.codegen` and `leonav codegen`."""
from __future__ import annotations

import argparse
import sys
import time


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output folder (default: the committed leonav_runtime/gen/)")
    parser.add_argument("--check", action="store_true",
                        help="regenerate into a temp folder and exit 1 if it differs from --out/the committed files")


def run(args: argparse.Namespace) -> int:
    from leonav.codegen.generate import default_output_dir, diff_against, generate

    out = args.out or default_output_dir()
    start = time.perf_counter()
    if args.check:
        changed = diff_against(out)
        if changed:
            print(f"generated code is stale in {out}: {', '.join(changed)} differ; run `python -m leonav.codegen` "
                  "to update", file=sys.stderr)
            return 1
        print(f"generated code in {out} is up to date ({time.perf_counter() - start:.1f} s)")
        return 0
    report = generate(out)
    n = sum(len(v) for k, v in report.items() if k != "removed")
    print(f"generated {out} in {time.perf_counter() - start:.1f} s: {n} files, {len(report['changed'])} changed"
          + "".join(f"\n  {kind}: {rel}" for kind in ("changed", "removed") for rel in report[kind]))
    return 0
