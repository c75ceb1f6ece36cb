"""On-disk cache of parsed TLE/3LE files, so a large element file is validated once, not at every start.

`leonav beacons` reads the day's whole Starlink file (9,543 sets) at every run; checking and
decoding every field of it costs about 0.6 s of CPU on the 2-vCPU build machine, rebuilding the
SGP4 records from already checked lines about 0.1 s. The cache keeps what the parser decided
(each accepted entry's name, catalog number, epoch and its two lines; each rejected entry) and
the command rebuilds the SGP4 records from those lines (`Satrec.twoline2rv`, as the parser does).

Folder: `$LEONAV_ELEMENT_CACHE` if set (`off` turns the cache off), else
`$XDG_CACHE_HOME/leonav/elements`, else `~/.cache/leonav/elements` (beside the `tle` and `build`
caches). Key: SHA-256 of the file's bytes, of the parser's own source files, the sgp4 version
and the parsing options, so an edited file (whatever its time stamp) or an updated parser is a
miss. An entry that cannot be read, does not match its key, or whose rebuilt records disagree
with it (catalog number) is ignored and rewritten; a cache that cannot be written only costs the
time (logged at debug level). At most `MAX_ENTRIES` files are kept, the least recently used
removed first. Files under `MIN_BYTES` (about 400 entries, parsed in a few tens of ms) are not
cached: they would only push the large ones out.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import json
import logging
import os
from pathlib import Path
from typing import Any

FORMAT = 1
MAX_ENTRIES = 16
MIN_BYTES = 64 * 1024
CACHE_ENV = "LEONAV_ELEMENT_CACHE"
_UNIX_EPOCH = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
_PARSER_FILES = ("elements.py", "tle.py", "element_checks.py", "element_cache.py")
_log = logging.getLogger("leonav.orbits")


_OFF_IN_PROCESS = False


def turn_off_in_this_process() -> None:
    """No cache from here on in this process: a server that must open no file once it serves
    (`leonav nav`) parses its built-in element sets in full instead."""
    global _OFF_IN_PROCESS
    _OFF_IN_PROCESS = True


def wanted(size_bytes: int) -> bool:
    """Whether a file of this size goes through the cache (a folder is set and it is not small)."""
    return size_bytes >= MIN_BYTES and not _OFF_IN_PROCESS and cache_dir() is not None


def cache_dir() -> Path | None:
    """The cache folder, or None when `$LEONAV_ELEMENT_CACHE` is `off`."""
    env = os.environ.get(CACHE_ENV, "")
    if env.lower() in ("off", "0", "no", "false"):
        return None
    if env:
        return Path(env)
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "leonav" / "elements"


def cache_key(data: bytes, options: dict[str, Any]) -> str:
    """SHA-256 (hex) of the file bytes, the parser's source, the sgp4 version and `options`."""
    import sgp4

    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for name in _PARSER_FILES:
        h.update(name.encode() + b"\0" + (here / name).read_bytes() + b"\0")
    h.update(json.dumps({"format": FORMAT, "sgp4": sgp4.__version__, **options}, sort_keys=True).encode() + b"\0")
    h.update(data)
    return h.hexdigest()


def _epoch_us(epoch: _dt.datetime) -> int:
    """Microseconds since 1970 (exact: datetimes hold whole microseconds)."""
    return (epoch - _UNIX_EPOCH) // _dt.timedelta(microseconds=1)


def store(key: str, entries: list[tuple], rejected: list[tuple[int, str, str]]) -> None:
    """Write one parsed file: entries (name, norad_id, epoch_utc, line1, line2, line number),
    rejected (line number, name, reason)."""
    folder = cache_dir()
    if folder is None:
        return
    body = {"format": FORMAT, "key": key,
            "entries": [[name, int(norad), _epoch_us(epoch), l1, l2, int(line)]
                        for name, norad, epoch, l1, l2, line in entries],
            "rejected": [[int(line), name, reason] for line, name, reason in rejected]}
    path = folder / f"{key}.json"
    tmp = folder / f".{key}.{os.getpid()}.tmp"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(body, separators=(",", ":")), encoding="utf-8")
        os.replace(tmp, path)
        _prune(folder)
    except OSError as exc:
        _log.debug("element cache not written (%s): %s", path, exc)
        try:
            tmp.unlink(missing_ok=True)
        except OSError:   # e.g. the folder itself could not be made
            pass


def _prune(folder: Path) -> None:
    files = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True)
    for old in files[MAX_ENTRIES:]:
        old.unlink(missing_ok=True)


def lookup(key: str) -> tuple[list[tuple], list[tuple[int, str, str]]] | None:
    """(entries with rebuilt SGP4 records: (name, norad_id, epoch_utc, satrec, line number),
    rejected) of a cached file, or None (no cache, a miss, or an entry that does not check out)."""
    from sgp4.api import WGS72, Satrec

    folder = cache_dir()
    if folder is None:
        return None
    path = folder / f"{key}.json"
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
        if body.get("format") != FORMAT or body.get("key") != key:
            raise ValueError("format or key differs")
        entries = []
        for name, norad, epoch_us, l1, l2, line in body["entries"]:
            satrec = Satrec.twoline2rv(l1, l2, WGS72)
            if satrec.satnum != norad:
                raise ValueError(f"line {line}: catalog number {satrec.satnum} != {norad}")
            entries.append((str(name), int(norad), _UNIX_EPOCH + _dt.timedelta(microseconds=int(epoch_us)),
                            satrec, int(line)))
        rejected = [(int(line), str(name), str(reason)) for line, name, reason in body["rejected"]]
    except FileNotFoundError:
        return None
    except (OSError, ValueError, TypeError, KeyError, AttributeError) as exc:
        _log.debug("element cache entry %s ignored: %s", path, exc)
        return None
    try:
        os.utime(path)   # recently used: pruned last
    except OSError:
        pass
    return entries, rejected
