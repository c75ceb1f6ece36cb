"""The phase-coherent synthetic IQ bench (`beacons/synthetic_phase.py`) puts in what it returns.

Checked against outside relations, not against its own code path: the pass's Doppler rate
at closest approach is -(f_c/c) v^2/h; the samples demodulated with the returned truth
phase give the tone's amplitude at zero phase (so the truth is the signal's phase); the
phase noise's variance over a band equals 2 int L(f) df of the stated density; C/N0 from
the samples' power equals the requested one.
"""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.beacons import synthetic_phase as sp
from leonav_runtime.gen.constants import C_LIGHT_MPS, STARLINK_BEACON_HZ


def test_truth_phase_is_the_phase_of_the_samples():
    cfg = sp.PhaseBenchConfig(duration_s=1.0, sample_rate_hz=600e3, lo_offset_hz=123.0, lo_drift_hz_s=5.0,
                              ppm=20.0, seed=4, phase_noise=None)
    tone = sp.ToneSpec(cn0_dbhz=50.0, if_hz=60e3, t_closest_s=0.5, phase0_cycles=0.37,
                       slips=[sp.SlipEvent(0.6, 0.2, 2, fade_db=6.0)])
    cap = sp.make_capture([tone], cfg)
    t_rx = np.arange(cap.iq.size) / cfg.sample_rate_hz
    truth = np.interp(t_rx, cap.t_s, cap.phase_cycles[0])  # 1 ms grid: < 1e-3 cycle between points
    base = cap.iq * np.exp(-2j * np.pi * (truth - np.floor(truth)))
    amp = np.sqrt(10 ** (5.0) / cfg.sample_rate_hz)
    blocks = base[: (base.size // 6000) * 6000].reshape(-1, 6000).mean(axis=1)   # 10 ms
    t_b = (np.arange(blocks.size) + 0.5) * 0.01
    clear = (t_b < 0.59) | (t_b > 0.81)
    # rad: the truth phase is the signal's (thermal noise of a 10 ms block at 50 dB-Hz: 0.022 rad)
    assert np.max(np.abs(np.angle(blocks[clear]))) < 0.1
    assert np.median(np.abs(blocks[clear])) == pytest.approx(amp, rel=0.03)
    faded = (t_b > 0.61) & (t_b < 0.79)
    assert np.median(np.abs(blocks[faded])) == pytest.approx(amp / 2, rel=0.05)   # 6 dB fade
    # the slip event added exactly its whole cycles over the fade
    k = cfg.f_c_hz / C_LIGHT_MPS
    free = sp._Truth([sp.ToneSpec(**{**tone.__dict__, "slips": ()})], cfg, np.random.default_rng(0))
    d = cap.phase_cycles[0] - free.phase(0, cap.t_s)[0]
    assert d[cap.t_s < 0.6] == pytest.approx(0.0, abs=1e-9) and d[cap.t_s > 0.8] == pytest.approx(2.0, abs=1e-9)
    assert k > 37  # cycles per metre at 11.325 GHz


def test_overhead_pass_rate_and_clock():
    cfg = sp.PhaseBenchConfig(duration_s=2.0, sample_rate_hz=200e3, phase_noise=None, ppm=50.0)
    tone = sp.ToneSpec(if_hz=0.0, t_closest_s=1.0)
    cap = sp.make_capture([tone], cfg)
    rate = np.gradient(cap.freq_hz[0], cap.t_s)
    expected = -(STARLINK_BEACON_HZ / C_LIGHT_MPS) * tone.speed_mps**2 / tone.altitude_m
    assert expected == pytest.approx(-3964, abs=5)   # the ~4 kHz/s of an overhead pass
    i = np.argmin(np.abs(cap.t_s - 1.0 * (1 + 50e-6)))  # closest approach in receiver time
    assert rate[i] == pytest.approx(expected * (1 - 2 * 50e-6), rel=2e-4)
    # tuner LO off by ppm x tuning, and every frequency seen 1 / (1 + ppm 1e-6) slower
    eps = 50e-6
    doppler = expected * (cap.t_s[i] / (1 + eps) - 1.0)   # linear about closest approach
    assert cap.freq_hz[0][i] == pytest.approx((doppler - eps * cfg.tuning_hz) / (1 + eps), abs=0.01)
    f_pred, r_pred = cap.predicted_baseband(np.array([1.0]), 0)
    assert f_pred[0] == pytest.approx(-50e-6 * cfg.tuning_hz, abs=1e-6) and r_pred[0] == pytest.approx(expected)


def test_phase_noise_variance_matches_the_density():
    rng = np.random.default_rng(1)
    rate, n = sp.PN_RATE_HZ, 400_000
    ph = sp.draw_phase_noise(n, rate, sp.LNB_PHASE_NOISE_DBC_HZ, rng)
    spec = np.abs(np.fft.rfft(ph)) ** 2 / (n * rate)        # two-sided density, rad^2/Hz
    f = np.fft.rfftfreq(n, 1 / rate)
    for lo, hi in ((500.0, 2e3), (5e3, 2e4), (5e4, 1.5e5)):
        band = (f >= lo) & (f < hi)
        grid = np.linspace(lo, hi, 20001)
        expected = 2 * np.trapezoid(sp.phase_noise_density(grid, sp.LNB_PHASE_NOISE_DBC_HZ), grid)
        assert 2 * spec[band].sum() * (f[1] - f[0]) == pytest.approx(expected, rel=0.1)
    assert 10 * np.log10(sp.phase_noise_density(np.array([1e3, 1e4, 1e5]), sp.LNB_PHASE_NOISE_DBC_HZ)) == \
        pytest.approx([-50, -75, -95])


def test_cn0_of_the_samples():
    fs = 200e3
    cap = sp.make_capture([sp.ToneSpec(cn0_dbhz=45.0, if_hz=20e3)],
                          sp.PhaseBenchConfig(duration_s=0.5, sample_rate_hz=fs, phase_noise=None))
    p_total = np.mean(np.abs(cap.iq) ** 2)
    assert p_total - 1.0 == pytest.approx(10 ** 4.5 / fs, rel=0.05)   # C = total - N, N0 = 1 / fs


def test_bad_bench_settings_are_one_line():
    with pytest.raises(ValueError, match=r"tone 0: reaches .* beyond 0.45 x the sample rate"):
        sp.make_capture([sp.ToneSpec(if_hz=95e3)], sp.PhaseBenchConfig(duration_s=0.1, sample_rate_hz=200e3))
    with pytest.raises(ValueError, match="do not fit"):
        sp.random_slips(np.random.default_rng(0), 3.0, 5)
