"""Predictions vs independent numerics, and satellite association on synthetic captures
made from real Starlink element sets (Rochester, 2026-02-23)."""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.beacons import associate, pipeline, predict, synth
from leonav_runtime.beacons.doppler import RidgeMeasurements
from tests.conftest import shared_file

SITE = predict.Site.from_degrees(43.0848638, -77.6786127, 170.0)
START = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)  # elements' median epoch is day 054
C = 299_792_458.0


@pytest.fixture(scope="module")
def elements():
    from leonav_runtime.orbits import load_elements

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_elements(shared_file("tle/starlink_2026-02-23.txt"))


def test_symbolic_prediction_matches_numerical_derivatives_of_range(elements):
    """Doppler = -(f/c) d(rho)/dt and rate = d(Doppler)/dt, by central differences of SGP4 ranges."""
    from leonav_runtime.orbits.geometry import geodetic_to_ecef
    from leonav_runtime.orbits import propagate_ecef

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = predict.predict_visible(elements, SITE, START, 10.0)
        sub = elements.select(pred.sat_index[:8])
        h = 0.05
        t = np.array([5.0 - h, 5.0, 5.0 + h])
        st = propagate_ecef(sub, START, t, acceleration=False)
    r_rx = np.asarray(geodetic_to_ecef(SITE.lat_rad, SITE.lon_rad, SITE.h_m))
    rho = np.linalg.norm(st.r_ecef_m - r_rx, axis=2)
    f = predict.STARLINK_BEACON_HZ
    d_num = -(f / C) * (rho[:, 2] - rho[:, 0]) / (2 * h)
    a_num = -(f / C) * (rho[:, 2] - 2 * rho[:, 1] + rho[:, 0]) / h**2
    d, a = pred.at(np.array([5.0]))
    assert len(pred.names) > 20  # ~60 Starlink above 28 deg from Rochester
    np.testing.assert_allclose(d[:8, 0], d_num, atol=0.5)   # Hz (of up to +/-260 kHz)
    np.testing.assert_allclose(a[:8, 0], a_num, atol=2.0)   # Hz/s; finite-difference noise ~1 Hz/s


def _trial(elements, tmp_path, seed, cn0, duration=6.0, fs=400e3, **kw):
    start = START + dt.timedelta(minutes=37 * seed)
    cfg = synth.SynthConfig(duration_s=duration, sample_rate_hz=fs, cn0_dbhz=cn0, seed=seed,
                            lo_offset_hz=float(np.random.default_rng(seed).uniform(-30e3, 30e3)), **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        info, truth = synth.write_synthetic_capture(tmp_path / f"t{seed}.cu8", elements, SITE, start, cfg)
        res = pipeline.process_capture(info, elements, SITE, pipeline.PipelineConfig(band_hz=fs))
    return res, truth


@pytest.mark.slow
def test_association_accuracy_over_20_trials(elements, tmp_path):
    """>= 95 % of ridges identified, five tones per capture at 35 dB-Hz, median |delta alpha| <= 0.8 Hz/s."""
    n_ridges = n_right = 0
    residuals = []
    for seed in range(20):
        res, truth = _trial(elements, tmp_path, seed, cn0=35.0)
        assert len(res.ridges) >= 5
        for a in res.associations:
            n_ridges += 1
            n_right += a.status == "associated" and a.norad_id in truth.norad_ids
            if a.status == "associated":
                residuals.append(np.abs(a.rate_residual_hz_s))
        got = sorted(a.norad_id for a in res.associations if a.status == "associated")
        assert len(set(got)) == len(got)  # joint assignment: never one satellite twice
    assert n_right / n_ridges >= 0.95, (n_right, n_ridges)
    assert np.median(np.concatenate(residuals)) <= 0.8


def test_dc_spike_ridge_is_reported_unassociated(elements, tmp_path):
    res, truth = _trial(elements, tmp_path, 3, cn0=38.0, dc_offset_codes=0.6)
    stationary = [a for r, a in zip(res.ridges, res.associations) if abs(np.median(r.f_hz)) < 50]
    assert len(stationary) == 1 and stationary[0].status == "unassociated"
    assert "max_cost" in stationary[0].reason
    assert sum(a.status == "associated" and a.norad_id in truth.norad_ids for a in res.associations) == 5


def _twin(elements, index, mean_anomaly_shift_deg):
    """An element set of satellite `index` plus a train mate `shift` degrees ahead in its orbit."""
    from leonav_runtime.orbits import parse_elements_text
    from leonav_runtime.orbits.tle import checksum

    sat = elements.satrecs[index]
    # rebuild the TLE lines from the stored file to shift the mean anomaly (cols 44-51 of line 2)
    path = shared_file("tle/starlink_2026-02-23.txt")
    lines = path.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("2 ") and int(ln[2:7]) == sat.satnum)
    l1, l2 = lines[k - 1], lines[k]
    m = (float(l2[43:51]) + mean_anomaly_shift_deg) % 360.0
    l2 = l2[:43] + f"{m:8.4f}" + l2[51:68]
    l2 = l2 + str(checksum(l2))
    twin = parse_elements_text(f"TWIN\n{l1}\n{l2}\n", "<twin>")
    return twin


def test_train_mates_are_flagged_ambiguous_not_silently_picked(elements, tmp_path):
    """A satellite 0.005 deg (~0.6 km, 0.08 s) behind another: curves identical within noise."""
    res0, truth = _trial(elements, tmp_path, 5, cn0=38.0)
    target = int(truth.sat_index[0])
    both = elements.concat(_twin(elements, target, 0.005))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = predict.predict_visible(both, SITE, res0.info.start_utc, res0.info.duration_s)
    assoc = associate.associate(res0.measurements, pred)
    hit = [a for a in assoc if a.norad_id == truth.norad_ids[0] or a.name == "TWIN"]
    assert len(hit) == 1 and hit[0].status == "ambiguous"
    assert hit[0].ambiguity_ratio < 1.5 and hit[0].second_cost < 1.5
    assert {hit[0].name, hit[0].second_name} == {truth.names[0], "TWIN"}


def test_longer_window_resolves_a_train(elements):
    """Measurement-level: mates 0.01 deg apart (~1.2 km, 0.16 s) are ambiguous over 2 s, resolved over 20 s."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred0 = predict.predict_visible(elements, SITE, START, 20.0)
        target = int(pred0.sat_index[np.argmax(pred0.elevation_rad[:, 0])])
        both = elements.select([target]).concat(_twin(elements, target, 0.01))
        pred = predict.predict_visible(both, SITE, START, 20.0)
    rng = np.random.default_rng(1)
    status = {}
    for span in (2.0, 20.0):
        t = np.arange(1.0, span + 0.5, 1.0) if span > 2 else np.array([1.0, 2.0])
        d, a = pred.at(t)
        row = pred.names.index(elements.names[target])
        m = RidgeMeasurements(0, t, d[row] - 35e3 + rng.normal(0, 1, t.size), np.full(t.size, 1.0),
                              a[row] + rng.normal(0, 0.5, t.size), np.full(t.size, 0.5),
                              np.full(t.size, 100), np.full(t.size, 20.0))
        status[span] = associate.associate([m], pred)[0]
    assert status[2.0].status == "ambiguous"
    assert status[20.0].status == "associated" and status[20.0].name == elements.names[target]
