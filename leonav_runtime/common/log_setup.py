"""Log levels and warnings of the command line (`leonav -v|-vv|-q COMMAND`).

Library code logs to the `leonav.*` loggers and raises Python warnings; the CLI shows
both as one line each, `leonav COMMAND: warning: ...`, on stderr, without the source path
Python's own warning display adds. A warning is printed once per run (the same message
from two places, or a stale-elements warning for each of several element sets, is shown
the first time only). Verbosity: -q errors only, default warnings, -v info, -vv debug.
"""
from __future__ import annotations

import contextlib
import logging
import sys
import warnings
from typing import Iterator

LEVELS = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}
ONCE_PER_RUN = ("StaleElementsWarning",)  # categories shown for their first occurrence only


def level_for(verbosity: int) -> int:
    """Logging level of a verbosity count (clamped: <= -1 errors, >= 2 debug)."""
    return logging.DEBUG if verbosity >= 2 else LEVELS[max(-1, verbosity)]


class _Once(logging.Filter):
    """Drops a record whose message was already shown in this run."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        key = getattr(record, "once_key", None) or record.getMessage()
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


@contextlib.contextmanager
def cli_logging(command: str, verbosity: int) -> Iterator[logging.Logger]:
    """Route `leonav.*` logs and Python warnings to stderr for one CLI run."""
    logger = logging.getLogger("leonav")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"leonav {command}: %(levelname)s: %(message)s"))
    handler.addFilter(_Once())
    old = (logger.level, logger.propagate, list(logger.handlers), warnings.showwarning)
    logger.handlers = [handler]
    logger.setLevel(level_for(verbosity))
    logger.propagate = False
    for name in ("WARNING", "INFO", "DEBUG", "ERROR"):
        logging.addLevelName(getattr(logging, name), name.lower())
    warn_log = logging.getLogger("leonav.warnings")

    def show(message, category, filename, lineno, file=None, line=None):  # noqa: ARG001 (warnings API)
        name = getattr(category, "__name__", "")
        key = name if name in ONCE_PER_RUN else None
        warn_log.warning(str(message), extra={"once_key": key} if key else None)

    warnings.showwarning = show
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = show
            yield logger
    finally:
        logger.setLevel(old[0])
        logger.propagate = old[1]
        logger.handlers = old[2]
        warnings.showwarning = old[3]
