"""The one place in cli.py that turns errors into one line and a documented exit status."""
from __future__ import annotations

import subprocess
import sys

import pytest

from leonav_runtime import cli
from leonav_runtime.cli import EXIT_BAD_INPUT, EXIT_BUILD, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_IO, main
from tests.conftest import shared_file


def _one_line(capsys, command: str) -> str:
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1, err
    assert err[0].startswith(f"leonav {command}: "), err
    return err[0]


def test_help_documents_exit_codes_and_limits(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for text in ("exit status:", "0    success", "2    bad input", "3    I/O error", "4    the generated C",
                 "130  interrupted", "--debug", "LEONAV_MAX_ELEMENT_MB", "--max-mb"):
        assert text in out, text


def test_out_that_is_a_file_or_under_a_file_is_an_io_error(tmp_path, capsys):
    tle = shared_file("tle/gps-ops_2026-03-09.txt")
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    assert main(["tle", "info", str(tle), "--out", str(a_file)]) == EXIT_IO
    assert "already exists" in _one_line(capsys, "tle info")
    assert main(["tle", "info", str(tle), "--out", str(a_file / "sub")]) == EXIT_IO
    assert "a part of the path is a file, expected a folder" in _one_line(capsys, "tle info")
    assert a_file.read_text() == "x"


def test_directory_or_missing_file_given_as_a_file(tmp_path, capsys):
    assert main(["tle", "info", str(tmp_path), "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    assert "is a directory, expected a TLE/3LE/OMM file" in _one_line(capsys, "tle info")
    assert main(["tle", "info", str(tmp_path / "missing.tle"), "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    assert "element file not found" in _one_line(capsys, "tle info")
    assert main(["sweep", str(tmp_path), "--out", str(tmp_path / "o2")]) in (EXIT_BAD_INPUT, EXIT_IO)
    assert str(tmp_path) in _one_line(capsys, "sweep")


def test_non_utf8_input_is_bad_input_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b'name = "caf\xe9"\n')
    assert main(["sweep", str(bad), "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    assert "UTF-8" in _one_line(capsys, "sweep")


def test_bad_compiler_is_a_build_error_in_one_line(tmp_path, capsys, monkeypatch):
    from leonav_runtime.core import compiled
    from leonav_runtime.beacons import predict

    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    monkeypatch.setenv("LEONAV_BUILD_DIR", str(tmp_path / "build"))
    compiled.clear_process_cache()
    predict._nav.cache_clear()  # the beacon predictions keep their loaded library per process
    try:
        rc = main(["beacons", str(tmp_path / "s.cu8"), "--simulate", "--duration", "4.5", "--sim-rate", "1e5",
                   "--band", "1e5", "--tle", str(shared_file("tle/starlink_2026-02-23.txt")),
                   "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "o")])
    finally:
        compiled.clear_process_cache()
        predict._nav.cache_clear()
    assert rc == EXIT_BUILD
    line = _one_line(capsys, "beacons")
    assert "cannot build the C filter: no C compiler found" in line and "no-such-cc" in line


def _raiser(exc):
    def func(args):
        raise exc
    return func


@pytest.mark.parametrize("exc,status,words", [
    (KeyboardInterrupt(), EXIT_INTERRUPTED, "interrupted"),
    (PermissionError(13, "Permission denied", "/root/x.csv"), EXIT_IO, "/root/x.csv: permission denied"),
    (OSError(28, "No space left on device", "/mnt/full/out.csv"), EXIT_IO, "no space left on the device"),
    (UnicodeDecodeError("utf-8", b"\xff", 0, 1, "invalid start byte"), EXIT_BAD_INPUT, "not valid utf-8"),
    (RecursionError("maximum recursion depth exceeded"), EXIT_BAD_INPUT, "nested too deeply"),
    (OverflowError("date value out of range"), EXIT_BAD_INPUT, "out of range"),
    (KeyError("x"), EXIT_INTERNAL, "internal error KeyError"),
])
def test_every_error_is_one_line_with_its_documented_status(tmp_path, capsys, monkeypatch, exc, status, words):
    from leonav_runtime.commands import tle

    monkeypatch.setattr(tle, "_cmd_info", _raiser(exc))
    assert main(["tle", "info", "x"]) == status
    line = _one_line(capsys, "tle info")
    assert words in line, line
    if status == EXIT_INTERNAL:
        assert "rerun with --debug" in line and "test_hostile_cli.py" in line


def test_debug_prints_the_traceback_with_the_same_status(capsys, monkeypatch):
    from leonav_runtime.commands import tle

    monkeypatch.setattr(tle, "_cmd_info", _raiser(PermissionError(13, "Permission denied", "/root/x")))
    assert main(["tle", "info", "x", "--debug"]) == EXIT_IO  # accepted after the command too
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and err.strip().splitlines()[-1].startswith("leonav tle info: error:")
    monkeypatch.setenv("LEONAV_DEBUG", "1")
    assert main(["tle", "info", "x"]) == EXIT_IO
    assert "Traceback" in capsys.readouterr().err
    assert cli._split_debug(["a", "--", "--debug"]) == (["a", "--", "--debug"], False)


def test_console_script_exit_status_in_a_real_process(tmp_path):
    code = "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.run([sys.executable, "-c", code, "tle", "info", str(tmp_path / "none.tle")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == EXIT_BAD_INPUT and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


@pytest.mark.parametrize("args,option", [
    (["sky", "--start", "9999-12-31T23:59:00Z"], "--start"),
    (["sky", "--start", "0001-01-01T00:00:00+01:00"], "--start"),
    (["beacons", "x.cu8", "--simulate", "--start", "0001-01-01T00:00:00+01:00"], "--start"),
    (["beacons", "x.cu8", "--simulate", "--start", "9999-12-31T23:59:00Z"], "--start"),
    (["tle", "info", "{gps}", "--stale-days", "nan"], "--stale-days"),
    (["tle", "info", "{gps}", "--epoch", "0001-01-01T00:00:00+01:00"], "--epoch"),
])
def test_times_and_ages_out_of_range_are_one_line_before_any_work(tmp_path, capsys, args, option):
    gps = str(shared_file("tle/gps-ops_2026-03-09.txt"))
    args = [a.replace("{gps}", gps).replace("x.cu8", str(tmp_path / "x.cu8")) for a in args]
    assert main(args + ["--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    assert option in _one_line(capsys, " ".join(args[:2]) if args[0] == "tle" else args[0])
    assert not (tmp_path / "x.cu8").exists()
