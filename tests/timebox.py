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


def communicate_or_stacks(proc, timeout: float, what: str):
    """(stdout, stderr) of a child process that should end within `timeout` s; one that does not is
    sent SIGABRT (with PYTHONFAULTHANDLER=1 in its environment it prints every thread's stack) and
    the test fails with the end of its stderr, saying `what` it did not do."""
    import subprocess

    import pytest

    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        err = err.decode(errors="replace") if isinstance(err, bytes) else err
        pytest.fail(f"{what} within {timeout:g} s; stderr: {err[-4000:]}")
