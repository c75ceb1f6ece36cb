"""`leonav sky` end to end: built-in constellations and real element sets, files and errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

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


def text_of(warnings):
    return "\n".join(warnings)


def _small_files(tmp_path):
    """A 300-satellite Starlink file whose entry 2 has a broken checksum, and the GPS file."""
    lines = shared_file("tle/starlink_2026-02-23.txt").read_text().splitlines()[: 3 * 300]
    bad = lines[4]  # line 2 of the second entry (file line 5)
    lines[4] = bad[:-1] + str((int(bad[-1]) + 1) % 10)
    star = tmp_path / "starlink_small.txt"
    star.write_text("\n".join(lines) + "\n")
    return star, shared_file("tle/gps-ops_2026-03-09.txt")


def test_sky_json_counts_masks_and_rejected_entries(tmp_path, capsys):
    star, gps = _small_files(tmp_path)
    out = tmp_path / "a"
    args = ["sky", "--tle", str(star), "--tle", str(gps), "--start", "2026-02-28T00:00:00Z",
            "--duration", "60", "--step", "20"]
    assert main([*args, "--out", str(out)]) == 0
    s = json.loads((out / "sky.json").read_text())
    for key in ("site", "window", "masks_deg", "visible", "dop_gps", "element_age_days", "satellites",
                "left_out", "warnings", "elements"):
        assert key in s, key
    assert s["masks_deg"] == pytest.approx({"starlink": 28.0, "gps": 10.0})
    assert s["satellites"]["starlink"]["loaded"] == 299
    assert s["left_out"]["starlink"]["rejected"][0]["file"] == str(star)
    assert s["left_out"]["starlink"]["rejected"][0]["line"] in (4, 5)
    assert "rejected" in text_of(s["warnings"]) and f"{star}:" in text_of(s["warnings"])
    # The CSV and the JSON tell the same story.
    rows = [r.split(",") for r in (out / "visible_counts.csv").read_text().splitlines()]
    header, data = rows[0], np.array(rows[1:], dtype=float)
    for name in ("starlink", "gps"):
        col = data[:, header.index(f"visible_{name}")]
        v = s["visible"][name]
        assert (v["min"], v["max"], v["current"]) == (col.min(), col.max(), col[0])
        assert v["mean"] == pytest.approx(col.mean())
    assert s["visible"]["gps"]["min"] >= 4 and s["dop_gps"]["pdop"]["max"] < 10
    assert any("gps" in w and "days" in w for w in s["warnings"])  # the GPS file is 9 days newer
    text = capsys.readouterr().out
    assert "start: --start" in text

    # A higher Starlink mask can only lower the counts; 90 deg leaves (almost surely) none.
    out2 = tmp_path / "b"
    assert main([*args, "--mask-starlink", "60", "--mask-gps", "40", "--out", str(out2)]) == 0
    s2 = json.loads((out2 / "sky.json").read_text())
    assert s2["masks_deg"] == pytest.approx({"starlink": 60.0, "gps": 40.0})
    assert s2["visible"]["starlink"]["max"] <= s["visible"]["starlink"]["max"]
    assert s2["visible"]["gps"]["max"] < s["visible"]["gps"]["max"]


def test_sky_bad_start_is_a_clear_error(tmp_path, capsys):
    assert main(["sky", "--start", "yesterday", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--start" in err and "ISO 8601" in err
    assert main(["sky", "--step", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--step" in capsys.readouterr().err


def test_stale_elements_warn_on_stderr_once_and_quiet_silences(tmp_path, capsys):
    """Element sets two weeks from the window: one `leonav sky: warning:` line on stderr, none
    on stdout; `-q` shows errors only."""
    tle = shared_file("tle/gps-ops_2026-03-09.txt")
    argv = ["sky", "--start", "2026-02-23T12:00:00Z", "--duration", "60", "--tle", str(tle)]
    assert main(argv + ["--out", str(tmp_path / "a")]) == 0
    cap = capsys.readouterr()
    warned = [ln for ln in cap.err.splitlines() if ln.startswith("leonav sky: warning: gps: 32 of 32 element sets")]
    assert len(warned) == 1 and "warning" not in cap.out, (cap.out, cap.err)
    assert main(["-q"] + argv + ["--out", str(tmp_path / "b")]) == 0
    assert "warning" not in capsys.readouterr().err
