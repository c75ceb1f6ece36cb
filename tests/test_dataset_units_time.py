"""Dataset options no shipped description exercises, and the scores beyond the RMSE.

Units: deg/s gyros and g accelerometers (one file and a split gyro/accelerometer pair) read back
as the rad/s, m/s^2 drive (standard gravity 9.80665 m/s^2, CGPM 1901); the unix time base said explicitly;
NAV-PVT velocity of frames encoded by pyubx2 (north, east, down). Scores: the percentiles
(linear interpolation between order statistics) and RMSEs of a hand-made error set, and the two
GNSS-alone baselines at and between fix epochs.
"""
from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from leonav_runtime.dataset import scoring
from leonav_runtime.inputs import FixTable
from tests.test_dataset_sources import _csv, _drive, _load, _write

STANDARD_GRAVITY_MPS2 = 9.80665


def _split(tmp_path, d, w, f, extra=""):
    """gyro.csv + acc.csv (own time columns) and a description reading them."""
    _csv(tmp_path / "gyro.csv", "tg,gx,gy,gz", [d["t"], w])
    _csv(tmp_path / "acc.csv", "ta,ax,ay,az", [d["t"], f])
    path = _write(tmp_path, d, imu='accel_file = "acc.csv"\naccel_time_column = "ta"\n' + extra)
    path.write_text(path.read_text().replace('file = "imu.csv"\ntime_column = "t"', 'file = "gyro.csv"\ntime_column = "tg"'))
    return path


def test_deg_s_gyros_and_g_accelerometers_read_as_si(tmp_path):
    d = _drive()
    si = _load(_write(tmp_path, d))
    conv = dict(d, w=np.degrees(d["w"]), f=d["f"] / STANDARD_GRAVITY_MPS2)
    one = _load(_write(tmp_path, conv, imu='gyro_unit = "deg/s"\naccel_unit = "g"'))
    np.testing.assert_allclose(one.imu.w_b_radps, si.imu.w_b_radps, rtol=0, atol=1e-10)   # CSV: 10 decimals
    np.testing.assert_allclose(one.imu.f_b_mps2, si.imu.f_b_mps2, rtol=1e-8, atol=1e-8)
    two = _load(_split(tmp_path, d, conv["w"], conv["f"], 'gyro_unit = "deg/s"\naccel_unit = "g"'))
    np.testing.assert_allclose(two.imu.w_b_radps, si.imu.w_b_radps, rtol=0, atol=1e-10)
    np.testing.assert_allclose(two.imu.f_b_mps2, si.imu.f_b_mps2, rtol=1e-8, atol=1e-8)


def test_unix_time_base_said_explicitly_is_the_default(tmp_path):
    d = _drive()
    default = _load(_write(tmp_path, d))
    said = _load(_write(tmp_path, d, imu='time_base = "unix"', gnss='time_base = "unix"'))
    assert said.t0_unix == default.t0_unix == pytest.approx(d["tf"][0])
    np.testing.assert_array_equal(said.imu.t, default.imu.t)
    np.testing.assert_allclose(said.imu.t, d["t"], rtol=0, atol=1e-6)   # unix s as written: no leap-second shift


def test_nav_pvt_velocity_is_east_north_up_of_pyubx2s_ned_frames(tmp_path):
    """A UBX log of NAV-PVT frames encoded by pyubx2 (velN/velE/velD mm/s, sAcc mm/s): the dataset
    velocity is (velE, velN, -velD) in m/s with sAcc on every axis. (The real u-blox logs' 3-D
    NAV-PVT fixes are at rest: velD 0 to the mm/s, no sign to see.)"""
    pyubx2 = pytest.importorskip("pyubx2", reason="needs pyubx2 (test extra)")
    t0 = dt.datetime(2023, 6, 28, 14, 52, 12, tzinfo=dt.timezone.utc)
    vel = [(1200 + 10 * k, -800 + 5 * k, (-1) ** k * (300 + 20 * k)) for k in range(20)]   # N E D, mm/s
    frames = b""
    for k, (vn, ve, vd) in enumerate(vel):
        t = t0 + dt.timedelta(seconds=k)
        frames += pyubx2.UBXMessage(
            "NAV", "NAV-PVT", pyubx2.GET, iTOW=(310332 + k) * 1000, year=t.year, month=t.month, day=t.day,
            hour=t.hour, min=t.minute, second=t.second, validDate=1, validTime=1, fullyResolved=1, tAcc=20, nano=0,
            fixType=3, gnssFixOk=1, numSV=12, lat=55.6 + 1e-6 * k, lon=37.6, height=206121, hMSL=192758, hAcc=1500,
            vAcc=2500, velN=vn, velE=ve, velD=vd, gSpeed=1400, headMot=0.0, sAcc=150, headAcc=1.0, pDOP=1.5).serialize()
    (tmp_path / "pvt.ubx").write_bytes(frames)
    t = t0.timestamp() - 1.0 + np.arange(0, 25 * 100) / 100.0
    rows = np.column_stack([t, np.full(t.size, 1e-3), np.zeros((t.size, 4)), np.full(t.size, 9.80665)])
    np.savetxt(tmp_path / "imu.csv", rows, delimiter=",", header="t,gx,gy,gz,ax,ay,az", comments="", fmt="%.6f")
    (tmp_path / "d.toml").write_text("""
[imu]
file = "imu.csv"
time_column = "t"
gyro_columns = ["gx", "gy", "gz"]
accel_columns = ["ax", "ay", "az"]
[gnss]
file = "pvt.ubx"
format = "ubx"
""")
    ds = _load(tmp_path / "d.toml")
    assert ds.velocity is not None and ds.velocity.t.size == len(vel)
    ned = np.array(vel, float) * 1e-3
    np.testing.assert_allclose(ds.velocity.v_enu_mps, np.column_stack([ned[:, 1], ned[:, 0], -ned[:, 2]]), atol=1e-12)
    np.testing.assert_allclose(ds.velocity.sigma_mps, 0.15, atol=1e-12)


def test_error_stats_percentiles_and_rmses_of_a_known_error_set():
    h = np.arange(1.0, 101.0)                                   # horizontal errors 1..100 m, along East
    err = np.column_stack([h, np.zeros(h.size), np.full(h.size, 2.0)])
    err[::2, 1], err[::2, 0] = err[::2, 0], 0.0                 # half of them along North
    err = np.vstack([err, [np.nan, 0.0, 0.0]])                  # an epoch without an estimate
    s = scoring.error_stats(err)
    # linear interpolation between order statistics: p at rank 1 + (n - 1) p / 100
    assert s["horizontal_p50_m"] == pytest.approx(50.5)
    assert s["horizontal_p68_m"] == pytest.approx(68.32)
    assert s["horizontal_p95_m"] == pytest.approx(95.05)
    assert s["horizontal_max_m"] == 100.0 and s["epochs"] == 100 and s["epochs_without_estimate"] == 1
    assert s["rmse_horizontal_m"] == pytest.approx(np.sqrt(np.mean(h**2)))
    assert s["rmse_vertical_m"] == pytest.approx(2.0)
    assert s["rmse_3d_m"] == pytest.approx(np.sqrt(np.mean(h**2) + 4.0))


def test_gnss_alone_baselines_at_and_between_fix_epochs():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    p = np.column_stack([10.0 * t, -2.0 * t, np.zeros(4)])
    fixes = FixTable(t, p, np.ones((4, 3)), np.full((4, 2), np.nan))
    at = np.array([-0.5, 0.0, 1.0, 1.5, 3.0, 3.5])
    held = scoring.hold_last_fix(fixes, at)
    assert np.all(np.isnan(held[0]))                            # before the first fix: nothing to hold
    np.testing.assert_array_equal(held[1:, 0], [0.0, 10.0, 10.0, 30.0, 30.0])   # a fix at the epoch is held
    inter = scoring.interpolated_fix(fixes, at)
    assert np.all(np.isnan(inter[[0, 5]]))                      # outside the fixes: no baseline, not a clamp
    np.testing.assert_allclose(inter[1:5, :2], [[0, 0], [10, -2], [15, -3], [30, -6]])
