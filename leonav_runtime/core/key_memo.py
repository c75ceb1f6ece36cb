"""Reading the sources for the build cache's keys, and the key memo (compiled.source_keys).

Key memo: computing the keys means reading and hashing every source and header (about 60 ms
of CPU in every process). `compiled.source_keys` keeps them in `keymemo-<id>.json` in the cache, beside
the stat of every file it hashed (device, inode, size, mtime_ns, ctime_ns) and of the folders
it searched: a process whose files all stat the same takes the keys from the memo, any other
rehashes the files and rewrites it. The keys are still the content keys. ctime cannot be set
back by a user (an edit that keeps the size and restores the mtime still changes it), and a
file changed within `RACY_NS` of being hashed is not memoized (a file system's time stamps
are coarse: two writes in one clock tick can carry the same times). A memo that cannot be read,
parsed or checked is ignored and rewritten (written under a temporary name and renamed, so
processes starting at once each read a whole memo, old or new). `$LEONAV_KEY_MEMO=off` turns
it off (every process hashes, as before).
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import threading
import time
from pathlib import Path
from typing import Callable

from leonav_runtime.core.build_cache import CompilerError, atomic_output



_INCLUDE = re.compile(rb'^\s*#\s*include\s+"([^"]+)"', re.M)


@functools.lru_cache(maxsize=None)
def _read(path: str, stat: tuple[int, ...]) -> tuple[bytes, tuple[str, ...]]:
    """A file's bytes and the names it `#include "..."`s, read once per process and version
    (every command computes the cache keys of ~180 sources: this halves the reads)."""
    data = Path(path).read_bytes()
    return data, tuple(m.decode(errors="replace") for m in _INCLUDE.findall(data))


def _stat(path: str | Path) -> tuple[int, ...]:
    """(device, inode, size, mtime_ns, ctime_ns): what changes when a file is replaced or written."""
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


_recording = threading.local()   # .hashed: path -> the stat its bytes were read under (source_keys' memo)


def _file(path: Path) -> tuple[bytes, tuple[str, ...]]:
    stat = _stat(path)
    hashed = getattr(_recording, "hashed", None)
    if hashed is not None:
        hashed[str(path)] = stat
    return _read(str(path), stat)


def included_headers(source: Path, include_dirs: list[Path]) -> list[Path]:
    """The project headers `source` includes, transitively (`#include "..."` found beside the
    including file or in `include_dirs`; system headers are the compiler's)."""
    seen: dict[Path, None] = {}
    todo = [Path(source)]
    while todo:
        current = todo.pop()
        for name in _file(current)[1]:
            for folder in [current.parent, *include_dirs]:
                path = (Path(folder) / name).resolve()
                if path.is_file():
                    if path not in seen:
                        seen[path] = None
                        todo.append(path)
                    break
    return sorted(seen)


MEMO_FORMAT = 1
MEMO_MAX_FILES = 32        # memo files kept per cache folder (one per sources/flags/compiler), newest first
RACY_NS = 2_000_000_000    # a file changed this recently (ctime) is hashed again next time, not memoized


def _memo_id(include_dirs: list[Path], flags: list[str], cc_version: str, link: list[str]) -> str:
    text = json.dumps([MEMO_FORMAT, [os.path.abspath(d) for d in include_dirs], flags, cc_version, link])
    return hashlib.sha256(text.encode()).hexdigest()


def _memo_check(body: dict) -> str:
    """SHA-256 of a memo's fields (its `check`): a memo altered or half-written is not trusted."""
    fields = {k: v for k, v in body.items() if k != "check"}
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()


def _read_memo(path: Path, srcs: list[Path], stat) -> tuple[list[str], str] | None:
    """(object keys, sources key) of a memo whose every file and folder stats as recorded, else None."""
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
        if body.get("format") != MEMO_FORMAT or body.get("check") != _memo_check(body):
            return None
        if body["sources"] != [os.path.abspath(s) for s in srcs]:
            return None
        for name, recorded in list(body["dirs"].items()) + list(body["files"].items()):
            if list(stat(name)) != recorded:
                return None
        keys, sources_key = [str(k) for k in body["object_keys"]], str(body["sources_key"])
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None   # missing, unreadable, corrupt or stale: the keys are computed again
    return (keys, sources_key) if len(keys) == len(srcs) else None


def _write_memo(path: Path, body: dict) -> None:
    body["check"] = _memo_check(body)
    try:
        atomic_output(path, lambda tmp: tmp.write_text(json.dumps(body), encoding="utf-8"))
        memos = sorted(path.parent.glob("keymemo-*.json"), key=lambda p: p.stat().st_mtime_ns, reverse=True)
        for old in memos[MEMO_MAX_FILES:]:
            old.unlink(missing_ok=True)
    except (CompilerError, OSError):
        pass   # a read-only or shared cache: the keys are only computed again next time


def memoized_keys(srcs: list[Path], include_dirs: list[Path], memo_parts: tuple, out: Path | None,
                  compute: Callable[[], tuple[list[str], str, dict]], stat: Callable) -> tuple[list[str], str]:
    """(object keys, sources key) of `srcs` from the memo in `out` when no file it names has
    changed (module docstring), else from `compute()` (which also returns the stat each file it
    hashed was read under) and memoized; `out=None`: always computed. memo_parts: (flags,
    compiler version, link flags), what else the keys depend on; stat(path): the stat tuple."""
    flags, cc_version, link = memo_parts
    path = Path(out) / f"keymemo-{_memo_id(include_dirs, flags, cc_version, link)[:20]}.json" if out else None
    if path is not None:
        known = _read_memo(path, srcs, stat)
        if known is not None:
            return known
    # the folders first: a file added, removed or renamed in one of them (a header that now
    # shadows another, say) changes the folder's stat
    folders = sorted({os.path.abspath(d) for d in include_dirs} | {os.path.abspath(Path(s).parent) for s in srcs})
    try:
        dirs_before = {d: stat(d) for d in folders}
    except OSError:   # e.g. no driver folder: nothing to memoize against
        path = None
    keys, sources_key, hashed = compute()
    hashed = {os.path.abspath(p): st for p, st in hashed.items()}
    if path is None:
        return keys, sources_key
    folders = sorted(set(folders) | {os.path.dirname(p) for p in hashed})
    try:
        dirs = {d: stat(d) for d in folders}
        now_ns = time.time_ns()
        settled = all(stat(p) == st for p, st in hashed.items()) and \
            all(dirs_before.get(d, st) == st for d, st in dirs.items()) and \
            all(st[4] < now_ns - RACY_NS for st in list(hashed.values()) + list(dirs.values()))
    except OSError:
        settled = False
    if settled:   # else a file is being written now: hash it again next time rather than trust its stat
        _write_memo(path, {"format": MEMO_FORMAT, "sources": [os.path.abspath(s) for s in srcs],
                           "object_keys": keys, "sources_key": sources_key,
                           "files": {p: list(v) for p, v in sorted(hashed.items())},
                           "dirs": {d: list(v) for d, v in dirs.items()}})
    return keys, sources_key
