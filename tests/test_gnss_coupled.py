"""Tightly coupled GNSS: `pseudorange+imu` and `pseudorange+leo-alpha+imu` in the Python API
and in `leonav replay`, through the one generated C filter.

Real data: the GEONET 0759 / 3040 RINEX files (2005-04-02, GPS, 30-s epochs) with a synthetic
static WT901 IMU at the station (gravity and Earth rate, the WT901 biases and noise); as a
recorded session their L1 C/A pseudoranges are RXM-RAWX frames and their broadcast
ephemerides and Klobuchar coefficients RXM-SFRBX LNAV subframes (tests/gnss_session.py).
Reference: rnx2rtkp's single-point positions with the same atmosphere models
(tests/data/rtklib/*.brdc_saas.pos, commands in its README). What a static WT901 adds between
30-s epochs is little (its velocity random walk and bias leave the position free within
tens of metres), so the filter's positions are single-point-like: they are compared epoch by
epoch with a bound of the single-point scatter, and their mean with a tight one.

Simulated: a 10-s session at the 0759 site with pseudoranges and Doppler made by the
generated models at the true position and clock plus white noise of the error model's sigma
(1 Hz), NMEA fixes and a Starlink beacon capture; scored against truth.csv.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime import replay
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gnss import coupled, gnss_ekf, solution_io
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from leonav_runtime.gnss.signals import klobuchar_coefficients, primary_rows
from leonav_runtime.inputs import ImuTable
from leonav_runtime.core.navfuncs import NavFunctions
from leonav_runtime.replay.timebase import filter_profile
from leonav_runtime.simulation.session_synth import SynthSessionConfig, simulate_sensors
from tests.conftest import shared_file
from tests.gnss_session import simulated_pseudoranges, write_rawx_session

FIXTURES = Path(__file__).parent / "data" / "rtklib"
_NAV: list[NavFunctions] = []


def nav_funcs() -> NavFunctions:
    if not _NAV:
        _NAV.append(NavFunctions())
    return _NAV[0]


def geonet(station: str):
    obs = read_rinex_obs(shared_file(f"gnss_rinex/{station}0920.05o"))
    nf = read_rinex_nav(shared_file(f"gnss_rinex/{station}0920.05n"))
    return obs, nf.ephemerides, klobuchar_coefficients(nf.iono)


def rtklib_positions(station: str, t_gps_s: np.ndarray) -> np.ndarray:
    ref = {round(r.t_gps_s, 1): r.r_ecef_m for r in solution_io.read_pos(FIXTURES / f"{station}0920.05.brdc_saas.pos")}
    return np.array([ref[round(float(t), 1)] for t in t_gps_s])


def epoch_positions(recs, res, t_run: np.ndarray, params, nav) -> np.ndarray:
    """Receiver ECEF after the last record at each epoch time (its updates applied)."""
    last = np.searchsorted(recs["t"], t_run + 1e-6, side="right") - 1
    return coupled.positions_ecef(res.x[last], params, nav)


def pr_stats(recs, res) -> dict:
    return coupled.nis_summary(recs, res, L.MEAS_GNSS_PSEUDORANGE)


def check_against_rtklib(r: np.ndarray, ref: np.ndarray, label: str) -> dict:
    d = np.linalg.norm(r - ref, axis=1)
    out = {"median_m": float(np.median(d)), "max_m": float(d.max()),
           "mean_offset_m": float(np.linalg.norm(r.mean(axis=0) - ref.mean(axis=0))),
           "scatter_filter_m": gnss_ekf.scatter_rms_m(r), "scatter_rtklib_m": gnss_ekf.scatter_rms_m(ref)}
    print(f"\n{label}: {out}")
    # epoch by epoch: within the single-point scatter (0.4-1.1 m RMS here, peaks 3-4 m) ...
    assert out["median_m"] <= 1.5 and out["max_m"] <= 6.0, out
    # ... and on average the same place (measured 0.23 m: 3040, the hour; 0.25 m: 0759, 10 min)
    assert out["mean_offset_m"] <= 0.5, out
    return out


def static_imu(obs_epochs: np.ndarray, site_ecef, epoch_utc, rate_hz: float = 2.0) -> ImuTable:
    from leonav_runtime.orbits import geometry

    lat, lon, h = (float(v) for v in geometry.ecef_to_geodetic(np.asarray(site_ecef, float)))
    cfg = SynthSessionConfig(seconds=float(obs_epochs[-1] - obs_epochs[0]) + 3.0, epoch_utc=epoch_utc,
                             lat_deg=np.degrees(lat), lon_deg=np.degrees(lon), alt_m=h, imu_rate_hz=rate_hz,
                             gnss_rate_hz=rate_hz, sdr=False)
    sim = simulate_sensors(cfg, nav_funcs())
    u, dt = sim["u_meas"], 1.0 / rate_hz
    return ImuTable.from_increments(sim["t_imu"][1:], np.full(u.shape[0], dt), u[:, L.U_DTHETA_B_SLICE],
                                    u[:, L.U_DVEL_B_SLICE], sim["ahrs_rpy_rad"])


@pytest.mark.slow
def test_python_api_pseudorange_imu_on_geonet_hour_agrees_with_rnx2rtkp():
    """3040, the whole hour (120 epochs), Klobuchar + Saastamoinen, 10 deg, through the API."""
    import datetime as dt

    from leonav_runtime.gnss import time as gtime

    nav = nav_funcs()
    obs, eph, klob = geonet("3040")
    spp = coupled.single_point(obs, eph, klob, elevation_mask_deg=10.0, systems="G", nav=nav)
    epoch_utc = gtime.gps_seconds_to_utc(float(spp.t_gps_s[0]) - 1.0).replace(tzinfo=dt.timezone.utc)
    imu = static_imu(spp.t_gps_s, obs.approx_position_ecef_m, epoch_utc)
    inputs = coupled.coupled_inputs(imu, spp, epoch_utc, filter_profile(0.5), nav=nav)
    assert inputs.counts["gnss_pseudorange_records"] == 819 and inputs.counts["gnss_range_rate_records"] == 0
    recs, res = coupled.run_mode(inputs, "pseudorange+imu", nav=nav)
    stats = pr_stats(recs, res)
    print(stats)
    assert res.n_failed == 0 and stats["gated"] <= 0.01 * stats["applied"]
    # the filters' R is conservative on these data (its 0.5 x Klobuchar term dominates): mean
    # NIS 0.40 (a model that were right would give 1; one too tight > 1)
    assert 0.15 <= stats["mean_nis"] <= 1.0
    t_run = spp.t_gps_s - coupled.gps_epoch(epoch_utc)
    r = epoch_positions(recs, res, t_run, inputs.params, nav)
    check_against_rtklib(r, rtklib_positions("3040", spp.t_gps_s), "3040 API pseudorange+imu vs rnx2rtkp")


@pytest.fixture(scope="module")
def geonet_session(tmp_path_factory):
    """0759, first 10 minutes (20 epochs: the 600-s tag is 600.001 s) as a u-blox session without NMEA."""
    obs, eph, klob = geonet("0759")
    rows, _ = primary_rows(obs, "G")
    o = obs.take(rows)
    o = o.take(np.flatnonzero((o.t_gps_s <= o.t_gps_s[0] + 600.0) & (o.signal == "1C")
                              & np.isfinite(o.pseudorange_m)))
    folder = tmp_path_factory.mktemp("geonet_session") / "s"
    synth, epoch_utc = write_rawx_session(folder, o.t_gps_s, o.prn, o.pseudorange_m, o.doppler_hz, o.cn0_dbhz,
                                          eph.data, obs.approx_position_ecef_m, klobuchar=klob, nav=nav_funcs())
    return folder, np.unique(o.t_gps_s), int((eph.data["system"] == "G").sum())


def test_replay_pseudorange_imu_of_a_ubx_session_agrees_with_rnx2rtkp(geonet_session, tmp_path):
    folder, epochs, n_eph = geonet_session
    nav = nav_funcs()
    options = replay.ReplayOptions(modes=("pseudorange+imu", "fix+imu"), use_truth=False)
    inputs = replay.decode_inputs(folder, options, None, tmp_path, nav)
    raw = inputs.raw_gnss
    # everything came from the session's bytes: 20 RAWX epochs, every ephemerides and the
    # Klobuchar page from SFRBX, the start from the single-point solution (no NMEA)
    assert raw["rawx_epochs"] == epochs.size == 20 and raw["ephemerides_from_sfrbx"] == n_eph
    assert raw["klobuchar"] == "SFRBX page 18"
    assert raw["epochs_solved"] == 20 and inputs.skipped == {}
    assert inputs.init["origin"].startswith("first single-point solution")
    metrics = replay.replay_session(folder, tmp_path, options, nav=nav, inputs=inputs)
    m = metrics["modes"]["pseudorange+imu"]
    assert m["records"]["failed"] == 0 and m["records"]["gated"] == 0 and m["records"]["applied"] > 100
    assert (tmp_path / "metrics.json").is_file() and metrics["raw_gnss"]["rawx_rows"] > 100
    runs = replay.run_modes(inputs, ("pseudorange+imu",), options.gate_nis, nav)
    recs, res, _ = runs["pseudorange+imu"]
    assert 0.15 <= pr_stats(recs, res)["mean_nis"] <= 1.0
    t_run = epochs - coupled.gps_epoch(inputs.epoch_utc)
    r = epoch_positions(recs, res, t_run, inputs.params, nav)
    check_against_rtklib(r, rtklib_positions("0759", epochs), "0759 replay pseudorange+imu vs rnx2rtkp")


def test_replay_names_why_pseudorange_modes_cannot_run(geonet_session, tmp_path, capsys):
    """Without SFRBX ephemerides nor --nav: skipped with the reason; with --nav: they run."""
    folder, _, _ = geonet_session
    bare = tmp_path / "bare"
    shutil.copytree(folder, bare)
    from leonav.hardware.gnss.reader import GnssSplitter
    from leonav.hardware.gnss.ubx import build_frame

    # the same session with the SFRBX frames zeroed in gnss.raw (same length: the chunk index holds)
    data = (bare / "gnss.raw").read_bytes()
    splitter = GnssSplitter()
    out, pos, n = bytearray(data), 0, 0
    for kind, item, _t in splitter.feed(data, 0.0):
        if kind == "ubx" and (item.msg_class, item.msg_id) == (0x02, 0x13):
            raw = build_frame(item.msg_class, item.msg_id, item.payload)
            k = data.find(raw, pos)
            out[k:k + len(raw)] = bytes(len(raw))
            pos, n = k + len(raw), n + 1
    assert n > 100
    (bare / "gnss.raw").write_bytes(bytes(out))
    options = replay.ReplayOptions(modes=("pseudorange+imu",), use_truth=False, origin_deg=(35.16, 139.61, 75.0))
    m = replay.replay_session(bare, tmp_path / "o1", options, nav=nav_funcs())
    assert "no broadcast ephemeris" in m["skipped_modes"]["pseudorange+imu"] and "--nav" in \
        m["skipped_modes"]["pseudorange+imu"]
    # through the command line: --nav gives the ephemerides and the Klobuchar coefficients
    import json

    from leonav_runtime.cli import main as leonav_main

    nav_file = str(shared_file("gnss_rinex/07590920.05n"))
    assert leonav_main(["replay", str(bare), "--modes", "pseudorange+imu", "--nav", nav_file, "--no-truth",
                        "--out", str(tmp_path / "o2")]) == 0
    assert "pseudorange+imu" in capsys.readouterr().out
    m = json.loads((tmp_path / "o2" / "metrics.json").read_text())
    assert m["skipped_modes"] == {} and m["raw_gnss"]["klobuchar"] == "RINEX header"
    assert m["modes"]["pseudorange+imu"]["records"]["gated"] == 0
    assert leonav_main(["replay", str(bare), "--modes", "pseudorange+imu", "--elevation-mask", "95",
                        "--out", str(tmp_path / "o3")]) == 2
    assert "--elevation-mask" in capsys.readouterr().err


def _one_hz_observations(obs, seconds: int):
    """The first epoch's primary GPS rows repeated every second (values replaced later)."""
    rows, _ = primary_rows(obs, "G")
    o = obs.take(rows)
    first = np.flatnonzero(o.t_gps_s == o.t_gps_s[0])
    parts = []
    for k in range(seconds):
        p = o.take(first)
        p.t_gps_s[:] = p.t_gps_s + k
        parts.append(p)
    out = parts[0]
    for p in parts[1:]:
        out = out.concat(p)
    return out


def test_simulated_session_with_truth_pseudorange_and_beacons(tmp_path):
    """10 s, truth known: both tightly coupled modes near the truth, NIS of the pseudoranges
    (whose noise has the error model's sigma) in the chi-square band, beacons applied."""
    nav = nav_funcs()
    obs, eph, klob = geonet("0759")
    o = _one_hz_observations(obs, 10)
    site = obs.approx_position_ecef_m
    rng = np.random.default_rng(3)
    sim, _sigma = simulated_pseudoranges(o, eph, klob, site, -7.7e4, 418.0, rng, nav)
    folder = tmp_path / "s"
    synth, _ = write_rawx_session(folder, sim.t_gps_s, sim.prn, sim.pseudorange_m, sim.doppler_hz, sim.cn0_dbhz,
                                  eph.data, site, klobuchar=klob, imu_rate_hz=10.0, nmea=True, sdr=True, nav=nav)
    options = replay.ReplayOptions(modes=("pseudorange+imu", "pseudorange+leo-alpha+imu", "fix+imu"))
    m = replay.replay_session(folder, tmp_path / "out", options, elements=synth.elements, nav=nav)
    assert m["reference"] == "truth.csv" and m["skipped_modes"] == {}
    pr, prl = m["modes"]["pseudorange+imu"], m["modes"]["pseudorange+leo-alpha+imu"]
    print({k: (v["rmse_position_m"], v["records"]) for k, v in m["modes"].items()})
    per = pr["per_observable"]
    print(per)
    n = per["gnss_pseudorange"]["applied"]
    assert n >= 60 and per["gnss_range_rate"]["applied"] >= 60
    band = 3.0 * np.sqrt(2.0 / n)
    assert abs(per["gnss_pseudorange"]["nis_mean"] - 1.0) <= band
    assert pr["records"]["failed"] == 0 and prl["per_observable"]["doppler_rate"]["applied"] > 0
    assert pr["rmse_position_m"] < 3.0 and prl["rmse_position_m"] < 3.0


def test_gnss_observation_table_check_names_the_field_and_row():
    from leonav_runtime.common.errors import UserInputError
    from leonav_runtime.inputs import GnssObservationTable

    n = 4
    good = dict(t=np.arange(n, dtype=float), sat_id=np.full(n, 71007), pseudorange_m=np.full(n, 2.1e7),
                sigma_pr_m=np.ones(n), range_rate_mps=np.full(n, np.nan), sigma_rr_mps=np.full(n, np.nan),
                aux=np.zeros((n, L.NAUX)), clock_t=np.zeros(1), clock_m=np.zeros(1), isb_m=np.zeros((1, 2)))
    GnssObservationTable(**good).check()
    cases = {
        "pseudorange_m": (dict(pseudorange_m=np.array([2.1e7, 2.1e7, np.nan, 2.1e7])), "row 2"),
        "t": (dict(t=np.array([0.0, 2.0, 1.0, 3.0])), "row 2 is earlier"),
        "sigma_pr_m": (dict(sigma_pr_m=np.array([1.0, 0.0, 1.0, 1.0])), "row 1"),
        "sigma_rr_mps": (dict(range_rate_mps=np.array([np.nan, 5.0, np.nan, np.nan])), "row 1"),
        "aux": (dict(aux=np.zeros((n, 3))), "shape"),
        "isb_m": (dict(isb_m=np.zeros((2, 2))), "shape"),
    }
    for field, (change, where) in cases.items():
        with pytest.raises(UserInputError) as err:
            GnssObservationTable(**(good | change)).check()
        text = str(err.value)
        assert text.startswith(f"GNSS observation table: {field}: ") and where in text and "expected" in text, text


def test_millisecond_receiver_clock_jumps_are_taken_out():
    """0759 with the receiver clock stepped by +1 ms after 20 min and -2 ms after 40 min (as
    receivers that keep their clock within 1 ms do): the filters see a continuous clock; the
    positions are those of the run without steps."""
    import datetime as dt

    from leonav_runtime.gen import constants as K
    from leonav_runtime.gnss import time as gtime

    nav = nav_funcs()
    obs, eph, klob = geonet("0759")
    t_rel = obs.t_gps_s - obs.t_gps_s[0]
    stepped = obs.take(np.arange(len(obs)))
    ms = K.C_LIGHT_MPS * 1e-3
    steps = (t_rel > 1200.0).astype(float) - 3.0 * (t_rel > 2400.0)
    # a step of the receiver clock moves its time tags and its pseudoranges alike
    stepped.pseudorange_m[:] = obs.pseudorange_m + ms * steps
    stepped.t_gps_s[:] = obs.t_gps_s + 1e-3 * steps
    runs = {}
    for name, o in (("plain", obs), ("stepped", stepped)):
        spp = coupled.single_point(o, eph, klob, systems="G", nav=nav)
        jumps = gnss_ekf.clock_jumps_m(spp)
        epoch_utc = gtime.gps_seconds_to_utc(float(spp.t_gps_s[0]) - 1.0).replace(tzinfo=dt.timezone.utc)
        imu = static_imu(spp.t_gps_s, obs.approx_position_ecef_m, epoch_utc)
        inputs = coupled.coupled_inputs(imu, spp, epoch_utc, filter_profile(0.5), nav=nav)
        recs, res = coupled.run_mode(inputs, "pseudorange+imu", nav=nav)
        t_run = spp.t_gps_s - coupled.gps_epoch(epoch_utc) + 0.01   # after the updates of the epoch
        ekf = gnss_ekf.run(spp, nav=nav)
        runs[name] = (jumps, pr_stats(recs, res), epoch_positions(recs, res, t_run, inputs.params, nav), ekf)
    jumps, stats, r, ekf = runs["stepped"]
    assert np.unique(np.round(jumps / ms)).tolist() == [-2.0, 0.0, 1.0]
    assert np.all(runs["plain"][0] == 0.0)
    assert stats["gated"] == 0 and ekf.gated.sum() == 0
    assert np.abs(r - runs["plain"][2]).max() < 0.01
    assert np.nanmax(np.linalg.norm(ekf.r_ecef_m - runs["plain"][3].r_ecef_m, axis=1)) < 0.01
