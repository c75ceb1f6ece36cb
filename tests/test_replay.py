"""`leonav replay` on synthetic sessions written in `leonav record`'s exact byte formats.

Acceptance: a 12 s synthetic session (NMEA at 10 Hz, WitMotion at 10 Hz, 400 kS/s beacon
capture with 5 tones) replays end to end, and its RMSE per mode is within 20 % of the
same truth and noise run directly through the filter without bytes (differences: int16
IMU quantization, NMEA rounding, arrival-stamp time tagging). Plus encoders vs the
decoders, the IMU time fit, and bad sessions. Modes: fix+imu (position fixes),
leo-alpha+imu (Doppler-rate), fix+leo-alpha+imu. Also: the Doppler-rate carrier from the capture's
metadata, the averaged specific force and its noise in the Doppler-rate R, GGA fixes without
an altitude, a late first fix, and one decoding per comparison.
"""
from __future__ import annotations

import datetime as dt
import json
import math
import shutil

import numpy as np
import pytest

from leonav.hardware.gnss import nmea_write
from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.imu import witmotion_encode as wenc
from leonav.hardware.imu.witmotion import SampleGrouper, WitMotionParser
from leonav.hardware.records import GnssFix, NmeaSentence
from leonav.hardware.session import decode_session
from leonav_runtime import inputs as road, replay
from leonav_runtime.core import model
from leonav_runtime.core import navfuncs
from leonav_runtime.simulation import session_synth as ss
from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.profiles import WT901
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ

C_LIGHT = 299_792_458.0

SECONDS = 12.0


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    folder = tmp_path_factory.mktemp("session") / "s"
    return ss.write_synthetic_session(folder, ss.SynthSessionConfig(seconds=SECONDS, seed=1))


@pytest.fixture(scope="module")
def comparison(synth, tmp_path_factory):
    """compare_replay_direct, counting how often the session is decoded and its capture processed."""
    from leonav.hardware import session as hw_session
    from leonav_runtime.beacons import pipeline

    calls = {"decode_session": 0, "process_capture": 0}

    def counted(module, name):
        real = getattr(module, name)

        def wrapper(*a, **k):
            calls[name] += 1
            return real(*a, **k)
        return wrapper

    out = tmp_path_factory.mktemp("replay")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(hw_session, "decode_session", counted(hw_session, "decode_session"))
        mp.setattr(pipeline, "process_capture", counted(pipeline, "process_capture"))
        res = replay.compare_replay_direct(synth, out)
    return res | {"out": out, "calls": calls}


def test_comparison_decodes_the_session_once(comparison):
    assert comparison["calls"] == {"decode_session": 1, "process_capture": 1}


def test_replay_matches_direct_simulation_within_20_percent(comparison):
    rep = comparison["replay"]
    assert rep["reference"] == "truth.csv" and rep["skipped_modes"] == {}
    assert rep["beacons"]["counts"]["associated"] >= 5
    for mode, row in comparison["table"].items():
        for key, v in row.items():
            assert v["replay"] == pytest.approx(v["direct"], rel=0.20), (mode, key, v)
    m = rep["modes"]
    # sanity against the noise put in: 1.5/1.5/3 m fixes, consumer IMU, 5 Starlink satellites
    assert m["fix+imu"]["rmse_position_m"] < 2.0
    assert m["fix+leo-alpha+imu"]["rmse_position_m"] < 2.0
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
    for name in ("metrics.json", "report.html", "rmse_vs_time.csv", "rmse_vs_time.png", "trajectories.png", "trajectory.csv",
                 "replay_vs_direct.json", "beacons/doppler_rate_measurements.csv", "beacons/waterfall.png"):
        assert (folder / name).is_file(), name
    rows = (folder / "rmse_vs_time.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,mode,position_error_m")
    # geodetic trajectories as `leonav run` writes them, one set per mode; .pos readable as RTKLIB's
    from leonav_runtime.gnss import solution_io
    for mode in comparison["replay"]["modes"]:
        stem = folder / f"trajectory_{mode.replace('+', '_')}"
        assert all(stem.with_suffix(ext).is_file() for ext in (".csv", ".pos", ".kml", ".gpx")), mode
        pos = solution_io.read_pos(stem.with_suffix(".pos"))
        assert len(pos) == len(stem.with_suffix(".csv").read_text().splitlines()) - 1 > 0
    assert len(rows) - 1 == 3 * int(comparison["replay"]["modes"]["fix+imu"]["eval_points"])


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
    got_a = np.array([s.rpy_rad for s in samples])
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


@pytest.mark.parametrize("seed", range(4))
def test_regular_sample_times_do_not_invent_gaps_from_read_jitter(seed):
    """50 Hz samples read by a host with 0.5 ms + Exp(4 ms) latency (the synthetic sessions' default):
    single stretched spacings of 1.5 periods must not count as lost samples; the 3 real ones must."""
    rng = np.random.default_rng(seed)
    k = np.delete(np.arange(400), [100, 250, 251])
    stamps = np.maximum.accumulate(5.0 + 0.02 * k + 0.0005 + rng.exponential(0.004, k.size))
    t, idx, missing = replay.regular_sample_times(stamps)
    assert missing == 3
    assert np.mean(idx == k) > 0.95
    np.testing.assert_allclose(np.median(np.diff(t) / np.diff(idx)), 0.02, rtol=1e-3)


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


def test_empty_capture_and_missing_fixes_skip_modes_with_reasons(synth, tmp_path, capsys):
    folder = _copy(synth, tmp_path)
    (folder / "sdr.cu8").write_bytes(b"")
    m = replay.replay_session(folder, tmp_path / "out1")
    assert set(m["modes"]) == {"fix+imu"}
    assert "empty" in m["skipped_modes"]["leo-alpha+imu"]
    assert m["modes"]["fix+imu"]["rmse_position_m"] < 2.0
    # no GNSS at all: no time map (host clock used, noted), no position -> nothing runs
    for name in ("gnss.raw", "gnss.chunks.csv", "sdr.cu8", "sdr.sigmf-meta"):
        (folder / name).unlink()
    rc = leonav_main(["replay", str(folder), "--out", str(tmp_path / "out2")])
    assert rc == 2            # bad input: one line that says why no mode ran
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("leonav replay: error: ") and "no mode could run" in err[0], err
    m = json.loads((tmp_path / "out2" / "metrics.json").read_text())
    assert m["modes"] == {}
    assert m["skipped_modes"]["fix+imu"] == "no GNSS fix in gnss.raw"
    assert "no initial position" in m["skipped_modes"]["leo-alpha+imu"]
    assert any("host wall clock" in n for n in m["notes"])


def test_cli_replay_with_origin_and_bad_modes(synth, tmp_path, capsys):
    folder = _copy(synth, tmp_path, drop=("sdr.cu8", "sdr.sigmf-meta"))
    # the old name of the position-fix mode still works, with a note
    rc = leonav_main(["replay", str(folder), "--modes", "gps+imu", "--origin", str(synth.cfg.lat_deg),
                      str(synth.cfg.lon_deg), str(synth.cfg.alt_m), "--yaw-deg", "90", "--out", str(tmp_path / "o")])
    assert rc == 0
    text = capsys.readouterr().out
    assert "fix+imu" in text and "reference: truth.csv" in text
    assert "note: mode 'gps+imu' is now 'fix+imu'" in text
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["initialization"]["origin"] == "--origin" and m["initialization"]["yaw"] == "--yaw-deg"
    assert set(m["modes"]) == {"fix+imu"} and m["modes"]["fix+imu"]["rmse_position_m"] < 2.0
    assert leonav_main(["replay", str(folder), "--modes", "gps-only", "--out", str(tmp_path / "o2")]) == 2


# ------------------------------------------------------------------ carrier, Doppler-rate inputs


@pytest.fixture(scope="module")
def carrier_session(tmp_path_factory):
    """6 s at a 11.2 GHz carrier (not the default), 50 Hz IMU so the f_b average spans 5 samples."""
    cfg = ss.SynthSessionConfig(seconds=6.0, seed=4, f_c_hz=11.2e9, imu_rate_hz=50.0, imu_baud=115200,
                                n_satellites=4)
    return ss.write_synthetic_session(tmp_path_factory.mktemp("carrier") / "s", cfg)


@pytest.fixture(scope="module")
def carrier_inputs(carrier_session):
    opts = replay.ReplayOptions(gnss_latency_s=carrier_session.cfg.gnss_latency_s)
    return replay.decode_inputs(carrier_session.folder, opts, carrier_session.elements), opts


def test_carrier_comes_from_the_capture_metadata(carrier_session, carrier_inputs, tmp_path):
    inputs, opts = carrier_inputs
    L = navfuncs.NavFunctions().layout
    meta = json.loads((carrier_session.folder / "sdr.sigmf-meta").read_text())
    assert meta["global"]["leonav:rf_center_hz"] == pytest.approx(11.2e9)
    assert inputs.f_c_hz == pytest.approx(11.2e9) and inputs.params[L.P_F_C_HZ] == pytest.approx(11.2e9)
    assert inputs.beacons["counts"]["associated"] >= 3 and inputs.counts["doppler_rate_records"] >= 8
    assert inputs.counts["imu_missing_samples"] == 0       # 50 Hz with 4 ms read jitter: no invented gaps
    m = replay.replay_session(carrier_session.folder, tmp_path, opts, inputs=inputs)
    assert m["f_c_hz"] == pytest.approx(11.2e9) and "capture metadata" in m["f_c_source"]
    assert not any("carrier" in n for n in m["notes"])
    # with the 11.325 GHz model the 1.1 % scale error on rates of 100s of Hz/s would be gated
    doppler_rate = m["modes"]["leo-alpha+imu"]["per_observable"]["doppler_rate"]
    assert doppler_rate["gated"] == 0 and doppler_rate["failed"] == 0 and doppler_rate["nis_mean"] < 2.0
    assert m["modes"]["leo-alpha+imu"]["rmse_position_m"] < 15.0


def test_carrier_falls_back_to_the_starlink_beacon_with_a_note(carrier_session, tmp_path):
    folder = _copy(carrier_session, tmp_path)
    meta_path = folder / "sdr.sigmf-meta"
    meta = json.loads(meta_path.read_text())
    meta["global"]["leonav:lnb_lo_hz"] = 0.0        # no LNB: the RF centre is the 1.45 GHz IF
    meta["global"]["leonav:rf_center_hz"] = meta["captures"][0]["core:frequency"]
    meta_path.write_text(json.dumps(meta))
    m = replay.replay_session(folder, tmp_path / "out", replay.ReplayOptions(modes=("fix+imu",)))
    saved = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert saved["f_c_hz"] == STARLINK_BEACON_HZ and saved["f_c_source"].startswith("default")
    assert any("carrier" in n and "outside the Ku downlink band" in n for n in saved["notes"])
    assert m["modes"]["fix+imu"]["rmse_position_m"] < 2.5


def test_doppler_rate_aux_is_the_averaged_specific_force_and_r_has_its_noise(carrier_inputs):
    inputs, opts = carrier_inputs
    L = navfuncs.NavFunctions().layout
    imu, rec = inputs.imu, inputs.records["doppler_rate"]
    assert rec.size == inputs.doppler_rate.t.size and np.allclose(rec["t"], inputs.doppler_rate.t)
    n_avg = round(road.F_B_AVERAGE_S * 50.0)
    assert n_avg == 5
    expect, single = [], []
    for t in rec["t"]:
        j = int(np.flatnonzero(imu.t <= t + 1e-9)[-1])        # latest sample at or before the epoch
        sl = slice(max(0, j - n_avg + 1), j + 1)
        expect.append((imu.f_b_mps2[sl] * imu.dt[sl, None]).sum(axis=0) / imu.dt[sl].sum())
        single.append(imu.f_b_mps2[j])
    f_b = rec["aux"][:, L.AUX_F_B_SLICE]
    np.testing.assert_allclose(f_b, expect, atol=1e-9)
    assert np.abs(f_b - np.array(single)).max() > 5e-3      # one raw sample would differ by its noise
    vrw = inputs.init["imu_profile"]["vrw"]
    sigma = np.maximum(inputs.doppler_rate.sigma, opts.doppler_rate_sigma_floor_hz_s)
    r_expect = sigma**2 + (inputs.f_c_hz / C_LIGHT) ** 2 * vrw**2 / road.F_B_AVERAGE_S
    np.testing.assert_allclose(rec["R"], r_expect, rtol=2e-3)
    assert np.all(rec["R"] > sigma**2 * 1.05)


# ------------------------------------------------------------------ GNSS start: no altitude, late first fix


@pytest.fixture(scope="module")
def degraded(tmp_path_factory):
    """GNSS silent for 2 s, then 1 s of GGA without altitude, then normal fixes; no SDR."""
    cfg = ss.SynthSessionConfig(seconds=6.0, seed=5, sdr=False, gnss_start_s=2.0, gga_no_altitude_s=3.0)
    synth = ss.write_synthetic_session(tmp_path_factory.mktemp("degraded") / "s", cfg)
    out = tmp_path_factory.mktemp("degraded_out")
    m = replay.replay_session(synth.folder, out, replay.ReplayOptions(gnss_latency_s=cfg.gnss_latency_s))
    return synth, m, out


def test_fixes_without_altitude_are_skipped_and_counted(degraded):
    synth, m, _ = degraded
    no_alt = int(np.sum(synth.fix_t < synth.cfg.gga_no_altitude_s - 1e-9))
    assert no_alt == 10
    c = m["counts"]
    assert c["gnss_fixes"] == synth.fix_t.size and c["gnss_fixes_unusable"] == no_alt
    lat, lon, h = m["initialization"]["origin_deg"]
    assert all(math.isfinite(v) for v in (lat, lon, h))
    assert abs(lat - synth.cfg.lat_deg) < 1e-4 and abs(lon - synth.cfg.lon_deg) < 1e-4
    assert abs(h - synth.cfg.alt_m) < 15.0
    assert any("without a finite latitude, longitude and height" in n for n in m["notes"])
    assert m["modes"]["fix+imu"]["rmse_position_m"] < 2.5
    assert m["modes"]["fix+imu"]["records"]["failed"] == 0


def test_late_first_fix_moves_the_filter_start(degraded):
    synth, m, out = degraded
    init, c = m["initialization"], m["counts"]
    # replay t = 0 is truth 0.1 s; the first usable fix is at truth 3.0 s
    t_fix = synth.cfg.gga_no_altitude_s - 1.0 / synth.cfg.imu_rate_hz
    assert init["start_s"] == pytest.approx(t_fix, abs=0.02)
    assert "initializing fix" in init["start"]
    n_imu = synth.u_meas.shape[0] - 1                      # the first sample only opens the time axis
    assert c["imu_records_before_start"] + c["imu_records"] == n_imu
    assert c["imu_records_before_start"] in (28, 29)
    rows = (out / "trajectory.csv").read_text().splitlines()[1:]
    assert min(float(r.split(",")[0]) for r in rows) > init["start_s"]


def _moving_tables(t_first_fix: float):
    """10 Hz IMU for 3 s and 10 Hz fixes from t_first_fix of a receiver going East at 10 m/s."""
    n = 30
    t = 0.1 * np.arange(1, n + 1)
    imu = road.ImuTable.from_rates(t, np.full(n, 0.1), np.zeros((n, 3)), np.tile([0.0, 0.0, 9.80], (n, 1)),
                                   np.tile([0.0, 0.0, math.pi / 2], (n, 1)))
    tf = np.arange(t_first_fix, 3.0 + 1e-9, 0.1)
    enu = np.column_stack([10.0 * tf, np.zeros_like(tf), np.zeros_like(tf)])
    fixes = road.FixTable(tf, enu, np.tile([1.5, 1.5, 3.0], (tf.size, 1)), np.tile([10.0, 0.0], (tf.size, 1)))
    return imu, fixes


@pytest.mark.parametrize("t_first_fix, start, dropped", [(0.03, 0.0, 0), (1.53, 1.53, 15)])
def test_assemble_starts_at_a_late_first_fix(t_first_fix, start, dropped):
    nav = navfuncs.NavFunctions()
    L = nav.layout
    imu, fixes = _moving_tables(t_first_fix)
    params = road.filter_params((0.75, -1.35, 170.0), WT901, STARLINK_BEACON_HZ)
    inp = road.assemble(imu, params, road.FirstFixPrior(WT901), fixes=fixes, nav=nav)
    rec = inp.records["imu"]
    assert inp.init["start_s"] == pytest.approx(start)
    assert inp.counts["imu_records_before_start"] == dropped and rec.size == 30 - dropped
    assert rec["t"][0] - rec["dt"][0] == pytest.approx(start)         # first interval begins at the start
    np.testing.assert_allclose(rec["dt"][1:], 0.1)
    np.testing.assert_allclose(rec["u"][0], [0, 0, 0, 0, 0, 9.80 * rec["dt"][0]])   # cut: mean rates kept
    assert inp.x0[L.X_P_ENU] == pytest.approx(10.0 * t_first_fix)     # the fix's own position and velocity
    assert inp.x0[L.X_V_ENU] == pytest.approx(10.0)
    assert inp.records["fix"].size == 3 * (fixes.t.size - 1) and np.all(inp.records["fix"]["t"] > start)
    # P0: fix sigma, 0.5 m/s, 0.5/0.5/5 deg, the profile's bias sigmas, clock/LO constants
    sig = np.sqrt(np.diag(inp.P0))
    np.testing.assert_allclose(sig[L.DX_DP_SLICE], [1.5, 1.5, 3.0])
    np.testing.assert_allclose(sig[L.DX_DTHETA_SLICE], np.radians([0.5, 0.5, 5.0]))
    np.testing.assert_allclose(sig[L.DX_DB_A_SLICE], WT901.acc_bias_sigma)
    assert sig[L.DX_DB_LO] == model.state_block("b_lo").prior["value"] and np.all(np.isfinite(inp.params))


def test_synthetic_imu_noise_is_the_simulators_draw(synth):
    """The session's biases are `simulate.bias_walks` of its seed, as in the Monte Carlo trials."""
    from leonav_runtime.simulation import simulate

    L = navfuncs.NavFunctions().layout
    n, dt_s = synth.u_meas.shape[0], 1.0 / synth.cfg.imu_rate_hz
    b_a, b_g = simulate.bias_walks(np.random.default_rng(synth.cfg.seed), WT901, n, dt_s)
    np.testing.assert_array_equal(synth.x_true[:, L.X_B_A_SLICE], b_a)
    np.testing.assert_array_equal(synth.x_true[:, L.X_B_G_SLICE], b_g)


def test_replay_reference_file_scores_like_the_truth(synth, tmp_path, capsys):
    """`leonav replay --reference FILE` (dataset/evaluate.score_reference_file): the session's own
    truth.csv given as a lat/lon/h CSV scores the run as the replay's truth scoring does."""
    import json

    from leonav_runtime import cli

    truth = synth.folder / "truth.csv"
    header = truth.read_text().splitlines()[0].split(",")
    cols = ",".join(str(header.index(k)) for k in ("utc_unix_s", "lat_deg", "lon_deg", "h_m"))
    out = tmp_path / "out"
    status = cli.main(["replay", str(synth.folder), "--modes", "fix+imu", "--reference", str(truth),
                       "--reference-columns", cols, "--out", str(out)])
    assert status == 0 and "against" in capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    own, ref = m["modes"]["fix+imu"], m["reference_file"]["modes"]["fix+imu"]
    assert m["reference_file"]["epochs"] > 100
    assert ref["rmse_3d_m"] == pytest.approx(own["rmse_position_m"], rel=0.25)
    assert (out / "errors_reference.csv").is_file() and (out / "error_cdf_reference.png").stat().st_size > 1000


def test_replay_estimates_the_fix_latency_on_request(synth, tmp_path):
    """`--gnss-latency estimate`: the latency is a filter state reported with its sigma. This session
    is static: a latency moves nothing at rest, so it stays near its prior (0 +- 0.3 s; the estimated
    velocity's noise informs it a little) and the run is as with the latency held at 0; a bad value is
    one line naming the option."""
    folder = _copy(synth, tmp_path, drop=("sdr.cu8", "sdr.sigmf-meta"))
    out = {}
    for latency in ("0", "estimate"):
        assert leonav_main(["replay", str(folder), "--modes", "fix+imu", "--gnss-latency", latency,
                            "--out", str(tmp_path / latency)]) == 0
        out[latency] = json.loads((tmp_path / latency / "metrics.json").read_text())
    est = out["estimate"]["modes"]["fix+imu"]["fix_latency_s"]
    assert est["sigma"] > 0.8 * 0.3 and abs(est["value"]) < est["sigma"], est   # barely informed
    assert "fix_latency_s" not in out["0"]["modes"]["fix+imu"]
    assert out["estimate"]["modes"]["fix+imu"]["rmse_position_m"] == pytest.approx(
        out["0"]["modes"]["fix+imu"]["rmse_position_m"], rel=0.05)
    assert leonav_main(["replay", str(folder), "--gnss-latency", "later", "--out", str(tmp_path / "bad")]) == 2
