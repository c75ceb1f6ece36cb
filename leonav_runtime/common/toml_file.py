"""Reading the small TOML files users write (scenarios, studies, dataset descriptions).

One reader, so every such file fails the same way: a one-line `UserInputError` naming the
file and what was expected, for a folder, an oversized file (read only up to the limit, so
a device or a huge file cannot hold the command), text that is not UTF-8, TOML syntax, or
nesting deep enough to exhaust the parser's recursion.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

from leonav_runtime.common.errors import UserInputError

MAX_FILE_BYTES = 1_000_000


def read_toml_file(path: str | Path, what: str, max_bytes: int = MAX_FILE_BYTES) -> dict[str, Any]:
    """The parsed content of the TOML file `path`, a `what` file ("scenario", "study", ...)."""
    path = Path(path)
    if path.is_dir():
        raise UserInputError(f"{path}: is a directory, expected a {what} TOML file")
    with open(path, "rb") as fh:
        raw = fh.read(max_bytes + 1)
    if len(raw) > max_bytes:
        size = max(path.stat().st_size, len(raw)) / 1e6
        raise UserInputError(f"{path}: {size:.1f} MB is more than a {what} file can be ({max_bytes / 1e6:g} MB)")
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserInputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise UserInputError(f"{path}: not a {what} file: arrays or tables nested too deeply") from None
