"""The one road into the filter (`leonav_runtime.inputs`): tables -> records, x0, P0, p.

- The simulator's trial records are the road's output for the trial's tables.
- One synthetic session, replayed from its bytes and run directly from the floats that
  went into it, gives the same records through the road: the same streams, record
  counts, kinds and satellites, with times, increments and fixes equal to within the time
  map, the int16 IMU quantization and the NMEA rounding, the same Doppler-rate values.
- Bad tables are rejected with one clear error naming the table and the field.
"""
from __future__ import annotations

import copy
import datetime as dt
import math

import numpy as np
import pytest

from leonav.hardware.imu import witmotion_encode as wenc
from leonav_runtime import inputs as road
from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime import replay
from leonav_runtime.core import navfuncs
from leonav_runtime.simulation import session_synth as ss, simulate
from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
from leonav_runtime.gen.profiles import WT901
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

ORIGIN = (0.75, -1.35, 170.0)


@pytest.fixture(scope="module")
def nav():
    return navfuncs.NavFunctions()


def test_simulated_trial_records_are_the_roads_output(monkeypatch):
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 3.0
    raw["starlink"]["counts"] = [5]
    scn = scenario_from_dict(raw, source="<inputs test>")
    setup, nav = mc.setup_for(scn)
    seen = []
    real = simulate.assemble

    def spy(*args, **kwargs):
        seen.append((args, kwargs))
        return real(*args, **kwargs)

    monkeypatch.setattr(simulate, "assemble", spy)
    trial = simulate.trial_records(setup, "gps+leo-alpha+imu", 5, mc.trial_rng(scn.seed, 0), nav)
    (imu, params, prior), kwargs = seen[0]
    assert isinstance(imu, road.ImuTable) and isinstance(prior, road.Prior)
    assert [type(t) for t in kwargs["satellites"]] == [road.PseudorangeTable, road.DopplerRateTable]
    again = real(imu, params, prior, satellites=kwargs["satellites"], nav=nav).merged()
    assert again.tobytes() == trial.records.tobytes()
    assert np.array_equal(prior.x0, trial.x0)


@pytest.fixture(scope="module")
def one_session(tmp_path_factory, nav):
    """A 5 s synthetic session, replayed and run directly (no bytes), both through the road."""
    cfg = ss.SynthSessionConfig(seconds=5.0, seed=3, sdr_rate_hz=200e3)
    synth = ss.write_synthetic_session(tmp_path_factory.mktemp("road") / "s", cfg)
    options = replay.ReplayOptions(gnss_latency_s=cfg.gnss_latency_s)
    replayed = replay.decode_inputs(synth.folder, options, synth.elements, None, nav)
    direct = replay.direct_inputs(synth, replayed, options, nav)
    return synth, replayed, direct


def test_replay_and_simulation_of_one_session_give_the_same_records(one_session):
    synth, rep, sim = one_session
    assert set(rep.records) == set(sim.records) == {"imu", "fix", "doppler_rate"}
    # the replay's axis starts at the first IMU sample; the direct run's at the truth's t = 0
    shift = (rep.epoch_utc - synth.cfg.epoch_utc).total_seconds()
    for stream in ("imu", "fix", "doppler_rate"):
        a, b = rep.records[stream], sim.records[stream]
        assert a.size == b.size > 0, stream
        np.testing.assert_array_equal(a["kind"], b["kind"])
        np.testing.assert_array_equal(a["sat_id"], b["sat_id"])
        np.testing.assert_allclose(a["t"] + shift, b["t"], atol=0.005, err_msg=stream)
    imu_a, imu_b = rep.records["imu"], sim.records["imu"]
    np.testing.assert_allclose(imu_a["dt"], imu_b["dt"], atol=1e-4)
    dt = np.broadcast_to(imu_b["dt"][:, None], (imu_b.size, 3))
    L = navfuncs.NavFunctions().layout
    du = np.abs(imu_a["u"] - imu_b["u"])    # int16 quantization of the rates, plus dt * rate of the fitted times
    np.testing.assert_array_less(du[:, L.U_DTHETA_B_SLICE], wenc.GYRO_LSB_RADPS / 2 * dt + 1e-7)
    np.testing.assert_array_less(du[:, L.U_DVEL_B_SLICE], wenc.ACC_LSB_MPS2 / 2 * dt + 1e-4)
    fix_a, fix_b = rep.records["fix"], sim.records["fix"]
    np.testing.assert_allclose(fix_a["z"], fix_b["z"], atol=0.06)        # NMEA: 1e-5 arc-min, 0.1 m height
    np.testing.assert_array_equal(fix_a["R"], fix_b["R"])                # GST sigmas = the simulated ones
    dr_a, dr_b = rep.records["doppler_rate"], sim.records["doppler_rate"]
    np.testing.assert_array_equal(dr_a["z"], dr_b["z"])                  # the same beacon measurements
    np.testing.assert_allclose(dr_a["R"], dr_b["R"], rtol=0.02)          # + quantization noise in the replay
    np.testing.assert_allclose(dr_a["aux"][:, L.AUX_R_S_ECEF_SLICE], dr_b["aux"][:, L.AUX_R_S_ECEF_SLICE], atol=60)
    np.testing.assert_allclose(dr_a["aux"][:, L.AUX_F_B_SLICE], dr_b["aux"][:, L.AUX_F_B_SLICE], atol=0.01)
    np.testing.assert_array_equal(rep.P0, sim.P0)
    np.testing.assert_allclose(rep.x0[L.X_P_ENU_SLICE], sim.x0[L.X_P_ENU_SLICE], atol=0.06)


# ------------------------------------------------------------------ bad tables


def _tables(n: int = 20):
    t = 0.1 * np.arange(1, n + 1)
    imu = road.ImuTable.from_rates(t, np.full(n, 0.1), np.zeros((n, 3)), np.tile([0.0, 0.0, 9.8], (n, 1)),
                                   np.tile([0.0, 0.0, math.pi / 2], (n, 1)))
    fixes = road.FixTable(t - 0.1, np.zeros((n, 3)), np.full((n, 3), 1.5), np.zeros((n, 2)))
    sat = np.tile([2.0e7, 0, 0, 0, 3.9e3, 0, -0.6, 0, 0], (n, 1))
    rate = road.DopplerRateTable(t.copy(), np.full(n, 44713), np.zeros(n), np.full(n, 1.2), sat)
    return imu, fixes, rate


def _assemble(imu, fixes, rate, nav, prior=None, params=None):
    params = road.filter_params(ORIGIN, WT901, STARLINK_BEACON_HZ) if params is None else params
    return road.assemble(imu, params, prior or road.FirstFixPrior(WT901), fixes=fixes, satellites=[rate], nav=nav)


def test_good_tables_assemble(nav):
    inp = _assemble(*_tables(), nav)
    assert inp.counts["imu_records"] == 20 and inp.counts["fix_epochs"] == 19
    assert inp.counts["doppler_rate_records"] == 20
    assert inp.merged(["fix"]).size == 20 + 3 * 19 and inp.merged().size == 20 + 3 * 19 + 20
    assert inp.f_c_hz == STARLINK_BEACON_HZ


def _break(what: str):
    imu, fixes, rate = _tables()
    if what == "imu dt":
        imu.dt[3] = -0.1
    elif what == "imu u":
        imu.u[5, 4] = np.nan
    elif what == "imu t":
        imu.t[7] = imu.t[6]
    elif what == "imu rpy":
        imu.rpy_rad = imu.rpy_rad[:-1]
    elif what == "fix sigma":
        fixes.sigma_enu_m[2, 1] = 0.0
    elif what == "fix p":
        fixes.p_enu_m[4, 0] = np.inf
    elif what == "rate z":
        rate.z[9] = np.nan
    elif what == "rate sigma":
        rate.sigma = -1.0
    elif what == "rate states":
        rate.sat_ecef = rate.sat_ecef[:, :6]
    return imu, fixes, rate


@pytest.mark.parametrize("what, message", [
    ("imu dt", "IMU table: dt: value <= 0 in row 3: expected positive numbers (s)"),
    ("imu u", "IMU table: u: non-finite value in row 5: expected finite numbers (rad, m/s)"),
    ("imu t", "IMU table: t: row 7 is not later than the row before: expected increasing times"),
    ("imu rpy", "IMU table: rpy_rad: shape (19, 3): expected shape (20, 3)"),
    ("fix sigma", "GNSS fix table: sigma_enu_m: value <= 0 in row 2: expected positive numbers (m)"),
    ("fix p", "GNSS fix table: p_enu_m: non-finite value in row 4: expected finite numbers (m)"),
    ("rate z", "doppler_rate table: z: non-finite value in row 9: expected finite numbers (Hz/s)"),
    ("rate sigma", "doppler_rate table: sigma: value <= 0 in row 0: expected positive numbers (Hz/s)"),
    ("rate states", "doppler_rate table: sat_ecef: shape (20, 6): expected shape (20, 9)"),
])
def test_assemble_rejects_bad_tables_naming_the_field(what, message, nav):
    with pytest.raises(UserInputError) as exc:
        _assemble(*_break(what), nav)
    assert str(exc.value) == message


def test_assemble_rejects_two_tables_of_one_kind_and_bad_params(nav):
    imu, fixes, rate = _tables()
    params = road.filter_params(ORIGIN, WT901, STARLINK_BEACON_HZ)
    with pytest.raises(UserInputError, match="at most one table per observable kind"):
        road.assemble(imu, params, road.FirstFixPrior(WT901), satellites=[rate, rate], nav=nav)
    with pytest.raises(UserInputError, match=r"params: shape \(3,\)"):
        _assemble(imu, fixes, rate, nav, params=np.zeros(3))
    with pytest.raises(UserInputError, match="filter parameters: non-finite"):
        road.filter_params((math.nan, 0.0, 0.0), WT901, STARLINK_BEACON_HZ)
    with pytest.raises(UserInputError, match="ofdm_range_diff table: ref_ecef: missing"):
        road.OfdmRangeDiffTable(rate.t, rate.sat_id, rate.z, 3.0, rate.sat_ecef).check()
    with pytest.raises(UserInputError, match="streams: 'alpha'"):
        _assemble(imu, fixes, rate, nav).merged(["alpha"])


def test_a_bad_table_is_one_line_from_the_cli(monkeypatch, tmp_path, capsys):
    """A source handing a bad table to the road ends the command with one line, no traceback."""
    def bad_session(*args, **kwargs):
        imu, fixes, rate = _break("rate z")
        return _assemble(imu, fixes, rate, navfuncs.NavFunctions())

    monkeypatch.setattr(replay.run, "decode_inputs", bad_session)
    rc = leonav_main(["replay", str(tmp_path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err == ["leonav replay: error: doppler_rate table: z: non-finite value in row 9: "
                               "expected finite numbers (Hz/s)"]


def test_imu_table_cut_keeps_the_mean_rates():
    imu, _, _ = _tables()
    cut, dropped = imu.from_time(0.25)
    assert dropped == 2 and cut.t[0] == pytest.approx(0.3) and cut.dt[0] == pytest.approx(0.05)
    assert cut.dvel_b[0, 2] == pytest.approx(9.8 * 0.05) and cut.f_b_mps2[0, 2] == 9.8
    bare = road.ImuTable.from_increments(imu.t, imu.dt, imu.dtheta_b, imu.dvel_b)
    cut2, _ = bare.from_time(0.25)
    np.testing.assert_allclose(cut2.u, cut.u, rtol=1e-12)
    assert cut2.rpy_rad is None and bare.f_b_mps2[0, 2] == pytest.approx(9.8)


def test_prior_without_a_fix_starts_at_the_origin(nav):
    imu, _, rate = _tables()
    notes = []
    inp = road.assemble(imu, road.filter_params(ORIGIN, WT901, STARLINK_BEACON_HZ), road.FirstFixPrior(WT901),
                        satellites=[rate], nav=nav, notes=notes, epoch_utc=dt.datetime(2026, 2, 23),
                        origin=ORIGIN)
    assert inp.init["position"] == "origin (no fix)" and np.all(inp.x0[nav.layout.X_P_ENU_SLICE] == 0)
    assert np.sqrt(inp.P0[0, 0]) == 10.0 and inp.records["fix"].size == 0 and inp.origin == ORIGIN
