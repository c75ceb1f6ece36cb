"""Dataset descriptions and the importer: the real CPET run 3 files, and bad input.

Outside references: ../shared/data/SOURCES.md section 6 (measured independently: IMU t = 0
is the first fix + 0.30..0.40 s) and issue 11's GPS-alone figures on the same data (hold
last fix, horizontal RMSE 0.968 m over the 800 ground-truth epochs; 7.3 / 4.3 / 9.5 / 6.6 /
10.9 m at the end of the 30 s outages), which pin the time axis, the UTM reference and the
scoring. The MAT and the CSV export of the IMU must agree.
"""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime import cli
from leonav_runtime.dataset import align, load, scoring, spec
from leonav_runtime.common.errors import UserInputError
from tests.conftest import shared_file

CPET = "gnss_ins/cpet_run3_navego"


@pytest.fixture(scope="module")
def cpet():
    shared_file(f"{CPET}/imu_planetary_200hz.csv")
    return load.load(spec.load_spec("cpet_run3"))


def test_cpet_files_import_on_one_axis(cpet):
    assert cpet.counts["imu"]["rows_used"] == 73453 and cpet.counts["gnss"]["rows_used"] == 7344
    assert cpet.reference.t.size == 800 and abs(cpet.counts["imu"]["rate_hz"] - 200.0) < 1e-3
    assert cpet.fixes.t[0] == 0.0 and abs(cpet.reference.t[0] - 5.1638) < 1e-3
    # vehicle FLU after the axis map: gravity on +z at rest, and forward acceleration at the first start
    rest = cpet.imu.f_b_mps2[:200].mean(axis=0)
    assert 9.7 < rest[2] < 9.9 and np.hypot(rest[0], rest[1]) < 0.6
    # reference and fixes describe the same place (metres apart, not kilometres)
    gap = scoring.hold_last_fix(cpet.fixes, cpet.reference.t) - cpet.reference.p_enu_m
    assert np.nanmax(np.hypot(gap[:, 0], gap[:, 1])) < 4.0


def test_gps_alone_matches_the_issue_figures(cpet):
    err = scoring.hold_last_fix(cpet.fixes, cpet.reference.t) - cpet.reference.p_enu_m
    assert scoring.error_stats(err)["rmse_horizontal_m"] == pytest.approx(0.968, abs=0.005)
    holds = []
    for start in (60, 120, 180, 240, 300):
        k = np.searchsorted(cpet.fixes.t, start) - 1
        p_ref = scoring.reference_at(cpet.reference, start + 30)[0]
        holds.append(np.hypot(*(cpet.fixes.p_enu_m[k, :2] - p_ref[:2])))
    np.testing.assert_allclose(holds, [7.3, 4.3, 9.5, 6.6, 10.9], atol=0.06)


def test_time_offset_calibration_finds_the_measured_offset(cpet):
    imu = cpet.imu_on_axis(0.0)
    cal = align.calibrate_time_offset(imu.t, imu.w_b_radps[:, 2], cpet.reference.t, cpet.reference.yaw_rad)
    assert 0.28 <= cal["offset_s"] <= 0.42 and cal["cost_rad"] < 0.7 * cal["cost_at_zero_rad"]
    # a z axis left pointing down (FRD not turned to FLU) turns the other way: no offset fits
    wrong = align.calibrate_time_offset(imu.t, -imu.w_b_radps[:, 2], cpet.reference.t, cpet.reference.yaw_rad)
    assert wrong["cost_rad"] > 3 * cal["cost_rad"]


def test_mat_and_csv_give_the_same_imu(cpet):
    shared_file(f"{CPET}/imu_planetary.mat")
    s = spec.load_spec("cpet_run3")
    s["imu"].update(format="mat", file="imu_planetary.mat", mat_struct="imu_planetary", time_column="t",
                    gyro_columns=["wb"], accel_columns=["fb"])
    t, w, f = load.read_imu(s, {})
    np.testing.assert_allclose(w, cpet.imu.w_b_radps, atol=1e-8)
    np.testing.assert_allclose(f, cpet.imu.f_b_mps2, atol=1e-8)
    np.testing.assert_allclose(t, cpet.imu_raw_t, atol=1e-6)


# ---- bad input ---------------------------------------------------------------------------

def _write_dataset(tmp_path, imu_rows: list[str], toml_extra: str = "", gnss_rows: list[str] | None = None):
    (tmp_path / "imu.csv").write_text("\n".join(["# a test IMU", "t,gx,gy,gz,ax,ay,az"] + imu_rows) + "\n")
    gnss = gnss_rows or [f"{1.5e9 + 0.1 * k:.3f},45.5,-73.4,25.0" for k in range(20)]
    (tmp_path / "gnss.csv").write_text("\n".join(gnss) + "\n")
    (tmp_path / "d.toml").write_text(f"""
name = "t"
[imu]
file = "imu.csv"
time_column = "t"
gyro_columns = ["gx", "gy", "gz"]
accel_columns = ["ax", "ay", "az"]
accel_range_mps2 = 20.0
{toml_extra}
[gnss]
file = "gnss.csv"
""")
    return tmp_path / "d.toml"


def _imu_rows(n=50, t0=1.5e9):
    return [f"{t0 + 0.01 * k:.3f},0.01,0,0,0,0,9.8" for k in range(n)]


def test_bad_rows_are_counted_and_skipped(tmp_path):
    rows = _imu_rows()
    rows[5] = rows[5].replace("9.8", "nan")          # NaN
    rows[7] = "1500000000.070,0.01,0"                 # short
    rows[9] = rows[8]                                 # duplicated time stamp
    rows[12] = rows[3]                                # back in time
    rows[20] = rows[20].replace("9.8", "20.0")        # at the accelerometer's full scale: clipped
    rows[30] = rows[30].replace("0.01", "abc", 1)     # not a number
    rows[21] = rows[18]                               # back in time, right after the clipped row
    rows[23] = rows[22]                               # duplicated
    ds = load.load(spec.load_spec(_write_dataset(tmp_path, rows)))
    c = ds.counts["imu"]
    assert (c["rows_nan"], c["rows_short"], c["rows_duplicate_time"], c["rows_non_monotonic"], c["rows_clipped"]) \
        == (2, 1, 2, 2, 1)
    assert c["rows_used"] == 50 - 8 and np.all(np.diff(ds.imu.t) > 0)


@pytest.mark.parametrize("extra, needle", [
    ('gyro_unit = "rpm"', "[imu] gyro_unit"),
    ('axes = "x,x,z"', "[imu] axes"),
    ('axes = "forward"', "[imu] axes"),
    ('time_offset_s = "later"', "[imu] time_offset_s"),
    ('frame = "NED"', "[imu] frame"),
    ("wobble = 1", "unknown key 'wobble'"),
])
def test_bad_description_is_one_line_naming_the_key(tmp_path, extra, needle):
    path = _write_dataset(tmp_path, _imu_rows(), extra)
    with pytest.raises(UserInputError) as err:
        spec.load_spec(path)
    assert needle in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


def test_missing_column_names_file_line_and_column(tmp_path):
    path = _write_dataset(tmp_path, _imu_rows())
    (tmp_path / "imu.csv").write_text("t,gx,gy,gz,ax,ay\n" + "\n".join(_imu_rows()) + "\n")
    with pytest.raises(UserInputError, match=r"imu\.csv:1: column 'az' \(accel_columns\) not in the header"):
        load.load(spec.load_spec(path))


def test_missing_file_and_no_usable_row(tmp_path):
    path = _write_dataset(tmp_path, _imu_rows())
    (tmp_path / "gnss.csv").unlink()
    with pytest.raises(UserInputError, match=r"gnss\.csv: GNSS file not found \(.*\[gnss\] file\)"):
        load.load(spec.load_spec(path))
    path = _write_dataset(tmp_path, [r.replace("9.8", "nan") for r in _imu_rows()])
    with pytest.raises(UserInputError, match="no row with finite numbers"):
        load.load(spec.load_spec(path))


def test_cli_reports_bad_input_in_one_line(tmp_path, capsys):
    path = _write_dataset(tmp_path, _imu_rows(), 'accel_unit = "furlong"')
    status = cli.main(["run", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.count("\n") == 0 and "[imu] accel_unit" in err and "Traceback" not in err
    status = cli.main(["run", str(tmp_path / "nothing.toml")])
    assert status == 2 and "dataset file not found" in capsys.readouterr().err


def test_every_key_is_documented():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "datasets.md").read_text()
    missing = [f"[{sec}] {key}" for sec, fields in spec.SCHEMA.items() for key in fields if f"`{key}`" not in text]
    assert not missing, f"docs/datasets.md lacks {missing}"


def test_nmea_log_as_the_gnss_file(tmp_path):
    """A receiver's NMEA log through the device decoders: positions as gpsd decodes them (.chk),
    per-fix sigma from the GST sentence of the same epoch (the receiver's own covariance)."""
    import json

    log = shared_file("nmea/gpsd/ublox-neo-m9n-nmea.log")
    tpv = {}
    for line in shared_file("nmea/gpsd/ublox-neo-m9n-nmea.log.chk").read_text().splitlines():
        if line.startswith("{"):
            rec = json.loads(line)
            if rec.get("class") == "TPV" and rec.get("mode") == 3:
                tpv[rec["time"]] = (rec["lat"], rec["lon"])
    t0 = 1594507065.0                       # 2020-07-11 22:37:45 UTC, the log's first epoch
    path = _write_dataset(tmp_path, _imu_rows(n=200, t0=t0))
    text = path.read_text().replace('file = "gnss.csv"', f'file = "{log}"\nformat = "nmea"')
    path.write_text(text)
    ds = load.load(spec.load_spec(path))
    assert ds.t0_unix == t0 and ds.fixes.t.size == len(tpv) == 61
    lat, lon = np.degrees(ds.origin[0]), np.degrees(ds.origin[1])
    assert (lat, lon) == pytest.approx(tpv["2020-07-11T22:37:45.000Z"], abs=1e-9)
    # $GNGST,223745.00,228650,2.5,2.4,126,0.98,1.0,3.1: sigma lat 0.98 (N), lon 1.0 (E), alt 3.1 m
    np.testing.assert_allclose(ds.fixes.sigma_enu_m[0], [1.0, 0.98, 3.1])
    assert ds.counts["gnss"]["sigma_source"] == {"GST": 61}


def test_per_fix_sigma_columns(tmp_path):
    rows = [f"{1.5e9 + 0.1 * k:.3f},45.5,-73.4,25.0,{0.5 + 0.01 * k},{0.6 + 0.01 * k},{1.2 + k}" for k in range(20)]
    rows[4] = rows[4].rsplit(",", 1)[0] + ",-1"          # a negative sigma: out of range, skipped
    rows[6] = rows[6].replace("45.5", "95.5")            # latitude beyond 90 deg: skipped
    path = _write_dataset(tmp_path, _imu_rows(), gnss_rows=rows)
    path.write_text(path.read_text() + "sigma_columns = [4, 5, 6]\n")
    ds = load.load(spec.load_spec(path))
    assert ds.counts["gnss"]["rows_out_of_range"] == 2 and ds.fixes.t.size == 18
    np.testing.assert_allclose(ds.fixes.sigma_enu_m[:4], [[0.5 + 0.01 * k, 0.6 + 0.01 * k, 1.2 + k] for k in range(4)])
    np.testing.assert_allclose(ds.fixes.sigma_enu_m[4], [0.55, 0.65, 6.2])


def test_shipped_dataset_says_where_the_shared_data_is_looked_for(tmp_path, monkeypatch):
    monkeypatch.setenv("LEONAV_SHARED_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(UserInputError) as err:
        load.load(spec.load_spec("cpet_run3"))
    msg = str(err.value)
    assert str(tmp_path / "nowhere") in msg and "LEONAV_SHARED_DATA" in msg and "[gnss] file" in msg


def test_reference_yaw_is_true_not_grid(cpet):
    """UTM grid north is not true north (1.15 deg here): the reference yaw is turned by pyproj's
    own meridian convergence (Proj.get_factors), computed independently of the importer's way."""
    from pyproj import Proj

    gt = np.loadtxt(shared_file(f"{CPET}/global-pose-utm.txt"), delimiter=",")
    x, y, z, w = gt[:, 4], gt[:, 5], gt[:, 6], gt[:, 7]
    grid_yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    lon, lat = np.degrees(cpet.origin[1]), np.degrees(cpet.origin[0])
    conv = np.radians(Proj("EPSG:32618").get_factors(lon, lat).meridian_convergence)
    diff = scoring.wrap(cpet.reference.yaw_rad - (grid_yaw - conv))
    assert np.abs(diff).max() < 1e-4 and conv > 0.019


@pytest.mark.parametrize("section, key, value, needle", [
    ("imu", "accel_unit", "g", "[imu] accel_unit = 'g': the median specific force"),
    ("imu", "time_unit", "ms", "[imu] time_unit = 'ms': "),
    ("imu", "gyro_unit", "deg/s", "[imu] gyro_unit = 'deg/s': over the turns the gyro integrates 0.01"),
    ("imu", "time_base", "unix", "[imu] time_base = 'unix', time_offset_s = 0.36: the IMU spans"),
    ("reference", "position_columns", [2, 1, 3], "[reference] crs / position_columns / time_column: the reference is"),
    ("reference", "time_unit", "ms", "no overlap"),
])
def test_wrong_unit_time_base_or_crs_is_named(tmp_path, section, key, value, needle):
    """A plausible-looking but wrong key on the real CPET files: one line naming the key, from
    physics (|f| ~ g, IMU rate, IMU/GNSS overlap, reference within metres of the fixes)."""
    from leonav_runtime.dataset.evaluate import run_dataset

    shared_file(f"{CPET}/imu_planetary_200hz.csv")
    s = spec.load_spec("cpet_run3")
    s[section][key] = value
    if needle is None:
        load.load(s)
        return
    with pytest.raises(UserInputError) as err:
        run_dataset(s, tmp_path, t_end_s=20.0, outages=False, files=False)
    msg = str(err.value)
    assert needle in msg and "\n" not in msg and s.source in msg


def test_llh_reference_declared_ecef_and_until_before_the_reference(cpet, tmp_path, capsys):
    from pyproj import Transformer

    gt = np.loadtxt(shared_file(f"{CPET}/global-pose-utm.txt"), delimiter=",")
    lon, lat = Transformer.from_crs("EPSG:32618", "EPSG:4326", always_xy=True).transform(gt[:, 1], gt[:, 2])
    np.savetxt(tmp_path / "llh.csv", np.column_stack([gt[:, 0], lat, lon, gt[:, 3]]), delimiter=",", fmt="%.10f")
    status = cli.main(["run", "cpet_run3", "--reference", str(tmp_path / "llh.csv"), "--reference-crs", "ecef",
                       "--until", "20", "--no-outages", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "--reference-crs" in err and "from the GNSS fixes" in err and "\n" not in err
    status = cli.main(["run", "cpet_run3", "--until", "3", "--no-outages", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "--until 3: the reference starts at 5.16" in err and "\n" not in err
    status = cli.main(["run", "cpet_run3", "--reference", str(tmp_path / "missing.pos"), "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "--reference" in err and "missing.pos" in err and "\n" not in err


def test_calibrate_uses_the_gnss_course_unless_the_reference_is_asked_for(cpet):
    from leonav_runtime.dataset import runner

    s = cpet.spec
    old = s["imu"]["time_offset_s"]
    try:
        s["imu"]["time_offset_s"] = "calibrate"
        rep: dict = {}
        off = runner.time_offset(cpet, rep)
        assert off == rep["time_offset_calibration"]["gnss_course"]["offset_s"]
        assert rep["time_offset_s"]["uses_reference"] is False and "GNSS course" in rep["time_offset_s"]["source"]
        s["imu"]["time_offset_s"] = "calibrate_reference"
        rep = {}
        off = runner.time_offset(cpet, rep)
        assert off == rep["time_offset_calibration"]["reference_yaw"]["offset_s"] and 0.28 <= off <= 0.42
        assert rep["time_offset_s"]["uses_reference"] is True
        no_yaw = load.Dataset(s, cpet.t0_unix, cpet.origin, cpet.imu_raw_t, cpet.imu, cpet.fixes,
                              load.Reference(cpet.reference.t, cpet.reference.p_enu_m, None), cpet.counts)
        with pytest.raises(UserInputError, match=r"\[imu\] time_offset_s = 'calibrate_reference': the reference has "
                                                 "no attitude"):
            runner.time_offset(no_yaw, {})
    finally:
        s["imu"]["time_offset_s"] = old


def test_msl_heights_become_ellipsoidal_with_the_geoid_separation(cpet):
    raw = np.loadtxt(shared_file(f"{CPET}/gps-latlong.txt"), delimiter=",")[0]
    s = cpet.spec
    assert s["gnss"]["height_datum"] == "msl" and s["reference"]["height_datum"] == "msl"
    assert cpet.origin[2] == pytest.approx(raw[3] + s["gnss"]["geoid_separation_m"], abs=1e-9)
    s2 = spec.load_spec("cpet_run3")
    s2["gnss"]["height_datum"] = s2["reference"]["height_datum"] = "ellipsoid"
    ell = load.load(s2)
    assert ell.origin[2] == pytest.approx(raw[3], abs=1e-9)
    # both moved together: the local scores do not change (mm over a few hundred metres)
    np.testing.assert_allclose(ell.reference.p_enu_m, cpet.reference.p_enu_m, atol=5e-3)
    text = spec.load_spec("cpet_run3").source
    with open(text) as fh:
        body = fh.read().replace("geoid_separation_m = -32.0", "")
    with pytest.raises(UserInputError, match=r"\[gnss\] geoid_separation_m: heights declared msl"):
        spec.spec_from_dict(__import__("tomllib").loads(body), source="cpet.toml")


def test_shared_data_is_found_beside_the_current_folder_after_a_plain_install(tmp_path, monkeypatch):
    """`pip install .` copies the package into site-packages: `{shared}` is then found beside
    the folder the command runs from (or a parent), as the README's tour runs it."""
    from leonav_runtime.dataset import spec

    (tmp_path / "shared" / "data").mkdir(parents=True)
    (tmp_path / "leonav" / "sub").mkdir(parents=True)
    monkeypatch.delenv("LEONAV_SHARED_DATA", raising=False)
    monkeypatch.setattr(spec, "__file__", str(tmp_path / "venv" / "lib" / "site" / "leonav_runtime" / "dataset" / "spec.py"))
    monkeypatch.chdir(tmp_path / "leonav" / "sub")
    assert spec.shared_data_dir() == (tmp_path / "shared" / "data").resolve()
    monkeypatch.setenv("LEONAV_SHARED_DATA", str(tmp_path / "elsewhere"))
    assert spec.shared_data_dir() == tmp_path / "elsewhere"
