"""Progress of long work: a live bar on a terminal, a line per ~10 % otherwise, nothing with -q.

A log file or a CI console is not a terminal: tqdm's carriage-return updates would fill it
with hundreds of partial lines, so there a plain line is written at each tenth of the work
(or, without a known total, at each new phase and every `LINE_EVERY_S`), none in the first
`QUIET_START_S`. `-q` (the "leonav" logger above WARNING) silences both.
"""
from __future__ import annotations

import logging
import sys
import time
from typing import TextIO

LINE_EVERY_S = 10.0
"""Without a known total, the shortest interval (s) between two progress lines off a terminal."""
QUIET_START_S = 2.0
"""No line in the first seconds: a short command (or one that fails at once) prints only its result."""


def quiet() -> bool:
    """True when the command runs with -q (warnings not shown)."""
    return not logging.getLogger("leonav").isEnabledFor(logging.WARNING)


class LineProgress:
    """tqdm's small interface (update, close, set_description_str, context manager) as lines."""

    def __init__(self, total: float | None, desc: str, unit: str, stream: TextIO) -> None:
        self.total, self.desc, self.unit, self.stream = total, desc, unit, stream
        self.n = 0.0
        self._t0 = self._last = time.monotonic()
        self._next_tenth = 1

    def update(self, n: float = 1) -> None:
        self.n += n
        now = time.monotonic()
        if self.total:
            tenth = int(10 * self.n / self.total)
            if tenth >= self._next_tenth:
                self._next_tenth = tenth + 1
                self._line(f"{min(100, 10 * tenth)} % ({self.n:g}/{self.total:g} {self.unit})", now)
        elif now - self._last >= LINE_EVERY_S:
            self._line(f"{self.n:g} {self.unit}", now)

    def set_description_str(self, desc: str) -> None:
        if desc != self.desc:
            self.desc = desc
            self._line("", time.monotonic())

    def _line(self, what: str, now: float) -> None:
        if now - self._t0 < QUIET_START_S:
            return
        self._last = now
        sep = ": " if what else ""
        print(f"{self.desc}{sep}{what}  [{now - self._t0:.0f} s]", file=self.stream, flush=True)

    def close(self) -> None:
        """Nothing to clear (lines stay, as a log's should)."""

    def __enter__(self) -> "LineProgress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class NoProgress(LineProgress):
    """-q: the same interface, silent."""

    def _line(self, what: str, now: float) -> None:
        pass


def progress(total: float | None = None, desc: str = "", unit: str = "it", stream: TextIO | None = None,
             **tqdm_options):
    """A progress reporter for `total` units of work (None: unknown): tqdm on a terminal, lines
    otherwise, silent with -q (module doc). `tqdm_options` go to tqdm only."""
    stream = stream or sys.stderr
    if quiet():
        return NoProgress(total, desc, unit, stream)
    if getattr(stream, "isatty", lambda: False)():
        from tqdm import tqdm

        return tqdm(total=total, desc=desc, unit=unit, file=stream, **tqdm_options)
    return LineProgress(total, desc, unit, stream)
