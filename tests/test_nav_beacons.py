"""The streaming beacon pipeline of `leonav nav`: the same Doppler-rate as the batch pipeline on one
capture, and the LEO modes against `leonav replay` of a synthetic session (fast playback, and
the live path: pty devices plus the recorded capture read back as an RTL-SDR at its pace, the
beacon work in its own process)."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from tests.test_nav_live import difference_rms, nav_options

SECONDS = 10.0


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from leonav_runtime.replay import ReplayOptions, replay_session
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    base = tmp_path_factory.mktemp("navbeacons")
    write_synthetic_session(base / "s", SynthSessionConfig(seconds=SECONDS, seed=0, sdr_rate_hz=240e3))
    replay_session(base / "s", base / "replay", ReplayOptions())
    return base


def test_streamed_doppler_rate_equals_the_batch_pipeline(session):
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.nav.beacon_stream import BeaconStream
    from leonav_runtime.simulation.session_synth import ROCHESTER, builtin_starlink

    warnings.simplefilter("ignore")
    info = capture_io.open_capture(session / "s" / "sdr.cu8")
    site = Site(math.radians(ROCHESTER[0]), math.radians(ROCHESTER[1]), ROCHESTER[2])
    elements = builtin_starlink(info.start_utc)
    bs = BeaconStream(info.sample_rate_hz, info.rf_center_hz, info.rf_center_hz, elements)
    bs.set_site(site, info.start_utc)
    got = []
    for blk in capture_io.iter_chunks(info, 24_000):                 # 0.1 s pieces, as read live
        bs.push(blk)
        got += bs.take()
    bs.flush()
    got += bs.take()
    res = pipeline.process_capture(info, elements, site, pipeline.PipelineConfig(f_c_hz=info.rf_center_hz,
                                                                                 band_hz=240e3))
    batch = {(a.norad_id, round(float(t), 3)): r for m, a in zip(res.measurements, res.associations)
             if a.status == "associated" for t, r in zip(m.t_s, m.rate_hz_s)}
    assert len(batch) >= 25
    streamed = {(e.norad_id, round(e.t_s, 3)): e.rate_hz_s for e in got}
    common = set(batch) & set(streamed)
    assert len(common) >= 0.8 * len(batch) and {k[0] for k in streamed} == {k[0] for k in batch}
    d = np.array([streamed[k] - batch[k] for k in common])
    assert np.max(np.abs(d)) < 0.05, d                # Hz/s; the LO drift comes from the window, not the capture
    assert max(e.data_lag_s for e in got) <= 2.0 and bs.counts["emitted"] == len(got)


@pytest.mark.parametrize("mode", ["fix+leo-alpha+imu", "leo-alpha+imu"])
def test_fast_playback_of_the_leo_modes_within_the_replays_sigma(session, mode):
    from leonav_runtime.nav.run import run_nav

    out = session / f"fast_{mode}"
    res = run_nav(nav_options(out, mode=mode, session=session / "s"))
    assert res["exit_code"] == 0 and res["road"].get("doppler_rate_released", 0) >= 20
    assert res["filter"]["late_dropped"] == 0
    rms, n, sigma = difference_rms(out, session / "replay", mode)
    assert n > 80 and rms < sigma, (rms, sigma)


@pytest.fixture(scope="module")
def long_session(tmp_path_factory):
    """A 20 s session for the live path: the beacon process's start-up (seconds on a loaded
    machine) costs a 10 s capture most of its measurements."""
    from leonav_runtime.replay import ReplayOptions, replay_session
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    base = tmp_path_factory.mktemp("navbeacons_live")
    write_synthetic_session(base / "s", SynthSessionConfig(seconds=2 * SECONDS, seed=0, sdr_rate_hz=240e3))
    replay_session(base / "s", base / "replay", ReplayOptions())
    return base


@pytest.mark.slow
def test_live_path_with_the_capture_agrees_with_the_replay(long_session):
    from leonav_runtime.nav.run import run_nav

    session = long_session
    out = session / "live"
    res = run_nav(nav_options(out, mode="fix+leo-alpha+imu", session=session / "s", realtime=True))
    assert res["exit_code"] == 0, res["events"]
    b = res["beacons"]
    # live, a measurement older than max_lag_s on the wall clock is dropped and counted (too_late):
    # on 10 s a quiet machine made 20-30 of 35 epochs' measurements, the suite's load 10, 3x
    # overload 0-5; every epoch is either made or counted
    made, late = b["counts"]["measurements"], b["stream"]["too_late"]
    assert not b["error"] and made >= 10 and made + late == b["stream"]["epochs"] and b["max_lag_s"] <= 2.0, \
        (made, late, b["stream"])
    # every measurement is released, or still waiting for the IMU when the run stopped (a loaded
    # machine lags the live beacon path at the end), or counted as dropped: none is lost silently
    released = res["road"].get("doppler_rate_released", 0)
    left = res["pending_measurements_at_end"] + res["road"].get("waiting_for_imu_dropped", 0)
    assert released >= 5 and released <= made <= released + left, (released, made, left)
    rms, n, sigma = difference_rms(out, session / "replay", "fix+leo-alpha+imu")
    assert n > 80 and rms < sigma, (rms, sigma)
    assert (out / "session" / "sdr.cu8").stat().st_size == (session / "s" / "sdr.cu8").stat().st_size
    # the playback ended, so the beacon process read the whole capture and flushed its stream (cu8: 2
    # bytes a sample) before the navigator settled
    assert b["counts"]["flushed_at_samples"] == (session / "s" / "sdr.cu8").stat().st_size // 2, b["counts"]
