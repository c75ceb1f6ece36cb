"""Results folders: every computing command writes JSON/CSV/PNG into one folder.

Default location is `./leonav-out/<command>-<UTC timestamp>/`; `--out DIR` overrides it.
"""
from __future__ import annotations

import argparse
import csv
import datetime as _dt
import json
import math
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

DEFAULT_ROOT = Path("leonav-out")


def add_out_argument(parser: argparse.ArgumentParser) -> None:
    """Add the common `--out DIR` option to a subcommand parser."""
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="results folder (default: ./leonav-out/<command>-<UTC time>/)",
    )


def results_dir(out: str | Path | None, command: str) -> Path:
    """Create and return the results folder for `command`."""
    if out is None:
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
        out = DEFAULT_ROOT / f"{command}-{stamp}"
    path = Path(out)
    path.mkdir(parents=True, exist_ok=True)
    return path


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        value = float(obj)
        return value if math.isfinite(value) else None  # JSON has no NaN/inf
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (_dt.datetime, _dt.date)):
        return obj.isoformat()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | Path, data: Any) -> Path:
    """Write `data` as indented JSON (numpy types converted, NaN/inf as null)."""
    path = Path(path)
    path.write_text(json.dumps(_jsonable(data), indent=2) + "\n")
    return path


def write_csv(path: str | Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """Write a CSV with a header row; floats are written with full precision."""
    path = Path(path)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        for row in rows:
            writer.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v for v in row])
    return path
