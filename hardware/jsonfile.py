"""JSON files with NumPy values: the writer behind session.json and every results file.

`write_json` converts NumPy scalars and arrays, datetimes (ISO 8601) and paths, and writes
NaN/inf as null (JSON has neither). The runtime's `leonav_runtime.output.write_json` is
this function.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["jsonable", "write_json"]


def jsonable(obj: Any) -> Any:
    """`obj` with every value JSON can hold: dict keys as str, arrays as lists, NaN/inf as None."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
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
    path.write_text(json.dumps(jsonable(data), indent=2) + "\n")
    return path
