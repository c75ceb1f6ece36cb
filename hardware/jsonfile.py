"""JSON files with NumPy values: the writer behind session.json and every results file.

`write_json` converts NumPy scalars and arrays, datetimes (ISO 8601) and paths, and writes
NaN/inf as null (JSON has neither). The runtime's `leonav_runtime.common.output.write_json` is
this function. Every file is written whole through `replace_file` (a temporary file renamed
over the target), so an interrupted run never leaves half a JSON file behind.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import uuid
from pathlib import Path
from typing import IO, Any, Callable

import numpy as np

__all__ = ["jsonable", "replace_file", "write_json"]


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


def replace_file(path: str | Path, write: Callable[[IO], None], binary: bool = False) -> Path:
    """Write `path` whole: `write(fh)` fills a temporary file beside it (same folder, mode
    from the umask), which is flushed to disk and renamed over `path`. On any error or
    interrupt the temporary file is removed and `path` keeps its old content (or stays
    absent); an OSError names `path`."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "xb" if binary else "x", **({} if binary else {"newline": "", "encoding": "utf-8"})) as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename in (str(tmp), tmp):
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    return path


def write_json(path: str | Path, data: Any) -> Path:
    """Write `data` as indented JSON (numpy types converted, NaN/inf as null), whole."""
    text = json.dumps(jsonable(data), indent=2) + "\n"
    return replace_file(path, lambda fh: fh.write(text))
