"""Progress off a terminal is a line per tenth (no carriage-return bar in a log), nothing with -q."""
from __future__ import annotations

import io
import logging

import pytest

from leonav_runtime.common import progress as pg


@pytest.fixture(autouse=True)
def _no_quiet_start(monkeypatch):
    monkeypatch.setattr(pg, "QUIET_START_S", 0.0)


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_per_tenth_off_a_terminal():
    out = io.StringIO()
    bar = pg.progress(50, "sweep paper", "task", stream=out, smoothing=0.05)
    assert isinstance(bar, pg.LineProgress)
    for _ in range(50):
        bar.update()
    bar.close()
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue() and len(lines) == 10
    assert lines[0].startswith("sweep paper: 10 % (5/50 task)") and lines[-1].startswith("sweep paper: 100 % (50/50")


def test_unknown_total_and_description_changes_are_lines():
    out = io.StringIO()
    with pg.progress(None, "leonav run", stream=out) as bar:
        bar.set_description_str("run fix+imu")
        bar.set_description_str("run fix+imu")      # unchanged: no new line
        bar.update(3)                                 # no total: a line only every LINE_EVERY_S
    assert out.getvalue().splitlines()[0].startswith("run fix+imu  [")
    assert len(out.getvalue().splitlines()) == 1


def test_a_terminal_gets_the_live_bar_and_quiet_gets_nothing():
    from tqdm import tqdm

    bar = pg.progress(10, "x", stream=_Tty())
    assert isinstance(bar, tqdm)
    bar.close()
    log = logging.getLogger("leonav")
    old = log.level
    log.setLevel(logging.ERROR)                       # what -q sets
    try:
        out = _Tty()
        bar = pg.progress(10, "x", stream=out)
        for _ in range(10):
            bar.update()
        bar.close()
        assert out.getvalue() == "" and isinstance(bar, pg.NoProgress)
    finally:
        log.setLevel(old)


def test_a_closed_pipe_ends_quietly():
    """`leonav completion bash | head -1`: the reader stops early; no 'Broken pipe' error, exit 0."""
    import shutil
    import subprocess

    exe = shutil.which("leonav")
    if exe is None:
        pytest.skip("the leonav console script is not on PATH")
    proc = subprocess.run(f"'{exe}' completion bash | head -c 10 >/dev/null; exit ${{PIPESTATUS[0]}}", shell=True,
                          executable="/bin/bash", capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Broken pipe" not in proc.stderr and "error" not in proc.stderr, proc.stderr


def test_no_line_in_the_first_seconds(monkeypatch):
    monkeypatch.setattr(pg, "QUIET_START_S", 60.0)
    out = io.StringIO()
    bar = pg.progress(10, "quick", stream=out)
    for _ in range(10):
        bar.update()
    bar.set_description_str("other")
    assert out.getvalue() == ""
