"""The build cache of the compiled filter under faults (used by `compiled.py`).

Every problem with the compiler's settings, the cache folder or a built library is a
`CompilerError` (`leonav` exit status 4) that names the setting to change:
- `$CC` / `$LEONAV_CFLAGS` that are not a command line (an unclosed quote);
- a cache folder that is a file or cannot be written (`$LEONAV_BUILD_DIR`);
- a library that does not load (then it is removed, so the next run builds it again).

Files are written under a temporary name that carries the writing process's id and renamed
onto the target; nothing exists before the compiler writes it, it is removed on any error or
interrupt, and one left by a killed process is removed by the next build
(`prepare_writes`).

Without a working compiler, a library built before from the same sources and flags still
loads: each build records its library under a key without the compiler
(`prebuilt-<key>.txt` in the cache, `record_prebuilt` / `prebuilt_library`).
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import shlex
import subprocess
from pathlib import Path
from typing import Callable


class CompilerError(RuntimeError):
    """No usable C compiler, or compilation failed (the message carries the compiler output)."""


def split_setting(setting: str, text: str) -> list[str]:
    """A command line from an environment setting; CompilerError when it is not one."""
    try:
        return shlex.split(text)
    except ValueError as exc:
        raise CompilerError(f"${setting}={text!r}: not a command line ({exc})") from None


def version_line(cc: str) -> str:
    """First line of `cc --version` (part of every cache key); CompilerError when it does not run."""
    try:
        proc = subprocess.run(split_setting("CC", cc) + ["--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CompilerError(f"$CC={cc!r} does not run ({exc})") from None
    if proc.returncode != 0:
        raise CompilerError(f"$CC={cc!r} does not run: `{cc} --version` exited with status {proc.returncode}")
    text = proc.stdout or proc.stderr
    return text.splitlines()[0] if text.strip() else cc


def atomic_output(target: Path, produce: Callable[[Path], None]) -> None:
    """produce(tmp_path) writes a file that is then renamed onto target (atomic)."""
    tmp = target.with_name(f"{target.name}.{os.getpid()}.{os.urandom(4).hex()}.tmp")
    try:
        produce(tmp)
        if not tmp.is_file() or tmp.stat().st_size == 0:
            raise CompilerError(f"the C compiler wrote no {target.suffix} file (expected {tmp.name})")
        os.replace(tmp, target)
    except OSError as exc:
        raise CompilerError(f"cannot write into the build cache {target.parent} ({exc.strerror or exc}); set "
                            "LEONAV_BUILD_DIR to a writable folder") from None
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)


@contextlib.contextmanager
def build_lock(out: Path):
    """Hold an exclusive lock on the cache folder while building into it.

    Processes that start at once on an empty cache (xdist workers, several commands) would
    otherwise all compile the same objects: one builds, the others wait and then find them.
    Where the lock cannot be taken (no fcntl, a cache that cannot be written) it is skipped.
    """
    try:
        import fcntl

        fh = open(out / ".build.lock", "a")
    except (ImportError, OSError):
        yield
        return
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def prepare_writes(out: Path) -> None:
    """Before compiling into `out`: CompilerError if it cannot be written, and remove the
    `<name>.<pid>.<random>.tmp` files of processes that no longer run (a killed build)."""
    probe = out / f".write-test.{os.getpid()}.{os.urandom(4).hex()}.tmp"
    try:
        probe.touch(exist_ok=False)
        probe.unlink()
    except OSError as exc:
        raise CompilerError(f"cannot write into the build cache {out} ({exc.strerror or exc}); set "
                            "LEONAV_BUILD_DIR to a writable folder") from None
    for tmp in out.glob("*.tmp"):
        parts = tmp.name.rsplit(".", 3)
        try:
            os.kill(int(parts[-3]), 0)
        except ProcessLookupError:
            tmp.unlink(missing_ok=True)
        except (ValueError, IndexError, OSError):   # not ours, or a process that still runs
            continue


def cache_dir(out: Path) -> Path:
    """The build cache folder, created; CompilerError naming the setting when it cannot be."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CompilerError(f"build cache {out}: {exc.strerror or exc} (a file where a folder is expected?); set "
                            "LEONAV_BUILD_DIR to a writable folder") from None
    return out


def _note(out: Path, sources_key: str) -> Path:
    return out / f"prebuilt-{sources_key[:20]}.txt"


def record_prebuilt(out: Path, sources_key: str, library: Path) -> None:
    """Note `library` as the build of these sources and flags (skipped in a read-only cache)."""
    note = _note(out, sources_key)
    try:
        if note.is_file() and note.read_text().strip() == library.name:
            return
        atomic_output(note, lambda tmp: tmp.write_text(library.name + "\n"))
    except (CompilerError, OSError):
        pass   # the library still loads; it is only not recorded for runs without a compiler


def prebuilt_library(out: Path, sources_key: str) -> Path | None:
    """The library recorded for these sources and flags, if it is still in the cache."""
    note = _note(out, sources_key)
    try:
        library = out / note.read_text().strip() if note.is_file() else None
    except (OSError, UnicodeDecodeError):
        return None
    return library if library is not None and library.is_file() else None


def load_library(library: Path, built_by: str) -> ctypes.CDLL:
    """ctypes handle of a built library; one that does not load is removed from the cache
    (the next run builds it again) and reported as a CompilerError."""
    try:
        return ctypes.CDLL(str(library))
    except OSError as exc:
        try:
            library.unlink()
        except OSError:
            pass
        raise CompilerError(f"{library} built by {built_by!r} cannot be loaded ({exc}); it was removed from the "
                            "cache: check $CC and $LEONAV_CFLAGS") from None
