"""Pieces of `leonav nav`, each against its batch twin: the lag-window stepper against one
`EKF.run` (bit for bit), online IMU timing against known sample times, the streaming time map
against the session's map, fix epochs, the pushed STFT against the batch STFT."""
from __future__ import annotations

import copy
import datetime as dt

import numpy as np
import pytest

from leonav.hardware.records import GnssFix


@pytest.fixture(scope="module")
def trial():
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep import montecarlo as mc
    from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 5.0
    raw["starlink"]["counts"] = [10]
    scn = scenario_from_dict(raw, source="<nav test>")
    setup, nav = mc.setup_for(scn)
    return setup, nav, simulate.trial_records(setup, "gps+leo-alpha+imu", 10, mc.trial_rng(1, 0), nav)


def _arrival_order(recs: np.ndarray, seed: int, max_delay_s: float) -> np.ndarray:
    """IMU records arrive at their time, each (time, observable) group of measurements later."""
    rng = np.random.default_rng(seed)
    keys = np.round(recs["t"] * 1e6).astype(np.int64) * 100 + recs["kind"]
    uk, inv = np.unique(keys, return_inverse=True)
    delay = rng.uniform(0.01, max_delay_s, uk.size)[inv]
    return np.argsort(recs["t"] + np.where(recs["kind"] == -1, 0.0, delay), kind="stable")


def _step_all(trial, max_delay_s: float, lag_s: float):
    from leonav_runtime.core.filter import EKF
    from leonav_runtime.nav.stepper import LagStepper

    setup, nav, tr = trial
    recs = tr.records
    st = LagStepper(EKF(tr.x0, setup.P0, setup.params, library=nav.library), lag_s=lag_s)
    settled, batch = [], []
    for j in _arrival_order(recs, 0, max_delay_s):
        batch.append(j)
        if recs["kind"][j] == -1:          # the navigator steps when an IMU sample arrives
            st.step(recs[np.array(batch)])
            batch = []
            s = st.settle()
            if s is not None:
                settled.append(s)
    st.step(recs[np.array(batch, int)])
    settled.append(st.settle_all())
    return st, settled


def test_stepper_on_out_of_order_batches_equals_one_batch_run_bit_for_bit(trial):
    from leonav_runtime.core.filter import EKF

    setup, nav, tr = trial
    st, settled = _step_all(trial, max_delay_s=1.5, lag_s=2.0)
    got = np.concatenate([s.recs for s in settled])
    x = np.concatenate([s.x for s in settled])
    ref = EKF(tr.x0, setup.P0, setup.params, library=nav.library).run(tr.records)
    assert st.counts["reruns"] > 10 and st.counts["late_dropped"] == 0
    np.testing.assert_array_equal(got["t"], tr.records["t"])
    np.testing.assert_array_equal(got["kind"], tr.records["kind"])
    np.testing.assert_array_equal(x, ref.x)
    np.testing.assert_array_equal(np.concatenate([s.status for s in settled]), ref.status)


def test_stepper_drops_and_counts_records_later_than_its_window(trial):
    st, settled = _step_all(trial, max_delay_s=1.5, lag_s=0.5)
    n = sum(s.recs.size for s in settled)
    assert st.counts["late_dropped"] > 0
    assert n + st.counts["late_dropped"] == trial[2].records.size


def _stamps(rate_hz: float, n: int, seed: int, jitter_s: float, missing=()):
    rng = np.random.default_rng(seed)
    k = np.setdiff1d(np.arange(n), missing)
    t_true = 100.0 + k / rate_hz
    return t_true, t_true + 0.002 + rng.exponential(jitter_s, k.size)


def test_online_imu_timing_finds_gaps_at_10_hz_at_once():
    from leonav_runtime.nav.imu_timing import OnlineImuTiming

    t_true, stamps = _stamps(10.0, 600, 1, 0.004, missing=(200, 401, 402))
    tm = OnlineImuTiming()
    got = np.array([tm.add(s)[0] for s in stamps])
    assert tm.counts.missing == 3 and tm.counts.late_gaps == 0
    err = got - t_true
    assert np.abs(err[50:] - np.median(err[50:])).max() < 0.01     # regular times: only a constant read delay
    assert np.all(np.diff(got) > 0)


def test_online_imu_timing_at_100_hz_has_no_false_gaps_and_finds_a_hidden_one_later():
    from leonav_runtime.nav.imu_timing import OnlineImuTiming

    _, stamps = _stamps(100.0, 6000, 2, 0.004)
    tm = OnlineImuTiming()
    for s in stamps:
        tm.add(s)
    assert tm.counts.missing == 0
    t_true, stamps = _stamps(100.0, 3000, 3, 0.004, missing=(1500,))
    tm = OnlineImuTiming()
    got = np.array([tm.add(s)[0] for s in stamps])
    assert tm.counts.missing == 1
    err = got - t_true
    assert np.abs(err[-500:] - np.median(err[-500:])).max() < 0.01


def test_online_imu_timing_burst_of_one_read_ends_on_time():
    from leonav_runtime.nav.imu_timing import OnlineImuTiming

    tm = OnlineImuTiming()
    for k in range(100):
        tm.add(10.0 + 0.1 * k + 0.003)
    times = tm.add(10.0 + 0.1 * 103 + 0.003, n=4)      # a host stall: four samples in one read
    np.testing.assert_allclose(np.diff(times), 0.1, atol=1e-6)
    assert times[-1] == pytest.approx(10.0 + 0.1 * 103 + 0.003, abs=1e-3) and tm.counts.missing == 0


def test_streaming_time_map_ends_at_the_sessions_map(tmp_path):
    from leonav.hardware.session import decode_session
    from leonav_runtime.nav.timemap import StreamingTimeMap
    from leonav_runtime.replay.timebase import mono_to_utc_function
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    write_synthetic_session(tmp_path / "s", SynthSessionConfig(seconds=6.0, sdr=False))
    dec = decode_session(tmp_path / "s")
    m = StreamingTimeMap(38400)
    for r in dec.gnss_records:
        m.add(r)
    to_utc, _ = mono_to_utc_function(dec)
    t = dec.gnss_records[-1].t_mono_s
    assert m.to_utc(t) == pytest.approx(float(to_utc(t)), abs=1e-9)


def _gnss_epoch(t: dt.datetime, gst: bool, t_mono: float):
    from leonav.hardware.gnss.nmea import parse_sentence
    from leonav.hardware.gnss.nmea_write import gst as gst_s, rmc

    recs = [parse_sentence(rmc(t, 43.0, -77.0, 0.0, 0.0).strip(), t_mono)]
    recs.append(GnssFix(t_mono + 0.02, "GGA", t, 0.75, -1.34, 170.0, 135.5, 1, 12, 0.8))
    if gst:
        recs.append(parse_sentence(gst_s(t, 1.5, 1.5, 3.0, 1.8).strip(), t_mono + 0.03))
    return recs


def test_fix_epochs_wait_for_their_gst_or_go_at_once_without():
    from leonav_runtime.nav.gnss_stream import FixAssembler

    t0 = dt.datetime(2026, 2, 23, 12, 0, 0, 100000, tzinfo=dt.timezone.utc)
    fa = FixAssembler()
    out = []
    for k in range(3):
        for r in _gnss_epoch(t0 + dt.timedelta(seconds=0.1 * k), True, 10.0 + 0.1 * k):
            got = fa.add(r)
            if isinstance(r, GnssFix):
                assert got == []                        # the fix waits for its GST
            out += got
    assert len(out) == 3 and all(any(getattr(x, "sentence_type", "") == "GST" for x in ep) for ep in out)
    fa = FixAssembler(timeout_s=0.3)
    first = _gnss_epoch(t0, False, 10.0)
    assert sum(len(fa.add(r)) for r in first) == 0          # no GST seen yet: wait
    assert len(fa.poll(10.5)) == 1 and fa.stream_has_gst is False
    assert len(fa.add(_gnss_epoch(t0 + dt.timedelta(seconds=0.1), False, 10.1)[1])) == 1   # now at once


def test_push_stft_gives_the_batch_slices():
    from leonav_runtime.beacons.waterfall import StftConfig, iter_spectra
    from leonav_runtime.nav.push_stft import PushStft

    fs = 200e3
    rng = np.random.default_rng(0)
    z = (rng.standard_normal(int(3.3 * fs)) + 1j * rng.standard_normal(int(3.3 * fs))).astype(np.complex64)
    cfg = StftConfig.for_rate(fs, 100e3)
    batch = list(iter_spectra([z[i:i + 50000] for i in range(0, z.size, 50000)], cfg, fs))
    push = PushStft(cfg, fs)
    got = [b for i in range(0, z.size, 7777) for b in push.push(z[i:i + 7777])] + push.flush()
    # the same slices at the same times with the same power; how they are grouped into blocks
    # follows the chunk sizes (7777 vs 50000 samples) and is not part of the contract
    np.testing.assert_array_equal(np.concatenate([b.t_s for b in got]), np.concatenate([b.t_s for b in batch]))
    np.testing.assert_array_equal(np.vstack([b.power for b in got]), np.vstack([b.power for b in batch]))


def test_gnss_latency_estimate_reaches_the_road_and_bad_values_are_named():
    from leonav_runtime.common.errors import UserInputError
    from leonav_runtime.nav.road import RoadConfig, StreamingRoad
    from leonav_runtime.replay.options import latency_values, parse_latency

    assert parse_latency("0.035") == 0.035 and parse_latency("estimate") == "estimate"
    for bad in ("1.5", "-0.1", "nan", "soon"):
        with pytest.raises(UserInputError, match=r"--gnss-latency: .*expected seconds in \[0, 1\) or 'estimate'"):
            parse_latency(bad)
    road = StreamingRoad(RoadConfig(gnss_latency_s="estimate"))
    assert road.tmap.gnss_latency_s == 0.0      # not removed from the time map: the filter estimates it
    assert latency_values("estimate")["dt_fix_rw"] > 0 and latency_values(0.035)["dt_fix_rw"] == 0.0
