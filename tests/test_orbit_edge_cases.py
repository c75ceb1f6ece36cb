"""Orbit edge cases: non-finite SGP4 output is a named failure; long captures see every pass."""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np

from leonav_runtime.orbits import load_elements, propagate
from tests.conftest import shared_file

UTC = dt.timezone.utc


def _quiet_load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_elements(path)


def test_non_finite_state_without_an_error_code_is_a_named_failure(monkeypatch):
    es = _quiet_load(shared_file("tle/gps-ops_2026-03-09.txt")).select([0, 1, 2])
    real = propagate.propagate_teme

    def nan_for_the_second(elements, epoch, t_s):
        err, r, v = real(elements, epoch, t_s)
        r = r.copy()
        r[1, 1:] = np.nan  # err stays 0: what a decoded-but-absurd element set can do
        return err, r, v

    monkeypatch.setattr(propagate, "propagate_teme", nan_for_the_second)
    st = propagate.propagate_ecef(es, es.epochs_utc[0], [0.0, 60.0, 120.0], warn_stale=False)
    assert st.ok.tolist() == [True, False, True]
    assert "non-finite position" in st.failures[0][2] and "first at t = 60 s" in st.failures[0][2]
    assert np.isnan(st.r_ecef_m[1, 1:]).all() and np.isfinite(st.r_ecef_m[[0, 2]]).all()


def test_long_capture_predictions_include_satellites_visible_only_mid_window():
    from leonav_runtime.beacons.predict import predict_visible
    from leonav_runtime.orbits.geometry import Site

    es = _quiet_load(shared_file("tle/starlink_2026-02-23.txt"))
    site = Site.from_degrees(43.0848638, -77.6786127, 170.0)
    start = dt.datetime(2026, 2, 23, 12, 0, tzinfo=UTC)
    duration = 600.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = predict_visible(es, site, start, duration, step_s=5.0)
    # every satellite above the mask at any epoch of a dense 5 s grid must be a candidate
    from leonav_runtime.orbits.geometry import az_el_range, geodetic_to_ecef

    t_dense = np.arange(0.0, duration + 1.0, 5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        st = propagate.propagate_ecef(es, start, t_dense, acceleration=False)
    r_rx = np.asarray(geodetic_to_ecef(site.lat_rad, site.lon_rad, site.h_m), float)
    _, el, _ = az_el_range(st.r_ecef_m, r_rx, site.lat_rad, site.lon_rad)
    dense = {str(es.names[i]) for i in np.flatnonzero((el >= np.radians(28)).any(axis=1) & st.ok)}
    missing = dense - set(pred.names)
    assert not missing, f"{len(missing)} satellites visible inside the window are not predicted: {sorted(missing)[:5]}"
