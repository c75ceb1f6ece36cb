"""Streaming carrier tracking (beacons/carrier_stream.py) and the phase modes of `leonav nav`:
tones joining a capture mid-way give, once locked, the batch tracker's phase differences; every
pair of epochs is a difference or a counted break; and fast playback of a session in
leo-phase+imu feeds the filter the replay's carrier-phase records (same z, R and satellite
states for the differences both make)."""
from __future__ import annotations

import numpy as np
import pytest

from tests.test_nav_live import nav_options, run_nav_records
from leonav_runtime.beacons import synthetic_phase as sp
from leonav_runtime.beacons.carrier_front import Aiding
from leonav_runtime.beacons.carrier_score import AID_STEP_S, track_capture
from leonav_runtime.beacons.carrier_stream import StreamingCarrier
from leonav_runtime.inputs.carrier_phase import phase_differences

START_S = 2.0


@pytest.fixture(scope="module")
def capture():
    cfg = sp.PhaseBenchConfig(duration_s=10.0, sample_rate_hz=240e3, seed=3, lo_offset_hz=1234.0,
                              lo_drift_hz_s=2.0, ppm=1.0)
    tones = [sp.ToneSpec(cn0_dbhz=30.0, if_hz=-40e3, t_closest_s=5.0),     # overhead at 5 s: -4 kHz/s
             sp.ToneSpec(cn0_dbhz=35.0, if_hz=30e3, t_closest_s=-20.0)]
    return sp.make_capture(tones, cfg)


def _stream(cap, chunk: int = 24_000):
    t = np.arange(-2 * AID_STEP_S, cap.cfg.duration_s + 3 * AID_STEP_S, AID_STEP_S)
    sc = StreamingCarrier(cap.sample_rate_hz)
    got, start = [], int(START_S * cap.sample_rate_hz) // chunk * chunk
    for k in range(0, cap.iq.size, chunk):
        if k == start:           # the tones join when the stream has identified them
            for i in range(len(cap.tones)):
                sc.start_tone(i, 100 + i, Aiding(t, cap.predicted_baseband(t, i, 0.05, 5.0)[0], f"tone {i}"))
        sc.push(cap.iq[k:k + chunk])
        got += sc.take()
    got += sc.take(final=True)
    return sc, got


def test_streamed_differences_are_the_batch_trackers_once_locked(capture):
    sc, got = _stream(capture)
    assert all(g.t_s > START_S for g in got)
    for i, tr in enumerate(track_capture(capture)):
        n = tr.t_s.size
        d = phase_differences(tr.t_s, np.full(n, 100 + i), np.full(n, i), tr.phase_cycles, tr.sigma_cycles,
                              tr.locked, tr.arc, 0.1)
        batch = {round(float(t), 3): (z, s) for t, z, s in zip(d.t, d.z_cycles, d.sigma_cycles)}
        streamed = {round(g.t_s, 3): (g.z_cycles, g.sigma_cycles) for g in got if g.key == i}
        late = [t for t in batch if t >= START_S + 2.0]       # 2 s after joining: locked, transient gone
        assert len(late) >= 55 and all(t in streamed for t in late)
        dz = np.array([streamed[t][0] - batch[t][0] for t in late])
        assert np.abs(dz).max() < 2e-3, np.abs(dz).max()      # cycles (measured 2.5e-4)
        ds = np.array([streamed[t][1] / batch[t][1] for t in late])
        assert np.abs(ds - 1).max() < 0.05
        assert set(streamed) <= set(batch) | {t for t in streamed if t < START_S + 2.0}


def test_every_streamed_pair_is_a_difference_or_a_counted_break(capture):
    sc, got = _stream(capture)
    c = sc.counts
    assert c["tones"] == 2 and c["differences"] == len(got)
    pairs = c["epochs"] - c["tones"]
    assert c["differences"] + sum(c["breaks"].values()) == pairs
    assert c["breaks"]["unlocked"] > 0          # the acquisition after joining
    # memory stays bounded: each tone keeps its last seconds of prompts, not the capture's
    for tone in sc.tones.values():
        span = (tone.loop.rec["i0"][-1] - tone.loop.rec["i0"][0]) / tone.front.sub_rate_hz
        assert span < 4.0


@pytest.mark.slow
def test_fast_playback_in_a_phase_mode_feeds_the_replays_phase_records(tmp_path):
    import warnings

    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.replay import ReplayOptions
    from leonav_runtime.replay.run import decode_inputs
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    mode = "leo-phase+imu"
    write_synthetic_session(tmp_path / "s", SynthSessionConfig(seconds=10.0, seed=0, sdr_rate_hz=240e3))
    res, nav = run_nav_records(nav_options(tmp_path / "nav", mode=mode, session=tmp_path / "s"), "carrier_phase")
    assert res["exit_code"] == 0 and res["road"]["carrier_phase_released"] >= 100
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        decoded = decode_inputs(tmp_path / "s", ReplayOptions(modes=(mode,)))
    ref = decoded.records["carrier_phase"].copy()
    # one clock for both: the nav road's axis starts where its causal time map put the first IMU sample
    ref["t"] += (decoded.epoch_utc - res["epoch_utc"]).total_seconds()

    # the same epoch of the same tone: the live time map (past GNSS tags only) puts the capture's
    # start a millisecond or so from the replay's whole-session fit
    common = []
    for r in nav:
        same = np.flatnonzero((ref["sat_id"] == r["sat_id"]) & (ref["aux"][:, L.AUX_DF_TONE] == r["aux"][L.AUX_DF_TONE])
                              & (np.abs(ref["t"] - r["t"]) < 0.02))
        if same.size == 1:
            common.append((r, ref[same[0]]))
    assert len(common) >= 0.8 * nav.size, (len(common), nav.size)
    # every tone the replay tracks is tracked live too (none left out for leaving the band long
    # after the capture), and up to the end: the stream is flushed when the playback ends
    def tones(recs):
        return {(int(x["sat_id"]), round(float(x["aux"][L.AUX_DF_TONE]))) for x in recs}
    assert tones(nav) == tones(ref), (tones(nav), tones(ref))
    assert nav["t"].max() > ref["t"].max() - 0.2, (nav["t"].max(), ref["t"].max())
    assert res["beacons"]["counts"]["flushed_at_samples"] > 0
    dt = np.array([a["t"] - b["t"] for a, b in common])
    assert np.abs(dt).max() < 5e-3
    dz = np.array([a["z"] - b["z"] for a, b in common])
    sigma = float(np.median(np.sqrt([b["R"] for _, b in common])))
    # the same tracked phase to a fraction of its noise: the loops differ only in their aiding (the
    # stream's predictions sampled on other knots, its constant from the ridge's first seconds)
    assert np.sqrt(np.mean(dz**2)) < 0.5 * sigma, (np.sqrt(np.mean(dz**2)), sigma)     # measured 0.37 sigma
    assert np.abs(dz).max() < 2.5 * sigma, (np.abs(dz).max(), sigma)
    r = np.array([a["R"] / b["R"] for a, b in common])
    assert np.abs(r - 1).max() < 0.1
    # the same satellite states, at the shifted time tag: |dr - v dt| (m)
    sat = np.array([np.linalg.norm(a["aux"][L.AUX_R_S_ECEF_SLICE] - b["aux"][L.AUX_R_S_ECEF_SLICE]
                                   - b["aux"][L.AUX_V_S_ECEF_SLICE] * (a["t"] - b["t"])) for a, b in common])
    assert sat.max() < 0.05, sat.max()


def test_the_live_beacon_process_sends_phase_tables(tmp_path):
    from tests.test_nav_operator_ephemerides import _child_tables
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    write_synthetic_session(tmp_path / "s", SynthSessionConfig(seconds=10.0, seed=0, sdr_rate_hz=240e3))
    (tmp_path / "m").mkdir()
    phase, summary = _child_tables(tmp_path / "s", None, tmp_path / "m", carrier_phase=True, kind="phase")
    tables = [m[1] for m in phase]
    n = sum(t.t.size for t in tables)
    assert n >= 100 and summary["counts"]["phase_differences"] == n
    for t in tables:
        assert t.KIND == "carrier_phase" and np.all(t.interval_s > 0)
        moved = np.linalg.norm(t.sat_ecef[:, 0:3] - t.sat_prev_r_m, axis=1)
        assert np.all(np.abs(moved - 760.0) < 100.0)          # 0.1 s of a LEO satellite's motion (m)
    # the names ride along (the road's operator files are read by name)
    assert {int(i) for t in tables for i in t.sat_id} == set().union(*(set(m[2]) for m in phase))


def test_a_tone_whose_ridge_is_gone_is_no_longer_tracked(capture):
    from leonav_runtime.nav.beacon_stream import TONE_GONE_S, BeaconStream
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, builtin_starlink

    bs = BeaconStream(capture.sample_rate_hz, 11.325e9, 11.325e9, builtin_starlink(PAPER_EPOCH), carrier_phase=True)
    t = np.arange(-2 * AID_STEP_S, capture.cfg.duration_s + 3 * AID_STEP_S, AID_STEP_S)
    bs.carrier.start_tone(99, 1, Aiding(t, capture.predicted_baseband(t, 0, 0.05, 5.0)[0], "tone"))
    bs.tones[99] = (1, 0, 0.0)       # a tone no STFT ridge of this stream carries (its ridge has ended)
    chunk = 24_000
    for k in range(0, capture.iq.size, chunk):
        bs.push(capture.iq[k:k + chunk])
        if bs.t_data < TONE_GONE_S - 0.5:
            assert 99 in bs.carrier.tones
    assert 99 not in bs.carrier.tones and bs.counts["tones_stopped"] == 1


def test_a_tone_about_to_leave_the_band_stops_and_one_that_would_soon_is_not_started(capture):
    from leonav_runtime.nav.beacon_stream import BAND_MARGIN_S, TONE_BAND_AHEAD_S, BeaconStream
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, builtin_starlink

    bs = BeaconStream(capture.sample_rate_hz, 11.325e9, 11.325e9, builtin_starlink(PAPER_EPOCH), carrier_phase=True)
    edge = 0.45 * capture.sample_rate_hz
    t = np.arange(-2 * AID_STEP_S, capture.cfg.duration_s + 3 * AID_STEP_S, AID_STEP_S)
    # the capture's first tone, predicted beyond the band from 6 s on
    leaving = np.where(t < 6.0, capture.predicted_baseband(t, 0, 0.05, 5.0)[0], 1.2 * edge)
    assert bs._in_band(Aiding(t, leaving, "x"), TONE_BAND_AHEAD_S)      # t_data 0: in band up to 5 s
    bs.t_data = 1.5
    assert not bs._in_band(Aiding(t, leaving, "x"), TONE_BAND_AHEAD_S)
    bs.t_data = 0.0
    bs.carrier.start_tone(7, 1, Aiding(t, leaving, "tone"))
    bs.tones[7] = (1, 0, 0.0)
    chunk, diffs, t_stop = 24_000, [], None
    for k in range(0, capture.iq.size, chunk):
        bs.push(capture.iq[k:k + chunk])
        new = bs.take_phase()
        assert all(bs.phase_tones[d.key] == (1, 0, 0.0) for d in new)     # known also once stopped
        diffs += new
        if bs.t_data < 6.0 - BAND_MARGIN_S - 0.1:
            assert 7 in bs.carrier.tones
        elif t_stop is None and 7 not in bs.carrier.tones:
            t_stop = bs.carrier.t_data
    assert 7 not in bs.carrier.tones and bs.counts["tones_left_band"] == 1 and bs.counts["tones_stopped"] == 1
    # its epochs that were final when it stopped still come (those within the lag are not confirmed)
    from leonav_runtime.beacons.carrier_stream import LAG_S

    assert diffs and max(d.t_s for d in diffs) >= t_stop - LAG_S - 0.15, (max(d.t_s for d in diffs), t_stop)


def test_a_tone_stopped_before_its_first_epochs_leaves_the_counts_whole(capture):
    t = np.arange(-2 * AID_STEP_S, capture.cfg.duration_s + 3 * AID_STEP_S, AID_STEP_S)
    sc = StreamingCarrier(capture.sample_rate_hz)
    chunk = 24_000
    for k in range(0, capture.iq.size, chunk):
        if k == 10 * chunk:
            for i in range(2):
                sc.start_tone(i, 100 + i, Aiding(t, capture.predicted_baseband(t, i, 0.05, 5.0)[0], f"tone {i}"))
        if k == 12 * chunk:
            sc.stop_tone(1)          # 0.2 s after joining: before any of its epochs was final
        sc.push(capture.iq[k:k + chunk])
        sc.take()
    sc.take(final=True)
    c = sc.counts
    assert c["tones"] == 1 and c["differences"] + sum(c["breaks"].values()) == c["epochs"] - c["tones"]


def test_a_stopped_tone_is_known_until_the_take_after_its_last_epochs():
    """phase_tones keeps a stopped tone for the take_phase that returns its last differences, and
    drops it at the one after (the stream's memory stays bounded over a long run)."""
    from leonav_runtime.nav.beacon_stream import BeaconStream
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, builtin_starlink

    bs = BeaconStream(240e3, 11.325e9, 11.325e9, builtin_starlink(PAPER_EPOCH), carrier_phase=True)
    t = np.arange(-1.0, 20.0, AID_STEP_S)
    bs.carrier.start_tone(3, 1, Aiding(t, np.zeros_like(t), "tone"))
    bs.tones[3] = (1, 0, 0.0)
    bs._stop(3)
    assert 3 not in bs.tones
    bs.take_phase()
    assert bs.phase_tones[3] == (1, 0, 0.0)      # for the differences this take returned
    bs.take_phase()
    assert 3 not in bs.phase_tones
