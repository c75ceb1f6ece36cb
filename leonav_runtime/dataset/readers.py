"""Read the columns a dataset description names from CSV, numpy .npy/.npz or MATLAB .mat files.

`read_columns` returns float columns and the file line of each row. Header: the first line
that is not a comment ('#', '%') when any column is named; indices need no header. Bad
rows are counted and skipped, never fatal on their own: too few fields, a cell that is not
a number or not finite (`rows_nan`). Time stamps that repeat (`rows_duplicate_time`) or go
back (`rows_non_monotonic`) are counted and skipped by `monotonic_rows`. A missing column,
a missing file or a file with no good row is one UserInputError naming the file (and line,
column).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError

COMMENTS = ("#", "%")
JUMP_INTERVALS = 1000.0
"""A forward time step longer than this many median sample intervals is a time jump."""


@dataclass
class Columns:
    """Float columns (n, k) of the good rows, their 1-based file lines, and counts of skipped rows."""

    path: Path
    values: np.ndarray
    lines: np.ndarray
    counts: dict = field(default_factory=dict)


def resolve(path: Path, what: str, where: str, shared: bool = False) -> Path:
    """The file, or a UserInputError naming it and the key that points at it (shared: the data
    folder is the project's shared public data, so say where it is looked for)."""
    if not path.is_file():
        hint = (" (the shared public data is not here: set LEONAV_SHARED_DATA to its folder, or run from a "
                "folder that has ../shared/data beside it; see its SOURCES.md)" if shared else "")
        raise UserInputError(f"{path}: {what} file not found ({where}){hint}")
    return path


def _header_index(header: list[str], name: str | int, path: Path, line_no: int, key: str) -> int:
    if isinstance(name, int):
        return name
    if name not in header:
        raise UserInputError(f"{path}:{line_no}: column {name!r} ({key}) not in the header; expected one of "
                             f"{', '.join(header[:12])}")
    return header.index(name)


def read_columns(path: Path, columns: list[tuple[str, str | int]], delimiter: str = ",") -> Columns:
    """The named columns [(key, header name or 0-based index)] of a delimited text file (module doc)."""
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}); expected a delimited text file") from None
    lines = text.splitlines()
    split = (lambda s: s.split()) if delimiter in (" ", "whitespace") else (lambda s: s.split(delimiter))
    start, header = 0, None
    if any(isinstance(c, str) for _, c in columns):
        for i, line in enumerate(lines):
            if line.strip() and not line.lstrip().startswith(COMMENTS):
                start, header = i + 1, [h.strip() for h in split(line)]
                break
        if header is None:
            raise UserInputError(f"{path}: no header line: expected one naming the columns")
    idx = [_header_index(header or [], c, path, start, key) for key, c in columns]
    need = max(idx) + 1
    vals, line_nos = [], []
    short = bad = 0
    for i in range(start, len(lines)):
        line = lines[i]
        if not line.strip() or line.lstrip().startswith(COMMENTS):
            continue
        cells = split(line)
        if len(cells) < need:
            short += 1
            continue
        try:
            row = [float(cells[j]) for j in idx]
        except ValueError:
            bad += 1
            continue
        vals.append(row)
        line_nos.append(i + 1)
    values = np.array(vals, float).reshape(-1, len(idx))
    finite = np.isfinite(values).all(axis=1)
    bad += int((~finite).sum())
    if not finite.all():
        values, line_nos = values[finite], np.asarray(line_nos)[finite]
    if values.shape[0] == 0:
        names = ", ".join(f"{k}={c!r}" for k, c in columns)
        raise UserInputError(f"{path}: no row with finite numbers in {names} ({short} short, {bad} bad rows): "
                             "expected numeric rows")
    return Columns(path, values, np.asarray(line_nos, int), {"rows_short": short, "rows_nan": bad})


def read_mat_columns(path: Path, struct: str, columns: list[tuple[str, str | int]]) -> Columns:
    """Fields of a MATLAB v5 .mat file (optionally inside struct `struct`), each (n,) or (n, 3),
    as columns in the order given; keys name the field ('gyro' -> 3 columns for a (n, 3) field)."""
    try:
        import scipy.io
    except ImportError:   # pragma: no cover - scipy is a dependency
        raise UserInputError(f"{path}: reading .mat needs scipy (pip install scipy)") from None
    try:
        mat = scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    except (ValueError, NotImplementedError, OSError) as exc:
        raise UserInputError(f"{path}: not a MATLAB v5 .mat file scipy can read ({exc})") from None
    holder = mat.get(struct) if struct else None
    if struct and holder is None:
        raise UserInputError(f"{path}: struct {struct!r} not found; expected one of "
                             f"{', '.join(k for k in mat if not k.startswith('__'))}")
    parts = []
    for key, name in columns:
        arr = getattr(holder, str(name), None) if struct else mat.get(str(name))
        if arr is None:
            raise UserInputError(f"{path}: field {name!r} ({key}) not found")
        arr = np.asarray(arr, float)
        parts.append(arr.reshape(arr.shape[0], -1))
    n = min(p.shape[0] for p in parts)
    if any(p.shape[0] != n for p in parts):
        raise UserInputError(f"{path}: fields {[c for _, c in columns]} have different lengths "
                             f"{[p.shape[0] for p in parts]}: expected one row per sample")
    values = np.hstack(parts)
    finite = np.isfinite(values).all(axis=1)
    return Columns(path, values[finite], np.flatnonzero(finite) + 1, {"rows_short": 0,
                                                                     "rows_nan": int((~finite).sum())})


def monotonic_rows(t: np.ndarray) -> tuple[np.ndarray, dict]:
    """Mask of rows to keep so that time strictly increases: a repeated time stamp
    (`rows_duplicate_time`) or one earlier than the last kept (`rows_non_monotonic`) is skipped.
    NaN times (rows the caller already rejected) are skipped without being counted here."""
    keep = np.isfinite(t)
    if t.size > 1 and keep.all() and np.all(np.diff(t) > 0):
        return keep, {"rows_duplicate_time": 0, "rows_non_monotonic": 0}
    dup = back = 0
    last = -np.inf
    for i, v in enumerate(t):
        if not keep[i]:
            continue
        if v == last:
            keep[i], dup = False, dup + 1
        elif v < last:
            keep[i], back = False, back + 1
        else:
            last = v
    return keep, {"rows_duplicate_time": dup, "rows_non_monotonic": back}


def read_array_columns(path: Path, columns: list[tuple[str, str | int]], array: str = "") -> Columns:
    """Columns (0-based indices) of a 2-D numpy array (n samples, k columns) in a .npy file, or the
    array `array` of a .npz (empty: its only array), loaded by numpy without pickles; rows with a
    value that is not finite are counted (`rows_nan`) and skipped."""
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise UserInputError(f"{path}: not a .npy/.npz file numpy can read ({exc})") from None
    name = path.name
    if isinstance(data, np.lib.npyio.NpzFile):
        names = list(data.files)
        if array and array not in names:
            raise UserInputError(f"{path}: array {array!r} not in the .npz; expected one of {', '.join(names)}")
        if not array and len(names) != 1:
            raise UserInputError(f"{path}: the .npz holds {len(names)} arrays ({', '.join(names)}): expected "
                                 "`array` naming one")
        name = f"{name}[{array or names[0]}]"
        data = data[array or names[0]]
    idx = [c for _, c in columns]
    if any(not isinstance(c, int) for c in idx):
        raise UserInputError(f"{path}: columns {idx}: expected 0-based indices (an array has no header)")
    need = max(idx) + 1
    if data.ndim != 2 or data.shape[1] < need or not np.issubdtype(data.dtype, np.number):
        raise UserInputError(f"{name}: array of shape {data.shape} ({data.dtype}): expected a numeric (n, >= {need}) "
                             f"array, one row per sample, columns {', '.join(f'{k}={c}' for k, c in columns)}")
    values = np.asarray(data[:, idx], float)
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        raise UserInputError(f"{name}: no row with finite numbers in columns {idx}: expected numeric rows")
    return Columns(path, values[finite], np.flatnonzero(finite), {"rows_short": 0, "rows_nan": int((~finite).sum())})


def read_source(path: Path, sec: dict, columns: list[tuple[str, str | int]], array_key: str = "array") -> Columns:
    """The columns of a section's file in its `format`: csv (`delimiter`), npy/npz (`array_key`:
    the key naming the .npz array), mat (`mat_struct`)."""
    fmt = sec.get("format", "csv")
    if fmt in ("npy", "npz"):
        return read_array_columns(path, columns, sec.get(array_key) or sec.get("array", ""))
    if fmt == "mat":
        return read_mat_columns(path, sec.get("mat_struct", ""), columns)
    return read_columns(path, columns, sec.get("delimiter", ","))


def time_jumps(t: np.ndarray) -> dict:
    """Jumps of a time column in file order (rows with NaN time left out): a forward step longer
    than JUMP_INTERVALS median steps, or any step back (a clock reset or a row out of order).
    They are treated as gaps: rows after a step back are skipped until time passes the last kept
    row (`monotonic_rows`), and a forward jump is a gap of the samples kept."""
    d = np.diff(np.asarray(t, float)[np.isfinite(t)])
    pos = d[d > 0]
    if pos.size == 0:
        return {"time_jumps": 0, "time_jump_forward_s": 0.0}
    fwd = d > JUMP_INTERVALS * float(np.median(pos))
    return {"time_jumps": int(fwd.sum() + (d < 0).sum()), "time_jump_forward_s": float(d[fwd].sum())}
