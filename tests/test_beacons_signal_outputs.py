"""Beacon signal chain beyond the ridge positions: the kept band and hop against numpy's FFT bin
frequencies, per-bin noise floor and SNR against the Hann window's known gains, the local fit and
its sigmas against numpy.polyfit's covariance, the window fill and SNR of each epoch, short
ridges dropped, and the files of `leonav beacons --simulate` (residual signs, the LO drift of the
simulation, summary statistics) read back."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from leonav_runtime.beacons.doppler import local_poly_fit, ridge_measurements
from leonav_runtime.beacons.ridges import Ridge, RidgeTracker, TrackerConfig
from leonav_runtime.beacons.waterfall import (
    SpectrumBlock,
    StftConfig,
    WaterfallImage,
    band_bins,
    iter_spectra,
)
from tests.conftest import shared_file


def test_band_keeps_the_fft_bins_within_half_the_band_and_hop_follows_the_overlap():
    fs, band = 2.4e6, 1.2e6
    cfg = StftConfig.for_rate(fs, band)
    idx, f = band_bins(cfg, fs)
    freq = np.fft.fftfreq(cfg.fft_size, 1.0 / fs)
    np.testing.assert_allclose(f, freq[idx], rtol=0, atol=1e-6)
    assert np.all(np.diff(f) > 0) and set(idx) == set(np.flatnonzero(np.abs(freq) <= band / 2))
    assert cfg.hop == cfg.fft_size // 2
    assert StftConfig.for_rate(fs, band, overlap=0.75).hop == cfg.fft_size // 4
    assert StftConfig.for_rate(fs, band, overlap=0.0).hop == cfg.fft_size


def _tone_capture(fs: float, n: int, seconds: float, amp: float, sigma: float, bin_k: int, seed: int = 3):
    rng = np.random.default_rng(seed)
    m = int(fs * seconds)
    t = np.arange(m) / fs
    noise = (rng.standard_normal(m) + 1j * rng.standard_normal(m)) * (sigma / math.sqrt(2))   # E|z|^2 = sigma^2
    return (amp * np.exp(2j * np.pi * (bin_k * fs / n) * t) + noise).astype(np.complex64)


def test_noise_floor_and_tone_snr_follow_the_hann_window_gains():
    """Per bin, white noise of variance s^2 has mean power s^2 sum(w^2); a bin-centred tone of
    amplitude A has peak power A^2 (sum w)^2: SNR = 10 log10(A^2 (sum w)^2 / (s^2 sum w^2))."""
    fs, n, sigma, amp, k = 500e3, 4096, 1.0, 0.3, 400
    cfg = StftConfig.for_rate(fs, None, n)
    w = np.hanning(n)
    noise_mean = sigma**2 * np.sum(w**2)
    snr_db = 10 * math.log10(amp**2 * np.sum(w) ** 2 / noise_mean)          # 23.9 dB
    x = _tone_capture(fs, n, 3.0, amp, sigma, k)
    blocks = list(iter_spectra([x[i:i + 262144] for i in range(0, x.size, 262144)], cfg, fs))
    mean = np.concatenate([b.noise_mean for b in blocks])
    assert np.median(mean) == pytest.approx(noise_mean, rel=0.03)
    _, f_hz = band_bins(cfg, fs)
    tracker = RidgeTracker(f_hz, TrackerConfig())
    image = WaterfallImage(f_hz)
    for b in blocks:
        tracker.add_block(b)
        image.add(b)
    ridges = tracker.finish()
    assert len(ridges) == 1 and ridges[0].f_hz.mean() == pytest.approx(k * fs / n, abs=5.0)
    assert np.median(ridges[0].snr_db) == pytest.approx(snr_db, abs=0.5)
    _, f_img, db = image.image()
    col = int(np.argmin(np.abs(f_img - k * fs / n)))
    assert np.median(db[:, col]) == pytest.approx(snr_db, abs=0.5)


def test_local_fit_and_its_sigmas_are_numpys_least_squares():
    rng = np.random.default_rng(7)
    t = np.linspace(-0.9, 0.9, 9)
    f = 1200.0 - 35.0 * t + 4.0 * t**2 + 0.8 * rng.standard_normal(t.size)
    got = local_poly_fit(t, f, 0.0, 1.0)
    coef, cov = np.polyfit(t, f, 2, cov=True)            # highest power first; scaled by SSR / (n - 3)
    assert got[4] == 9
    assert got[0] == pytest.approx(coef[2], rel=1e-12) and got[2] == pytest.approx(coef[1], rel=1e-10)
    assert got[1] == pytest.approx(math.sqrt(cov[2, 2]), rel=1e-9)
    assert got[3] == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-9)
    # a noise peak taken inside the gate: dropped, the fit is the one without it
    t15 = np.linspace(-0.95, 0.95, 15)
    f15 = 1200.0 - 35.0 * t15 + 4.0 * t15**2 + 0.8 * rng.standard_normal(t15.size)
    f15[4] += 400.0
    got = local_poly_fit(t15, f15, 0.0, 1.0)
    keep = np.arange(15) != 4
    coef, cov = np.polyfit(t15[keep], f15[keep], 2, cov=True)
    assert got[4] == 14 and got[2] == pytest.approx(coef[1], rel=1e-9)
    assert got[3] == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-9)


def _ridge(t: np.ndarray, snr: np.ndarray) -> Ridge:
    return Ridge(t, 1000.0 + 50.0 * t - 2.0 * t**2, snr, ridge_id=3)


def test_epochs_take_their_windows_snr_and_need_their_fill():
    t = np.round(np.arange(0.0, 10.0, 0.01), 6)
    m = ridge_measurements(_ridge(t, np.where(t < 5.0, 10.0, 30.0)), 0.0, 0.0, 1.0, 1.0)
    np.testing.assert_array_equal(m.t_s, np.arange(1.0, 9.0))   # each epoch needs +-1 s of ridge
    snr = dict(zip(m.t_s, m.snr_db))
    assert (snr[2.0], snr[3.0], snr[7.0], snr[8.0]) == (10.0, 10.0, 30.0, 30.0)
    np.testing.assert_allclose(m.rate_hz_s, 50.0 - 4.0 * m.t_s, atol=1e-6)   # the fitted rate of a known curve
    # points missing over 4.5..5.5 s: the window around 5 s holds half the points its spacing predicts
    keep = (t < 4.5) | (t > 5.5)
    m = ridge_measurements(_ridge(t[keep], np.full(keep.sum(), 20.0)), 0.0, 0.0, 1.0, 1.0, min_fill=0.6)
    assert 5.0 not in m.t_s and {4.0, 6.0} <= set(m.t_s)
    assert np.all(m.n_points >= 0.6 * 200)


def _blocks(n_slices: int, n_bins: int, tones: list[tuple[int, int, int]], hop_s: float, seed: int = 5):
    """SpectrumBlocks of exponential noise (mean 1) with tones (bin, first slice, last slice) 30 dB up."""
    rng = np.random.default_rng(seed)
    p = rng.exponential(1.0, (n_slices, n_bins)).astype(np.float32)
    for k, a, b in tones:
        p[a:b, k] = 1000.0
    med = np.median(p, axis=1)
    mad = np.median(np.abs(p - med[:, None]), axis=1)
    t = np.arange(n_slices) * hop_s
    return [SpectrumBlock(t[i:i + 50], p[i:i + 50], med[i:i + 50], mad[i:i + 50]) for i in range(0, n_slices, 50)]


def test_a_tone_shorter_than_min_duration_is_dropped_and_counted():
    f_hz = np.arange(512) * 100.0
    tracker = RidgeTracker(f_hz, TrackerConfig(min_duration_s=1.0))
    for b in _blocks(400, 512, [(100, 0, 400), (300, 100, 160)], 0.01):   # 4 s and 0.6 s
        tracker.add_block(b)
    ridges = tracker.finish()
    assert len(ridges) == 1 and ridges[0].f_hz.mean() == pytest.approx(100 * 100.0, abs=1.0)
    assert tracker.stats.discarded_short >= 1


# ---- `leonav beacons --simulate` files -----------------------------------------------------------------

LO_DRIFT_HZ_S = 4.0


@pytest.fixture(scope="module")
def sim_out(tmp_path_factory):
    from leonav_runtime.cli import main

    tle = shared_file("tle/starlink_2026-02-23.txt")
    tmp = tmp_path_factory.mktemp("beacons_sim")
    out = tmp / "out"
    rc = main(["beacons", str(tmp / "sim.cu8"), "--simulate", "--tle", str(tle), "--duration", "8",
               "--sim-rate", "500e3", "--band", "500e3", "--n-sats", "5", "--cn0", "38",
               "--lo-drift", str(LO_DRIFT_HZ_S), "--start", "2026-02-23T06:00:00Z", "--out", str(out)])
    assert rc == 0
    read = (lambda name: list(csv.DictReader((out / name).open())))
    return json.loads((out / "summary.json").read_text()), read("doppler_rate_measurements.csv"), read("associations.csv")


def test_lo_drift_of_the_simulation_is_found_and_removed(sim_out):
    summary, rows, _ = sim_out
    lo = summary["lo"]
    assert lo["drift_removed"] and summary["counts"]["associated"] == 5
    # measured - predicted Doppler = minus the LNB LO error: the simulated +4 Hz/s drift shows as -4
    assert abs(lo["drift_hz_s"] + LO_DRIFT_HZ_S) < 3 * lo["sigma_drift_hz_s"]
    for r in rows:
        t = float(r["t_s"])
        assert float(r["lo_offset_hz"]) == pytest.approx(lo["offset_hz"] + lo["drift_hz_s"] * t, abs=1e-6)
        assert float(r["lo_drift_hz_s"]) == lo["drift_hz_s"]


def test_residual_columns_are_measured_minus_predicted(sim_out):
    summary, rows, assoc = sim_out
    resid = np.array([float(r["rate_residual_hz_s"]) for r in rows])
    meas = np.array([float(r["doppler_rate_hz_s"]) for r in rows])
    pred = np.array([float(r["predicted_rate_hz_s"]) for r in rows])
    np.testing.assert_allclose(resid, meas - pred, atol=1e-9)
    assert np.max(np.abs(resid)) < 2.0               # the drift out: well inside the LO drift itself
    # per-ridge rows of associations.csv: the same residual (single-tone combs), the drift taken out too
    by_key = {(r["t_s"], r["ridge_id"]): float(r["rate_residual_hz_s"]) for r in rows}
    same = [(float(a["rate_residual_hz_s"]), by_key[(a["t_s"], a["ridge_id"])]) for a in assoc
            if a["status"] == "associated" and (a["t_s"], a["ridge_id"]) in by_key]
    assert len(same) == len(rows)
    np.testing.assert_allclose(*np.array(same).T, atol=1e-6)
    # the summary: statistics of |residual| over the same epochs
    s = summary["rate_residual_abs_hz_s"]
    assert s["n"] == resid.size and s["median"] == pytest.approx(np.median(np.abs(resid)))
    assert s["mean"] == pytest.approx(np.mean(np.abs(resid))) and s["max"] == pytest.approx(np.max(np.abs(resid)))
    assert summary["rate_residual_signed_mean_hz_s"] == pytest.approx(np.mean(resid))


def test_summary_stft_figures(sim_out):
    summary, _, _ = sim_out
    st, fs = summary["stft"], 500e3
    assert st["slice_s"] == pytest.approx(st["fft_size"] / fs) and st["bin_hz"] == pytest.approx(fs / st["fft_size"])
    assert st["hop"] == st["fft_size"] // 2 and st["band_hz"] == 500e3
