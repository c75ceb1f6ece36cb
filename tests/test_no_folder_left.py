"""A command that fails leaves no results folder behind (and a partial one says FAILED)."""
from __future__ import annotations

import pytest

from leonav_runtime.cli import main
from leonav_runtime.common import output

FAILING = {
    "sweep counts beyond the sky": ["sweep", "--counts", "5,100"],
    "beacons on a missing file": ["beacons", "missing.cu8", "--tle", "missing.tle"],
    "replay of no session": ["replay", "nosuchdir"],
    "nav on a missing device": ["nav", "--gnss", "/dev/nonexistent", "--seconds", "1", "--nmea-port", "0"],
    "study with a bad --set": ["study", "where-is-6-9m", "--set", "site.lat_deg=north"],
    "record on a missing device": ["record", "leonav-out/rec", "--seconds", "1", "--gnss", "/dev/nonexistent"],
}


@pytest.mark.parametrize("argv", FAILING.values(), ids=FAILING.keys())
def test_a_failing_command_leaves_no_results_folder(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) != 0
    capsys.readouterr()
    assert not (tmp_path / output.DEFAULT_ROOT).exists(), list((tmp_path / output.DEFAULT_ROOT).rglob("*"))


def test_a_partial_result_is_kept_with_a_failed_note(tmp_path):
    folder = output.results_dir(tmp_path / "a" / "b", "x")
    (folder / "metrics.json").write_text("{}")
    empty = output.results_dir(tmp_path / "c", "y")
    removed = output.finish_results(failed=True, why="ValueError: boom")
    assert removed == [empty] and not empty.exists()
    note = (tmp_path / "a" / "FAILED.txt").read_text()
    assert "partial" in note and "boom" in note and (folder / "metrics.json").exists()
    kept = output.results_dir(tmp_path / "d", "z")
    assert output.finish_results(failed=False) == [] and kept.exists()
