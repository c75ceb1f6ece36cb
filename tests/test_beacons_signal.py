"""Waterfall, peak interpolation, ridge tracking and Doppler-rate fits against known signals."""
from __future__ import annotations

import numpy as np

from leonav_runtime.beacons import capture_io, doppler, pipeline
from leonav_runtime.beacons.ridges import (Ridge, RidgeTracker, TrackerConfig, _local_maxima, _Track,
                                           interpolate_peak)
from leonav_runtime.beacons.waterfall import SpectrumBlock, StftConfig, band_bins, default_fft_size, iter_spectra

FS = 250e3


def test_default_fft_size_matches_rate_smear_tradeoff():
    # slice ~ 1/sqrt(4 kHz/s) = 16 ms: 2^15 at 2.4 MS/s (13.7 ms), 2^12 at 250 kS/s (16.4 ms)
    assert default_fft_size(2.4e6) == 2**15
    assert default_fft_size(250e3) == 2**12


def test_sub_bin_interpolation_error_is_small():
    n = 4096
    cfg = StftConfig(n, n, FS)
    idx, f = band_bins(cfg, FS)
    df = FS / n
    for frac in np.linspace(-0.5, 0.5, 11):
        f0 = 1000.3 * df / 10 + frac * df + 123 * df
        t = np.arange(n) / FS
        x = np.exp(2j * np.pi * f0 * t).astype(np.complex64)
        blk = next(iter_spectra([x], cfg, FS, slices_per_block=1))
        k = int(np.argmax(blk.power[0]))
        est = f[k] + interpolate_peak(blk.power[0], k) * df
        assert abs(est - f0) < 0.1 * df  # Gaussian interpolation of a Hann peak: bias < 0.1 bin


def _chirps(duration_s, tracks, cn0_dbhz, seed=0):
    """Noise plus linear chirps f(t) = f0 + a t, C/N0 per tone (dB-Hz), unit noise power."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * FS)
    t = np.arange(n) / FS
    x = (rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2)
    amp = np.sqrt(10 ** (cn0_dbhz / 10) / FS)
    for f0, a in tracks:
        x += amp * np.exp(2j * np.pi * (f0 * t + 0.5 * a * t**2))
    return x.astype(np.complex64)


def _write(tmp_path, x, name="c.cf32"):
    path = tmp_path / name
    path.write_bytes(x.tobytes())
    return capture_io.open_capture(path, sample_rate_hz=FS, center_freq_hz=1.575e9)


def test_tracker_follows_crossing_ridges(tmp_path):
    tracks = [(-20e3, 3000.0), (10e3, -3000.0), (50e3, -200.0)]  # the first two cross at t = 5 s
    info = _write(tmp_path, _chirps(8.0, tracks, 40.0))
    cfg = pipeline.PipelineConfig(band_hz=FS)
    ridges, stats, stft, _ = pipeline.extract_ridges(info, cfg)
    assert len(ridges) == 3, stats
    df = FS / stft.fft_size
    for f0, a in tracks:
        # the ridge that starts on this chirp must stay on it through the crossing
        r = min(ridges, key=lambda r: abs(r.f_hz[0] - f0))
        assert r.duration_s > 7.5
        err = np.abs(r.f_hz - (f0 + a * r.t_s))
        assert np.median(err) < 0.15 * df
        assert np.mean(err > 2 * df) < 0.02  # only slices where the two tones merge into one peak
        assert np.all(err[r.t_s > r.t_s[-1] - 1.0] < 0.5 * df)  # and it ends on its own chirp


def test_noise_only_capture_gives_empty_result_with_reason(tmp_path):
    info = _write(tmp_path, _chirps(4.0, [], 0.0, seed=3))
    res = pipeline.process_capture(info, elements=None, site=None, cfg=pipeline.PipelineConfig(band_hz=FS))
    assert res.ridges == [] and res.associations == []
    assert "no tone ridge" in res.reason


def test_capture_shorter_than_one_fft(tmp_path):
    info = _write(tmp_path, _chirps(0.001, [], 0.0))
    res = pipeline.process_capture(info, elements=None, site=None)
    assert "fewer than one FFT" in res.reason


def test_finite_difference_is_paper_eq5():
    t = np.linspace(0, 2, 21)
    f = 100 - 2500 * t + 40 * t**2
    tm, rate = doppler.finite_difference_rate(t, f)
    np.testing.assert_allclose(rate, -2500 + 80 * tm, atol=1e-9)


def test_local_fit_rate_and_its_sigma_are_calibrated():
    """Over many noise draws the fitted rate is unbiased and its sigma matches the spread."""
    rng = np.random.default_rng(7)
    t = np.arange(0, 2.0, 0.01)
    truth = lambda tt: 1e3 - 1800 * tt + 35 * tt**2  # noqa: E731  rate 1800 - 70 t at t=1: -1730
    est, sig = [], []
    for _ in range(300):
        f = truth(t) + rng.normal(0, 3.0, t.size)
        _, _, a, s, _ = doppler.local_poly_fit(t, f, 1.0, 1.0)
        est.append(a)
        sig.append(s)
    est, sig = np.asarray(est), np.asarray(sig)
    assert abs(est.mean() - (-1730.0)) < 3 * est.std() / np.sqrt(est.size)
    assert 0.85 < est.std() / sig.mean() < 1.15


def test_measurements_refer_doppler_to_the_tone():
    t = np.arange(0, 6.005, 0.01)
    r = Ridge(t, 5e3 - 1000 * t, np.full(t.size, 20.0), 0)
    m = doppler.ridge_measurements(r, rf_center_hz=11.325e9 + 2e3, f_c_hz=11.325e9, interval_s=1.0)
    np.testing.assert_allclose(m.t_s, [1, 2, 3, 4, 5])
    np.testing.assert_allclose(m.doppler_hz, 7e3 - 1000 * m.t_s, atol=1e-6)
    np.testing.assert_allclose(m.rate_hz_s, -1000, atol=1e-6)


def test_synthetic_tone_phase_is_the_integral_of_its_frequency():
    """Block-wise Horner evaluation of the phase spline equals the spline's antiderivative."""
    from scipy.interpolate import CubicSpline

    from leonav_runtime.beacons import synth

    t = np.arange(-1, 7.01, 0.25)
    bb = np.vstack([1e4 - 2000 * t + 30 * t**2])
    truth = synth.SynthTruth(None, np.array([0]), ["a"], np.array([1]), np.array([130.0]), t, bb, bb, 0 * t, bb)
    cfg = synth.SynthConfig(duration_s=6, sample_rate_hz=400e3, noise_rms_codes=1e-3, seed=0)
    x = np.concatenate(list(synth.iter_synthetic_iq(truth, cfg)))
    ts = np.arange(x.size) / 400e3
    phase0 = np.random.default_rng(1).uniform(0, 1, (1, 1))[0, 0]  # the generator's first draw
    ref = CubicSpline(t, bb[0]).antiderivative()(ts) + phase0
    assert x.size == 2_400_000
    assert np.max(np.abs(np.angle(x * np.exp(-2j * np.pi * ref)))) < 5e-3  # rad


def test_local_maxima_are_the_interior_peaks_above_threshold():
    # ties (plateaus of quantized power), NaN, peaks at the band edges and per-row thresholds
    rng = np.random.default_rng(3)
    p = np.round(rng.exponential(1.0, (7, 300)), 1).astype(np.float32)
    p[2, 10:14] = 9.0           # a plateau: only its last bin is a peak (>= before, > after)
    p[3, 0], p[3, -1] = 50, 50  # edge bins are never peaks
    p[4, 100] = np.nan
    p[4, 101] = 30              # a NaN neighbour compares false: not a peak
    thr = np.linspace(0.5, 3.0, 7).astype(np.float32)
    rows, cols = _local_maxima(p, thr)
    mid = p[:, 1:-1]
    want = (mid > thr[:, None]) & (mid >= p[:, :-2]) & (mid > p[:, 2:])
    r, c = np.nonzero(want)
    assert np.array_equal(rows, r) and np.array_equal(cols, c + 1) and rows.size > 50
    found = set(zip(rows.tolist(), cols.tolist()))
    assert (2, 13) in found and not found & {(2, 10), (2, 11), (2, 12), (4, 101)}


def test_births_start_the_strongest_peaks_and_skip_their_side_lobes():
    nb = 400
    f_hz = np.arange(nb) * 10.0
    power = np.ones((1, nb), np.float32)
    # 50 is a side lobe of 54, 124 of 120 (refused: its side lobes are not candidates either)
    strength = {50: 300.0, 54: 900.0, 120: 500.0, 124: 400.0, 200: 700.0, 300: 100.0}
    for k, v in strength.items():
        power[0, k] = v
    blk = SpectrumBlock(np.array([0.0]), power, np.array([1.0], np.float32), np.array([1.0], np.float32))
    tr = RidgeTracker(f_hz, TrackerConfig(max_active=2), hop_s=0.01)
    tr.add_block(blk)
    started = sorted(round(t.f[0] / 10.0) for t in tr.active)
    assert started == [54, 200]                   # the two strongest, by power
    assert tr.stats.births == 2 and tr.stats.births_refused == 2  # 120 and 300 refused; 50 and 124 side lobes


def test_births_order_float64_power_in_its_own_precision():
    power = np.ones((1, 64))
    power[0, 10], power[0, 40] = 1e3, 1e3 + 1e-6   # equal in float32
    blk = SpectrumBlock(np.array([0.0]), power, np.array([1.0]), np.array([1.0]))
    tr = RidgeTracker(np.arange(64) * 10.0, TrackerConfig(max_active=1), hop_s=0.01)
    tr.add_block(blk)
    assert [round(t.f[0] / 10.0) for t in tr.active] == [40]


def test_ridge_rate_is_the_least_squares_slope_of_its_last_second():
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.005, 0.009, 400))
    f = 1e3 + 40.0 * t + 0.5 * t**2 + rng.normal(0, 2.0, t.size)
    track = _Track(float(t[0]), float(f[0]), 20.0)
    for ti, fi in zip(t[1:], f[1:]):
        track.add(float(ti), float(fi), 20.0, 1.0)
    n = len(track.t)
    if n % 4:
        track.refit_rate(1.0)
    last = np.arange(max(0, t.size - 256), t.size)
    keep = last[t[last] >= t[-1] - 1.0]
    slope = np.polyfit(t[keep], f[keep], 1)[0]
    assert track.n_fit == keep.size and abs(track.rate - slope) < 1e-9 * abs(slope)


def test_slices_do_not_depend_on_how_the_capture_is_split_into_blocks():
    # every slice at j * hop, Hann-windowed, whatever the block sizes: blocks shorter than a slice,
    # just over a slice plus a hop (slices that start in the carried samples come from a join),
    # at 75 % and 95 % overlap more such slices than a spectrum block holds; no overlap
    fs, n = 64e3, 512
    rng = np.random.default_rng(2)
    x = (rng.standard_normal(20000) + 1j * rng.standard_normal(20000)).astype(np.complex64)
    for overlap, per_block in ((0.5, 64), (0.75, 2), (0.75, 64), (0.0, 64), (0.95, 3)):
        cfg = StftConfig.for_rate(fs, 40e3, n, overlap)
        idx, _ = band_bins(cfg, fs)
        starts = np.arange(0, x.size - n + 1, cfg.hop)
        frames = np.stack([x[s:s + n] for s in starts]) * np.hanning(n)
        want = np.abs(np.fft.fft(frames, axis=1)[:, idx]) ** 2
        whole = list(iter_spectra([x], cfg, fs, slices_per_block=per_block))
        ref_power = np.vstack([b.power for b in whole])
        np.testing.assert_allclose(ref_power, want, rtol=2e-4, atol=1e-3 * want.max())
        np.testing.assert_array_equal(np.concatenate([b.t_s for b in whole]), (starts + n / 2) / fs)
        for size in (100, 511, n + cfg.hop - 1, n + cfg.hop, 2 * n + 3, 3001):
            got = list(iter_spectra([x[i:i + size] for i in range(0, x.size, size)], cfg, fs,
                                    slices_per_block=per_block))
            assert all(b.power.shape[0] <= per_block for b in got)
            np.testing.assert_array_equal(np.vstack([b.power for b in got]), ref_power, err_msg=f"blocks of {size}")
            np.testing.assert_array_equal(np.concatenate([b.t_s for b in got]), (starts + n / 2) / fs)
    # a hop longer than the FFT (samples between slices are skipped): the carried samples can
    # hold a whole slice
    cfg = StftConfig(32, 64, fs)
    want = [b.power for b in iter_spectra([x], cfg, fs)]
    t_want = (np.arange(0, x.size - 32 + 1, 64) + 16) / fs
    for size in (40, 100, 1960):
        got = list(iter_spectra([x[i:i + size] for i in range(0, x.size, size)], cfg, fs, slices_per_block=2))
        np.testing.assert_array_equal(np.vstack([b.power for b in got]), np.vstack(want), err_msg=f"blocks of {size}")
        np.testing.assert_array_equal(np.concatenate([b.t_s for b in got]), t_want)
