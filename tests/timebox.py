"""`bounded(seconds)`: a test block that must finish within a wall-time budget (hang guard)."""
from __future__ import annotations

import signal
from contextlib import contextmanager


@contextmanager
def bounded(seconds: float):
    """Fail with TimeoutError when the block runs longer than `seconds` of wall time."""
    def _alarm(signum, frame):
        raise TimeoutError(f"took longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
