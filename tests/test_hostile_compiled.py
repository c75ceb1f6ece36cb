"""The compiled filter's build and loader under hostile settings: every problem with the
compiler, its flags, the cache or the built library is a CompilerError (`leonav` exit 4, one
line); a library already in the cache loads without a compiler; a killed build never leaves
a temporary file behind for good.

Failure cases build two tiny C files in a temporary cache (fast); the prebuilt case uses the
real library in the default cache.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from leonav_runtime.core import compiled
from leonav_runtime.cli import EXIT_BUILD, classify_error

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def tiny(tmp_path):
    """(gen dir, csrc dir, cache dir) of a two-file library that compiles in a blink."""
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    (gen / "c").mkdir(parents=True)
    csrc.mkdir()
    (gen / "c" / "tiny_gen.c").write_text("int tiny(void) { return 1; }\n")
    (csrc / "tiny_driver.c").write_text("int tiny_driver(void) { return 2; }\n")
    return gen, csrc, tmp_path / "cache"


@pytest.fixture(autouse=True)
def fresh_process_cache():
    compiled.clear_process_cache()
    compiled._version_cache.clear()
    yield
    compiled.clear_process_cache()
    compiled._version_cache.clear()


def _script(path: Path, body: str) -> str:
    path.write_text("#!/bin/sh\n" + body)
    path.chmod(0o755)
    return str(path)


@pytest.mark.parametrize("env,words", [
    ({"CC": "/nonexistent/cc"}, "no C compiler found"),
    ({"CC": "false"}, "false"),
    ({"CC": '"unclosed'}, r"\$CC='\"unclosed': not a command line"),
    ({"LEONAV_CFLAGS": '"unclosed'}, r"\$LEONAV_CFLAGS='\"unclosed': not a command line"),
    ({"LEONAV_CFLAGS": "-fno-such-flag-leonav"}, "-fno-such-flag-leonav"),
], ids=["cc-missing", "cc-false", "cc-unclosed-quote", "cflags-unclosed-quote", "cflags-unknown"])
def test_compiler_problems_are_compiler_errors(tiny, monkeypatch, env, words):
    # before: shlex's ValueError escaped for the unclosed quotes (an internal error, exit 1)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    with pytest.raises(compiled.CompilerError, match=words) as info:
        compiled.build(*tiny[:2], out_dir=tiny[2])
    status, line = classify_error(info.value)
    assert status == EXIT_BUILD and line.startswith("cannot build the C filter: ") and "\n" not in line


def test_a_library_that_does_not_load_is_a_compiler_error_and_leaves_the_cache(tiny, tmp_path, monkeypatch):
    # before: ctypes' OSError ("invalid ELF header"): exit 3 as if a file were unreadable, and the
    # broken library stayed in the cache for every later run
    cc = _script(tmp_path / "bogus-cc", 'if [ "$1" = --version ]; then echo bogus 1.0; exit 0; fi\n'
                 'while [ $# -gt 1 ]; do [ "$1" = -o ] && echo garbage > "$2"; shift; done\n')
    monkeypatch.setenv("CC", cc)
    with pytest.raises(compiled.CompilerError, match=r"cannot be loaded .*removed from the cache") as info:
        compiled.load(*tiny[:2], out_dir=tiny[2])
    assert classify_error(info.value)[0] == EXIT_BUILD
    assert not list(tiny[2].glob("libleonav-*.so"))


def test_a_cache_that_is_a_file_or_read_only_is_a_compiler_error(tiny, tmp_path, monkeypatch):
    # before: FileExistsError / PermissionError (exit 3) without saying which setting to change
    a_file = tmp_path / "cache-file"
    a_file.write_text("x")
    monkeypatch.setenv("LEONAV_BUILD_DIR", str(a_file))
    with pytest.raises(compiled.CompilerError, match=r"build cache .*cache-file.*LEONAV_BUILD_DIR"):
        compiled.build(*tiny[:2])
    if Path("/sys/kernel").is_dir():   # a folder nobody can write into, not even root
        with pytest.raises(compiled.CompilerError, match=r"cannot write into the build cache /sys/kernel.*LEONAV_BUILD_DIR"):
            compiled.build(*tiny[:2], out_dir=Path("/sys/kernel"))


def test_a_prebuilt_library_loads_without_a_compiler(monkeypatch):
    # before: CC=/nonexistent failed even with the library in the cache
    built = compiled.load()                      # with the compiler: built or found in the cache
    compiled.clear_process_cache()
    for cc in ("/nonexistent/cc", '"unclosed', "false"):
        monkeypatch.setenv("CC", cc)
        lib = compiled.load()
        assert lib.build.library == built.build.library and "prebuilt" in lib.build.compiler
        assert lib.lib.leonav_work_size() == built.work_size
        compiled.clear_process_cache()
    monkeypatch.setenv("LEONAV_CFLAGS", "-DLEONAV_NEVER_BUILT=1")   # other flags: no such library yet
    with pytest.raises(compiled.CompilerError, match="no C compiler found|does not run"):
        compiled.load()


KILLED_BUILD = """
import sys
from pathlib import Path
from leonav_runtime.core import compiled
compiled.build(Path(sys.argv[1]), Path(sys.argv[2]), out_dir=Path(sys.argv[3]))
"""


def test_a_killed_build_leaves_no_temporary_file(tiny, tmp_path):
    # before: mkstemp's 0-byte `*.tmp` stayed in the cache after a kill, one per object
    marker = tmp_path / "compiling"
    cc = _script(tmp_path / "slow-cc", f'if [ "$1" = --version ]; then echo slow 1.0; exit 0; fi\n'
                 f'touch {marker}; sleep 30; exec cc "$@"\n')
    gen, csrc, cache = tiny
    proc = subprocess.Popen([sys.executable, "-c", KILLED_BUILD, str(gen), str(csrc), str(cache)], cwd=REPO,
                            env=dict(os.environ, CC=cc, PYTHONPATH=str(REPO)), start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not marker.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marker.exists()
        os.killpg(proc.pid, signal.SIGKILL)       # the build and its compiler, mid-compile
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert cache.is_dir() and not list(cache.glob("*.tmp"))
    # a leftover of a process that no longer runs (SIGKILL after the compiler wrote it) goes at the next build
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = cache / f"tiny_gen-0123.o.{dead.stdout.strip()}.deadbeef.tmp"
    stale.write_bytes(b"half an object")
    compiled.build(gen, csrc, out_dir=cache)
    assert not stale.exists() and list(cache.glob("libleonav-*.so"))
