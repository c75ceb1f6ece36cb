"""Results folders: every computing command writes JSON/CSV/PNG into one folder.

`write_json` is `hardware.jsonfile.write_json` (one JSON writer for session files and results).
`write_csv` writes through `hardware.jsonfile.replace_file`: a temporary file in the
same folder renamed over the target, so a full disk or a kill never leaves a half-written
CSV (the old file, if any, stays whole).

Default location is `./leonav-out/<command>-<UTC timestamp>/`; `--out DIR` overrides it. The
default folder's name never leaves `./leonav-out` (path separators and `..` in the command
name, e.g. from a scenario name, become `_`).
"""
from __future__ import annotations

import argparse
import csv
import shutil
import datetime as _dt
import re
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from leonav.hardware.jsonfile import write_json
from leonav.hardware.jsonfile import replace_file

__all__ = ["add_out_argument", "results_dir", "write_json", "write_csv"]

DEFAULT_ROOT = Path("leonav-out")
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]|\.\.+")


def add_out_argument(parser: argparse.ArgumentParser) -> None:
    """Add the common `--out DIR` option to a subcommand parser."""
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="results folder (default: ./leonav-out/<command>-<UTC time>/)",
    )


_CREATED: list[Path] = []
"""Results folders this process created (outermost new folder first), for `finish_results`."""


def results_dir(out: str | Path | None, command: str) -> Path:
    """Create and return the results folder for `command` (remembered: a failed command removes
    it again when nothing was written into it, `finish_results`)."""
    if out is None:
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
        out = DEFAULT_ROOT / f"{_UNSAFE.sub('_', command).lstrip('.') or 'results'}-{stamp}"
    path = Path(out)
    new = next((p for p in reversed([path, *path.parents]) if not p.exists()), None)
    path.mkdir(parents=True, exist_ok=True)
    if new is not None:
        _CREATED.append(new)
    return path


def finish_results(failed: bool, why: str = "") -> list[Path]:
    """At the end of a command: when it failed, remove the results folders it created that hold
    no file with content, and leave a FAILED.txt (with `why`) in those that hold a partial result. Returns the
    folders removed."""
    removed = []
    while _CREATED:
        top = _CREATED.pop()
        if not failed or not top.exists():
            continue
        if not any(p.is_file() and p.stat().st_size > 0 for p in top.rglob("*")):   # empty files hold nothing
            shutil.rmtree(top, ignore_errors=True)
            removed.append(top)
        else:
            (top if top.is_dir() else top.parent).joinpath("FAILED.txt").write_text(
                f"this command failed before it finished; the files here are partial\n{why}\n")
    return removed


def write_csv(path: str | Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """Write a CSV with a header row; floats are written with full precision."""
    def fill(fh) -> None:
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in rows:
            writer.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v for v in row])

    return replace_file(path, fill)
