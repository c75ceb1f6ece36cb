"""Association under an LO that drifts (both signs), the association thresholds at their
edges, and the LO fit's robust estimators on cases small enough to check by hand.

Measurement-level captures are built from real Starlink predictions (Rochester,
2026-02-23): measured Doppler d = D + b0 + b1 t (+ noise) and measured rate a = alpha + b1,
b(t) = b0 + b1 t the common LO offset seen by every satellite of the capture.
"""
from __future__ import annotations

import dataclasses
import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.beacons import associate, comb, lo_fit, predict
from leonav_runtime.beacons.doppler import RidgeMeasurements
from tests.conftest import shared_file

SITE = predict.Site.from_degrees(43.0848638, -77.6786127, 170.0)
START = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)
SPACING = comb.COMB_SPACING_HZ
ROWS = [3, 11, 19, 27, 35]


@pytest.fixture(scope="module")
def pred():
    from leonav_runtime.orbits import load_elements

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        elements = load_elements(shared_file("tle/starlink_2026-02-23.txt"))
        return predict.predict_visible(elements, SITE, START, 40.0)


def _meas(rid, t, d, a, sig_d=1.0, sig_a=0.4, seed=None):
    rng = np.random.default_rng(rid if seed is None else seed)
    n = t.size
    return RidgeMeasurements(rid, t, d + rng.normal(0, sig_d, n), np.full(n, sig_d), a + rng.normal(0, sig_a, n),
                             np.full(n, sig_a), np.full(n, 100), np.full(n, 20.0))


def _capture(pred, b0, b1, rows=ROWS, t=None, rate_bias=None):
    t = np.arange(1.0, 31.0) if t is None else t
    D, A = pred.at(t)
    bias = rate_bias or [0.0] * len(rows)
    return [_meas(i, t, D[r] + b0 + b1 * t, A[r] + b1 + bias[i]) for i, r in enumerate(rows)], t


@pytest.mark.parametrize("b1", [-4.0, -1.5, 1.5, 4.0])
def test_lo_drift_of_either_sign_is_estimated_and_removed(pred, b1):
    """The comb costs, the LO consistency and the filter's rates are as good as without drift."""
    b0 = -27e3
    ms, t = _capture(pred, b0, b1)
    res = associate.associate_capture(ms, pred)
    assert all(a.status == "associated" and a.name == pred.names[r] for a, r in zip(res.associations, ROWS))
    lo = res.lo
    assert lo.drift_removed and lo.n_combs == 5
    assert lo.drift_hz_s == pytest.approx(b1, abs=0.05)
    assert abs(lo_fit.wrap(lo.offset_hz - b0, SPACING)) < 3.0            # offset at t = 0, not at mid-capture
    _, A = pred.at(t)
    for a, m, r in zip(res.associations, ms, ROWS):
        assert a.cost < 1.0                              # drift removed in both the Doppler and the rate terms
        assert a.rms_doppler_hz < 3.0 and a.rms_rate_hz_s < 1.0
        assert abs(a.lo_deviation_hz) < 5.0              # each comb agrees with the others' offset at t = 0
        assert abs(np.mean(a.rate_residual_hz_s)) < 0.3  # reported residuals: drift removed
        f = res.filter_measurements[a.ridge_id]
        assert f.rate_hz_s == pytest.approx(m.rate_hz_s - lo.drift_hz_s)
        assert f.sigma_rate_hz_s == pytest.approx(np.hypot(m.sigma_rate_hz_s, lo.sigma_drift_hz_s))
        assert abs(np.mean(f.rate_hz_s - A[r])) < 0.3    # what the filter gets is unbiased
    # the same capture without drift removal: every rate is biased by b1
    kept = associate.associate_capture(ms, pred, associate.AssociationConfig(remove_drift=False))
    f = kept.filter_measurements[0]
    assert np.mean(f.rate_hz_s - A[ROWS[0]]) == pytest.approx(b1, abs=0.3)
    assert not kept.lo.drift_removed and "switched off" in kept.lo.note


def test_one_comb_does_not_remove_the_drift(pred):
    ms, _ = _capture(pred, 5e3, 2.0, rows=ROWS[:1])
    res = associate.associate_capture(ms, pred)
    assert res.associations[0].status in ("associated", "ambiguous")
    assert not res.lo.drift_removed and "need 2" in res.lo.note


def test_combs_whose_slopes_disagree_do_not_remove_the_drift(pred):
    ms, _ = _capture(pred, 5e3, 0.0, rate_bias=[-3.0, 3.0, -3.0, 3.0, 0.0],
                     t=np.arange(1.0, 6.0))   # short: the rate means set each comb's slope
    res = associate.associate_capture(ms, pred, associate.AssociationConfig(max_cost=50.0))
    assert not res.lo.drift_removed and "scatter" in res.lo.note


def _candidates(pred, rows, extra=()):
    """Predictions of `rows` plus decoys: (name, row, Doppler shift Hz, rate shift Hz/s)."""
    names = [pred.names[r] for r in rows] + [e[0] for e in extra]
    D = [pred.doppler_hz[r] for r in rows] + [pred.doppler_hz[e[1]] + e[2] for e in extra]
    A = [pred.rate_hz_s[r] for r in rows] + [pred.rate_hz_s[e[1]] + e[3] for e in extra]
    el = [pred.elevation_rad[r] for r in rows] + [pred.elevation_rad[e[1]] for e in extra]
    return dataclasses.replace(pred, names=names, norad_ids=np.arange(len(names)) + 90000,
                               doppler_hz=np.vstack(D), rate_hz_s=np.vstack(A), elevation_rad=np.vstack(el),
                               sat_index=np.arange(len(names)))


def _single(pred, row, rate_bias, t=np.arange(1.0, 11.0)):
    D, A = pred.at(t)
    return RidgeMeasurements(0, t, D[row] - 12e3, np.full(t.size, 1.0), A[row] + rate_bias, np.full(t.size, 0.4),
                             np.full(t.size, 100), np.full(t.size, 20.0))


@pytest.mark.parametrize("rate_bias, status", [(11.0, "associated"), (20.0, "unassociated")])
def test_max_cost_default_is_five(pred, rate_bias, status):
    """A ridge whose rate is off by b (Hz/s) costs b / (2 sqrt 2) with the 2 Hz/s floor: 3.9 passes, 7.1 does not."""
    cands = _candidates(pred, [ROWS[0], ROWS[2]])
    a = associate.associate([_single(pred, ROWS[0], rate_bias)], cands)[0]
    assert a.cost == pytest.approx(rate_bias / (2 * np.sqrt(2)), rel=0.02)
    assert a.status == status
    if status == "unassociated":
        assert "> max_cost 5" in a.reason


@pytest.mark.parametrize("decoy_rate, status", [(7.6, "ambiguous"), (9.9, "associated")])
def test_ambiguity_ratio_default_is_one_and_a_half(pred, decoy_rate, status):
    """Best cost 2.0 (rate off by 5.66 Hz/s); a decoy 7.6 Hz/s further costs 2.7 (ratio 1.35 < 1.5):
    ambiguous; at 9.9 Hz/s it costs 3.5 (ratio 1.75): associated."""
    r = ROWS[0]
    cands = _candidates(pred, [r], extra=[("DECOY", r, 0.0, 5.657 + decoy_rate)])
    a = associate.associate([_single(pred, r, 5.657)], cands)[0]
    assert a.cost == pytest.approx(2.0, rel=0.02) and a.name == pred.names[r]
    assert a.second_name == "DECOY" and a.status == status
    assert a.ambiguity_ratio == pytest.approx(a.second_cost / a.cost)


def test_ratio_is_taken_against_a_best_cost_of_at_least_one(pred):
    """Best cost 0.3, second 1.2: 4x apart, but both within the model's own error: ambiguous."""
    r = ROWS[0]
    cands = _candidates(pred, [r], extra=[("DECOY", r, 0.0, 3.4)])
    a = associate.associate([_single(pred, r, 0.0)], cands)[0]
    assert a.cost < 0.5 and 1.0 < a.second_cost < 1.5
    assert a.status == "ambiguous" and a.ambiguity_ratio == pytest.approx(a.second_cost)


def test_a_single_epoch_is_too_short(pred):
    cands = _candidates(pred, ROWS)
    a = associate.associate([_single(pred, ROWS[0], 0.0, t=np.array([3.0]))], cands)[0]
    assert a.status == "unassociated" and a.reason == "only 1 measurement epoch(s); need 2"
    a = associate.associate([_single(pred, ROWS[0], 0.0, t=np.array([3.0, 4.0]))], cands)[0]
    assert a.status != "unassociated"


def test_ambiguous_combs_stay_out_of_the_capture_lo(pred):
    """A train mate (identical curves) makes one comb ambiguous: the LO comes from the other four."""
    cands = _candidates(pred, ROWS, extra=[("MATE", ROWS[1], 0.0, 0.0)])
    ms, _ = _capture(pred, 31e3, 1.0)
    res = associate.associate_capture(ms, cands)
    status = [a.status for a in res.associations]
    assert status == ["associated", "ambiguous", "associated", "associated", "associated"]
    assert res.lo.n_combs == 4 and 1 not in res.filter_measurements
    assert res.lo.drift_hz_s == pytest.approx(1.0, abs=0.05)


def test_filter_doppler_is_referred_to_the_central_tone(pred):
    """Combs of 9 tones k = -4..4 at b + k * spacing: the filter gets the central tone's Doppler."""
    t = np.arange(1.0, 16.0)
    D, A = pred.at(t)
    b = 20e3 + 0.5 * t
    ms = []
    for r in ROWS[:3]:
        for k in range(-4, 5):
            ms.append(_meas(len(ms), t, D[r] + b + k * SPACING, A[r] + 0.5))
    res = associate.associate_capture(ms, pred)
    assert res.lo.pinned and len(res.filter_measurements) == 3
    for c in res.combs:
        f = res.filter_measurements[c.carrier_ridge_id]
        r = next(r for r in ROWS if pred.names[r] == res.associations[c.ridge_ids[0]].name)
        assert np.mean(f.doppler_hz - D[r] - b) == pytest.approx(0.0, abs=2.0)
    assert res.lo.offset_hz == pytest.approx(20e3, abs=3.0)


# ---- lo_fit estimators by hand ------------------------------------------------------------


def test_wrap_is_centred():
    assert lo_fit.wrap(-1.0, 10.0) == -1.0 and lo_fit.wrap(6.0, 10.0) == -4.0
    assert lo_fit.wrap(5.0, 10.0) == -5.0 and lo_fit.wrap(-5.0, 10.0) == -5.0
    assert lo_fit.wrap(23.0, 10.0) == pytest.approx(3.0)


def test_robust_mean_drops_values_beyond_three_sigma_and_inflates_by_scatter():
    m, s = lo_fit.robust_mean(np.array([0.31, 0.29, 0.30, 0.32, 0.50]), np.full(5, 0.02))
    assert m == pytest.approx(0.305, abs=1e-9) and s == pytest.approx(0.02 / 2)   # scatter below sigma: no inflation
    v = np.array([0.0, 2.0, -2.0, 2.5, -2.5])
    m, s = lo_fit.robust_mean(v, np.ones(5))
    assert m == pytest.approx(0.0, abs=1e-12)
    assert s == pytest.approx(np.sqrt(np.sum(v**2) / 4) / np.sqrt(5))   # chi2 = 5.1 inflates 1/sqrt(5)


def test_circular_offset_prefers_the_largest_consistent_group():
    """Three combs agree at 0, three others scatter at 20 and 40 (5 Hz sigma): the centre is 0."""
    c, sig, inl = lo_fit.circular_offset(np.array([0.0, 1.0, -1.0, 20.0, 40.0, 41.0]), np.full(6, 5.0), 9000.0)
    assert c == pytest.approx(0.0, abs=1e-9) and inl.tolist() == [True, True, True, False, False, False]
    assert sig == pytest.approx(5.0 / np.sqrt(3))


def test_comb_residual_takes_the_more_precise_drift_estimate():
    t = np.arange(0.0, 60.0)
    jerk_rate = 100.0 - 0.5 * t                 # predicted rate, jerk -0.5 Hz/s^2
    # long comb, precise Doppler: its slope (1.0) wins over a rate mean biased to 1.8 with sigma 5
    r = lo_fit.comb_residual(t, 7.0 + 1.0 * t, np.full(t.size, 0.5), np.full(t.size, 1.8), np.full(t.size, 5.0),
                             jerk_rate, 0.1, 50.0, 0.02)
    sig_fit = 0.5 / np.sqrt(np.sum((t - t.mean()) ** 2))
    assert r.slope_hz_s == pytest.approx(1.0) and r.intercept(1.0) == pytest.approx(7.0)
    assert r.sigma_slope_hz_s == pytest.approx(np.sqrt(sig_fit**2 + (0.5 * 0.1) ** 2 + 0.02**2))
    # short comb, precise rates: the rate mean (1.8) wins over the noisy Doppler slope
    t = np.arange(0.0, 3.0)
    r = lo_fit.comb_residual(t, 7.0 + 1.0 * t, np.full(3, 20.0), np.full(3, 1.8), np.full(3, 0.1),
                             100.0 - 0.5 * t, 0.1, 50.0, 0.02)
    assert r.slope_hz_s == pytest.approx(1.8)
    assert r.mean_t_s == 1.0 and r.intercept(1.8) == pytest.approx(8.0 - 1.8)
    # the rates of neighbouring epochs share half their fit window: sigma of their mean is sqrt(2) larger
    sig_rate = np.sqrt(2 * 0.1**2 / 3)
    assert r.sigma_slope_hz_s == pytest.approx(np.sqrt(sig_rate**2 + (0.5 * 0.1) ** 2 + 0.02**2))
    # offset sigma: the 50 Hz floor and alpha * sigma_t (rms predicted rate 99.5 Hz/s), plus the fit
    rms_rate = np.sqrt(np.mean((100.0 - 0.5 * t) ** 2))
    assert r.sigma_offset_hz == pytest.approx(np.hypot(np.hypot(50.0, 0.1 * rms_rate), 20.0 / np.sqrt(3)))


def test_combs_without_all_tones_leave_the_offset_ambiguous_by_the_spacing(pred):
    """5 of the 9 tones per satellite: the channel index is not fixed, the offset is known modulo the spacing."""
    t = np.arange(1.0, 16.0)
    D, A = pred.at(t)
    tones = [(r, k) for r in ROWS[:3] for k in range(-2, 3)]
    ms = [_meas(i, t, D[r] + 20e3 + k * SPACING, A[r]) for i, (r, k) in enumerate(tones)]
    res = associate.associate_capture(ms, pred)
    assert not res.lo.pinned and "modulo the tone spacing" in res.lo.note
    assert abs(lo_fit.wrap(res.lo.offset_hz - 20e3, SPACING)) < 3.0
