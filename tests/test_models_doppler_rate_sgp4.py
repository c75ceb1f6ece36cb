"""Doppler-rate model fed with SGP4 satellite states vs a numeric second derivative of range.

Real Starlink TLEs (../shared/data/tle/starlink_2026-02-23.txt), static receiver at
Rochester (43.0848638 N, -77.6786127 E, 170 m). The model gets r, v, a from
`leonav_runtime.orbits.propagate_ecef`; the reference is a 5-point second difference of
the range computed from skyfield's independent SGP4 + ITRS positions. 0.05 Hz/s at
11.325 GHz is 1.3 mm/s^2 of range acceleration.
"""
from __future__ import annotations

import datetime as dt
import math
import warnings

import numpy as np
import pytest

from leonav_runtime.gen import state_layout as L
from leonav_runtime.core.params import build_params
from tests.eop_reference import skyfield_timescale_same_eop

LAT, LON, H = 43.0848638, -77.6786127, 170.0
F_C = 11.325e9
C = 299_792_458.0


def test_doppler_rate_matches_second_difference_of_skyfield_range(shared_data):
    orbits = pytest.importorskip("leonav_runtime.orbits", reason="needs leonav_runtime.orbits (other engineer)")
    api = pytest.importorskip("skyfield.api")
    from skyfield.framelib import itrs
    from tests import symbolic

    fns = symbolic.FNS
    tle_path = shared_data / "tle" / "starlink_2026-02-23.txt"
    if not tle_path.exists():
        pytest.skip(f"needs {tle_path}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        elements = orbits.load_elements(tle_path)
    epoch = dt.datetime(2026, 2, 23, 2, 0, 0, tzinfo=dt.timezone.utc)
    t_grid = np.array([0.0, 40.0, 80.0])
    # Same Earth orientation on both sides (UT1-UTC and polar motion from leonav's IERS
    # table): without UT1-UTC (~0.07 s here) the ECEF positions differ by ~20 m along the
    # Earth's rotation, which alone changes the Doppler rate by ~0.2 Hz/s.
    ts = skyfield_timescale_same_eop()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        states = orbits.propagate_ecef(elements, epoch, t_grid)

    p = np.array(build_params(math.radians(LAT), math.radians(LON), H, f_c_hz=F_C))
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0  # level, body forward = East, at rest at the origin
    site = np.array(fns["leonav_receiver_ecef"](x, p)[0]).ravel()
    g_enu = np.array(fns["leonav_gravity_enu"](np.zeros(3), p)).ravel()
    up = site / np.linalg.norm(site)

    r0 = states.r_ecef_m[:, 0, :]
    los = r0 - site
    sin_el = (los @ up) / np.linalg.norm(los, axis=1)
    visible = np.nonzero(states.ok & (sin_el > math.sin(math.radians(25))))[0]
    assert len(visible) >= 4, "expected several Starlink satellites above 25 deg"
    chosen = visible[:: max(1, len(visible) // 6)][:6]

    receiver = api.wgs84.latlon(LAT, LON, H).itrs_xyz.m
    step = 1.0
    names, lines = elements_lines(tle_path, [elements.names[i] for i in chosen])
    errors = []
    for k, i in enumerate(chosen):
        sat = api.EarthSatellite(lines[k][0], lines[k][1], names[k], ts)
        for j, t in enumerate(t_grid):
            aux = np.zeros(L.NAUX)
            aux[L.AUX_R_S_ECEF_SLICE] = states.r_ecef_m[i, j]
            aux[L.AUX_V_S_ECEF_SLICE] = states.v_ecef_mps[i, j]
            aux[L.AUX_A_S_ECEF_SLICE] = states.a_ecef_mps2[i, j]
            aux[L.AUX_F_B_SLICE] = -g_enu  # f_b of a level body at rest
            alpha = float(fns["leonav_h_doppler_rate"](x, aux, p)[0])
            offsets = np.arange(-2, 3) * step
            when = ts.from_datetimes([epoch + dt.timedelta(seconds=float(t + o)) for o in offsets])
            r_sky = sat.at(when).frame_xyz(itrs).m.T
            rho = np.linalg.norm(r_sky - receiver, axis=1)
            rho_ddot = (-rho[4] + 16 * rho[3] - 30 * rho[2] + 16 * rho[1] - rho[0]) / (12 * step**2)
            errors.append(alpha - (-F_C / C * rho_ddot))
            assert abs(alpha) > 1.0  # a visible LEO satellite has a Doppler rate of tens to hundreds of Hz/s
    errors = np.array(errors)
    assert np.abs(errors).max() < 0.03, f"max |alpha error| {np.abs(errors).max():.4f} Hz/s"


def elements_lines(path, wanted_names):
    """(names, [(line1, line2)]) of the wanted satellites from a 3LE file."""
    text = path.read_text().splitlines()
    table = {}
    for n in range(len(text) - 2):
        if text[n + 1].startswith("1 ") and text[n + 2].startswith("2 "):
            table[text[n].strip()] = (text[n + 1], text[n + 2])
    return list(wanted_names), [table[name.strip()] for name in wanted_names]
