"""Shared argument handling of `python -m leonav.codegen` and `leonav codegen`."""
from __future__ import annotations

import argparse
import sys
import time


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output folder (default: the committed leonav_runtime/gen/)")
    parser.add_argument("--check", action="store_true",
                        help="regenerate into memory and exit 1 if it differs from --out/the committed files")
    sub = parser.add_subparsers(dest="action", metavar="ACTION")
    new = sub.add_parser("new-observable", help="write models/measurements/NAME.py: a template sensor, one file",
                         description="Write models/measurements/NAME.py, a documented template observable with "
                         "its registry entry (a local sensor, mode word NAME, scenario/dataset section [NAME]); "
                         "then run `leonav codegen`.")
    new.add_argument("name", metavar="NAME", help="lower_case name: module, mode word, record stream")
    new.add_argument("--bias-state", action="store_true", help="add a random-walk bias state b_NAME (m)")


def run(args: argparse.Namespace) -> int:
    if getattr(args, "action", None) == "new-observable":
        from leonav.codegen.new_observable import write

        try:
            path = write(args.name, args.bias_state)
        except ValueError as exc:
            print(f"leonav codegen: error: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {path}: edit its h and registry entry, then run `leonav codegen`")
        return 0
    from leonav.codegen.generate import default_output_dir, diff_against, generate
    from leonav.models.registry import RegistryError

    out = args.out or default_output_dir()
    start = time.perf_counter()
    try:
        if args.check:
            changed = diff_against(out)
            if changed:
                print(f"generated code is stale in {out}: {', '.join(changed)} differ; run `python -m leonav.codegen` "
                      "to update", file=sys.stderr)
                return 1
            print(f"generated code in {out} is up to date ({time.perf_counter() - start:.1f} s)")
            return 0
        report = generate(out)
    except RegistryError as exc:
        print(f"leonav codegen: error: {exc}", file=sys.stderr)
        return 2
    n = sum(len(v) for k, v in report.items() if k != "removed")
    print(f"generated {out} in {time.perf_counter() - start:.1f} s: {n} files, {len(report['changed'])} changed"
          + "".join(f"\n  {kind}: {rel}" for kind in ("changed", "removed") for rel in report[kind]))
    return 0
