"""`leonav record` end to end with pty devices and a fake RTL-SDR; time map; SDR capture.

Devices are pseudo-terminals fed with real recorded bytes; a device "disappears" when
its pty master is closed; Ctrl-C is a real SIGINT sent to a `leonav record` process.
"""
from __future__ import annotations

import csv
import datetime as dt
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from leonav.hardware.clock import TimeMap
from leonav.hardware.fakes import FakeRtlSdr, PtyDevice, split_bytes
from leonav.hardware.records import GnssTimeTag
from leonav.hardware.sdr import capture as sdr_capture
from leonav.hardware.session import RecordSession, decode_session
from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from tests.conftest import shared_file

REPO = Path(__file__).resolve().parents[1]


def rtk_epochs(n: int) -> list[bytes]:
    """The first n 10 Hz epochs (GGA + RMC) of the Trimble RTK log, one bytes per epoch."""
    lines = [l for l in shared_file("nmea/gpsd/nmea-rtk.log").read_bytes().split(b"\n") if l.startswith(b"$")]
    return [lines[2 * k] + b"\n" + lines[2 * k + 1] + b"\n" for k in range(n)]


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_time_map_fit_recovers_offset_jitter_and_rejects_outliers():
    rng = np.random.default_rng(3)
    t0 = dt.datetime(2024, 1, 1, tzinfo=dt.timezone.utc)
    tags = []
    for k in range(200):
        t_mono = 1000.0 + 0.1 * k
        latency = 0.045 + rng.normal(0, 0.004)       # output latency and its jitter
        utc = t0 + dt.timedelta(seconds=0.1 * k)
        tags.append(GnssTimeTag(t_mono + latency, utc, "RMC"))
    tags.append(GnssTimeTag(1010.0, t0 + dt.timedelta(seconds=50), "RMC"))   # stale/misparsed
    m = TimeMap.fit(tags)
    expected = t0.timestamp() - 1000.0 - 0.045
    assert m.source == "RMC" and m.n_outliers == 1 and m.n_tags == 200
    assert m.offset_s == pytest.approx(expected, abs=0.002)
    assert m.residual_std_s == pytest.approx(0.004, rel=0.25)
    # a 50 ppm host clock drift is recovered by the line fit
    drifted = [GnssTimeTag(1000 + 10.0 * k * (1 + 50e-6) + 0.045 + rng.normal(0, 0.004),
                           t0 + dt.timedelta(seconds=10.0 * k), "NAV-PVT") for k in range(200)]
    m2 = TimeMap.fit(drifted + tags, drift=True)
    assert m2.source == "NAV-PVT" and m2.drift == pytest.approx(-50e-6, abs=2e-6)
    assert m2.residual_std_s == pytest.approx(0.004, rel=0.25)
    assert set(m2.per_source) == {"NAV-PVT", "RMC"}


def test_time_map_of_two_equal_groups_of_tags_is_a_clear_error():
    """A receiver restarted mid-session: half the tags 30 s off; no majority, one clear line."""
    t0 = dt.datetime(2024, 1, 1, tzinfo=dt.timezone.utc)
    tags = [GnssTimeTag(1000.0 + k, t0 + dt.timedelta(seconds=k + (30 if k >= 5 else 0)), "RMC")
            for k in range(10)]
    with pytest.raises(UserInputError, match="RMC time tags disagree: 10 tags"):
        TimeMap.fit(tags)


def test_sdr_capture_writes_cu8_and_valid_sigmf(tmp_path):
    from sigmf import SigMFFile

    fake = FakeRtlSdr(tone_hz=100e3)
    settings = sdr_capture.SdrSettings(sample_rate_hz=2.4e6, gain_db=30.0, ppm=-2)
    res = sdr_capture.capture(fake, tmp_path / "sdr", settings, seconds=0.25)
    assert res.end_reason == "done" and res.n_samples == 600000
    assert fake.center_freq == pytest.approx(1.575e9) and fake.freq_correction == -2 and fake.gain == 30.0
    raw = np.fromfile(tmp_path / "sdr.cu8", np.uint8)
    assert raw.size == 2 * 600000
    meta = json.loads((tmp_path / "sdr.sigmf-meta").read_text())
    g = meta["global"]
    assert g["core:datatype"] == "cu8" and g["core:sample_rate"] == 2.4e6
    assert g["leonav:lnb_lo_hz"] == 9.75e9 and g["leonav:rf_center_hz"] == pytest.approx(11.325e9)
    assert meta["captures"][0]["core:frequency"] == pytest.approx(1.575e9)
    dt.datetime.strptime(meta["captures"][0]["core:datetime"], "%Y-%m-%dT%H:%M:%S.%fZ")
    # SigMF reads it back (checksum verified) and the tone sits at +100 kHz
    handle = SigMFFile(metadata=meta, data_file=str(tmp_path / "sdr.cu8"))
    iq = handle.read_samples(0, 65536)
    spec = np.abs(np.fft.fftshift(np.fft.fft(iq)))
    freqs = np.fft.fftshift(np.fft.fftfreq(iq.size, 1 / 2.4e6))
    assert freqs[np.argmax(spec)] == pytest.approx(100e3, abs=2 * 2.4e6 / iq.size)


def test_sdr_unplugged_keeps_what_was_captured(tmp_path):
    fake = FakeRtlSdr(fail_after_bytes=3 * sdr_capture.READ_BLOCK_BYTES)
    res = sdr_capture.capture(fake, tmp_path / "sdr", sdr_capture.SdrSettings(), seconds=2.0)
    assert res.end_reason.startswith("device error") and res.n_bytes == 3 * sdr_capture.READ_BLOCK_BYTES
    meta = json.loads((tmp_path / "sdr.sigmf-meta").read_text())
    assert meta["global"]["leonav:end_reason"].startswith("device error")
    assert (tmp_path / "sdr.cu8").stat().st_size == res.n_bytes


def test_missing_librtlsdr_gives_a_clear_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "rtlsdr", None)     # import fails as without librtlsdr
    with pytest.raises(sdr_capture.SdrUnavailable, match="librtlsdr not found: install"):
        sdr_capture.open_rtlsdr(0)
    with pytest.raises(UserInputError, match="outside the RTL-SDR tuning range"):
        sdr_capture.configure(FakeRtlSdr(), sdr_capture.SdrSettings(rf_center_hz=12.75e9))


def test_cli_record_errors_are_one_line(tmp_path, capsys, monkeypatch):
    assert leonav_main(["record", "--seconds", "1", str(tmp_path / "s")]) == 2
    assert "give at least one device" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "rtlsdr", None)
    assert leonav_main(["record", "--sdr", "0", "--seconds", "1", str(tmp_path / "s2")]) == 2
    assert "librtlsdr not found: install" in capsys.readouterr().err
    assert leonav_main(["record", "--gnss", "/dev/does-not-exist", "--seconds", "1", str(tmp_path / "s3")]) == 2
    assert "cannot open" in capsys.readouterr().err


def test_record_end_to_end_with_a_device_that_disappears(tmp_path):
    epochs = rtk_epochs(20)
    imu_bytes = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()[: 44 * 40]
    gnss = PtyDevice(epochs, delay_s=0.1)                                      # paced at 10 Hz
    imu = PtyDevice(split_bytes(imu_bytes, 44), delay_s=0.02, close_after_s=0.1)  # unplugged after 0.9 s
    session = RecordSession(tmp_path, gnss=gnss.path, imu=imu.path, sdr_index=0,
                            sdr_factory=lambda index: FakeRtlSdr(realtime=True),
                            sdr_settings=sdr_capture.SdrSettings(sample_rate_hz=1.0e6), progress=False)
    gnss.start()
    imu.start()
    try:
        info = session.run(2.6)
    finally:
        gnss.close()
        imu.close()
    assert info["status"] == "complete"
    dev = {d["kind"]: d for d in info["devices"]}
    assert dev["imu"]["end_reason"].startswith("device error") and dev["imu"]["error"] == ""
    assert dev["imu"]["accepted"]["samples"] == 40 and dev["imu"]["bytes_read"] == len(imu_bytes)
    assert dev["gnss"]["accepted"]["nmea_sentences"] == 40 and dev["gnss"]["accepted"]["fixes"] == 20
    assert dev["gnss"]["rejected"] == {} and dev["gnss"]["end_reason"] == "stopped"
    assert dev["sdr"]["n_samples"] > 1e6 and dev["sdr"]["end_reason"] in ("done", "stopped")

    # files: raw logs byte-exact, CSVs complete
    assert (tmp_path / "gnss.raw").read_bytes() == b"".join(epochs)
    assert (tmp_path / "imu.raw").read_bytes() == imu_bytes
    fixes = read_csv(tmp_path / "gnss_fix.csv")
    imu_rows = read_csv(tmp_path / "imu.csv")
    assert len(fixes) == 20 and len(imu_rows) == 40
    assert float(fixes[-1]["lat_deg"]) == pytest.approx(41.5749659, abs=1e-5)
    assert (tmp_path / "sdr.cu8").stat().st_size == 2 * dev["sdr"]["n_samples"]
    assert json.loads((tmp_path / "sdr.sigmf-meta").read_text())["global"]["core:sha512"]

    # time map from RMC at 10 Hz: a few ms of spread (sentence-end stamps); the bounds
    # leave room for the feeder thread's scheduling on a loaded 2-core machine
    tm = info["time_map"]
    assert tm["source"] == "RMC" and tm["n_tags"] + tm["n_outliers"] == 20 and tm["n_tags"] >= 15
    assert tm["residual_std_s"] < 0.03
    # UTC of the fixes through the map agrees with the receiver's own fix time
    for row in fixes[5:]:
        assert float(row["t_utc_mapped_s"]) == pytest.approx(float(row["fix_utc_s"]), abs=0.1)

    # decode_session reproduces the live decoding from the raw logs and chunk stamps
    dec = decode_session(tmp_path)
    assert dec.gnss_summary["accepted"] == dev["gnss"]["accepted"]
    assert [s.f_b_mps2 for s in dec.imu_samples] == [
        tuple(float(r[c]) for c in ("f_x_mps2", "f_y_mps2", "f_z_mps2")) for r in imu_rows]
    assert [s.t_mono_s for s in dec.imu_samples] == [float(r["t_mono_s"]) for r in imu_rows]
    assert dec.time_map.offset_s == pytest.approx(tm["offset_s"], abs=1e-9)
    out = dec.write_csvs(tmp_path / "redecoded")
    again = read_csv(out / "imu.csv")
    assert len(again) == 40 and all(r["t_utc_mapped_s"] for r in again)


def test_ctrl_c_leaves_a_readable_session(tmp_path):
    """A real SIGINT to `leonav record` mid-run: raw logs, CSVs and session.json survive."""
    epochs = rtk_epochs(60)
    imu_bytes = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()
    gnss = PtyDevice(epochs, delay_s=0.05)
    imu = PtyDevice(split_bytes(imu_bytes, 44), delay_s=0.01)
    out = tmp_path / "session"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "leonav_runtime.cli", "record", "--gnss", gnss.path,
                             "--imu", imu.path, "--seconds", "60", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=REPO)
    try:
        deadline = time.monotonic() + 30
        while not (out / "session.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        partial = json.loads((out / "session.json").read_text())
        assert partial["status"] == "recording"
        time.sleep(0.3)          # the ports are open: start the devices
        gnss.start()
        imu.start()
        time.sleep(1.5)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        gnss.close()
        imu.close()
    assert proc.returncode == 130, stderr.decode()
    assert "interrupted" in stdout.decode()
    info = json.loads((out / "session.json").read_text())
    assert info["status"] == "interrupted"
    dev = {d["kind"]: d for d in info["devices"]}
    n_samples = dev["imu"]["accepted"]["samples"]
    assert 10 < n_samples < 2017
    assert len(read_csv(out / "imu.csv")) == n_samples
    assert len(read_csv(out / "gnss_fix.csv")) == dev["gnss"]["accepted"]["fixes"] > 5
    dec = decode_session(out)
    assert len(dec.imu_samples) == n_samples
    assert dec.gnss_summary["accepted"] == dev["gnss"]["accepted"]
    assert (out / "imu.raw").read_bytes() == imu_bytes[: dev["imu"]["bytes_read"]]


def test_uart_delay_profile_gives_the_readme_figures():
    """hardware/README.md "Time alignment": the NEO-M9N log's default NMEA set (1,336 bytes per
    epoch as logged, RMC first, 10 bits per byte): the end of RMC is 72 / 18 / 6 ms after the
    start of the burst at 9600 / 38400 / 115200 baud, GGA 189 / 47 / 16 ms, ZDA 1.35 / 0.34 / 0.11 s."""
    from leonav.hardware.clock import uart_delay_profile
    from leonav.hardware.uart import serialization_s

    lines = [ln for ln in shared_file("nmea/gpsd/ublox-neo-m9n-nmea.log").read_bytes().split(b"\n")
             if ln.startswith(b"$")]
    epochs: list[list[bytes]] = []
    for ln in lines:
        if ln[3:6] == b"RMC" or not epochs:
            epochs.append([])
        epochs[-1].append(ln + b"\n")
    assert np.median([sum(len(ln) for ln in e) for e in epochs]) == 1336
    expected = {b"RMC": (0.072, 0.018, 0.006), b"GGA": (0.189, 0.047, 0.016), b"ZDA": (1.35, 0.34, 0.11)}
    for kind, delays in expected.items():
        ends = [np.cumsum([len(ln) for ln in e])[[ln[3:6] for ln in e].index(kind)] for e in epochs]
        for baud, want in zip((9600, 38400, 115200), delays):
            got = uart_delay_profile(ends, baud)
            assert got["median_s"] == pytest.approx(want, rel=0.03), (kind, baud)
            assert got["max_s"] == pytest.approx(float(serialization_s(max(ends), baud)))


def test_device_layer_and_runtime_share_one_error_class_and_one_json_writer():
    """hardware/ defines UserInputError and write_json; the runtime's names are the same objects,
    so the CLI's `except UserInputError` catches device errors as one line."""
    from leonav.hardware import errors as hw_errors
    from leonav.hardware import jsonfile as hw_jsonfile
    from leonav_runtime.common import errors, output

    assert errors.UserInputError is hw_errors.UserInputError
    assert output.write_json is hw_jsonfile.write_json
    assert sdr_capture.SdrUnavailable.__mro__[1] is UserInputError
