"""Fix latency as a state, alignment in motion and the GNSS velocity, on a synthetic drive with
known truth (dataset/synthetic.py) and on CPET with its fixes shifted by a known amount."""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.dataset import align, load, runner, scoring, synthetic
from leonav_runtime.dataset.spec import load_spec, spec_from_dict
from leonav_runtime.inputs import FixTable, VelocityTable
from leonav_runtime.inputs.measurements import tag_lead

LATENCY_S = 0.1


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = synthetic.write_drive(tmp_path_factory.mktemp("drive"), synthetic.DriveConfig(fix_latency_s=LATENCY_S))
    ds = load.load(load_spec(d.toml))
    return d, ds


def _velocity(ds, folder: Path, sigma=(0.05, 0.05, 0.1)) -> VelocityTable:
    raw = np.loadtxt(folder / "fixes.csv", delimiter=",", skiprows=1)
    return VelocityTable(raw[:, 0] - ds.t0_unix, raw[:, 4:7], np.tile(sigma, (raw.shape[0], 1)))


def _at(res, layout, t_s: float):
    _, x, pd = scoring.states_at(res, np.array([t_s]))
    return x[0], pd[0]


def test_in_motion_alignment_heading_within_2_deg_10_s_after_the_start(drive):
    """With the car's motion constraint or the GNSS velocity (fixes alone and a free gyro bias take
    longer: 4.4 deg at 10 s on this drive, reported, not asserted)."""
    d, ds = drive
    ds.velocity = _velocity(ds, d.toml.parent)
    prep = runner.prepare(ds)
    ds.velocity = None
    al = prep.report["alignment"]
    assert al["kind"] == "in motion" and "left to the filter" in al["gyro_bias_source"]
    # the quiet straight start is not taken for a standstill: the GNSS speed vetoed it
    assert prep.report["standstill_vetoed_by_gnss_speed_s"] > 1.0
    L = prep.nav.layout
    for mode in ("fix+imu+nhc", "fix+vel+imu", "fix+vel+imu+nhc"):
        _, res, _, _ = runner.run_mode(prep, mode)
        t = al["start_s"] + 10.0
        x, _ = _at(res, L, t)
        k = np.searchsorted(ds.reference.t, t)
        err = math.degrees(scoring.wrap(scoring.yaw_of(x[None, L.X_Q_NB_SLICE])[0] - ds.reference.yaw_rad[k]))
        assert abs(err) < 2.0, (mode, err)


def test_levelling_in_motion_removes_the_centripetal_acceleration(drive):
    """In a steady turn the specific force leans by atan(v w / g); the in-motion level does not."""
    d, ds = drive
    imu = ds.imu_on_axis(0.0)
    from leonav_runtime.core import navfuncs
    nav = navfuncs.NavFunctions()
    t_v, v = align.gnss_velocity(ds.fixes, 2.0)
    L = nav.layout
    t_turn = 4.0 + 5.0 + 3.0   # the middle of the first 15 deg/s turn (maneuvers)
    k = np.searchsorted(d.t_s, t_turn)
    truth = nav.euler_from_quat(d.x_true[k, L.X_Q_NB_SLICE])[0]
    roll, pitch, rep = align.level_in_motion(imu, ds.fixes, t_v, v, t_turn, truth[2], 2.0, nav)
    naive_roll = math.radians(rep["naive_roll_pitch_deg"][0])
    assert abs(naive_roll - truth[0]) > math.radians(5.0)        # 12 m/s at 0.26 rad/s: 18 deg of lean
    assert abs(roll - truth[0]) < math.radians(1.0) and abs(pitch - truth[1]) < math.radians(1.0)
    assert rep["naive_error_deg"] > 5.0


def test_latency_100_ms_estimated_within_5_ms_after_30_s_of_turns(drive):
    d, ds = drive
    ds.velocity = _velocity(ds, d.toml.parent)
    prep = runner.prepare(ds)
    L = prep.nav.layout
    assert prep.report["fix_latency"]["source"].startswith("estimated")
    for mode in ("fix+vel+imu", "fix+vel+imu+nhc"):
        _, res, _, _ = runner.run_mode(prep, mode)
        x, pd = _at(res, L, 30.0)
        assert abs(x[L.X_DT_FIX] - LATENCY_S) < 0.005, (mode, x[L.X_DT_FIX])
        sigma = math.sqrt(pd[L.DX_DDT_FIX])
        assert sigma < 0.005 and abs(x[L.X_DT_FIX] - LATENCY_S) < 4 * sigma
    ds.velocity = None


def test_fixes_alone_find_the_latency_with_an_honest_sigma(drive):
    d, ds = drive
    prep = runner.prepare(ds)
    L = prep.nav.layout
    _, res, _, _ = runner.run_mode(prep, "fix+imu+nhc")
    est = scoring.latency_estimate(res, L)
    assert abs(est["value"] - LATENCY_S) < 3 * est["sigma"] and est["sigma"] < 0.01


def test_estimating_the_latency_is_nearly_as_good_as_knowing_it(tmp_path):
    rmse = {}
    for name, offset in (("ignored", "0"), ("estimated", "estimate"), ("known", str(LATENCY_S))):
        d = synthetic.write_drive(tmp_path / name, synthetic.DriveConfig(fix_latency_s=LATENCY_S, time_offset=offset,
                                                                         modes=("fix+imu+nhc",)))
        ds = load.load(load_spec(d.toml))
        prep = runner.prepare(ds)
        _, res, _, _ = runner.run_mode(prep, "fix+imu+nhc")
        late = ds.reference.t > 30.0
        ref = load.Reference(ds.reference.t[late], ds.reference.p_enu_m[late], None)
        rmse[name] = scoring.run_scores(res, prep.nav.layout, ref, 0.0)[0]["rmse_horizontal_m"]
    # estimating costs little against knowing it (after 30 s), ignoring it costs the along-track metre
    assert rmse["estimated"] < 1.3 * rmse["known"] and 3 * rmse["estimated"] < rmse["ignored"], rmse
    assert rmse["ignored"] > 0.5        # 0.1 s at 10..14 m/s: a metre along the track


def test_tag_lead_places_a_fix_between_imu_samples():
    from leonav_runtime.inputs import ImuTable
    t = np.arange(1, 11) * 0.01
    imu = ImuTable.from_rates(t, np.full(10, 0.01), np.zeros((10, 3)), np.zeros((10, 3)))
    lead = tag_lead(imu, np.array([0.0, 0.025, 0.05, 0.0999]))
    np.testing.assert_allclose(lead, [0.0, 0.005, 0.0, 0.0099], atol=1e-9)
    assert np.all(tag_lead(None, np.array([1.0, 2.0])) == 0)


def test_known_latency_shifts_the_tags_and_estimate_needs_no_number():
    fixes = FixTable(np.array([1.0, 2.0]), np.zeros((2, 3)), np.ones((2, 3)), np.full((2, 2), np.nan))
    np.testing.assert_allclose(runner.shift_fixes(fixes, 0.25).t, [0.75, 1.75])
    assert runner.shift_fixes(fixes, "estimate") is fixes


def test_latency_keys_are_checked():
    base = {"imu": {"file": "i.csv", "gyro_columns": [1, 2, 3], "accel_columns": [4, 5, 6]}, "gnss": {"file": "g.csv"}}
    for bad, text in (("soon", "'estimate'"), (30.0, "+-10 s")):
        raw = {**base, "gnss": {"file": "g.csv", "time_offset_s": bad}}
        with pytest.raises(UserInputError, match=r"\[gnss\] time_offset_s.*" + text.replace("+", r"\+")):
            spec_from_dict(raw, "d.toml")


def test_a_mode_with_velocity_needs_velocity_data(drive):
    d, ds = drive
    raw = tomllib.loads(d.toml.read_text())
    raw["filter"]["modes"] = ["fix+vel+imu"]
    spec = spec_from_dict(raw, str(d.toml), d.toml.parent)
    ds2 = load.load(spec)
    ds2.velocity = None
    with pytest.raises(UserInputError, match=r"velocity_columns"):
        runner.prepare(ds2)


def test_scoring_defaults_scale_to_a_short_run():
    sc = scoring.settings({"outage_starts_s": "auto", "outage_length_s": "auto", "yaw_skip_s": "auto"},
                          np.array([0.5, 60.5]), np.array([0.0, 60.0]))
    assert sc["outage_length_s"] == pytest.approx(5.95) and sc["yaw_skip_s"] == pytest.approx(8.925)
    assert sc["outage_starts_s"][0] == pytest.approx(0.5 + 0.2 * 59.5)
    assert all(s + sc["outage_length_s"] <= 60.0 for s in sc["outage_starts_s"])
    long = scoring.settings({"outage_starts_s": [60.0], "outage_length_s": 30.0, "yaw_skip_s": "auto"},
                            np.array([0.0, 1000.0]), np.array([0.0, 1000.0]))
    assert long["outage_starts_s"] == [60.0] and long["yaw_skip_s"] == 60.0


def test_run_reports_latency_baselines_and_writes_outage_trajectories(drive, tmp_path):
    from leonav_runtime.dataset.evaluate import run_dataset
    d, _ = drive
    m = run_dataset(load_spec(d.toml), tmp_path)
    best = m["modes"]["fix+imu+nhc"]
    assert abs(best["fix_latency_s"]["value"] - LATENCY_S) < 3 * best["fix_latency_s"]["sigma"]
    # the hold-last-fix baseline lags by up to a fix interval: interpolating does better on a 10 Hz drive
    assert m["gps_alone_interpolated"]["rmse_horizontal_m"] < m["gps_alone"]["rmse_horizontal_m"]
    assert m["scoring"]["source"]["outage_starts_s"] == "auto" and len(m["scoring"]["outage_starts_s"]) == 5
    assert best["outage_files"] and all((tmp_path / f).stat().st_size > 0 for f in best["outage_files"])
    assert m["summary"]["horizontal_rmse_m"]["ratio_to_better_gps_alone"] < 1.0


CPET = Path(__file__).resolve().parents[1] / "leonav_runtime" / "dataset" / "descriptions" / "cpet_run3.toml"


def _cpet(shift_s: float, offset):
    raw = tomllib.loads(CPET.read_text())
    raw["gnss"]["time_offset_s"] = offset
    spec = spec_from_dict(raw, str(CPET), CPET.parent)
    if not spec.data_dir.is_dir():
        pytest.skip(f"CPET data not found at {spec.data_dir} (../shared/data)")
    ds = load.load(spec)
    ds.fixes = FixTable(ds.fixes.t + shift_s, ds.fixes.p_enu_m, ds.fixes.sigma_enu_m, ds.fixes.v_en_mps)
    prep = runner.prepare(ds)
    _, res, _, _ = runner.run_mode(prep, "fix+imu+nhc")
    return scoring.run_scores(res, prep.nav.layout, ds.reference, 60.0)[0]["rmse_horizontal_m"]


def test_cpet_with_fixes_shifted_by_a_known_latency_is_undone_by_the_key():
    """CPET's fixes tagged 1 s late (0.4 m at the rover's speed): `[gnss] time_offset_s = 1` gives
    back the unshifted run's figure; ignoring the shift costs."""
    base = _cpet(0.0, 0.0)
    assert base <= 0.62
    assert _cpet(1.0, 1.0) == pytest.approx(base, abs=0.01)
    assert _cpet(1.0, 0.0) > base + 0.03


def test_a_latency_beyond_a_second_is_warned_about(tmp_path):
    """An estimate beyond 1 s is more likely a wrong time base than a receiver: the run warns. The state
    is a first-order look-back (p - v dt): at 1.5 s in a 2.6 m/s^2 turn its 1/2 a dt^2 is 3 m, so such
    a latency is not estimable (measured: from a prior 1.5 +- 0.05 s it ends at 1.01 +- 0.004 s); a
    known large offset is given as a number (the tags are shifted exactly). Here the prior pins it."""
    from leonav_runtime.dataset.evaluate import run_dataset
    d = synthetic.write_drive(tmp_path / "d", synthetic.DriveConfig(fix_latency_s=1.5, modes=("fix+vel+imu+nhc",)))
    raw = tomllib.loads(d.toml.read_text())
    raw["gnss"] |= {"time_offset_prior_s": 1.5, "time_offset_sigma_s": 1e-4, "time_offset_rw": 0.0}
    raw["scoring"] = {"outage_starts_s": []}
    m = run_dataset(spec_from_dict(raw, str(d.toml), d.toml.parent), tmp_path / "out", files=False)
    lat = m["modes"]["fix+vel+imu+nhc"]["fix_latency_s"]
    assert abs(lat["value"] - 1.5) < 1e-3, lat
    assert any(n.startswith("WARNING: fix+vel+imu+nhc: estimated fix latency +1.50") for n in m["notes"])
    # the same offset given as a number: no state, no warning, the tags shifted
    raw["gnss"] = {k: v for k, v in raw["gnss"].items() if not k.startswith("time_offset")} | {"time_offset_s": 1.5}
    m = run_dataset(spec_from_dict(raw, str(d.toml), d.toml.parent), tmp_path / "out2", files=False)
    assert "fix_latency_s" not in m["modes"]["fix+vel+imu+nhc"] and not any("latency" in n for n in m["notes"])
    assert m["modes"]["fix+vel+imu+nhc"]["rmse_horizontal_m"] < 0.5
