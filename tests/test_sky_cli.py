"""`leonav sky` end to end: built-in constellations and real element sets, files and errors."""
from __future__ import annotations

import json

from leonav_runtime.cli import main
from tests.conftest import shared_file


def test_sky_builtin_writes_json_csv_png_consistent_with_the_printout(tmp_path, capsys):
    out = tmp_path / "sky"
    assert main(["sky", "--start", "2026-02-23T12:00:00Z", "--duration", "60", "--step", "30",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    summary = json.loads((out / "sky.json").read_text())
    star = summary["visible"]["starlink"]
    assert star["min"] >= 47  # the paper: at least 47 Starlink satellites above 28 deg
    assert summary["visible"]["gps"]["min"] >= 4
    assert f"{star['min']:>6}" in text.split("starlink", 1)[1].splitlines()[0]
    rows = (out / "visible_counts.csv").read_text().splitlines()
    assert rows[0] == "t_s,visible_gps,visible_starlink" and len(rows) == 1 + 3
    assert (out / "sky.png").stat().st_size > 10_000


def test_sky_with_real_starlink_elements_starts_at_their_newest_epoch(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    out = tmp_path / "sky"
    assert main(["sky", "--tle", str(tle), "--duration", "20", "--step", "10", "--out", str(out)]) == 0
    summary = json.loads((out / "sky.json").read_text())
    assert summary["window"]["start_source"].startswith("newest element-set epoch")
    assert summary["window"]["start_utc"].startswith("2026-02-23T06:03:40")
    assert summary["visible"]["starlink"]["min"] >= 20
    assert "starlink" in capsys.readouterr().out


def test_sky_bad_arguments_are_clear_errors(tmp_path, capsys):
    assert main(["sky", "--lat", "123", "--out", str(tmp_path / "o")]) == 2
    assert "--lat" in capsys.readouterr().err
    assert main(["sky", "--tle", str(tmp_path / "missing.txt"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err
