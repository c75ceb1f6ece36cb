"""Local sensors made from the registry alone: the barometer (height + random-walk bias) and the
magnetometer heading (with a declination parameter), from their models against outside
references to a simulated run that matches its bound and a dataset description's section."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model, navfuncs
from leonav_runtime.core.params import build_params
from leonav_runtime.dataset import load, spec
from leonav_runtime.gen import state_layout as L
from leonav_runtime.inputs import LocalSensorTable
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict
from leonav_runtime.sweep.run import run_sweep
from tests.test_dataset_import import _imu_rows, _write_dataset

LAT, LON, H0 = math.radians(43.0848638), math.radians(-77.6786127), 170.0


def _nav(declination_rad: float = 0.0) -> navfuncs.NavFunctions:
    return navfuncs.NavFunctions(params=np.array(build_params(LAT, LON, H0, values={
        "mag_declination_rad": declination_rad})))


def _state(p_enu, rpy, b_baro=0.0, nav=None):
    nav = nav or _nav()
    x = np.zeros(L.NX)
    x[L.X_P_ENU_SLICE] = p_enu
    x[L.X_Q_NB_SLICE] = nav.quat_from_euler(np.array(rpy))[0]
    x[L.X_B_BARO] = b_baro
    return x


def test_barometer_is_the_ellipsoidal_height_plus_its_bias():
    """Against pyproj's ECEF -> WGS84 conversion, 5 km from the origin (where ENU up and the
    ellipsoidal height part by ~2 m)."""
    pyproj = pytest.importorskip("pyproj")
    nav = _nav()
    to_llh = pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    for p_enu, bias in (([0.0, 0.0, 0.0], 0.0), ([4000.0, -3000.0, 120.0], 7.5), ([-2500.0, 4200.0, -30.0], -3.0)):
        x = _state(p_enu, [0.0, 0.0, 1.0], bias, nav)
        r_ecef, _ = nav.receiver_ecef(x)
        _, _, h_ref = to_llh.transform(*r_ecef)
        z, H = nav.h("baro_height", x, np.zeros(L.NAUX))
        assert z == pytest.approx(h_ref + bias, abs=1e-3)
        assert H[L.DX_DB_BARO] == pytest.approx(1.0) and H[L.DX_DP + 2] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("yaw_deg, declination_deg", [(10.0, 0.0), (170.0, 12.0), (-95.0, -8.5)])
def test_magnetometer_heading_is_the_yaw_plus_the_declination(yaw_deg, declination_deg):
    nav = _nav(math.radians(declination_deg))
    x = _state([0.0, 0.0, 0.0], [math.radians(4.0), math.radians(-6.0), math.radians(yaw_deg)], nav=nav)
    psi = math.radians(yaw_deg + declination_deg)
    assert nav.h("mag_cos", x, np.zeros(L.NAUX))[0] == pytest.approx(math.cos(psi), abs=1e-12)
    assert nav.h("mag_sin", x, np.zeros(L.NAUX))[0] == pytest.approx(math.sin(psi), abs=1e-12)


@pytest.fixture(scope="module")
def sweep():
    base = load_scenario("paper")
    raw = copy.deepcopy(base.raw)
    raw["time"]["duration_s"] = 60.0
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"]["trials"] = 20
    raw["monte_carlo"]["modes"] = ["gps+imu", "gps+imu+baro", "leo-alpha+imu", "leo-alpha+imu+baro",
                                   "leo-alpha+imu+mag"]
    raw["mag"] = {"declination_deg": -11.0}
    scn = scenario_from_dict(raw, source=base.source)
    return scn, run_sweep(scn, None, progress=False, workers=1).summaries


def test_the_barometer_sharpens_the_vertical_and_matches_its_bound(sweep):
    scn, s = sweep
    baro_kind = model.observable("baro_height").kind
    for base in ("gps+imu", "leo-alpha+imu"):
        without, with_ = s[(base, 10)], s[(f"{base}+baro", 10)]
        assert with_["vertical"]["rmse"] < 0.9 * without["vertical"]["rmse"], base
        assert 0.7 < with_["vertical"]["ratio"] < 1.4, base         # RMSE against sqrt(PCRB)
        nis = with_["nis"][baro_kind]
        assert nis["count"] > 10_000 and nis["band95"][0] < nis["mean"] < nis["band95"][1]
    assert scn.local["baro"]["sigma_m"] == model.observable("baro_height").noise.default


def test_the_magnetometer_gives_the_heading_with_the_scenario_declination(sweep):
    scn, s = sweep
    assert scn.params["mag_declination_rad"] == pytest.approx(math.radians(-11.0))
    without, with_ = s[("leo-alpha+imu", 10)], s[("leo-alpha+imu+mag", 10)]
    assert with_["attitude"]["rmse"] < 0.5 * without["attitude"]["rmse"]
    for kind in (model.observable("mag_cos").kind, model.observable("mag_sin").kind):
        nis = with_["nis"][kind]
        assert nis["band95"][0] < nis["mean"] < nis["band95"][1]


def test_a_local_table_is_checked_like_the_others():
    ok = LocalSensorTable("mag", np.arange(3.0), np.zeros((3, 2)), 0.03)
    ok.check()
    with pytest.raises(UserInputError, match=r"mag table: z: shape \(3, 1\): expected shape \(3, 2\)"):
        LocalSensorTable("mag", np.arange(3.0), np.zeros((3, 1)), 0.03).check()
    with pytest.raises(UserInputError, match="baro table: sigma: value <= 0"):
        LocalSensorTable("baro", np.arange(3.0), np.zeros((3, 1)), 0.0).check()
    with pytest.raises(UserInputError, match="local sensor table: stream: 'fix'"):
        LocalSensorTable("fix", np.arange(3.0), np.zeros((3, 1)), 1.0).check()


def test_dataset_section_of_a_local_sensor(tmp_path):
    rows = [f"{1.5e9 + 0.1 * k:.3f},{25.0 + 0.01 * k:.3f}" for k in range(30)]
    rows[4] = rows[4].split(",")[0] + ",nan"
    rows[9] = rows[8]
    (tmp_path / "baro.csv").write_text("t,height\n" + "\n".join(rows) + "\n")
    extra = '[filter]\nmodes = ["fix+imu+baro"]\n[baro]\nfile = "baro.csv"\ntime_column = "t"\ncolumns = ["height"]\n' \
            "sigma_m = 0.8\n"
    toml = _write_dataset(tmp_path, _imu_rows(), "", None)
    toml.write_text(toml.read_text() + extra)
    ds = load.load(spec.load_spec(toml))
    assert ds.counts["baro"]["rows_nan"] == 1 and ds.counts["baro"]["rows_duplicate_time"] == 1
    (table,) = ds.local_on_axis(0.0)
    assert table.stream == "baro" and table.z.shape == (28, 1) and table.sigma == 0.8
    assert table.t[0] == pytest.approx(0.0) and table.z[0, 0] == pytest.approx(25.0)
    # a mode that uses the sensor needs its file; the columns must be one per observable
    toml.write_text(toml.read_text().replace('file = "baro.csv"\n', ""))
    with pytest.raises(UserInputError, match=r"\[baro\] file: missing: a mode uses baro"):
        spec.load_spec(toml)
    toml.write_text(toml.read_text().replace('[baro]\n', '[baro]\nfile = "baro.csv"\n').replace(
        'columns = ["height"]', 'columns = ["height", "t"]'))
    with pytest.raises(UserInputError, match=r"\[baro\] columns"):
        spec.load_spec(toml)


def test_a_mode_word_of_no_sensor_is_one_line():
    with pytest.raises(UserInputError, match="unknown word 'sonar'"):
        model.parse_mode("gps+imu+sonar")
    with pytest.raises(UserInputError, match="'baro' is a local sensor or constraint: it goes after imu"):
        model.parse_mode("baro+imu")
    assert model.parse_mode("gps+imu+baro+mag").streams == ("pseudorange", "baro", "mag")   # merged with the IMU's
