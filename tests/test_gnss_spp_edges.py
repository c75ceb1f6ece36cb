"""Single-point positioning at the edges test_spp.py (RTKLIB agreement) does not reach: RAIM at
redundancy 2 and 1, gross errors in a minority of rows, DOPs and the GDOP limit, the URA
classes and limit, the signal chosen per satellite, the Doppler sign and the ionosphere scale
per band, the C/N0 mask at its value. Real data: GEONET 0759 (shared), the DELF / LARM /
ESBC files of tests/data (tests/data/README.md).
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gnss import spp
from leonav_runtime.gnss.ephemeris import Ephemerides
from leonav_runtime.gnss.observations import COLUMNS, ObservationTable
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from leonav_runtime.gnss.signals import (CN0_MASK, EPOCH_UNSOLVED, IMPLAUSIBLE, RAIM_EXCLUDED, URA_TOO_LARGE,
                                         gnss_rows, klobuchar_coefficients, primary_rows, ura_m)
from tests.conftest import shared_file

DATA = Path(__file__).parent / "data" / "rinex"
F_L1, F_B1I = 1575.42e6, 1561.098e6   # Hz (IS-GPS-200, BDS-SIS-ICD B1I)


@pytest.fixture(scope="module")
def geonet():
    obs = read_rinex_obs(shared_file("gnss_rinex/07590920.05o"))
    nf = read_rinex_nav(shared_file("gnss_rinex/07590920.05n"))
    rows = gnss_rows(obs, nf.ephemerides, klobuchar=klobuchar_coefficients(nf.iono), systems="G")
    res = spp.solve(rows, approx_ecef_m=obs.approx_position_ecef_m)
    return obs, nf, rows, res


def _epoch_rows(res, e: int) -> np.ndarray:
    return np.flatnonzero((res.epoch_index == e) & (res.row_status == 0))


def _solve_with(rows, idx, obs, offsets: dict[int, float]):
    r = rows.take(idx)
    r.pseudorange_m = r.pseudorange_m.copy()
    for k, d in offsets.items():
        r.pseudorange_m[k] += d
    return spp.solve(r, approx_ecef_m=obs.approx_position_ecef_m)


def test_raim_excludes_the_faulty_satellite_at_redundancy_2(geonet):
    """6 satellites (2 degrees of freedom): a 300 m error on any one of them is found and
    that satellite, and no other, excluded; the solution moves by metres, not by the error."""
    obs, _nf, rows, res = geonet
    for e in (0, 60, 119):
        idx = _epoch_rows(res, e)[:6]
        assert idx.size == 6
        for bad in range(6):
            s = _solve_with(rows, idx, obs, {bad: 300.0})
            assert spp.EPOCH_STATUS[int(s.status[0])] == "ok_after_exclusion" and s.n_excluded[0] == 1
            assert list(np.flatnonzero(s.row_status == RAIM_EXCLUDED)) == [bad], (e, bad)
            assert s.dof[0] == 1 and np.linalg.norm(s.r_ecef_m[0] - res.r_ecef_m[e]) < 10.0


def test_at_redundancy_1_a_failing_epoch_has_no_solution(geonet):
    """5 satellites (1 degree of freedom): excluding one would leave nothing to check the
    rest with (RTKLIB runs RAIM from 6 satellites too), so the epoch fails the test."""
    obs, _nf, rows, res = geonet
    idx = _epoch_rows(res, 0)[:5]
    ok = _solve_with(rows, idx, obs, {})
    assert spp.EPOCH_STATUS[int(ok.status[0])] == "ok" and ok.dof[0] == 1
    s = _solve_with(rows, idx, obs, {2: 300.0})
    assert spp.EPOCH_STATUS[int(s.status[0])] == "chi2_failed"
    assert s.n_excluded[0] == 0 and np.all(s.row_status == EPOCH_UNSOLVED)
    assert s.counts["epochs_chi2_failed"] == 1 and s.counts["used"] == 0


def test_gross_errors_in_three_of_eight_rows_are_the_ones_flagged(geonet):
    """Codes 30,000 km off (a wrapped or garbled code) on 3 of 8 satellites: those 3 rows, not
    the 5 sound ones, are implausible, and the epoch is solved from the 5."""
    obs, nf, _rows, res = geonet
    e = next(e for e in range(res.t_gps_s.size) if res.ns[e] >= 8)
    t = res.t_gps_s[e]
    o = obs.take(obs.t_gps_s == t)
    rows = gnss_rows(o, nf.ephemerides, klobuchar=None, iono=False, tropo=False, systems="G")
    usable = np.flatnonzero(rows.status == 0)[:8]
    rows = rows.take(usable)
    rows.pseudorange_m = rows.pseudorange_m.copy()
    rows.pseudorange_m[[1, 4, 6]] += 3.0e7
    s = spp.solve(rows, approx_ecef_m=obs.approx_position_ecef_m)
    assert list(np.flatnonzero(s.row_status == IMPLAUSIBLE)) == [1, 4, 6]
    assert s.counts["implausible_pseudorange"] == 3 and s.solved[0] and s.ns[0] == 5


def test_dops_are_those_of_the_used_geometry(geonet):
    """GDOP, PDOP, HDOP, VDOP from the elevations and azimuths of the used satellites, computed
    here from their definition (Q = (G^T G)^-1, G rows: line of sight in ENU and 1)."""
    _obs, _nf, _rows, res = geonet
    solved = np.flatnonzero(res.solved)
    assert solved.size == 120
    for e in solved[::7]:
        k = _epoch_rows(res, e)
        el, az = res.el_rad[k], res.az_rad[k]
        G = np.c_[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el), np.ones(k.size)]
        q = np.diag(np.linalg.inv(G.T @ G))
        want = [np.sqrt(q.sum()), np.sqrt(q[:3].sum()), np.sqrt(q[0] + q[1]), np.sqrt(q[2])]
        np.testing.assert_allclose(res.dop[e], want, rtol=1e-9)


def test_a_gdop_above_the_limit_leaves_the_epoch_unsolved(geonet):
    obs, _nf, rows, res = geonet
    limit = float(np.min(res.dop[:, 0])) - 0.01    # below every epoch's GDOP
    s = spp.solve(rows, spp.SppOptions(max_gdop=limit), approx_ecef_m=obs.approx_position_ecef_m)
    assert np.all(s.status == spp.GDOP_FAILED) and s.counts["epochs_gdop_too_large"] == 120
    assert s.counts["used"] == 0 and np.all(s.row_status[res.row_status == 0] == EPOCH_UNSOLVED)
    assert np.all(res.dop[:, 0] < K.SPP_MAX_GDOP)   # with the default limit: all solved


def _esbc():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return read_rinex_nav(DATA / "ESBC00DNK_R_20201770000_cut_MN.rnx").ephemerides


def test_ura_of_gps_and_qzss_is_the_upper_bound_of_its_class_galileo_sisa_as_broadcast():
    """IS-GPS-200 20.3.3.3.1.3 / IS-QZSS-PNT: a URA of 2.8 m is index 1 (2.4 < URA <= 3.4 m);
    RINEX writes the nominal value, the error model takes the class bound (as RTKLIB)."""
    eph = _esbc()
    d = eph.data
    pick = {s: d[(d["system"] == s[0]) & (d["prn"] == int(s[1:]))][:1] for s in ("G02", "J01", "E14")}
    assert pick["J01"]["accuracy_m"][0] == 2.8 and pick["G02"]["accuracy_m"][0] == 2.0
    assert ura_m(pick["J01"])[0] == 3.4 and ura_m(pick["G02"])[0] == 2.4
    assert ura_m(pick["E14"])[0] == pick["E14"]["accuracy_m"][0] == 3.12


def test_a_satellite_with_a_ura_beyond_300_m_is_not_used(geonet):
    obs, nf, _rows, _res = geonet
    eph = Ephemerides(nf.ephemerides.data.copy(), list(nf.ephemerides.sources))
    eph.data["accuracy_m"][eph.data["prn"] == 7] = 768.0     # URA index 11
    rows = gnss_rows(obs, eph, klobuchar=None, systems="G")
    g07 = rows.prn == 7
    assert g07.sum() > 0 and np.all(rows.status[g07] == URA_TOO_LARGE)
    assert rows.counts["ura_too_large"] == g07.sum() and np.all(rows.status[~g07] != URA_TOO_LARGE)


def test_c_a_code_is_chosen_over_p1():
    """DELF (RINEX 2.11) has C1 and P1 for every GPS satellite: the single-point signal is C/A
    (1C), as RTKLIB's default code priority; P1 (1W) and P2 rows count as other signals."""
    obs = read_rinex_obs(DATA / "delf0010_cut.21o")
    chosen, counts = primary_rows(obs, "G")
    gps = obs.system == "G"
    assert set(obs.signal[gps]) == {"1C", "1W", "2W"}
    assert chosen.size == 4 * 12 and set(obs.signal[chosen]) == {"1C"}
    assert counts["other_signal"] == 2 * 4 * 12 and counts["system_not_used"] == 3 * 4 * 8   # GLONASS: 3 signals


def test_range_rate_has_the_sign_of_the_pseudorange_change():
    """LARM (RINEX 3, 30 s): -lambda D (the GNSS_RANGE_RATE measurement) against the change of
    the pseudorange over each 30 s, both differenced between satellites so that the receiver
    clock drift cancels; they agree to decimetres per second, with the opposite sign they
    would differ by twice the range rates (hundreds of m/s)."""
    obs = read_rinex_obs(DATA / "LARM0010.22O")
    rows = gnss_rows(obs, Ephemerides.empty(), klobuchar=None, systems="G")
    epochs = np.unique(rows.t_gps_s)
    diffs = []
    for t0, t1 in zip(epochs[:-1], epochs[1:]):
        a = {s: k for k, s in enumerate(rows.sat) if rows.t_gps_s[k] == t0}
        b = {s: k for k, s in enumerate(rows.sat) if rows.t_gps_s[k] == t1}
        common = sorted(set(a) & set(b))
        dpr = np.array([rows.pseudorange_m[b[s]] - rows.pseudorange_m[a[s]] for s in common]) / (t1 - t0)
        rr = np.array([0.5 * (rows.range_rate_mps[a[s]] + rows.range_rate_mps[b[s]]) for s in common])
        assert np.all(np.isfinite(rr)) and len(common) >= 8
        diffs.append((dpr - dpr[0]) - (rr - rr[0]))
        assert np.abs(rr - rr[0]).max() > 100.0
    assert np.abs(np.concatenate(diffs)).max() < 0.5


def _table(rows: list[tuple]) -> ObservationTable:
    cols = {name: [] for name, _ in COLUMNS}
    for t, system, prn, signal, pr, cn0 in rows:
        vals = {"t_gps_s": t, "system": system, "prn": prn, "signal": signal, "pseudorange_m": pr,
                "carrier_phase_cyc": np.nan, "doppler_hz": np.nan, "cn0_dbhz": cn0, "sigma_pr_m": np.nan, "lli": 0,
                "ssi": 0, "flags": 1, "freq_slot": 0}
        for name, column in cols.items():
            column.append(vals[name])
    return ObservationTable(**cols)


def test_ionosphere_scale_of_beidou_b1i_and_the_cn0_mask_at_its_value():
    eph = _esbc()
    d = eph.data
    g02 = d[(d["system"] == "G") & (d["prn"] == 2)][0]
    c05 = d[(d["system"] == "C") & (d["prn"] == 5)][0]
    t = float(g02["toe"]) + 60.0
    obs = _table([(t, "G", 2, "1C", 21.5e6, 39.9), (t + 30, "G", 2, "1C", 21.5e6, 40.0),
                  (t + 60, "G", 2, "1C", 21.5e6, 40.1), (float(c05["toe"]) + 60.0, "C", 5, "2I", 37.9e6, 45.0)])
    klob = np.r_[1e-8, 0, 0, 0, 9e4, 0, 0, 0]
    rows = gnss_rows(obs, eph, klobuchar=klob, systems="GC", cn0_mask_dbhz=40.0)
    scale = dict(zip(rows.sat + rows.signal, rows.aux[:, L.AUX_IONO_SCALE]))
    assert scale["G021C"] == 1.0
    assert scale["C052I"] == pytest.approx((F_L1 / F_B1I) ** 2, rel=1e-12)   # 1.0184
    # a C/N0 below the mask is masked, one at the mask is not
    g = rows.system == "G"
    assert list(rows.status[g]) == [CN0_MASK, 0, 0] and rows.counts["below_cn0_mask"] == 1
