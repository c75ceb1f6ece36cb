"""leonav_runtime.orbits.geometry against independent references.

References: WGS84 defining values at the equator and poles, skyfield's own WGS84 code
(`wgs84.latlon(...).itrs_xyz`, `(sat - topos).at(t).altaz()`), and closed-form DOP of a
symmetric constellation.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.orbits import geometry as g
from tests.conftest import shared_file

ROCHESTER = (43.0848638, -77.6786127, 170.0)  # the paper's site: deg, deg, m


def test_known_points_equator_pole():
    # On the equator at lon 0 the point is (a + h, 0, 0); at the North pole (0, 0, b + h).
    np.testing.assert_allclose(g.geodetic_to_ecef(0.0, 0.0, 0.0), [6378137.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(g.geodetic_to_ecef(0.0, math.pi / 2, 100.0), [0.0, 6378237.0, 0.0], atol=1e-6)
    # Published WGS84 semi-minor axis b = 6356752.314245 m.
    np.testing.assert_allclose(g.geodetic_to_ecef(math.pi / 2, 0.3, 0.0), [0.0, 0.0, 6356752.314245], atol=1e-5)
    np.testing.assert_allclose(g.geodetic_to_ecef(-math.pi / 2, 0.0, 50.0)[2], -6356802.314245, atol=1e-5)


def test_geodetic_to_ecef_matches_skyfield():
    wgs84 = pytest.importorskip("skyfield.api").wgs84
    rng = np.random.default_rng(1)
    lat_deg = np.concatenate([[ROCHESTER[0], 0.0, 89.999, -89.5], rng.uniform(-90, 90, 50)])
    lon_deg = np.concatenate([[ROCHESTER[1], 0.0, 10.0, -170.0], rng.uniform(-180, 180, 50)])
    h_m = np.concatenate([[ROCHESTER[2], 0.0, 3000.0, -50.0], rng.uniform(-400, 9000, 50)])
    ours = g.geodetic_to_ecef(np.radians(lat_deg), np.radians(lon_deg), h_m)
    for i in range(lat_deg.size):
        ref = wgs84.latlon(lat_deg[i], lon_deg[i], elevation_m=h_m[i]).itrs_xyz.m
        np.testing.assert_allclose(ours[i], ref, atol=1e-6, err_msg=f"point {i}")


def test_geodetic_round_trip_mm_from_ground_to_gnss_altitude():
    rng = np.random.default_rng(2)
    n = 20000
    lat = np.radians(rng.uniform(-90, 90, n))
    lat[:4] = np.radians([90.0, -90.0, 0.0, 89.9999999])  # poles and equator explicitly
    lon = np.radians(rng.uniform(-180, 180, n))
    h = rng.uniform(-1000.0, 25_000_000.0, n)  # below the sea down to above GPS orbits
    r = g.geodetic_to_ecef(lat, lon, h)
    lat2, lon2, h2 = g.ecef_to_geodetic(r)
    # Compare in metres: re-project, and compare heights directly.
    np.testing.assert_allclose(g.geodetic_to_ecef(lat2, lon2, h2), r, atol=1e-3)
    np.testing.assert_allclose(h2, h, atol=1e-3)
    # Latitude error along the meridian (m) at the surface scale.
    assert np.max(np.abs(lat2 - lat)) * 6.4e6 < 1e-3


def test_ecef_to_geodetic_matches_skyfield_for_satellite_positions():
    api = pytest.importorskip("skyfield.api")
    ts = api.load.timescale(builtin=True)
    t = ts.utc(2026, 2, 23, 12, 0, 0)
    rng = np.random.default_rng(3)
    for _ in range(10):
        lat_deg, lon_deg, h_m = rng.uniform(-85, 85), rng.uniform(-180, 180), rng.uniform(0, 2.2e7)
        topos = api.wgs84.latlon(lat_deg, lon_deg, elevation_m=h_m)
        r = topos.itrs_xyz.m
        lat, lon, h = g.ecef_to_geodetic(r)
        # skyfield's inverse (its own short iteration, which we measured to be ~2 mm off
        # near the surface) on the same Earth-fixed point: agree to 1 cm on the ground.
        geo = api.wgs84.geographic_position_of(topos.at(t))
        assert abs(math.radians(geo.latitude.degrees) - lat) * 6.4e6 < 1e-2
        assert abs(math.radians(geo.longitude.degrees) - lon) * 6.4e6 < 1e-2
        assert abs(h - geo.elevation.m) < 1e-2
        # And ours recovers the generating coordinates to well under a millimetre.
        assert abs(math.degrees(lat) - lat_deg) * 1.1e5 < 1e-4
        assert abs(h - h_m) < 1e-4


def test_enu_rotation_is_orthonormal_and_round_trips():
    lat0, lon0 = np.radians(ROCHESTER[0]), np.radians(ROCHESTER[1])
    c = g.C_enu_ecef(lat0, lon0)
    np.testing.assert_allclose(c @ c.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(c) == pytest.approx(1.0)
    r0 = g.geodetic_to_ecef(lat0, lon0, ROCHESTER[2])
    # Up is the ellipsoid normal: a point 100 m higher is (0, 0, 100) in ENU.
    np.testing.assert_allclose(
        g.ecef_to_enu(g.geodetic_to_ecef(lat0, lon0, ROCHESTER[2] + 100.0), r0, lat0, lon0), [0, 0, 100], atol=1e-8
    )
    # A point slightly North has a positive North and ~zero East component.
    north = g.ecef_to_enu(g.geodetic_to_ecef(lat0 + 1e-5, lon0, ROCHESTER[2]), r0, lat0, lon0)
    assert north[1] > 60 and abs(north[0]) < 1e-6
    east = g.ecef_to_enu(g.geodetic_to_ecef(lat0, lon0 + 1e-5, ROCHESTER[2]), r0, lat0, lon0)
    assert east[0] > 40 and abs(east[1]) < 1e-3
    p = np.random.default_rng(4).normal(0, 5000, (7, 5, 3))
    np.testing.assert_allclose(g.ecef_to_enu(g.enu_to_ecef(p, r0, lat0, lon0), r0, lat0, lon0), p, atol=1e-7)
    # Batched rotations equal the single one.
    cs = g.C_enu_ecef(np.full(4, lat0), np.full(4, lon0))
    assert cs.shape == (4, 3, 3)
    np.testing.assert_allclose(cs[2], c)


def test_az_el_range_simple_cases():
    lat0, lon0 = np.radians(ROCHESTER[0]), np.radians(ROCHESTER[1])
    r0 = g.geodetic_to_ecef(lat0, lon0, ROCHESTER[2])
    targets_enu = np.array([[0, 0, 550e3], [1000, 0, 0], [0, 1000, 1000], [-1000, 0, 0], [0, -1000, -1000]])
    az, el, rng = g.az_el_range(g.enu_to_ecef(targets_enu, r0, lat0, lon0), r0, lat0, lon0)
    np.testing.assert_allclose(el, np.radians([90, 0, 45, 0, -45]), atol=1e-12)
    np.testing.assert_allclose(az[1:], np.radians([90, 0, 270, 180]), atol=1e-12)
    np.testing.assert_allclose(rng, np.linalg.norm(targets_enu, axis=1), rtol=1e-12)
    assert np.all((az >= 0) & (az < 2 * np.pi))


def test_az_el_against_skyfield_real_tles():
    api = pytest.importorskip("skyfield.api")
    from skyfield.framelib import itrs

    path = shared_file("tle/starlink_2026-02-23.txt")
    lines = path.read_text().splitlines()
    ts = api.load.timescale(builtin=True)
    topos = api.wgs84.latlon(ROCHESTER[0], ROCHESTER[1], elevation_m=ROCHESTER[2])
    sats = [api.EarthSatellite(lines[i + 1], lines[i + 2], lines[i].strip(), ts) for i in range(0, 3 * 200, 3)]
    t = ts.utc(2026, 2, 23, 18, 0, np.arange(0.0, 600.0, 60.0))
    lat0, lon0 = np.radians(ROCHESTER[0]), np.radians(ROCHESTER[1])
    r_rx = topos.itrs_xyz.m
    max_err_deg = 0.0
    for sat in sats:
        # Same Earth-fixed satellite position for both: skyfield's ITRS of the SGP4 state.
        r_sat = sat.at(t).frame_xyz(itrs).m.T  # (nt, 3)
        az, el, rng = g.az_el_range(r_sat, r_rx, lat0, lon0)
        alt_ref, az_ref, dist_ref = (sat - topos).at(t).altaz()
        d_az = (np.degrees(az) - az_ref.degrees + 180.0) % 360.0 - 180.0
        # Azimuth is ill-defined at the zenith: weight its error by cos(el) (arc on the sky).
        err = np.maximum(np.abs(np.degrees(el) - alt_ref.degrees), np.abs(d_az) * np.cos(el))
        max_err_deg = max(max_err_deg, float(np.max(err)))
        np.testing.assert_allclose(rng, dist_ref.m, atol=1e-3)
    # Both sides use the same positions and the same WGS84 normal, so only rounding and
    # skyfield's own topocentric rotation path remain: far below 1e-6 deg.
    assert max_err_deg < 1e-6


def test_visible_mask_and_defaults():
    assert g.ELEVATION_MASK_DEFAULTS_RAD["gps"] == pytest.approx(math.radians(10))
    assert g.ELEVATION_MASK_DEFAULTS_RAD["starlink"] == pytest.approx(math.radians(28))
    assert g.default_mask_rad("Starlink") == pytest.approx(math.radians(28))
    assert g.default_mask_rad("oneweb") == pytest.approx(math.radians(10))
    el = np.radians([27.9, 28.0, 28.1, np.nan, -5])
    np.testing.assert_array_equal(g.visible_mask(el, math.radians(28)), [False, True, True, False, False])


def _ring_with_zenith(n: int, el0_rad: float, az_offset: float = 0.3):
    az = np.concatenate([[0.0], az_offset + 2 * np.pi * np.arange(n) / n])
    el = np.concatenate([[np.pi / 2], np.full(n, el0_rad)])
    return az, el


@pytest.mark.parametrize("n, el0_deg", [(3, 15.0), (4, 30.0), (8, 10.0), (12, 45.0)])
def test_dop_closed_form_ring_plus_zenith(n, el0_deg):
    # One satellite at the zenith and n equally spaced at elevation el0. G^T G is
    # block diagonal: E/N block (n cos^2/2) I, and the (up, clock) block
    # [[1 + n s^2, -(1 + n s)], [-(1 + n s), n + 1]] with determinant n (1 - s)^2.
    s, c = math.sin(math.radians(el0_deg)), math.cos(math.radians(el0_deg))
    det = n * (1 - s) ** 2
    q_ee = 2.0 / (n * c**2)
    q_uu = (n + 1) / det
    q_tt = (1 + n * s**2) / det
    az, el = _ring_with_zenith(n, math.radians(el0_deg))
    d = g.dop(az, el)
    assert d["reason"] == ""
    assert d["n_used"] == n + 1
    assert d["hdop"] == pytest.approx(math.sqrt(2 * q_ee), rel=1e-10)
    assert d["vdop"] == pytest.approx(math.sqrt(q_uu), rel=1e-10)
    assert d["pdop"] == pytest.approx(math.sqrt(2 * q_ee + q_uu), rel=1e-10)
    assert d["tdop"] == pytest.approx(math.sqrt(q_tt), rel=1e-10)
    assert d["gdop"] == pytest.approx(math.sqrt(2 * q_ee + q_uu + q_tt), rel=1e-10)


def test_dop_batched_with_use_mask_and_failures():
    az4, el4 = _ring_with_zenith(4, math.radians(30))
    az8, el8 = _ring_with_zenith(8, math.radians(10))
    # Epoch 0: the 5-satellite geometry padded with 4 unused entries (they must not count).
    # Epoch 1: the 9-satellite geometry. Epoch 2: only 3 usable. Epoch 3: 4 on one cone.
    az = np.zeros((4, 9))
    el = np.zeros((4, 9))
    use = np.zeros((4, 9), dtype=bool)
    az[0, :5], el[0, :5], use[0, :5] = az4, el4, True
    az[0, 5:], el[0, 5:] = 1.0, 0.5  # garbage that is masked out
    az[1], el[1], use[1] = az8, el8, True
    az[2, :3], el[2, :3], use[2, :3] = [0, 2, 4], [0.5, 0.6, 0.7], True
    az[3, :4], el[3, :4], use[3, :4] = [0, 1.5, 3, 4.5], 0.5, True
    d = g.dop(az, el, use)
    ref0, ref1 = g.dop(az4, el4), g.dop(az8, el8)
    for key in g.DOP_KEYS:
        assert d[key][0] == pytest.approx(ref0[key], rel=1e-12)
        assert d[key][1] == pytest.approx(ref1[key], rel=1e-12)
        assert np.isnan(d[key][2]) and np.isnan(d[key][3])
    np.testing.assert_array_equal(d["n_used"], [5, 9, 3, 4])
    assert "fewer than 4 satellites at 1 of 4 epochs" in d["reason"]
    assert "singular geometry at 1 of 4 epochs" in d["reason"]


def test_dop_matches_least_squares_covariance_random_geometry():
    rng = np.random.default_rng(5)
    az = rng.uniform(0, 2 * np.pi, 9)
    el = rng.uniform(np.radians(10), np.radians(85), 9)
    u = g.line_of_sight_enu(az, el)
    h = np.column_stack([-u, np.ones(9)])
    # Independent route: covariance of the least-squares estimate via pseudo-inverse.
    pinv = np.linalg.pinv(h)
    cov = pinv @ pinv.T
    d = g.dop(az, el)
    assert d["gdop"] == pytest.approx(math.sqrt(np.trace(cov)), rel=1e-9)
    assert d["hdop"] == pytest.approx(math.sqrt(cov[0, 0] + cov[1, 1]), rel=1e-9)
