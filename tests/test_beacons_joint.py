"""Joint LO offset/drift per capture and tone-comb grouping, on real element sets
(Rochester, 2026-02-23): measurement-level cases built from the predictions, and synthetic
captures whose LO error and tones are known."""
from __future__ import annotations

import dataclasses
import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.beacons import associate, comb, lo_fit, pipeline, predict, synth
from leonav_runtime.beacons.doppler import RidgeMeasurements
from tests.conftest import shared_file

SITE = predict.Site.from_degrees(43.0848638, -77.6786127, 170.0)
START = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)
SPACING = comb.COMB_SPACING_HZ


@pytest.fixture(scope="module")
def elements():
    from leonav_runtime.orbits import load_elements

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_elements(shared_file("tle/starlink_2026-02-23.txt"))


@pytest.fixture(scope="module")
def pred(elements):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return predict.predict_visible(elements, SITE, START, 20.0)


def _meas(rid, t, d, a, sig_d=1.0, sig_a=0.4, rng=None):
    rng = rng or np.random.default_rng(rid)
    n = t.size
    return RidgeMeasurements(rid, t, d + rng.normal(0, sig_d, n), np.full(n, sig_d), a + rng.normal(0, sig_a, n),
                             np.full(n, sig_a), np.full(n, 100), np.full(n, 20.0))


def _with_decoy(pred, row, shift_hz):
    """Predictions plus a DECOY whose Doppler is satellite `row`'s shifted by a constant (same rate)."""
    return dataclasses.replace(
        pred, names=pred.names + ["DECOY"], norad_ids=np.append(pred.norad_ids, 99999),
        doppler_hz=np.vstack([pred.doppler_hz, pred.doppler_hz[row] + shift_hz]),
        rate_hz_s=np.vstack([pred.rate_hz_s, pred.rate_hz_s[row]]),
        elevation_rad=np.vstack([pred.elevation_rad, pred.elevation_rad[row]]),
        sat_index=np.append(pred.sat_index, -1))


def test_common_offset_resolves_a_ridge_that_alone_is_ambiguous(pred):
    """Two candidates differing by a constant 2 kHz: ambiguous per ridge, resolved by the other ridges."""
    rows = [3, 11, 19, 27, 35]
    target = rows[0]
    p2 = _with_decoy(pred, target, 2000.0)
    t = np.arange(1.0, 20.0)
    D, A = pred.at(t)
    b = -31e3 + 0.3 * t  # the capture's common offset and drift
    ms = [_meas(i, t, D[r] + b, A[r] + 0.3) for i, r in enumerate(rows)]
    per_ridge = associate.associate(ms, p2, associate.AssociationConfig(joint_lo=False))
    assert per_ridge[0].status == "ambiguous" and {per_ridge[0].name, per_ridge[0].second_name} == {
        pred.names[target], "DECOY"}
    joint = associate.associate_capture(ms, p2)
    a0 = joint.associations[0]
    assert a0.status == "associated" and a0.name == pred.names[target]
    assert a0.second_name == "DECOY" and a0.ambiguity_ratio > 3
    assert all(a.status == "associated" and a.name == pred.names[r] for a, r in zip(joint.associations, rows))
    assert abs(lo_fit.wrap(joint.lo.offset_hz - b[0], SPACING)) < 5.0
    assert joint.lo.drift_hz_s == pytest.approx(0.3, abs=0.05)
    # the ridge alone cannot confirm itself against its own offset (leave-one-out): still ambiguous
    alone = associate.associate([ms[0]], p2)[0]
    assert alone.status == "ambiguous"


def test_circular_offset_across_the_wrap_and_robust_mean_ignore_outliers():
    v = np.array([SPACING / 2 - 30, -SPACING / 2 + 20, SPACING / 2 - 10, 5000.0])  # 3 agree across the wrap
    c, sig, inl = lo_fit.circular_offset(v, np.full(4, 50.0), SPACING)
    assert abs(lo_fit.wrap(c - (SPACING / 2 - 6.7), SPACING)) < 1.0 and inl.tolist() == [True, True, True, False]
    assert sig == pytest.approx(50 / np.sqrt(3))
    m, s = lo_fit.robust_mean(np.array([0.31, 0.29, 0.30, 0.32, 9.0]), np.full(5, 0.02))
    assert m == pytest.approx(0.305, abs=0.01) and s < 0.05


def _comb_ridges(pred, rows, tones, b, t, band_hz, rng, dropout=0.0):
    """One ridge per tone in the band: measured Doppler d = D + b + k * spacing (k from the channel centre)."""
    D, A = pred.at(t)
    ms, truth = [], []
    ks = np.arange(tones) - tones // 2
    for r in rows:
        for k in ks:
            d = D[r] + b + k * SPACING
            keep = np.abs(d) < band_hz / 2
            if keep.sum() < 3 or rng.uniform() < dropout:
                continue
            truth.append((r, int(k)))
            ms.append(_meas(len(ms), t[keep], d[keep], A[r][keep], rng=rng))
    order = rng.permutation(len(ms))  # ridge ids do not follow the satellites
    out = []
    for new_id, i in enumerate(order):
        ms[i].ridge_id = new_id
        out.append((ms[i], truth[i]))
    return [m for m, _ in out], [tr for _, tr in out]


@pytest.mark.parametrize("tones", [3, 5, 7, 9])
def test_combs_group_every_satellites_tones_and_associate_as_one(pred, tones):
    rng = np.random.default_rng(tones)
    rows = [2, 9, 17, 30]
    t = np.arange(1.0, 15.0)
    b = rng.uniform(-40e3, 40e3) + 0.3 * t
    ms, truth = _comb_ridges(pred, rows, tones, b, t, band_hz=900e3, rng=rng, dropout=0.1)
    res = associate.associate_capture(ms, pred)
    by_ridge = dict(zip([m.ridge_id for m in ms], truth))
    assert len(res.combs) == len({r for r, _ in truth})  # one comb per satellite seen
    for c in res.combs:
        sats = {by_ridge[i][0] for i in c.ridge_ids}
        assert len(sats) == 1
        ks = [by_ridge[i][1] for i in c.ridge_ids]
        assert [k - min(ks) for k in ks] == c.rel_index
        # the combined rate is the inverse-variance mean: sigma falls as 1/sqrt(tones)
        assert np.min(c.measurement.sigma_rate_hz_s) == pytest.approx(0.4 / np.sqrt(np.max(c.n_tones)))
    for a, m in zip(res.associations, ms):
        r, k = by_ridge[m.ridge_id]
        assert a.status == "associated" and a.name == pred.names[r]
        assert (a.tone_index - k) % tones == 0 if not res.lo.pinned else a.tone_index == k
    assert abs(lo_fit.wrap(res.lo.offset_hz - b[0], SPACING)) < 5.0
    assert len(res.filter_measurements) == len(res.combs)  # one measurement per satellite for the filter


def test_tones_outside_the_band_and_full_comb_pin_the_offset(pred):
    """9 tones, a narrow band cuts the outer tones of some satellites; the full comb fixes the index."""
    rng = np.random.default_rng(5)
    t = np.arange(1.0, 10.0)
    D, _ = pred.at(t)
    rows = [int(np.argmin(np.abs(D[:, 0])))] + [2, 9, 17]  # one satellite near 0 Hz: all its tones in band
    b = np.full(t.size, 12345.0)
    band = 2 * (np.max(np.abs(D[rows[0]] + b[0])) + 4 * SPACING) + 1e3
    ms, truth = _comb_ridges(pred, rows, 9, b, t, band_hz=band, rng=rng)
    n_in = {r: sum(tr[0] == r for tr in truth) for r in rows}
    assert n_in[rows[0]] == 9 and min(n_in.values()) < 9  # some tones fell outside the band
    res = associate.associate_capture(ms, pred)
    assert res.lo.pinned and res.lo.offset_hz == pytest.approx(12345.0, abs=5.0)
    assert [a.tone_index for a in res.associations] == [k for _, k in truth]


def _capture(elements, tmp_path, seed, **kw):
    cfg = synth.SynthConfig(sample_rate_hz=400e3, seed=seed, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        info, truth = synth.write_synthetic_capture(tmp_path / f"c{seed}.cu8", elements, SITE,
                                                    START + dt.timedelta(minutes=37 * seed), cfg)
        res = pipeline.process_capture(info, elements, SITE, pipeline.PipelineConfig(band_hz=400e3))
    return res, truth, cfg


def test_capture_with_lo_drift_offset_drift_estimated_and_rate_bias_removed(elements, tmp_path):
    """20 s, LO drift 1 Hz/s plus random walk: b(t) = -(LO error) recovered, rates unbiased."""
    res, truth, cfg = _capture(elements, tmp_path, 2, duration_s=20.0, cn0_dbhz=40.0, lo_offset_hz=-22e3,
                               lo_drift_hz_s=1.0)
    inside = (truth.t_grid_s >= 0) & (truth.t_grid_s <= cfg.duration_s)
    slope, icpt = np.polyfit(truth.t_grid_s[inside], -truth.lo_err_hz[inside], 1)  # best line through -LO error
    lo = res.lo
    assert lo.drift_removed and lo.n_combs == 5
    assert lo.offset_hz == pytest.approx(icpt, abs=10.0)     # Hz
    assert lo.drift_hz_s == pytest.approx(slope, abs=0.1)    # Hz/s
    raw, corrected = [], []
    for m0, m, a in zip(res.ridge_measurements, res.measurements, res.associations):
        assert a.status == "associated" and a.norad_id in truth.norad_ids
        row = list(truth.norad_ids).index(a.norad_id)
        true_rate = lambda tt: np.interp(tt, truth.t_grid_s, truth.rate_hz_s[row])  # noqa: E731
        raw.append(m0.rate_hz_s - true_rate(m0.t_s))
        corrected.append(m.rate_hz_s - true_rate(m.t_s))
    raw, corrected = np.concatenate(raw), np.concatenate(corrected)
    assert np.mean(raw) == pytest.approx(-1.0, abs=0.15)     # the drift biases every measured rate
    assert abs(np.mean(corrected)) < 0.1                     # ... and is gone from what the filter gets
    out = pipeline.write_outputs(res, tmp_path / "out")
    import csv

    rows = list(csv.DictReader(out["measurements"].open()))
    assert {float(r["lo_drift_hz_s"]) for r in rows} == {lo.drift_hz_s}
    assert abs(np.mean([float(r["rate_residual_hz_s"]) for r in rows])) < 0.1


def test_capture_with_tone_combs_some_outside_the_band(elements, tmp_path):
    """3 satellites x 5 tones at 400 kS/s: outer tones leave the band; one comb per satellite."""
    res, truth, cfg = _capture(elements, tmp_path, 1, duration_s=6.0, cn0_dbhz=35.0, tones_per_satellite=5,
                               full_comb_in_band=False, n_satellites=3)
    offsets = (np.arange(5) - 2) * SPACING
    outside = np.abs(truth.baseband_hz[:, :, None] + offsets).max(axis=1) > 0.9 * cfg.sample_rate_hz / 2
    assert outside.any()  # the capture really lost tones at the band edge
    assert len(res.ridges) > 3 * 3 and len(res.combs) == 3
    for c in res.combs:
        names = {a.norad_id for a in res.associations if a.comb_id == c.comb_id}
        assert len(names) == 1 and names <= set(truth.norad_ids)
    assert all(a.status == "associated" for a in res.associations)
    carriers = [m for m, a in zip(res.measurements, res.associations) if a.carrier]
    others = [m for m, a in zip(res.measurements, res.associations) if not a.carrier]
    assert len(carriers) == 3 and all(m.t_s.size == 0 for m in others)  # one filter measurement per satellite
    s = pipeline.summary(res)
    assert s["counts"]["satellites_associated"] == 3 and s["rate_residual_abs_hz_s"]["median"] < 0.8
