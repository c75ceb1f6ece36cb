"""Datasets as they come (issue 23): time bases, split gyro/accelerometer files, numpy arrays,
reference attitude frames, GNSS velocity, and the physics checks that refuse a wrong unit.

Fixtures are small synthetic drives written to tmp_path: a car at 5 m/s turning left and
right (yaw rate known), IMU at 100 Hz in body FLU, fixes at 10 Hz. Independent facts used:
GPS - UTC = 18 s since 2017-01-01; the GPS epoch is unix 315964800; scipy's Rotation builds
the quaternions the importer must read back; gpsd's own decoding (.chk) of the real logs.
"""
from __future__ import annotations

import json
import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.dataset import load, spec
from tests.conftest import shared_file

T0_UNIX = 1_700_000_000.0          # 2023-11-14 22:13:20 UTC
LEAP_S = 18.0                      # GPS - UTC since 2017-01-01
GPS_EPOCH_UNIX = 315964800.0
LAT0, LON0, R_E = 45.5, -73.4, 6378137.0


def _drive(seconds: float = 60.0, imu_hz: float = 100.0, gnss_hz: float = 10.0, speed: float = 5.0,
           t0: float = T0_UNIX) -> dict:
    """A car at `speed` m/s with a known yaw-rate profile: IMU (t, w, f FLU) and fixes (t, lat, lon, h)."""
    t = np.arange(0.0, seconds, 1.0 / imu_hz)
    rate = np.where((t % 20) < 5, 0.3, np.where((t % 20 >= 10) & (t % 20 < 15), -0.25, 0.0))
    yaw = 0.5 + np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) / imu_hz)])
    x = np.concatenate([[0.0], np.cumsum(speed * np.cos(yaw[:-1]) / imu_hz)])
    y = np.concatenate([[0.0], np.cumsum(speed * np.sin(yaw[:-1]) / imu_hz)])
    rng = np.random.default_rng(1)
    w = np.column_stack([1e-4 * rng.standard_normal(t.size), 1e-4 * rng.standard_normal(t.size), rate + 2e-4])
    f = np.column_stack([0.01 * rng.standard_normal(t.size), speed * rate, np.full(t.size, 9.80665)])
    k = np.arange(0, t.size, int(imu_hz / gnss_hz))
    lat = LAT0 + np.degrees(y[k] / R_E)
    lon = LON0 + np.degrees(x[k] / (R_E * np.cos(np.radians(LAT0))))
    return {"t": t0 + t, "w": w, "f": f, "tf": t0 + t[k], "lat": lat, "lon": lon, "h": np.full(k.size, 30.0),
            "yaw": yaw[k], "x": x[k], "y": y[k]}


def _csv(path: Path, header: str, cols: list[np.ndarray]) -> None:
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="", fmt="%.10f")


def _write(tmp: Path, d: dict, imu: str = "", gnss: str = "", ref: str = "", imu_t=None, fix_t=None) -> Path:
    """imu.csv, fixes.csv and d.toml (extra TOML lines per section); imu_t / fix_t replace the times."""
    _csv(tmp / "imu.csv", "t,gx,gy,gz,ax,ay,az", [d["t"] if imu_t is None else imu_t, d["w"], d["f"]])
    _csv(tmp / "fixes.csv", "t,lat,lon,h", [d["tf"] if fix_t is None else fix_t, d["lat"], d["lon"], d["h"]])
    (tmp / "d.toml").write_text(f"""
name = "synthetic"
[imu]
file = "imu.csv"
time_column = "t"
gyro_columns = ["gx", "gy", "gz"]
accel_columns = ["ax", "ay", "az"]
frame = "FLU"
{imu}
[gnss]
file = "fixes.csv"
{gnss}
{"[reference]" if ref else ""}
{ref}
""")
    return tmp / "d.toml"


def _load(path: Path) -> load.Dataset:
    return load.load(spec.load_spec(path))


def _one_line(err) -> str:
    msg = str(err.value)
    assert "\n" not in msg
    return msg


# ---- time bases --------------------------------------------------------------------------

def _tow(unix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    gps = unix - GPS_EPOCH_UNIX + LEAP_S
    return np.floor(gps / 604800), gps % 604800


def test_gps_week_tow_and_gps_seconds_give_the_unix_times(tmp_path):
    d = _drive()
    ref = _load(_write(tmp_path, d))
    week, tow = _tow(d["t"])
    wf, towf = _tow(d["tf"])
    _csv(tmp_path / "imu_tow.csv", "tow,gx,gy,gz,ax,ay,az", [tow, d["w"], d["f"]])
    _csv(tmp_path / "fix_tow.csv", "tow,week,lat,lon,h", [towf, wf, d["lat"], d["lon"], d["h"]])
    path = _write(tmp_path, d, imu=f'time_base = "gps_week_tow"\ngps_week = {int(week[0])}',
                  gnss='time_base = "gps_week_tow"\nweek_column = 1\nlat_column = 2\nlon_column = 3\nheight_column = 4')
    text = path.read_text().replace('file = "imu.csv"\ntime_column = "t"', 'file = "imu_tow.csv"\ntime_column = "tow"')
    path.write_text(text.replace('file = "fixes.csv"', 'file = "fix_tow.csv"'))
    ds = _load(path)
    assert ds.t0_unix == pytest.approx(ref.t0_unix, abs=1e-6)
    np.testing.assert_allclose(ds.imu.t, ref.imu.t, atol=1e-6)
    np.testing.assert_allclose(ds.fixes.t, ref.fixes.t, atol=1e-6)
    # seconds since the GPS epoch, in ms
    _csv(tmp_path / "imu_gps.csv", "t,gx,gy,gz,ax,ay,az", [(d["t"] - GPS_EPOCH_UNIX + LEAP_S) * 1e3, d["w"], d["f"]])
    path = _write(tmp_path, d, imu='time_base = "gps_seconds"\ntime_unit = "ms"')
    path.write_text(path.read_text().replace('file = "imu.csv"', 'file = "imu_gps.csv"'))
    np.testing.assert_allclose(_load(path).imu.t, ref.imu.t, atol=1e-5)


def test_gps_week_key_follows_the_week_rollover(tmp_path):
    """A record across Sunday midnight (GPS) with only gps_week: the time of week falls back to 0."""
    gps_week_start = (np.floor((T0_UNIX - GPS_EPOCH_UNIX + LEAP_S) / 604800) + 1) * 604800
    t0 = gps_week_start + GPS_EPOCH_UNIX - LEAP_S - 20.0          # 20 s before the rollover
    d = _drive(seconds=40.0, t0=t0)
    week, tow = _tow(d["t"])
    assert tow.max() > 604770 and tow.min() < 30 and week[0] != week[-1]
    path = _write(tmp_path, d, imu=f'time_base = "gps_week_tow"\ngps_week = {int(week[0])}', imu_t=tow)
    ds = _load(path)
    np.testing.assert_allclose(ds.imu.t, d["t"], atol=1e-6)
    assert ds.counts["imu"]["time_jumps"] == 0
    bad = _write(tmp_path, d, imu='time_base = "gps_week_tow"\ngps_week = 2000')    # unix times declared TOW
    with pytest.raises(UserInputError) as err:
        _load(bad)
    assert "[imu] time_base = 'gps_week_tow': the time column's median" in _one_line(err)
    with pytest.raises(UserInputError, match=r"\[imu\] time_base = 'gps_week_tow': expected week_column"):
        spec.load_spec(_write(tmp_path, d, imu='time_base = "gps_week_tow"'))


def test_boot_clock_by_a_clock_pair_or_an_offset(tmp_path):
    d = _drive()
    ref = _load(_write(tmp_path, d))
    boot = d["t"] - T0_UNIX + 1234.5                 # the board booted 1234.5 s before the drive
    pair = _write(tmp_path, d, imu=f'time_base = "boot"\nclock_pair = [1300.0, {T0_UNIX + 65.5}]', imu_t=boot)
    ds = _load(pair)
    np.testing.assert_allclose(ds.imu_on_axis(0.0).t, ref.imu_on_axis(0.0).t, atol=1e-6)
    off = _write(tmp_path, d, imu=f'time_base = "boot"\ntime_offset_s = {T0_UNIX - 1234.5}', imu_t=boot)
    ds = _load(off)
    np.testing.assert_allclose(ds.imu_on_axis(T0_UNIX - 1234.5).t, ref.imu_on_axis(0.0).t, atol=1e-6)
    # a pair read a day apart puts the IMU nowhere near the fixes: one line naming the key and both spans
    wrong = _write(tmp_path, d, imu=f'time_base = "boot"\nclock_pair = [1300.0, {T0_UNIX + 86400}]', imu_t=boot)
    with pytest.raises(UserInputError) as err:
        _load(wrong)
    msg = _one_line(err)
    assert "[imu] clock_pair = [1300.0, " in msg and "the IMU spans unix 1700086334.500" in msg
    assert "the fixes 1700000000.000..1700000059.900 s" in msg
    for extra, needle in (('time_base = "boot"', "expected clock_pair"),
                          ('time_base = "boot"\ntime_offset_s = "calibrate"', "expected clock_pair"),
                          ("time_offset_s = 5000.0", "expected seconds within +-3600"),
                          ("clock_pair = [1.0, 2.0]", "given with time_base = 'unix'")):
        with pytest.raises(UserInputError) as err:
            spec.load_spec(_write(tmp_path, d, imu=extra))
        assert needle in _one_line(err)


# ---- separate gyro and accelerometer files -----------------------------------------------------

def test_two_imu_files_give_the_samples_of_one(tmp_path):
    d = _drive()
    one = _load(_write(tmp_path, d))
    _csv(tmp_path / "gyro.csv", "tg,gx,gy,gz", [d["t"], d["w"]])
    _csv(tmp_path / "acc.csv", "ta,ax,ay,az", [d["t"], d["f"]])
    path = _write(tmp_path, d, imu='accel_file = "acc.csv"\naccel_time_column = "ta"')
    path.write_text(path.read_text().replace('file = "imu.csv"\ntime_column = "t"', 'file = "gyro.csv"\ntime_column = "tg"'))
    two = _load(path)
    np.testing.assert_array_equal(two.imu.t, one.imu.t)
    np.testing.assert_allclose(two.imu.w_b_radps, one.imu.w_b_radps, atol=1e-12)
    np.testing.assert_allclose(two.imu.f_b_mps2, one.imu.f_b_mps2, atol=1e-12)
    assert two.counts["imu"]["rows_outside_common_span"] == 0
    # the accelerometer starts 1 s later, on its own clock ticks (half a sample off): 101 gyro rows
    # outside the common span; the specific force is the accelerometer's, linearly interpolated
    _csv(tmp_path / "acc.csv", "ta,ax,ay,az", [d["t"][100:] + 0.005, d["f"][100:]])
    late = _load(path)
    assert late.counts["imu"]["rows_outside_common_span"] == 101 + 1      # + the accelerometer's last row
    assert late.imu.t[0] == pytest.approx(d["t"][101]) and late.imu.t.size == d["t"].size - 101
    expect = np.column_stack([np.interp(late.imu.t, d["t"][100:] + 0.005, d["f"][100:, j]) for j in range(3)])
    np.testing.assert_allclose(late.imu.f_b_mps2, expect * [1, 1, 1], atol=1e-9)
    np.testing.assert_allclose(late.imu.w_b_radps, one.imu.w_b_radps[101:], atol=1e-12)
    # spans that hardly meet: one line naming both files
    _csv(tmp_path / "acc.csv", "ta,ax,ay,az", [d["t"][:3000] + 50.0, d["f"][:3000]])     # 10 s of its 30 s
    with pytest.raises(UserInputError) as err:
        _load(path)
    msg = _one_line(err)
    assert "gyro.csv ([imu] file) spans" in msg and "acc.csv ([imu] accel_file)" in msg and "less than half" in msg


# ---- numpy arrays --------------------------------------------------------------------------------

def test_npy_and_npz_sources_read_like_csv(tmp_path):
    d = _drive()
    csv = _load(_write(tmp_path, d))
    np.save(tmp_path / "imu.npy", np.column_stack([d["t"], d["w"], d["f"]]))
    np.savez(tmp_path / "fix.npz", junk=np.zeros(3), fixes=np.column_stack([d["tf"], d["lat"], d["lon"], d["h"]]))
    path = _write(tmp_path, d, imu='format = "npy"', gnss='format = "npz"\narray = "fixes"')
    text = path.read_text().replace('file = "imu.csv"\ntime_column = "t"', 'file = "imu.npy"\ntime_column = 0')
    text = text.replace('gyro_columns = ["gx", "gy", "gz"]\naccel_columns = ["ax", "ay", "az"]',
                        "gyro_columns = [1, 2, 3]\naccel_columns = [4, 5, 6]").replace('"fixes.csv"', '"fix.npz"')
    path.write_text(text)
    arr = _load(path)
    np.testing.assert_array_equal(arr.imu.t, csv.imu.t)
    np.testing.assert_allclose(arr.imu.w_b_radps, csv.imu.w_b_radps, atol=1e-9)
    np.testing.assert_allclose(arr.fixes.p_enu_m, csv.fixes.p_enu_m, atol=1e-4)
    np.save(tmp_path / "imu.npy", np.column_stack([d["t"], d["w"]]))          # accelerometer missing
    with pytest.raises(UserInputError) as err:
        _load(path)
    assert "imu.npy: array of shape (6000, 4) (float64): expected a numeric (n, >= 7) array" in _one_line(err)
    path.write_text(text.replace('array = "fixes"\n', ""))
    with pytest.raises(UserInputError, match=r"fix\.npz: the \.npz holds 2 arrays \(junk, fixes\): expected `array`"):
        _load(path)
    with pytest.raises(UserInputError, match=r"\[imu\] time_column = 't' with format = 'npy': expected 0-based"):
        spec.load_spec(_write(tmp_path, d, imu='format = "npy"'))


# ---- reference attitude ----------------------------------------------------------------------------

def _enu_to_ecef(lat_deg: float, lon_deg: float) -> np.ndarray:
    la, lo = np.radians(lat_deg), np.radians(lon_deg)
    e = [-np.sin(lo), np.cos(lo), 0.0]
    n = [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)]
    u = [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]
    return np.column_stack([e, n, u])


@pytest.mark.parametrize("attitude, order", [("quat_enu", "xyzw"), ("quat_ned", "wxyz"), ("quat_ecef", "xyzw"),
                                             ("quat_ecef", "wxyz"), ("euler_deg", "xyzw")])
def test_reference_attitude_gives_back_the_enu_yaw(tmp_path, attitude, order):
    from scipy.spatial.transform import Rotation

    d = _drive()
    yaw, pitch, roll = d["yaw"], np.full(d["yaw"].size, 0.05), np.full(d["yaw"].size, -0.03)
    c_enu_b = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    ned_enu = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]])
    if attitude == "quat_enu":
        mats = c_enu_b
    elif attitude == "quat_ned":
        mats = ned_enu @ c_enu_b
    else:
        mats = np.array([_enu_to_ecef(la, lo) @ c for la, lo, c in zip(d["lat"], d["lon"], c_enu_b)])
    if attitude == "euler_deg":
        # the NED convention: yaw from North clockwise (roll and pitch do not move the body x heading)
        att = np.column_stack([np.degrees(roll), np.degrees(pitch), 90.0 - np.degrees(yaw)])
        cols = "euler_columns = [4, 5, 6]"
    else:
        q = Rotation.from_matrix(mats).as_quat()                      # x y z w
        att = q[:, [3, 0, 1, 2]] if order == "wxyz" else q
        cols = f'quaternion_columns = [4, 5, 6, 7]\nquaternion_order = "{order}"'
    att[7] = 0.0 if attitude != "euler_deg" else att[7]              # a zero quaternion: counted, skipped
    _csv(tmp_path / "ref.csv", "t,lat,lon,h,a,b,c" + (",d" if attitude != "euler_deg" else ""),
         [d["tf"], d["lat"], d["lon"], d["h"], att])
    ds = _load(_write(tmp_path, d, ref=f'file = "ref.csv"\nattitude = "{attitude}"\n{cols}'))
    keep = np.arange(yaw.size) != 7 if attitude != "euler_deg" else np.ones(yaw.size, bool)
    np.testing.assert_allclose(ds.reference.yaw_rad, np.unwrap(yaw[keep]), atol=1e-9)
    assert ds.counts["reference"].get("rows_bad_quaternion", 0) == (0 if attitude == "euler_deg" else 1)


def test_non_unit_quaternions_are_counted_and_a_wrong_column_set_refused(tmp_path):
    d = _drive()
    n = d["tf"].size
    q = np.tile([0.0, 0.0, np.sin(0.25), np.cos(0.25)], (n, 1))
    q[3] *= 1.01                                      # |q| = 1.01: a mis-scaled export
    q[5] = 0.0
    _csv(tmp_path / "ref.csv", "t,lat,lon,h,qx,qy,qz,qw", [d["tf"], d["lat"], d["lon"], d["h"], q])
    ds = _load(_write(tmp_path, d, ref='file = "ref.csv"\nquaternion_columns = [4, 5, 6, 7]'))
    assert ds.counts["reference"]["rows_bad_quaternion"] == 2 and ds.reference.t.size == n - 2
    np.testing.assert_allclose(ds.reference.yaw_rad, 0.5, atol=1e-12)
    with pytest.raises(UserInputError) as err:
        spec.load_spec(_write(tmp_path, d, ref='file = "ref.csv"\nquaternion_columns = [4, 5, 6]'))
    assert "[reference] quaternion_columns = [4, 5, 6]: expected 4 columns (x y z w) or none" in _one_line(err)
    with pytest.raises(UserInputError, match=r"\[reference\] quaternion_columns given with attitude = 'euler_deg'"):
        spec.load_spec(_write(tmp_path, d, ref='file = "ref.csv"\nquaternion_columns = [4, 5, 6, 7]\n'
                                                'attitude = "euler_deg"'))


# ---- GNSS velocity -----------------------------------------------------------------------------------

def test_gnss_velocity_columns_become_dataset_velocity(tmp_path):
    d = _drive()
    v = np.column_stack([5 * np.cos(d["yaw"]), 5 * np.sin(d["yaw"]), np.zeros(d["yaw"].size)])
    sig = np.tile([0.05, 0.06, 0.1], (v.shape[0], 1))
    v[4, 0] = np.nan                                    # a fix without a velocity keeps its position
    sig[6, 2] = -1.0                                    # an impossible sigma: the velocity row is skipped
    _csv(tmp_path / "fixv.csv", "t,lat,lon,h,ve,vn,vu,se,sn,su", [d["tf"], d["lat"], d["lon"], d["h"], v, sig])
    path = _write(tmp_path, d, gnss='velocity_columns = ["ve", "vn", "vu"]\nvelocity_sigma_columns = [7, 8, 9]')
    path.write_text(path.read_text().replace('"fixes.csv"', '"fixv.csv"'))
    ds = _load(path)
    keep = ~np.isin(np.arange(v.shape[0]), [4, 6])
    assert ds.fixes.t.size == v.shape[0] and ds.velocity.t.size == keep.sum()
    np.testing.assert_allclose(ds.velocity.t, ds.fixes.t[keep])
    np.testing.assert_allclose(ds.velocity.v_enu_mps, v[keep])
    np.testing.assert_allclose(ds.velocity.sigma_mps, sig[keep])
    assert ds.counts["gnss_velocity"]["rows_nan"] == 1 and ds.counts["gnss_velocity"]["rows_bad_sigma"] == 1
    assert _load(_write(tmp_path, d)).velocity is None


def _tpv(chk: Path) -> dict:
    out = {}
    for line in chk.read_text().splitlines():
        if line.startswith("{"):
            rec = json.loads(line)
            if rec.get("class") == "TPV" and "time" in rec and "speed" in rec:
                t = dt.datetime.fromisoformat(rec["time"].replace("Z", "+00:00")).timestamp()
                out[round(t, 3)] = rec
    return out


@pytest.mark.parametrize("log, fmt, source", [("nmea/gpsd/nmea-rtk.log", "nmea", "RMC"),
                                               ("ubx/gpsd/ublox-glo.log", "ubx", "NAV-PVT")])
def test_decoded_log_velocity_matches_gpsd(tmp_path, log, fmt, source):
    """RMC speed + course (horizontal, a large Up sigma) and NAV-PVT velN/velE/velD (sAcc) as gpsd
    decodes the same logs (.chk: speed m/s, track deg clockwise from North)."""
    path = shared_file(log)
    tpv = _tpv(shared_file(log + ".chk"))
    t_first = min(tpv)
    t = t_first - 1.0 + np.arange(0, 400 * 100) / 100.0
    rows = np.column_stack([t, np.full(t.size, 1e-3), np.zeros((t.size, 2)), np.zeros((t.size, 2)),
                            np.full(t.size, 9.80665)])
    np.savetxt(tmp_path / "imu.csv", rows, delimiter=",", header="t,gx,gy,gz,ax,ay,az", comments="", fmt="%.6f")
    (tmp_path / "d.toml").write_text(f"""
[imu]
file = "imu.csv"
time_column = "t"
gyro_columns = ["gx", "gy", "gz"]
accel_columns = ["ax", "ay", "az"]
[gnss]
file = "{path}"
format = "{fmt}"
""")
    ds = _load(tmp_path / "d.toml")
    vel = ds.velocity
    assert vel is not None and vel.t.size == ds.fixes.t.size >= 16
    matched = 0
    for k, tk in enumerate(vel.t + ds.t0_unix):
        rec = tpv.get(round(tk, 3))
        if rec is None:
            continue
        matched += 1
        e, n, _ = vel.v_enu_mps[k]
        assert np.hypot(e, n) == pytest.approx(rec["speed"], abs=0.011)
        if rec["speed"] > 0.5 and "track" in rec:
            assert (np.degrees(np.arctan2(e, n)) - rec["track"] + 180) % 360 - 180 == pytest.approx(0, abs=0.5)
    assert matched > 0.8 * vel.t.size
    if source == "RMC":
        assert np.all(vel.sigma_mps[:, 2] == 10.0) and np.all(vel.v_enu_mps[:, 2] == 0.0)
        assert any("RMC speed and course (horizontal only" in n for n in ds.notes)
    else:
        assert ds.counts["gnss_velocity"]["from_nav_pvt"] == vel.t.size and np.all(vel.sigma_mps > 0)


# ---- physics checks -----------------------------------------------------------------------------------

def test_gyro_unit_is_checked_against_the_gnss_course(tmp_path):
    d = _drive()
    ds = _load(_write(tmp_path, d))
    assert 0.8 < ds.counts["imu"]["gyro_vs_gnss_course_ratio"] < 1.2
    with pytest.raises(UserInputError) as err:           # rad/s data declared deg/s: 57 times too small
        _load(_write(tmp_path, d, imu='gyro_unit = "deg/s"'))
    msg = _one_line(err)
    assert "[imu] gyro_unit = 'deg/s': over the turns the gyro integrates 0.017" in msg and "d.toml" in msg
    # deg/s data declared rad/s: 17 rad/s at most, below the 20 rad/s rate check, refused by the course
    deg = dict(d, w=np.degrees(d["w"]))
    with pytest.raises(UserInputError, match=r"\[imu\] gyro_unit = 'rad/s': over the turns the gyro integrates 5[67]"):
        _load(_write(tmp_path, deg))
    assert _load(_write(tmp_path, deg, imu='gyro_unit = "deg/s"')).counts["imu"]["gyro_vs_gnss_course_ratio"] > 0.8


def test_gyro_unit_at_rest_against_the_earth_rate(tmp_path):
    d = _drive(seconds=30.0, speed=0.0)
    d["w"] = np.tile([4e-5, 2e-5, 5.5e-5], (d["t"].size, 1)) + 1e-6 * np.random.default_rng(2).standard_normal(
        (d["t"].size, 3))                                 # a good gyro at rest reads about the Earth rate
    ds = _load(_write(tmp_path, d))
    assert ds.counts["imu"]["rate_at_rest_radps"] == pytest.approx(7.2e-5, rel=0.05)
    with pytest.raises(UserInputError, match=r"\[imu\] gyro_unit = 'deg/s': at rest the gyro reads 1.2[0-9]e-06 rad/s"):
        _load(_write(tmp_path, d, imu='gyro_unit = "deg/s"'))


def test_imu_time_jumps_are_counted_as_gaps(tmp_path):
    d = _drive()
    t = d["t"].copy()
    t[3000:] += 1e6                                          # the clock jumps a million seconds ahead
    ds = _load(_write(tmp_path, d, imu_t=t))
    c = ds.counts["imu"]
    assert c["time_jumps"] == 1 and c["gaps"] == 1 and c["time_jump_forward_s"] == pytest.approx(1e6, abs=1)
    t = d["t"].copy()
    t[3000:] -= 5.005                                        # and back by 5 s (a clock reset)
    ds = _load(_write(tmp_path, d, imu_t=t))
    c = ds.counts["imu"]
    # the rows stamped before the last kept one are skipped until the clock passes it again
    assert c["time_jumps"] == 1 and c["rows_non_monotonic"] == 500 and c["rows_used"] == t.size - 500
    assert np.all(np.diff(ds.imu.t) > 0)


# ---- documentation -----------------------------------------------------------------------------------

def test_docs_list_every_key_in_its_own_section():
    """docs/datasets.md has a table per section naming each of its SCHEMA keys (`| `key` |`), so a key
    added to a section without a row there fails (the key's name elsewhere in the page does not count)."""
    from leonav_runtime.core import model

    text = (Path(__file__).resolve().parents[1] / "docs" / "datasets.md").read_text()
    keys_doc = text[text.index("## Keys"):]
    tables: dict[str, set[str]] = {}
    current = None
    for line in keys_doc.splitlines():
        if line.startswith("`[") and line.rstrip().endswith("]`"):
            current = line.strip("`[] ")
        elif line == "top level":
            current = ""
        elif line.startswith("Local sensors:"):
            current = "local"
        elif line.startswith("| `") and current is not None:
            cell = line.split("|")[1]
            tables.setdefault(current, set()).update(k.strip(" `") for k in cell.split(","))
    missing = [f"[{sec}] {key}" for sec, fields in spec.SCHEMA.items() for key in fields
               if key not in tables.get("local" if sec in model.LOCAL_SENSORS else sec, set())]
    assert not missing, f"docs/datasets.md lacks a row for {missing}"
