"""The GNSS observables and atmosphere models (generated code, evaluated through navfuncs).

End-to-end agreement with RTKLIB's Klobuchar and Saastamoinen implementations is in
tests/test_spp.py (solutions within 2 mm); here: the models' defining properties.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.orbits.geometry import geodetic_to_ecef
from leonav_runtime.core.navfuncs import NavFunctions
from leonav_runtime.core.params import params_array

LAT, LON, H = math.radians(35.16), math.radians(139.61), 70.0
P = params_array(LAT, LON, H)
KLOB = np.array([1.118e-08, 1.49e-08, -5.96e-08, -5.96e-08, 8.806e04, 1.638e04, -1.966e05, -1.311e05])


@pytest.fixture(scope="module")
def nav():
    return NavFunctions(params=P)


def state(**kw):
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    for name, value in kw.items():
        x[getattr(L, f"X_{name.upper()}_SLICE")] = value
    return x


def sat_at(el_deg, az_deg, rng_m=2.2e7):
    """ECEF of a satellite at elevation/azimuth from the ENU origin."""
    el, az = math.radians(el_deg), math.radians(az_deg)
    from leonav_runtime.orbits.geometry import C_enu_ecef
    los = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    r0 = np.asarray(geodetic_to_ecef(LAT, LON, H), float)
    return r0 + rng_m * (C_enu_ecef(LAT, LON).T @ los)


def aux_for(r_s, *, v_s=(0.0, 0.0, 0.0), t_sod=50400.0, iono=1.0, tropo=1.0, sel=(0.0, 0.0), clock=(0.0, 0.0)):
    a = np.zeros(L.NAUX)
    a[L.AUX_R_S_ECEF_SLICE], a[L.AUX_V_S_ECEF_SLICE] = r_s, v_s
    a[L.AUX_SAT_CLOCK_SLICE], a[L.AUX_T_SOD] = clock, t_sod
    a[L.AUX_IONO_SCALE], a[L.AUX_TROPO_SCALE] = iono, tropo
    a[L.AUX_ISB_SELECT_SLICE], a[L.AUX_KLOBUCHAR_SLICE] = sel, KLOB
    return a


def test_elevation_azimuth_and_saastamoinen(nav):
    terms = nav.gnss_terms(state(), np.array([aux_for(sat_at(e, 40.0)) for e in (90.0, 30.0, 10.0, -5.0)]))
    np.testing.assert_allclose(np.degrees(terms[:3, 0]), [90.0, 30.0, 10.0], atol=1e-6)
    assert math.degrees(terms[1, 1]) == pytest.approx(40.0, abs=1e-6)
    # zenith: ZHD 0.0022768 P / (1 - 0.00266 cos 2lat - 0.00028 h_km) with P of the standard
    # atmosphere at 70 m, plus a wet part of ~0.1 m at 70 % humidity and 14.5 C
    p_hpa = K.STD_PRESSURE_HPA * (1 - 2.2557e-5 * H) ** 5.2568
    zhd = 0.0022768 * p_hpa / (1 - 0.00266 * math.cos(2 * LAT) - 0.00028 * H / 1e3)
    assert 0.08 < terms[0, 3] - zhd < 0.2
    assert terms[1, 3] == pytest.approx(terms[0, 3] / math.sin(math.radians(30.0)), rel=1e-9)  # 1/sin(el)
    assert terms[3, 3] == 0.0  # below the horizon


def test_troposphere_is_zero_above_its_model_height(nav):
    x = state(p_enu=[0.0, 0.0, 20000.0])
    assert nav.gnss_terms(x, aux_for(sat_at(45.0, 0.0)))[0, 3] == 0.0


def test_klobuchar_night_value_obliquity_and_frequency_scaling(nav):
    r_s = sat_at(90.0, 0.0)
    # local time near 02:00 at 139.6 E: the night value 5 ns times the obliquity factor
    night = nav.gnss_terms(state(), aux_for(r_s, t_sod=(2.0 - 139.61 / 15.0) * 3600.0 % 86400.0))[0, 2]
    E = 0.5
    assert night == pytest.approx(K.C_LIGHT_MPS * 5e-9 * (1 + 16 * (0.53 - E) ** 3), rel=1e-12)
    # 14:00 local: the maximum of the cosine, larger than at night
    day = nav.gnss_terms(state(), aux_for(r_s, t_sod=(14.0 - 139.61 / 15.0) * 3600.0))[0, 2]
    assert day > 2 * night
    # L2 scaling: (f1 / f2)^2 as written in aux by the input side
    l2 = nav.gnss_terms(state(), aux_for(r_s, iono=(K.GPS_L1_HZ / K.GPS_L2_HZ) ** 2,
                                          t_sod=(14.0 - 139.61 / 15.0) * 3600.0))[0, 2]
    assert l2 == pytest.approx(day * 1.6469, rel=1e-4)
    # low elevation: larger slant delay
    low = nav.gnss_terms(state(), aux_for(sat_at(10.0, 0.0), t_sod=(14.0 - 139.61 / 15.0) * 3600.0))[0, 2]
    assert 2.0 < low / day < 3.5


def test_gnss_pseudorange_without_corrections_equals_the_paper_pseudorange(nav):
    """With the atmosphere off, a GPS signal and a zero satellite clock, GNSS_PSEUDORANGE is the
    paper's PSEUDORANGE (range + Sagnac + c_dt), and its H the same."""
    x = state(p_enu=[12.0, -30.0, 4.0], c_dt=[1234.5], isb=[7.0, -9.0])
    a = aux_for(sat_at(35.0, 200.0), iono=0.0, tropo=0.0)
    h1, H1 = nav.h_many("gnss_pseudorange", x, a, P)
    h0, H0 = nav.h_many("pseudorange", x, a, P)
    assert h1[0] == pytest.approx(h0[0], abs=1e-8)
    np.testing.assert_allclose(H1, H0, atol=1e-12)


def test_clock_per_constellation_and_satellite_clock(nav):
    x = state(c_dt=[100.0], isb=[7.0, -9.0])
    r_s = sat_at(50.0, 10.0)
    h = {name: nav.h_many("gnss_pseudorange", x, aux_for(r_s, iono=0.0, tropo=0.0, sel=sel, clock=(3.0, 0.0)), P)
         for name, sel in (("G", (0, 0)), ("E", (1, 0)), ("C", (0, 1)))}
    assert h["E"][0][0] - h["G"][0][0] == pytest.approx(7.0, abs=1e-7)
    assert h["C"][0][0] - h["G"][0][0] == pytest.approx(-9.0, abs=1e-7)
    H = h["E"][1][0]
    assert H[L.DX_DC_DT] == 1.0 and H[L.DX_DISB] == 1.0 and H[L.DX_DISB + 1] == 0.0
    no_clock = nav.h_many("gnss_pseudorange", x, aux_for(r_s, iono=0.0, tropo=0.0), P)[0][0]
    assert no_clock - h["G"][0][0] == pytest.approx(3.0, abs=1e-7)


def test_range_rate_is_the_time_derivative_of_the_pseudorange(nav):
    """Receiver and satellite moving, clocks drifting, atmosphere off: the generated range rate
    equals a central difference of the generated pseudorange (geometry + Sagnac + clocks)."""
    r_s0, v_s = sat_at(40.0, 120.0), np.array([1500.0, -2500.0, 2100.0])
    p0, v_u = np.array([5.0, -3.0, 1.0]), np.array([12.0, -4.0, 0.5])
    c_dt, c_ddt, sat_c, sat_d = 300.0, 80.0, 1e4, -0.7

    def pr(t):
        x = state(p_enu=p0 + v_u * t, v_enu=v_u, c_dt=[c_dt + c_ddt * t], c_ddt=[c_ddt])
        a = aux_for(r_s0 + v_s * t, v_s=v_s, iono=0.0, tropo=0.0, clock=(sat_c + sat_d * t, sat_d))
        return nav.h_many("gnss_pseudorange", x, a, P, jacobian=False)[0][0]

    x0 = state(p_enu=p0, v_enu=v_u, c_dt=[c_dt], c_ddt=[c_ddt])
    rr = nav.h_many("gnss_range_rate", x0, aux_for(r_s0, v_s=v_s, iono=0.0, tropo=0.0, clock=(sat_c, sat_d)), P)[0][0]
    dt = 1e-3
    assert rr == pytest.approx((pr(dt) - pr(-dt)) / (2 * dt), abs=2e-5)
