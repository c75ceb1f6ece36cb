"""WitMotion IMU decoding: datasheet-generated packets, the real WT901SD recording,
corruption/resync, sample grouping and configuration commands."""
from __future__ import annotations

import datetime as dt
import math
import random
import threading

import numpy as np
import pytest
import serial

from leonav.hardware.fakes import PtyDevice, split_bytes
from leonav.hardware.imu import witmotion as wm
from leonav.hardware.records import ImuSample
from tests.conftest import shared_file

G = wm.G_MPS2


def reference_decode(data: bytes) -> dict[int, np.ndarray]:
    """Independent vectorised decode of an aligned, clean stream: type -> int16 words (N,4)."""
    arr = np.frombuffer(data, np.uint8)
    assert arr.size % 11 == 0
    pk = arr.reshape(-1, 11)
    assert np.all(pk[:, 0] == 0x55)
    assert np.all((pk[:, :10].sum(axis=1) & 0xFF) == pk[:, 10])
    words = pk[:, 2:10].copy().view("<i2")
    return {k: words[pk[:, 1] == k] for k in np.unique(pk[:, 1])}


def cycle_bytes(acc_g, gyro_dps, angle_deg, temp_c=25.0, mag=(100, -200, 300), quat=None,
                clock: dt.datetime | None = None) -> bytes:
    """One output cycle built from physical values with the datasheet's formulas."""
    out = b""
    if clock is not None:
        out += wm.build_time_packet(clock)
    out += wm.build_packet(wm.ACC, tuple(round(a / 16 * 32768) for a in acc_g) + (round(temp_c * 100),))
    out += wm.build_packet(wm.GYRO, tuple(round(w / 2000 * 32768) for w in gyro_dps) + (330,))
    out += wm.build_packet(wm.ANGLE, tuple(round(a / 180 * 32768) for a in angle_deg) + (1234,))
    out += wm.build_packet(wm.MAG, tuple(mag) + (round(temp_c * 100),))
    if quat is not None:
        out += wm.build_packet(wm.QUAT, tuple(round(q * 32768) for q in quat))
    return out


def decode_all(data: bytes, chunk: int | None = None) -> tuple[list[ImuSample], wm.WitMotionParser, wm.SampleGrouper]:
    parser, grouper = wm.WitMotionParser(), wm.SampleGrouper()
    samples = []
    chunks = split_bytes(data, chunk) if chunk else [data]
    for k, c in enumerate(chunks):
        for p in parser.feed(c, float(k)):
            samples.extend(grouper.push(p))
    parser.close()
    samples.extend(grouper.flush())
    return samples, parser, grouper


def test_datasheet_packets_decode_to_physical_values():
    clock = dt.datetime(2024, 5, 6, 7, 8, 9, 250000, tzinfo=dt.timezone.utc)
    data = cycle_bytes((0.5, -1.25, 1.0), (90.0, -45.0, 1000.0), (10.0, -20.0, 170.0), temp_c=25.31,
                       quat=(0.5, 0.5, -0.5, 0.5), clock=clock)
    samples, parser, _ = decode_all(data)
    assert len(samples) == 1 and not parser.rejected
    s = samples[0]
    assert s.f_b_mps2 == pytest.approx((0.5 * G, -1.25 * G, 1.0 * G), abs=16 * G / 32768)
    assert s.w_b_radps == pytest.approx(tuple(math.radians(w) for w in (90.0, -45.0, 1000.0)),
                                        abs=math.radians(2000 / 32768))
    assert s.rpy_rad == pytest.approx(tuple(math.radians(a) for a in (10.0, -20.0, 170.0)),
                                        abs=math.radians(180 / 32768))
    assert s.temperature_c == pytest.approx(25.31)
    assert s.mag_raw == (100, -200, 300)
    assert s.q_wxyz == pytest.approx((0.5, 0.5, -0.5, 0.5))
    assert s.device_time == clock.replace(microsecond=250000)


def test_checksum_is_low_byte_of_sum():
    pkt = wm.build_packet(wm.ACC, (0, 0, 2048, 2530))  # az = 1 g, 25.30 C
    assert pkt[:10] == bytes([0x55, 0x51, 0, 0, 0, 0, 0x00, 0x08, 0xE2, 0x09])
    assert pkt[10] == (0x55 + 0x51 + 0x08 + 0xE2 + 0x09) & 0xFF


def test_real_wt901sd_recording():
    data = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()
    ref = reference_decode(data)
    assert {k: len(v) for k, v in ref.items()} == {0x51: 2017, 0x52: 2017, 0x53: 2017, 0x54: 2017}
    samples, parser, grouper = decode_all(data, chunk=97)
    assert len(samples) == 2017 and not parser.rejected and grouper.incomplete == 0
    f = np.array([s.f_b_mps2 for s in samples])
    w = np.array([s.w_b_radps for s in samples])
    e = np.array([s.rpy_rad for s in samples])
    temp = np.array([s.temperature_c for s in samples])
    # scalings against the independent decode
    np.testing.assert_allclose(f, ref[0x51][:, :3] / 32768 * 16 * G)
    np.testing.assert_allclose(np.degrees(w), ref[0x52][:, :3] / 32768 * 2000)
    np.testing.assert_allclose(np.degrees(e), ref[0x53][:, :3] / 32768 * 180)
    np.testing.assert_array_equal(np.array([s.mag_raw for s in samples]), ref[0x54][:, :3])
    # physics of the static, level start (SOURCES.md: az ~ 1.037 g, ~25.3 C)
    static = slice(0, 1000)
    az_g = np.median(f[static, 2]) / G
    assert az_g == pytest.approx(1.037, abs=0.003)
    assert abs(np.median(f[static, 0])) < 0.01 * G and abs(np.median(f[static, 1])) < 0.01 * G
    assert temp[0] == pytest.approx(25.3, abs=0.1)
    assert np.all(np.abs(w[100:1000]) < math.radians(0.5))
    # the sensor's roll/pitch agree with the gravity direction (FLU axes, Z-Y-X angles)
    roll_acc = np.arctan2(f[static, 1], f[static, 2])
    pitch_acc = np.arctan2(-f[static, 0], np.hypot(f[static, 1], f[static, 2]))
    assert np.median(roll_acc) == pytest.approx(np.median(e[static, 0]), abs=math.radians(0.2))
    assert np.median(pitch_acc) == pytest.approx(np.median(e[static, 1]), abs=math.radians(0.2))


def test_garbage_partial_packets_and_bad_checksums_are_skipped_and_counted():
    good = [cycle_bytes((0.0, 0.0, 1.0), (1.0, 2.0, 3.0), (0.0, 0.0, float(k))) for k in range(6)]
    bad_sum = bytearray(good[1])
    bad_sum[10] ^= 0xFF                              # acc checksum broken -> cycle incomplete
    partial = good[2][:30]                           # a cycle cut after 2 packets + 8 bytes
    stream = (b"\x00\x55\x55\x99garbage" + good[0] + bytes(bad_sum) + partial + b"\x55\x51" + good[3]
              + bytes(range(256)) + good[4] + good[5][:-3])
    samples, parser, grouper = decode_all(stream, chunk=7)
    yaws = [round(math.degrees(s.rpy_rad[2])) for s in samples]
    assert yaws == [0, 3, 4, 5]                     # cycle 5 lost only its mag packet
    assert parser.rejected["bad_checksum"] >= 1
    assert parser.rejected["unknown_type"] >= 1
    assert parser.rejected["junk_bytes"] > 256
    assert parser.rejected["truncated_at_end"] == 1
    assert grouper.incomplete == 2                  # cycle 1 (no acc), cycle 2 (cut before angle)


def test_randomized_corruption_never_crashes():
    rng = random.Random(20240601)
    data = bytearray(b"".join(cycle_bytes((0.005 * k, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
                              for k in range(2000)))
    clean_total = 2000
    for _ in range(400):
        data[rng.randrange(len(data))] = rng.randrange(256)
    for _ in range(100):
        pos = rng.randrange(len(data))
        data[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 30)))
        del data[rng.randrange(len(data)):][:rng.randint(1, 15)]
    samples, parser, grouper = decode_all(bytes(data), chunk=61)
    assert 0.6 * clean_total < len(samples) < clean_total
    assert parser.rejected["bad_checksum"] > 50 and parser.rejected["junk_bytes"] > 0
    assert grouper.incomplete > 0
    # accepted samples carry generated values, but for the rare corruption that keeps
    # the 8-bit checksum valid (about 1 in 256 corrupted packets)
    wrong = [s for s in samples if abs(s.f_b_mps2[2] - G) > 1e-3 or not 0 <= s.f_b_mps2[0] / G <= 10.0]
    assert len(wrong) <= 0.01 * len(samples)


def test_grouper_emits_as_soon_as_the_learned_cycle_is_complete():
    grouper = wm.SampleGrouper()
    parser = wm.WitMotionParser()
    cyc = cycle_bytes((0, 0, 1), (0, 0, 0), (0, 0, 0))
    out = []
    for k in range(3):
        emitted_at = []
        for p in parser.feed(cyc, float(k)):
            got = grouper.push(p)
            emitted_at.append(len(got))
            out.extend(got)
        if k == 0:
            assert emitted_at == [0, 0, 0, 0]   # first cycle: the set of types is not known yet
        elif k == 1:
            assert emitted_at == [1, 0, 0, 1]   # cycle 0 when cycle 1 starts, cycle 1 on its mag
        else:
            assert emitted_at == [0, 0, 0, 1]   # from now on: on the cycle's last packet
    assert len(out) == 3 and grouper.flush() == []


def test_imu_reader_over_loop_and_pty():
    data = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()[: 44 * 300]
    port = serial.serial_for_url("loop://", timeout=0.05)
    reader = wm.ImuReader(port)
    threading.Thread(target=lambda: [port.write(c) for c in split_bytes(data, 333)], daemon=True).start()
    threading.Timer(1.0, reader.stop).start()
    samples = list(reader)
    assert len(samples) == 300 and reader.end_reason == "stopped"

    dev = PtyDevice(split_bytes(data, 100), delay_s=0.001, close_after_s=0.2)
    reader = wm.ImuReader(dev.path, 115200)
    dev.start()
    try:
        samples_pty = list(reader)
    finally:
        reader.close()
        dev.close()
    assert reader.end_reason.startswith("device error")
    assert [s.f_b_mps2 for s in samples_pty] == [s.f_b_mps2 for s in samples]


def test_configuration_commands():
    assert wm.unlock_command() == bytes([0xFF, 0xAA, 0x69, 0x88, 0xB5])
    assert wm.rate_command(10) == bytes([0xFF, 0xAA, 0x03, 0x06, 0x00])
    assert wm.rate_command(200) == bytes([0xFF, 0xAA, 0x03, 0x0B, 0x00])
    assert wm.save_command() == bytes([0xFF, 0xAA, 0x00, 0x00, 0x00])
    assert wm.baud_command(115200) == bytes([0xFF, 0xAA, 0x04, 0x06, 0x00])
    # datasheet default RSW: 0x51..0x54 on -> low byte 0b00011110
    assert wm.content_command() == bytes([0xFF, 0xAA, 0x02, 0x1E, 0x00])
    seq = wm.configure_sequence(10)
    assert seq[0] == wm.unlock_command() and seq[-1] == wm.save_command()
    with pytest.raises(ValueError, match="expected one of"):
        wm.rate_command(15)
