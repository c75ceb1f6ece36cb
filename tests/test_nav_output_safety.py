"""`leonav nav` never destroys what is not its own (GitHub issue 24, failures 3 and 6).

- `--nmea-pty FILE` replaces only a symbolic link to a pty device (the one an earlier run left);
  a regular file, a directory or a link to anything else is refused in one line, exit 2, untouched.
- One output folder has one writer: a run holds an exclusive lock on OUT while it writes; a second
  run on the same OUT is refused in one line naming the folder and the other run's pid, exit 2,
  and the first run's files stay whole. A lock left by a dead process does not block.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from leonav_runtime.common.errors import UserInputError
from tests.test_nav_live import nav_options

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Path:
    """A short synthetic session without SDR (fast playback takes about a second)."""
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    folder = tmp_path_factory.mktemp("navsafety") / "s"
    write_synthetic_session(folder, SynthSessionConfig(seconds=4.0, seed=3, sdr=False))
    return folder


def _cli(capsys, *argv: str) -> tuple[int, str]:
    """`leonav ARGV` in this process: (exit code, stderr)."""
    from leonav_runtime.cli import main

    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


def _nav_cli(capsys, session: Path, out: Path, *extra: str) -> tuple[int, str]:
    return _cli(capsys, "nav", "--from", session, "--out", out, "--nmea-port", "0", "--quiet", "--no-record",
                *extra)


def _error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "error" in line]


# -- failure 3: --nmea-pty FILE

def test_nmea_pty_refuses_a_regular_file_and_keeps_it(session, tmp_path, capsys):
    data = tmp_path / "track.txt"
    data.write_text("the user's data\n")
    code, err = _nav_cli(capsys, session, tmp_path / "out", "--nmea-pty", data)
    assert code == 2
    assert data.read_text() == "the user's data\n" and not data.is_symlink()
    lines = _error_lines(err)
    assert len(lines) == 1 and f"--nmea-pty {data}" in lines[0] and "regular file" in lines[0], err
    assert not (tmp_path / "out" / "nav.json").exists()


def test_nmea_pty_refuses_a_directory_naming_it(session, tmp_path, capsys):
    folder = tmp_path / "somedir"
    folder.mkdir()
    (folder / "keep").write_text("x")
    code, err = _nav_cli(capsys, session, tmp_path / "out", "--nmea-pty", folder)
    assert code == 2 and (folder / "keep").read_text() == "x"
    lines = _error_lines(err)
    assert len(lines) == 1 and f"--nmea-pty {folder}" in lines[0] and "directory" in lines[0], err
    assert "port" not in lines[0] and "another program" not in lines[0], err


def test_nmea_pty_refuses_a_link_to_something_else(session, tmp_path, capsys):
    target = tmp_path / "config.txt"
    target.write_text("keep me\n")
    link = tmp_path / "nmea"
    link.symlink_to(target)
    code, err = _nav_cli(capsys, session, tmp_path / "out", "--nmea-pty", link)
    assert code == 2
    assert link.is_symlink() and os.readlink(link) == str(target) and target.read_text() == "keep me\n"
    lines = _error_lines(err)
    assert len(lines) == 1 and f"--nmea-pty {link}" in lines[0] and "symbolic link" in lines[0], err


def test_nmea_pty_replaces_the_pty_link_an_earlier_run_left(tmp_path):
    from leonav_runtime.nav.sinks.servers import PtyOutput

    link = tmp_path / "nmea"
    link.symlink_to("/dev/pts/987654")          # a killed run's link: its pty is gone
    out = PtyOutput(link)
    try:
        assert link.is_symlink() and os.readlink(link) == out.device != "/dev/pts/987654"
    finally:
        out.close()
    assert not link.is_symlink() and not link.exists()


def test_pty_close_leaves_a_link_someone_else_put_there(tmp_path):
    from leonav_runtime.nav.sinks.servers import PtyOutput

    link = tmp_path / "nmea"
    out = PtyOutput(link)
    link.unlink()
    link.symlink_to(tmp_path / "theirs")
    out.close()
    assert link.is_symlink() and os.readlink(link) == str(tmp_path / "theirs")


# -- failure 6: one writer per --out

def test_a_second_run_on_the_same_out_is_refused_while_the_first_writes(session, tmp_path):
    """The first run (a thread) is held inside its run, after opening its outputs, until the second
    run has tried: the overlap is certain, whatever the machine's speed."""
    from leonav_runtime.nav.run import run_nav

    out = tmp_path / "out"
    started, tried = threading.Event(), threading.Event()
    first: dict = {}

    def hold() -> None:
        started.set()
        tried.wait(20)

    def first_run() -> None:
        first["result"] = run_nav(nav_options(out, session=session, record=False), on_started=hold)

    thread = threading.Thread(target=first_run)
    thread.start()
    try:
        assert started.wait(20), "the first run never started"
        with pytest.raises(UserInputError) as exc:
            run_nav(nav_options(out, session=session, record=False))
    finally:
        tried.set()
        thread.join(30)
    msg = str(exc.value)
    assert "\n" not in msg and str(out) in msg and f"pid {os.getpid()}" in msg, msg
    assert first["result"]["exit_code"] == 0
    nav = json.loads((out / "nav.json").read_text())
    assert nav["exit_code"] == 0 and nav["outputs"]["solutions"] == first["result"]["outputs"]["solutions"]
    lines = (out / "solutions.jsonl").read_text().splitlines()
    assert len(lines) == nav["outputs"]["solutions"] > 0
    assert all(json.loads(line) for line in lines)
    rows = (out / "trajectory.csv").read_text().splitlines()
    assert len(rows) == nav["trajectory_rows"] + 1


def _child_holding_the_lock(out: Path, exit_at_once: bool) -> subprocess.Popen:
    """Another process that takes OUT's lock through the public function and says so."""
    code = ("import sys, os\n"
            "from leonav_runtime.nav.out_lock import lock_out_dir\n"
            f"lock = lock_out_dir({str(out)!r})\n"
            "print('locked', flush=True)\n"
            + ("os._exit(0)\n" if exit_at_once else "sys.stdin.read()\n"))
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


def test_cli_refuses_an_out_another_process_writes(session, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "solutions.jsonl").write_text('{"theirs": 1}\n')
    proc = _child_holding_the_lock(out, exit_at_once=False)
    try:
        code, err = _nav_cli(capsys, session, out)
    finally:
        proc.stdin.close()
        proc.wait(10)
    assert code == 2
    lines = _error_lines(err)
    assert len(lines) == 1 and f"--out {out}" in lines[0] and f"pid {proc.pid}" in lines[0], err
    assert (out / "solutions.jsonl").read_text() == '{"theirs": 1}\n' and not (out / "nav.json").exists()


def test_a_lock_left_by_a_dead_process_does_not_block(session, tmp_path, capsys):
    out = tmp_path / "out"
    proc = _child_holding_the_lock(out, exit_at_once=True)     # ends without releasing: a stale lock file
    proc.wait(10)
    code, err = _nav_cli(capsys, session, out)
    assert code == 0, err
    assert json.loads((out / "nav.json").read_text())["exit_code"] == 0


def test_the_lock_is_released_at_the_end_of_a_run(session, tmp_path):
    from leonav_runtime.nav.out_lock import lock_out_dir
    from leonav_runtime.nav.run import run_nav

    out = tmp_path / "out"
    assert run_nav(nav_options(out, session=session, record=False))["exit_code"] == 0
    with pytest.raises(UserInputError):           # the lock refuses a second holder ...
        with lock_out_dir(out):
            lock_out_dir(out)
    with lock_out_dir(out):                       # ... and is free again once released
        pass
