"""Capture impairments: each changes the synthetic IQ as stated; none leaves it unchanged."""
from __future__ import annotations

import dataclasses
import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.beacons import impairment_study, predict, synth
from leonav_runtime.beacons.impairments import BlockImpairer, Impairments, image_rejection_db, lo_error_hz
from tests.conftest import shared_file

SITE = predict.Site.from_degrees(43.0848638, -77.6786127, 170.0)
START = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)
FS = 100e3


@pytest.fixture(scope="module")
def elements():
    from leonav_runtime.orbits import load_elements

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_elements(shared_file("tle/starlink_2026-02-23.txt"))


def _tone(f_hz: float, n: int = 1 << 16) -> np.ndarray:
    k = np.arange(n)
    return (0.1 * np.exp(2j * np.pi * f_hz * k / FS)).astype(np.complex64)


def _power_at(x: np.ndarray, f_hz: float) -> float:
    spec = np.abs(np.fft.fft(x * np.hanning(x.size))) ** 2
    k = int(round(f_hz / FS * x.size)) % x.size
    return float(spec[k - 2:k + 3].sum())


def test_iq_imbalance_mirrors_a_tone_at_the_stated_level():
    imp = Impairments(iq_gain_db=0.5, iq_phase_deg=3.0)
    f = 12_500.0
    y = BlockImpairer(imp, FS, 0.05, 0).iq_imbalance(_tone(f))
    measured = 10 * np.log10(_power_at(y, -f) / _power_at(y, f))
    assert measured == pytest.approx(image_rejection_db(imp), abs=0.3)
    assert -30 < image_rejection_db(imp) < -25


def test_phase_noise_is_a_wiener_phase_of_the_linewidth():
    lw, lag = 20.0, 10_000   # Hz, samples (0.1 s)
    incr = []
    for seed in range(40):   # non-overlapping 0.1 s increments of independent realizations
        y = BlockImpairer(Impairments(phase_noise_linewidth_hz=lw), FS, 0.05, seed)(np.ones(1 << 16, np.complex64))
        ph = np.unwrap(np.angle(y).astype(float))[::lag]
        incr.append(np.diff(ph))
    var = np.var(np.concatenate(incr))
    assert var == pytest.approx(2 * np.pi * lw * lag / FS, rel=0.25)


def test_cw_interferer_has_the_stated_carrier_to_noise_density():
    sigma = 10 / 127.5
    imp = Impairments(cw_offset_hz=7_000.0, cw_cn0_dbhz=55.0)
    y = BlockImpairer(imp, FS, sigma, 2)(np.zeros(1 << 16, np.complex64))
    power = np.mean(np.abs(y) ** 2)
    n0 = 2 * sigma**2 / FS
    assert 10 * np.log10(power / n0) == pytest.approx(55.0, abs=0.01)
    assert np.argmax(np.abs(np.fft.fft(y))) == round(7_000.0 / FS * y.size)


def test_lo_warm_up_and_sdr_drift_add_the_stated_frequency_error():
    imp = Impairments(lo_temp_step_hz=3000.0, lo_temp_tau_s=600.0, sdr_ppm=1.0, sdr_ppm_rate_per_s=0.002)
    t = np.array([0.0, 1e-3, 600.0])
    e = lo_error_hz(imp, t, 1.575e9)
    assert e[0] == pytest.approx(1575.0)                                   # 1 ppm of the tuning
    assert (e[1] - e[0]) / 1e-3 == pytest.approx(5.0 + 3.15, rel=1e-3)    # Hz/s: warm-up + crystal drift
    assert e[2] == pytest.approx(3000 * (1 - np.exp(-1)) + 1575 * (1 + 1.2), rel=1e-9)


def _capture(elements, tmp_path, name, **kw):
    cfg = synth.SynthConfig(duration_s=1.0, sample_rate_hz=FS, cn0_dbhz=40.0, seed=4, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, truth = synth.write_synthetic_capture(tmp_path / f"{name}.cu8", elements, SITE, START, cfg)
    return np.fromfile(tmp_path / f"{name}.cu8", np.uint8), truth


def test_no_impairments_leave_the_capture_byte_identical_and_clipping_clips(elements, tmp_path):
    base, _ = _capture(elements, tmp_path, "base")
    off, _ = _capture(elements, tmp_path, "off", impairments=Impairments())
    assert np.array_equal(base, off)
    assert np.mean((base == 0) | (base == 255)) < 1e-4
    clipped, _ = _capture(elements, tmp_path, "clip", noise_rms_codes=45.0)
    assert 1e-3 < np.mean((clipped == 0) | (clipped == 255)) < 0.05


def test_all_impairments_at_30_dbhz_keep_association_correct(elements, tmp_path):
    # the 6 s capture of `leonav impairments` (shorter ones leave train mates ambiguous): ~3 s
    s = impairment_study.one_capture(elements, SITE, START, 0, 30.0, "all", tmp_path)
    assert s.ridges >= 5 and s.wrong == 0
    assert s.correct / s.ridges >= 0.9 and s.satellites_found >= 4


def test_sets_are_each_impairment_alone():
    on = {k: v for k, v in impairment_study.SETS.items() if k not in ("none", "all")}
    assert len(on) == 8
    for name, (imp, extra) in on.items():
        changed = (sum(1 for f in dataclasses.fields(Impairments)
                       if imp is not None and getattr(imp, f.name) != f.default) + len(extra))
        assert changed >= 1, name
