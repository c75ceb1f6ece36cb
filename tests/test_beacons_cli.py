"""`leonav beacons` end to end: --simulate writes every output; bad input exits 2 with a reason."""
from __future__ import annotations

import csv
import json

from leonav_runtime.cli import main
from tests.conftest import shared_file


def test_simulate_writes_all_outputs(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    out = tmp_path / "out"
    rc = main(["beacons", str(tmp_path / "sim.cu8"), "--simulate", "--tle", str(tle), "--duration", "5",
               "--sim-rate", "500e3", "--band", "500e3", "--n-sats", "5", "--cn0", "38",
               "--start", "2026-02-23T06:00:00Z", "--out", str(out)])
    assert rc == 0
    for name in ("associations.csv", "doppler_rate_measurements.csv", "doppler_rate_measurements.columns.txt",
                 "waterfall.png", "summary.json", "synthetic_truth.json"):
        assert (out / name).stat().st_size > 0, name
    truth = set(json.loads((out / "synthetic_truth.json").read_text())["norad_ids"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"]["associated"] == 5 and summary["counts"]["ridges"] == 5
    rows = list(csv.DictReader((out / "doppler_rate_measurements.csv").open()))
    assert {int(r["norad_id"]) for r in rows} == truth
    assert all(abs(float(r["rate_residual_hz_s"])) < 5 and float(r["sigma_hz_s"]) > 0 for r in rows)
    assert "associated 5" in capsys.readouterr().out


def test_raw_capture_without_start_is_a_clear_error(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    cap = tmp_path / "x.cu8"
    cap.write_bytes(bytes(4096))
    rc = main(["beacons", str(cap), "--tle", str(tle), "--sample-rate", "1e6", "--center-freq", "1.575e9",
               "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "start time unknown" in capsys.readouterr().err


def test_no_tle_is_a_clear_error(tmp_path, capsys):
    cap = tmp_path / "x.cu8"
    cap.write_bytes(bytes(4096))
    assert main(["beacons", str(cap), "--out", str(tmp_path / "o")]) == 2
    assert "--tle" in capsys.readouterr().err
