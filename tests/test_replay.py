"""`leonav replay` on synthetic sessions written in `leonav record`'s exact byte formats.

Acceptance: a 12 s synthetic session (NMEA at 10 Hz, WitMotion at 10 Hz, 400 kS/s beacon
capture with 5 tones) replays end to end, and its RMSE per mode is within 20 % of the
same truth and noise run directly through the filter without bytes (differences: int16
IMU quantization, NMEA rounding, arrival-stamp time tagging). Plus encoders vs the
decoders, the IMU time fit, and bad sessions.
"""
from __future__ import annotations

import datetime as dt
import json
import math
import shutil

import numpy as np
import pytest

from hardware.gnss import nmea_write
from hardware.gnss.reader import GnssDecoder
from hardware.imu import witmotion_encode as wenc
from hardware.imu.witmotion import SampleGrouper, WitMotionParser
from hardware.records import GnssFix, NmeaSentence
from hardware.session import decode_session
from leonav_runtime import replay, session_synth as ss
from leonav_runtime.cli import main as leonav_main
from leonav_runtime.errors import UserInputError

SECONDS = 12.0


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    folder = tmp_path_factory.mktemp("session") / "s"
    return ss.write_synthetic_session(folder, ss.SynthSessionConfig(seconds=SECONDS, seed=1))


@pytest.fixture(scope="module")
def comparison(synth, tmp_path_factory):
    out = tmp_path_factory.mktemp("replay")
    return ss.compare_replay_direct(synth, out) | {"out": out}


def test_replay_matches_direct_simulation_within_20_percent(comparison):
    rep = comparison["replay"]
    assert rep["reference"] == "truth.csv" and rep["skipped_modes"] == {}
    assert rep["beacons"]["counts"]["associated"] >= 5
    for mode, row in comparison["table"].items():
        for key, v in row.items():
            assert v["replay"] == pytest.approx(v["direct"], rel=0.20), (mode, key, v)
    m = rep["modes"]
    # sanity against the noise put in: 1.5/1.5/3 m fixes, consumer IMU, 5 Starlink satellites
    assert m["gps+imu"]["rmse_position_m"] < 2.0
    assert m["gps+leo-alpha+imu"]["rmse_position_m"] < 2.0
    assert m["leo-alpha+imu"]["rmse_position_m"] < 15.0
    assert all(mm["records"]["failed"] == 0 for mm in m.values())
    assert m["leo-alpha+imu"]["per_observable"]["doppler_rate"]["applied"] >= 5 * (SECONDS - 4)


def test_replay_outputs_and_time_axis(comparison, synth):
    out = comparison["replay"]
    init = out["initialization"]
    # the replay's t = 0 is the first IMU sample, truth 0.1 s; the time map error is a few ms
    epoch = dt.datetime.fromisoformat(str(init["epoch_utc"]))
    err = (epoch - synth.cfg.epoch_utc).total_seconds() - 1.0 / synth.cfg.imu_rate_hz
    assert abs(err) < 0.01, err
    start = dt.datetime.fromisoformat(str(out["beacons"]["capture_start_utc"]))
    assert abs((start - synth.cfg.epoch_utc).total_seconds() - synth.cfg.sdr_start_s) < 0.01
    assert out["counts"]["fix_sigma_source"] == {"GST": SECONDS * 10}


def test_output_files(comparison):
    folder = comparison["out"]
    for name in ("metrics.json", "rmse_vs_time.csv", "rmse_vs_time.png", "trajectories.png", "trajectory.csv",
                 "replay_vs_direct.json", "beacons/doppler_rate_measurements.csv", "beacons/waterfall.png"):
        assert (folder / name).is_file(), name
    rows = (folder / "rmse_vs_time.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,mode,position_error_m")
    assert len(rows) - 1 == 3 * int(comparison["replay"]["modes"]["gps+imu"]["eval_points"])


def test_session_files_decode_like_a_recording(synth):
    dec = decode_session(synth.folder)
    n = int(SECONDS * 10)
    assert dec.gnss_summary["accepted"] == {"fixes": n, "nmea_GGA": n, "nmea_GST": n, "nmea_RMC": n,
                                            "nmea_sentences": 3 * n}
    assert dec.gnss_summary["rejected"] == {} and dec.imu_summary["rejected"] == {}
    assert dec.imu_summary["accepted"]["samples"] == n
    info = json.loads((synth.folder / "session.json").read_text())
    assert info["time_map"]["offset_s"] == pytest.approx(dec.time_map.offset_s, abs=1e-9)
    assert dec.time_map.residual_std_s < 0.01
    # the live CSVs have one row per record, like the recorder's
    assert len((synth.folder / "imu.csv").read_text().splitlines()) == n + 1
    assert len((synth.folder / "gnss_fix.csv").read_text().splitlines()) == n + 1
    meta = json.loads((synth.folder / "sdr.sigmf-meta").read_text())
    assert meta["global"]["core:datatype"] == "cu8" and meta["global"]["core:sha512"]
    assert not (synth.folder / "sdr.cu8.json").exists()


def test_nmea_writers_round_trip_through_the_decoder():
    utc = dt.datetime(2026, 2, 23, 23, 59, 59, 995000, tzinfo=dt.timezone.utc)  # rounds into the next second
    lat, lon = -33.8688197, 151.2092955
    data = (nmea_write.rmc(utc, lat, lon, 3.0, -4.0) + nmea_write.gga(utc, lat, lon, 58.26, 22.1, 1, 9, 1.23)
            + nmea_write.gst(utc, 1.2, 0.9, 2.5))
    dec = GnssDecoder()
    recs = dec.decode(data, 1.0)
    assert dec.summary()["rejected"] == {}
    fix = next(r for r in recs if isinstance(r, GnssFix))
    assert math.degrees(fix.lat_rad) == pytest.approx(lat, abs=1e-5 / 60 * 0.51)
    assert math.degrees(fix.lon_rad) == pytest.approx(lon, abs=1e-5 / 60 * 0.51)
    assert fix.hmsl_m == pytest.approx(58.3) and fix.height_m == pytest.approx(80.4)
    assert fix.hdop == pytest.approx(1.23) and fix.num_sv == 9
    assert fix.utc.time() == dt.time(0, 0, 0)
    sent = {r.sentence_type: r for r in recs if isinstance(r, NmeaSentence)}
    assert float(sent["RMC"].msg.spd_over_grnd) * 1852 / 3600 == pytest.approx(5.0, abs=1e-3)
    assert float(sent["RMC"].msg.true_course) == pytest.approx(math.degrees(math.atan2(3.0, -4.0)) % 360, abs=0.01)
    assert (float(sent["GST"].msg.std_dev_latitude), float(sent["GST"].msg.std_dev_longitude)) == (1.2, 0.9)


def test_witmotion_encoders_round_trip_with_quantization_and_saturation():
    parser, grouper = WitMotionParser(), SampleGrouper()
    rng = np.random.default_rng(0)
    f = rng.normal(0, 5, (20, 3))
    w = rng.normal(0, 1, (20, 3))
    rpy = rng.uniform(-math.pi, math.pi, (20, 3))
    f[0, 0], w[0, 1] = 200.0, -50.0          # beyond 16 g and 2000 deg/s: saturate
    data = b"".join(wenc.acc_packet(f[k]) + wenc.gyro_packet(w[k]) + wenc.angle_packet(rpy[k]) for k in range(20))
    samples = [s for p in parser.feed(data, 0.0) for s in grouper.push(p)] + grouper.flush()
    assert len(samples) == 20 and not parser.rejected
    got_f = np.array([s.f_b_mps2 for s in samples])
    got_w = np.array([s.w_b_radps for s in samples])
    got_a = np.array([s.euler_rad for s in samples])
    assert got_f[0, 0] == pytest.approx(32767 * wenc.ACC_LSB_MPS2)
    assert got_w[0, 1] == pytest.approx(-32768 * wenc.GYRO_LSB_RADPS)
    np.testing.assert_array_less(np.abs(got_f[1:] - f[1:]), wenc.ACC_LSB_MPS2 / 2 + 1e-12)
    np.testing.assert_array_less(np.abs(got_w[1:] - w[1:]), wenc.GYRO_LSB_RADPS / 2 + 1e-12)
    d = (got_a - rpy + math.pi) % (2 * math.pi) - math.pi
    np.testing.assert_array_less(np.abs(d), wenc.ANGLE_LSB_RAD / 2 + 1e-12)


def test_regular_sample_times_recover_period_and_gaps():
    rng = np.random.default_rng(2)
    k = np.delete(np.arange(100), [40, 41, 70])           # three lost cycles
    stamps = 5.0 + 0.1 * k + 0.02 + rng.uniform(0, 0.012, k.size)
    stamps[10:13] = stamps[12]                             # a host stall: three cycles in one read
    t, idx, missing = replay.regular_sample_times(stamps)
    assert missing == 3 and list(idx) == list(k)
    np.testing.assert_allclose(np.diff(t), 0.1 * np.diff(k), rtol=2e-3)
    assert abs(np.median(t - (5.0 + 0.1 * k)) - 0.026) < 0.004


def _copy(synth, tmp_path, drop=()):
    dst = tmp_path / "s"
    shutil.copytree(synth.folder, dst)
    for name in drop:
        (dst / name).unlink()
    return dst


def test_bad_sessions_give_clear_errors(synth, tmp_path):
    with pytest.raises(UserInputError, match="not a session folder"):
        replay.replay_session(tmp_path / "nope", tmp_path / "out")
    folder = _copy(synth, tmp_path, drop=("imu.raw", "imu.chunks.csv", "truth.csv"))
    with pytest.raises(UserInputError, match="no imu.raw"):
        replay.replay_session(folder, tmp_path / "out")
    (folder / "imu.raw").write_bytes(b"\x00garbage" * 20)
    with pytest.raises(UserInputError, match="no complete WitMotion cycle"):
        replay.replay_session(folder, tmp_path / "out")


def test_empty_capture_and_missing_fixes_skip_modes_with_reasons(synth, tmp_path):
    folder = _copy(synth, tmp_path)
    (folder / "sdr.cu8").write_bytes(b"")
    m = replay.replay_session(folder, tmp_path / "out1")
    assert set(m["modes"]) == {"gps+imu"}
    assert "empty" in m["skipped_modes"]["leo-alpha+imu"]
    assert m["modes"]["gps+imu"]["rmse_position_m"] < 2.0
    # no GNSS at all: no time map (host clock used, noted), no position -> nothing runs
    for name in ("gnss.raw", "gnss.chunks.csv", "sdr.cu8", "sdr.sigmf-meta"):
        (folder / name).unlink()
    rc = leonav_main(["replay", str(folder), "--out", str(tmp_path / "out2")])
    assert rc == 1
    m = json.loads((tmp_path / "out2" / "metrics.json").read_text())
    assert m["modes"] == {}
    assert m["skipped_modes"]["gps+imu"] == "no GNSS fix in gnss.raw"
    assert "no initial position" in m["skipped_modes"]["leo-alpha+imu"]
    assert any("host wall clock" in n for n in m["notes"])


def test_cli_replay_with_origin_and_bad_modes(synth, tmp_path, capsys):
    folder = _copy(synth, tmp_path, drop=("sdr.cu8", "sdr.sigmf-meta"))
    rc = leonav_main(["replay", str(folder), "--modes", "gps+imu", "--origin", str(synth.cfg.lat_deg),
                      str(synth.cfg.lon_deg), str(synth.cfg.alt_m), "--yaw-deg", "90", "--out", str(tmp_path / "o")])
    assert rc == 0
    text = capsys.readouterr().out
    assert "gps+imu" in text and "reference: truth.csv" in text
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["initialization"]["origin"] == "--origin" and m["initialization"]["yaw"] == "--yaw-deg"
    assert m["modes"]["gps+imu"]["rmse_position_m"] < 2.0
    assert leonav_main(["replay", str(folder), "--modes", "gps-only", "--out", str(tmp_path / "o2")]) == 2
