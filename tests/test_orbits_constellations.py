"""Generated Walker constellations: valid TLE text, and the geometry they were asked for."""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.orbits import (
    default_elements,
    gps_walker_tle,
    parse_elements_text,
    propagate_ecef,
    propagate_teme,
    starlink_walker_tle,
)
from leonav_runtime.orbits.constellations import (
    GPS_NORAD_BASE,
    R_EQUATOR_KM,
    STARLINK_SHELLS,
)
from leonav_runtime.orbits.tle import checksum

EPOCH = dt.datetime(2026, 3, 1, 6, 0, 0, tzinfo=dt.timezone.utc)


@pytest.fixture(scope="module")
def builtin():
    return default_elements(EPOCH)


def _element_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line[:2] in ("1 ", "2 ")]


def test_text_has_valid_checksums_and_parses_back(builtin):
    for text, count in ((starlink_walker_tle(EPOCH), 9616), (gps_walker_tle(EPOCH), 31)):
        lines = _element_lines(text)
        assert len(lines) == 2 * count
        assert all(len(line) == 69 and int(line[68]) == checksum(line) for line in lines)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # not a single rejected entry
            parsed = parse_elements_text(text, "gen")
        assert len(parsed) == count and parsed.rejected == []
    starlink, gps = builtin["starlink"], builtin["gps"]
    assert starlink.constellation == "starlink" and gps.constellation == "gps"
    assert starlink.names[0] == "STARLINK-W53-0001" and gps.names[0].startswith("GPS-W A1 (PRN 01)")
    ids = np.concatenate([gps.norad_ids, starlink.norad_ids])
    assert len(set(ids.tolist())) == len(ids) and ids.min() >= 90000 and ids.max() <= 99999
    assert gps.norad_ids[0] == GPS_NORAD_BASE
    assert np.all(np.abs(starlink.ages_s(EPOCH)) < 1e-3)  # epoch written to 1e-8 day


def _orbit_geometry(elements, epoch, period_s):
    """Mean radius (km), inclination and RAAN (deg) from one orbit of propagated TEME states."""
    t_s = np.linspace(0.0, period_s, 73)[:-1]
    err, r_km, v_kmps = propagate_teme(elements, epoch, t_s)
    assert not err.any()
    mean_radius_km = np.linalg.norm(r_km, axis=-1).mean(axis=1)
    h = np.cross(r_km, v_kmps).mean(axis=1)
    incl_deg = np.degrees(np.arccos(h[:, 2] / np.linalg.norm(h, axis=1)))
    raan_deg = np.degrees(np.arctan2(h[:, 0], -h[:, 1])) % 360.0
    return mean_radius_km, incl_deg, raan_deg


def test_starlink_shells_altitude_inclination_and_plane_spacing(builtin):
    starlink = builtin["starlink"]
    assert sum(s.total for s in STARLINK_SHELLS) == len(starlink) == 9616
    first = 0
    for shell in STARLINK_SHELLS:
        # first satellite of every plane of the shell
        rows = first + np.arange(shell.planes) * shell.per_plane
        first += shell.total
        sub = starlink.select(rows)
        # SGP4's mean semi-major axis is exactly R_E + h; the orbit-averaged radius differs
        # from it by SGP4's J2 short-period terms (a few km, largest at high inclination)
        a_km = np.array([s.a * s.radiusearthkm for s in sub.satrecs])
        np.testing.assert_allclose(a_km, R_EQUATOR_KM + shell.altitude_km, atol=1e-3)
        radius, incl, raan = _orbit_geometry(sub, EPOCH, 5800.0)
        assert np.all(np.abs(radius - R_EQUATOR_KM - shell.altitude_km) < 5.0), (shell.label, radius)
        assert np.all(np.abs(incl - shell.inclination_deg) < 0.05), (shell.label, incl)
        spacing = np.diff(np.unwrap(np.radians(raan)))
        np.testing.assert_allclose(np.degrees(spacing), 360.0 / shell.planes, atol=0.05)
        assert all(n.startswith(f"STARLINK-W{round(shell.inclination_deg):02d}-") for n in sub.names)
    # satellites of one plane are evenly spread in mean anomaly
    plane = starlink.select(np.arange(22))
    m = np.degrees([s.mo for s in plane.satrecs])
    np.testing.assert_allclose(np.diff(m), 360.0 / 22, atol=1e-3)


def test_gps_planes_altitude_and_period(builtin):
    gps = builtin["gps"]
    assert len(gps) == 31
    periods_s = np.array([2 * np.pi / s.no_kozai * 60.0 for s in gps.satrecs])  # Kozai: TLE mean motion
    mean_motion_period_s = np.array([2 * np.pi / s.no * 60.0 for s in gps.satrecs])  # SGP4 (Brouwer)
    sidereal_half_day_s = 11 * 3600 + 58 * 60 + 2
    assert np.all(np.abs(mean_motion_period_s - sidereal_half_day_s) < 30.0), mean_motion_period_s
    assert np.all(np.abs(periods_s - sidereal_half_day_s) < 60.0)
    radius, incl, raan = _orbit_geometry(gps, EPOCH, sidereal_half_day_s)
    assert np.all(np.abs(radius - 26559.7) < 5.0)
    assert np.all(np.abs(incl - 55.0) < 0.05)
    planes = np.round(raan / 60.0).astype(int) % 6
    off_deg = (raan - planes * 60.0 + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(off_deg) < 0.1)  # RAANs 0, 60, ..., 300 deg (mean over an orbit)
    assert planes.tolist() == [0] * 6 + [1] * 5 + [2] * 5 + [3] * 5 + [4] * 5 + [5] * 5
    # after one revolution the satellite is back near its start (in TEME, J2 drift aside)
    err, r_km, _ = propagate_teme(gps, EPOCH, [0.0, float(np.mean(mean_motion_period_s))])
    assert np.all(np.linalg.norm(r_km[:, 1] - r_km[:, 0], axis=-1) < 50.0)


def test_builtin_sets_propagate_through_the_common_path(builtin):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # fresh elements: no stale warning, no failures
        states = propagate_ecef(builtin["starlink"], EPOCH, np.array([0.0, 60.0]))
    assert states.ok.all() and np.isfinite(states.r_ecef_m).all()
    speed = np.linalg.norm(states.v_ecef_mps, axis=-1)
    assert np.all((speed > 6.5e3) & (speed < 8.0e3))
