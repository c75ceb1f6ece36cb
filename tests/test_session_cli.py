"""`leonav session synth` and `leonav replay` through the CLI entry point (`cli.main`), as a user runs them.

The command modules import their work lazily, so only running them catches a broken import.
"""
from __future__ import annotations

import json
import math
import re

import pytest

from leonav_runtime.cli import main as leonav_main
from leonav_runtime.replay import MODES
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ

SESSION_FILES = ("gnss.raw", "gnss.chunks.csv", "gnss_fix.csv", "imu.raw", "imu.chunks.csv", "imu.csv", "sdr.cu8",
                 "sdr.sigmf-meta", "session.json", "truth.csv", "synthetic.json")
REPLAY_FILES = ("metrics.json", "rmse_vs_time.csv", "rmse_vs_time.png", "trajectory.csv", "trajectories.png",
                "columns.txt", "beacons/doppler_rate_measurements.csv")


def _mode_rows(text: str) -> dict[str, str]:
    """Replay summary rows by mode: the rest of the line after the mode name."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"^\s+(\S+)\s+(.*)$", line)
        if m and m.group(1) in MODES:
            rows[m.group(1)] = m.group(2)
    return rows


def test_session_synth_then_replay(tmp_path, capsys):
    session, out = tmp_path / "session", tmp_path / "replay"
    # 5 s is the shortest session whose ridges give Doppler-rate fits for every satellite
    assert leonav_main(["session", "synth", str(session), "--seconds", "5", "--sdr-rate", "200e3", "--seed", "3"]) == 0
    text = capsys.readouterr().out
    assert re.search(r"synthetic session .*: 50 GNSS epochs, 50 IMU samples, 5 Starlink tones", text), text
    for name in SESSION_FILES:
        assert (session / name).is_file(), name

    assert leonav_main(["replay", str(session), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "reference: truth.csv" in text and "carrier f_c: 11.325000 GHz, capture metadata" in text
    rows = _mode_rows(text)
    assert set(rows) == set(MODES), text
    for mode, rest in rows.items():       # every mode ran: RMSEs, applied/gated/failed counts
        cells = rest.split()
        assert len(cells) == 6 and "skipped" not in rest, (mode, rest)
        assert float(cells[0]) < (15.0 if mode == "leo-alpha+imu" else 3.0), (mode, rest)
        assert int(cells[3]) > 0 and int(cells[5]) == 0, (mode, rest)
    for name in REPLAY_FILES:
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["modes"]) == set(MODES) and m["skipped_modes"] == {}
    assert all(math.isfinite(mm["rmse_position_m"]) for mm in m["modes"].values())
    assert m["f_c_hz"] == STARLINK_BEACON_HZ and "capture metadata" in m["f_c_source"]


def test_session_synth_without_sdr_and_compare(tmp_path, capsys):
    session, out = tmp_path / "session", tmp_path / "compare"
    rc = leonav_main(["session", "synth", str(session), "--seconds", "3", "--no-sdr", "--compare", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert not (session / "sdr.cu8").exists() and (session / "truth.csv").is_file()
    assert "replay vs direct simulation" in text
    row = _mode_rows(text)
    assert set(row) == {"fix+imu"}        # no capture: the Starlink modes are skipped
    replayed, direct = (float(v) for v in row["fix+imu"].split()[0:3:2])
    assert 0 < replayed < 3.0 and 0 < direct < 3.0
    saved = json.loads((out / "replay_vs_direct.json").read_text())
    assert saved["rmse"]["fix+imu"]["rmse_position_m"]["replay"] == pytest.approx(replayed, abs=5e-4)
    m = json.loads((out / "metrics.json").read_text())
    assert "no capture" in m["f_c_source"] and not any("carrier" in n for n in m["notes"])


def test_session_cli_errors(tmp_path, capsys):
    assert leonav_main(["session"]) == 2
    assert "synth" in capsys.readouterr().out
    assert leonav_main(["session", "synth", str(tmp_path / "s"), "--seconds", "1"]) == 2
    assert "--seconds" in capsys.readouterr().err
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep me")
    assert leonav_main(["session", "synth", str(tmp_path / "full"), "--seconds", "2", "--no-sdr"]) == 2
    assert "not empty" in capsys.readouterr().err and (tmp_path / "full" / "x").read_text() == "keep me"
