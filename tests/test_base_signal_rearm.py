"""`leonav base`: a signal during the corrections build ends it even when a library swallows the
raise where it lands (pynmea2's field conversion has a bare `except:` that hands back the text)."""
from __future__ import annotations

import json
import signal
import threading
import time

import pytest

from leonav_runtime.cli import main
from leonav_runtime.commands import base as base_command

pytestmark = [
    pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the re-raise uses setitimer (POSIX)"),
    pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                       reason="signal handlers can only be installed in the main thread"),
]

BUSY_S = 10.0     # what the build would still take if the signal were lost


def _pair(tmp_path):
    (tmp_path / "p" / "base").mkdir(parents=True)
    (tmp_path / "p" / "pair.json").write_text(json.dumps({"base_position_deg_m": [43.0, -77.0, 170.0]}))
    return str(tmp_path / "p")


def _swallowing_build(after_swallow):
    """A build whose first raise (SIGINT's) is eaten by a bare except, then `after_swallow()`."""
    calls = []

    def build(*_args, **_kwargs):
        calls.append(time.monotonic())
        try:
            signal.raise_signal(signal.SIGINT)     # the handler runs here and raises
        except BaseException:                      # noqa: BLE001 (what the library does)
            pass
        return after_swallow()
    return build, calls


def _busy():
    t0 = time.monotonic()
    while time.monotonic() - t0 < BUSY_S:
        sum(range(1000))
    return [], 0.0, []


@pytest.mark.parametrize("after", [_busy, lambda: "12x456.00".hour], ids=["busy", "fails-on-the-text"])
def test_a_swallowed_signal_still_ends_the_build(tmp_path, monkeypatch, capsys, after):
    """Busy on: SIGALRM raises again within REARM_S, so the build ends long before BUSY_S. Failing
    on what the swallow left (an AttributeError on the text): exit 130 'interrupted', not a crash."""
    build, calls = _swallowing_build(after)
    monkeypatch.setattr(base_command, "build_corrections", build)
    before = signal.getsignal(signal.SIGALRM)
    code = main(["base", "--simulate", _pair(tmp_path), "--listen", "127.0.0.1:0"])
    ended = time.monotonic()
    err = capsys.readouterr().err
    assert code == 130 and "interrupted (SIGINT)" in err and "error" not in err, err
    assert len(calls) == 1 and ended - calls[0] < BUSY_S / 4, ended - calls[0]
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)      # the re-raise timer is off again
    assert signal.getsignal(signal.SIGALRM) is before


def test_an_error_of_the_build_without_a_signal_is_still_an_error(tmp_path, monkeypatch, capsys):
    """The 'signal is the news' rule covers only builds after a signal: a plain failure is reported."""
    def build(*_args, **_kwargs):
        raise base_command.UserInputError("no Doppler-rate measurements (test)")
    monkeypatch.setattr(base_command, "build_corrections", build)
    code = main(["base", "--simulate", _pair(tmp_path), "--listen", "127.0.0.1:0"])
    err = capsys.readouterr().err
    assert code == 2 and "no Doppler-rate measurements (test)" in err and "interrupted" not in err, err
