"""The `leonav` command line.

Each subcommand lives in its own module under `leonav_runtime/commands/` and exposes
`register(subparsers) -> None`, which adds a parser whose `func(args) -> int` does the
work. Modules are discovered here, so adding a command never edits this file.

Errors are turned into one line `leonav CMD: error: ...` and a documented exit status
here, in one place (`report_error`); `--debug` (anywhere on the command line, or
LEONAV_DEBUG=1) prints the traceback as well.
"""
from __future__ import annotations

import argparse
import csv
import errno
import importlib
import json
import os
import pkgutil
import sys
import traceback

from leonav_runtime import commands as _commands_pkg
from leonav_runtime.common import provenance
from leonav_runtime.common.arg_parser import OneLineErrorParser
from leonav_runtime.common.errors import UserInputError

# One BLAS thread unless the user's environment names a number: the runtime's matrices are
# small (tens of states), so OpenBLAS's extra threads do no work and their start and idle spinning
# cost CPU (0.12 s of CPU at `import numpy` on a 2-core machine). Set before numpy is imported;
# children (the beacon process, workers) inherit it.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "GOTO_NUM_THREADS", "MKL_NUM_THREADS")
if not any(v in os.environ for v in BLAS_THREAD_VARIABLES):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"

EXIT_OK = 0
EXIT_INTERNAL = 1       # an unexpected error: a bug (rerun with --debug and report the traceback)
EXIT_BAD_INPUT = 2      # a file, field or option value is not what was expected
EXIT_IO = 3             # a file or folder cannot be read or written (missing, permissions, disk full)
EXIT_BUILD = 4          # the generated C could not be compiled or loaded ($CC, compiler errors)
EXIT_INTERRUPTED = 130  # Ctrl-C

EPILOG = """\
exit status:
  0    success
  1    unexpected internal error (a bug: rerun with --debug and report the traceback)
  2    bad input: a file, field or option value is not what was expected (an input file
       that is missing or a directory included), or a download failed; the message names
       the file/line/field and what was expected
  3    I/O error: a file or folder cannot be read or written by the system (permissions,
       disk full, --out or the cache is a file, a path the command did not check itself)
  4    the generated C filter could not be built or loaded (check $CC and the compiler)
  130  interrupted (Ctrl-C)
Errors are one line `leonav COMMAND: error: ...`; add --debug (anywhere) or set
LEONAV_DEBUG=1 to also print the Python traceback.

limits on untrusted input:
  element files (TLE/3LE/OMM)   64 MB; raise with LEONAV_MAX_ELEMENT_MB=<megabytes>
  compressed RINEX files        2048 MB once expanded (.gz .Z .bz2 Hatanaka .crx/.YYd); raise
                                with LEONAV_MAX_RINEX_MB=<megabytes>
  leonav tle fetch replies      64 MB; raise with --max-mb; --timeout (default 60 s) is the
                                deadline of the whole download; a reply with rejected entries
                                or < 90 % of the cached group's satellites needs --force
  leonav beacons                metadata files 16 MB, sample rates 1e3..1e9 S/s, captures up
                                to 6 h, --fft-size 16..4194304, --interval 0.05..3600 s,
                                --simulate up to 3600 s and the free disk space
"""


class _VersionAction(argparse.Action):
    """`--version`: the version and git commit, looked up only when asked for (the lookup
    runs git, which every other command line would otherwise pay for)."""

    def __call__(self, parser, namespace, values, option_string=None):
        print(provenance.version_text())   # stdout, as argparse's own version action
        parser.exit()


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Build the top-level parser with every discovered subcommand (errors are one line); with
    `command` (the command word of a command line), only that command's module is imported,
    so a command starts without the imports of all the others (the full parser when the word
    names no command module, and always for `completion`, which describes every command)."""
    parser = OneLineErrorParser(
        prog="leonav",
        description=(
            "LEO-aided 9D navigation (position, velocity, attitude): IMU + GPS + passive "
            "Starlink Doppler-rate in a generated-C error-state EKF, with its PCRB."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action=_VersionAction, nargs=0,
                        help="print the leonav version and the git commit of this checkout, then exit")
    parser.add_argument("--debug", action="store_true",
                        help="print the Python traceback of an error (also accepted after the command)")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log messages: -v info, -vv debug (short forms also accepted after the command)")
    parser.add_argument("-q", "--quiet", action="count", default=0,
                        help="only errors: warnings are not printed (short form also accepted after the command)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    names = [m.name for m in sorted(pkgutil.iter_modules(_commands_pkg.__path__), key=lambda m: m.name)
             if not m.name.startswith("_")]
    only = command.replace("-", "_") if command and command != "completion" else None
    for name in names if only not in names else [only]:
        module = importlib.import_module(f"{_commands_pkg.__name__}.{name}")
        module.register(sub)
    if only in names and command not in sub.choices:   # the module registers another name
        return build_parser()
    return parser


def _split_debug(argv: list[str]) -> tuple[list[str], bool]:
    """Remove `--debug` from anywhere before a `--` separator; (remaining argv, debug?)."""
    out, debug, literal = [], False, False
    for arg in argv:
        if not literal and arg == "--debug":
            debug = True
            continue
        if arg == "--":
            literal = True
        out.append(arg)
    return out, debug


_VERBOSITY = {"-v": 1, "-vv": 2, "-vvv": 3, "-q": -1, "-qq": -2}


def _split_verbosity(argv: list[str]) -> tuple[list[str], int]:
    """Remove the short `-v`/`-vv`/`-q` from anywhere before `--` (no subcommand uses them);
    (remaining argv, verbosity: 0 default, > 0 more, < 0 less)."""
    out, level, literal = [], 0, False
    for arg in argv:
        if not literal and arg in _VERBOSITY:
            level += _VERBOSITY[arg]
            continue
        if arg == "--":
            literal = True
        out.append(arg)
    return out, level


def _command_name(args: argparse.Namespace) -> str:
    words = [str(args.command)]
    for key in ("tle_action", "session_command"):
        value = getattr(args, key, None)
        if isinstance(value, str):
            words.append(value)
    return " ".join(words)


def _build_error_types() -> tuple[type, ...]:
    """Exception types of the C build (only when the build module was imported at all)."""
    module = sys.modules.get("leonav_runtime.core.compiled")
    if module is None:
        return ()
    return tuple(t for t in (getattr(module, "CompilerError", None), getattr(module, "LayoutMismatchError", None))
                 if isinstance(t, type))


def _toml_error_types() -> tuple[type, ...]:
    types = []
    for name in ("tomllib", "tomli"):
        module = sys.modules.get(name)
        if module is not None and isinstance(getattr(module, "TOMLDecodeError", None), type):
            types.append(module.TOMLDecodeError)
    return tuple(types)


def _os_error_text(exc: OSError) -> str:
    """'<file>: <what went wrong>' for an OSError, with a hint for the common cases."""
    what = exc.strerror or str(exc) or type(exc).__name__
    custom = bool(exc.strerror) and exc.errno is not None and exc.strerror != os.strerror(exc.errno)
    hints = {
        errno.ENOENT: "no such file or folder",
        errno.EISDIR: "is a directory, expected a file",
        errno.ENOTDIR: "a part of the path is a file, expected a folder",
        errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted",
        errno.ENOSPC: "no space left on the device",
        errno.EROFS: "read-only file system",
        errno.EEXIST: "already exists (a file where a folder is expected?)",
    }
    if exc.errno in hints and not custom:  # a message the code wrote is kept as it is
        what = hints[exc.errno]
    where = exc.filename
    if where is None:
        return what if exc.strerror else str(exc) or type(exc).__name__
    text = f"{os.fsdecode(where) if isinstance(where, (bytes, os.PathLike)) else where}: {what}"
    if getattr(exc, "filename2", None):
        text += f" (and {exc.filename2})"
    return text


def _first_line(text: str) -> str:
    lines = [ln for ln in str(text).splitlines() if ln.strip()]
    if not lines:
        return ""
    more = f" (+{len(lines) - 1} more lines; --debug shows everything)" if len(lines) > 1 else ""
    return lines[0].strip() + more


def classify_error(exc: BaseException) -> tuple[int, str]:
    """(exit status, one-line message) of an exception raised by a command."""
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED, "interrupted"
    build = _build_error_types()
    if build and isinstance(exc, build):
        return EXIT_BUILD, f"cannot build the C filter: {_first_line(exc)}"
    if isinstance(exc, UserInputError):
        return EXIT_BAD_INPUT, _first_line(exc)
    if isinstance(exc, UnicodeError):
        where = f" at byte {exc.start}" if isinstance(exc, UnicodeDecodeError) else ""
        return EXIT_BAD_INPUT, (f"text is not valid {getattr(exc, 'encoding', 'UTF-8')}{where} "
                                f"({getattr(exc, 'reason', exc)}); expected a UTF-8 text file")
    if isinstance(exc, json.JSONDecodeError):
        return EXIT_BAD_INPUT, f"not valid JSON: line {exc.lineno}, column {exc.colno}: {exc.msg}"
    if isinstance(exc, csv.Error):
        return EXIT_BAD_INPUT, f"not valid CSV: {exc}"
    toml = _toml_error_types()
    if toml and isinstance(exc, toml):
        return EXIT_BAD_INPUT, f"not valid TOML: {_first_line(exc)}"
    if isinstance(exc, OverflowError):  # a number or date in the input beyond what can be represented
        return EXIT_BAD_INPUT, f"a value is out of range ({_first_line(exc)})"
    if isinstance(exc, RecursionError):
        return EXIT_BAD_INPUT, "input nested too deeply (recursion limit reached); expected a flat file"
    if isinstance(exc, OSError):
        return EXIT_IO, _os_error_text(exc)
    if isinstance(exc, MemoryError):
        return EXIT_INTERNAL, "out of memory (the input is larger than this machine can hold)"
    frames = traceback.extract_tb(exc.__traceback__)
    at = f" at {os.path.relpath(frames[-1].filename) if frames else '?'}:{frames[-1].lineno}" if frames else ""
    return EXIT_INTERNAL, (f"internal error {type(exc).__name__}: {_first_line(exc) or '(no message)'}{at}; "
                           "rerun with --debug and report the traceback")


def report_error(command: str, exc: BaseException, debug: bool = False) -> int:
    """Print the one-line message of `exc` (and the traceback when `debug`); return the exit status."""
    status, message = classify_error(exc)
    if debug:
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    label = "" if status == EXIT_INTERRUPTED else "error: "
    print(f"leonav {command}: {label}{message}", file=sys.stderr)
    return status


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `leonav` console script; returns the process exit code."""
    from leonav_runtime.common import log_setup

    argv = list(sys.argv[1:] if argv is None else argv)
    provenance.set_command_line(argv)
    argv, debug = _split_debug(argv)
    argv, verbosity = _split_verbosity(argv)
    debug = debug or os.environ.get("LEONAV_DEBUG", "") not in ("", "0")
    parser = build_parser(next((a for a in argv if not a.startswith("-")), None))
    args, extra = parser.parse_known_args(argv)
    if extra:   # named after the command they were given to, as every other error
        prog = f"leonav {_command_name(args)}" if getattr(args, "command", None) else "leonav"
        print(f"{prog}: error: unrecognized arguments: {' '.join(extra)} (see `{prog} --help`)", file=sys.stderr)
        return EXIT_BAD_INPUT
    verbosity += args.verbose - args.quiet
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    with log_setup.cli_logging(_command_name(args), verbosity):
        try:
            rc = int(args.func(args) or 0)
            _finish_results(failed=rc != 0, why=f"exit code {rc}")
            return rc
        except BrokenPipeError:
            # the reader closed the pipe (`leonav completion bash | head`): what it wanted was written
            _silence_stdout()
            _finish_results(failed=False)
            return 0
        except (KeyboardInterrupt, Exception) as exc:  # noqa: BLE001 (one place turns every error into one line)
            rc = report_error(_command_name(args), exc, debug)
            _finish_results(failed=True, why=f"{type(exc).__name__}: {exc}")
            return rc


def _finish_results(failed: bool, why: str = "") -> None:
    """A failed command removes the empty results folders it created (`output.finish_results`);
    a command that never imported the output module created none."""
    out = sys.modules.get("leonav_runtime.common.output")
    if out is not None:
        out.finish_results(failed, why)


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


if __name__ == "__main__":
    sys.exit(main())
