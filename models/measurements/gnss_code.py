"""GNSS code pseudorange (m) and Doppler range rate (m/s) for any constellation (GPS,
Galileo, BeiDou), with broadcast atmosphere corrections and inter-system biases.

Pseudorange (z = the raw pseudorange as the receiver measured it):

    P = |r_S - r_U| + w_ie/c (x_S y_U - y_S x_U) + c_dt + s_E isb_E + s_C isb_C - c dt_sv
        + k_I c I_L1 + k_T T

r_S (aux `r_S_ecef`) is the satellite position at transmit time in the ECEF frame of the
transmit epoch, so the Earth's rotation during the flight is the Sagnac term; r_U the
receiver position at receive time. c dt_sv (aux `sat_clock`[0]) is the broadcast satellite
clock with its relativistic correction minus the group delay of the tracked signal
(TGD/BGD). I_L1: Klobuchar (aux `klobuchar`, `t_sod`), scaled by k_I = (f_L1/f)^2
(aux `iono_scale`, 0 = not applied); T: Saastamoinen with 1/sin(el) mapping, applied when
k_T (aux `tropo_scale`) is 1 (gnss_atmosphere.py). One receiver clock per constellation:
GPS (and QZSS) use c_dt, Galileo c_dt + isb[0], BeiDou c_dt + isb[1] (aux `isb_select`).

Range rate (z = -lambda D, D the Doppler in Hz, positive when the satellite approaches):

    rho_dot = u . (v_S - v_U) + w_ie/c (vx_S y_U + x_S vy_U - vy_S x_U - y_S vx_U) + c_ddt - c ddt_sv

the time derivative of the geometric part above (velocities Earth-relative, ECEF) plus the
receiver clock drift and minus the satellite clock drift (aux `sat_clock`[1]). The rates of
the atmosphere terms (mm/s) are not modelled. All systems share the receiver oscillator, so
there is one drift.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import registry as R
from leonav.models.constants import C_LIGHT_MPS, ISB_RW_PSD_M2PS, OMEGA_IE_RADPS
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.measurements.gnss_atmosphere import klobuchar_l1_s, look_angles, saastamoinen_m
from leonav.models.state import AUX, X


# Inter-system biases: differences of hardware delays, nearly constant (docs/design.md, "State")
STATES = (
    R.StateBlock("isb", 2, "m", "inter-system biases [Galileo - GPS, BeiDou - GPS] of the receiver clock, times c",
                 R.RandomWalk(psd_value=ISB_RW_PSD_M2PS),
                 R.Prior(0.0, doc="started from the single-point clocks of the data (inputs/gnss_obs.py)"),
                 fd_step=1e-2, typical=5.0, truth=R.Truth("zero", "none"),
                 error_doc="inter-system bias errors [Galileo - GPS, BeiDou - GPS]"),
)


def _aux(aux, name):
    return aux[AUX[name].slice]


def delay_terms(x, aux, p):
    """(el, az, iono_m, tropo_m) of a GNSS signal: elevation and azimuth (rad) at the receiver,
    the ionosphere delay of the signal (m, k_I c I_L1) and the troposphere delay (m, k_T T)
    exactly as the pseudorange model adds them."""
    r_U, _ = receiver_ecef(x, p)
    lat, lon, h, el, az = look_angles(r_U, _aux(aux, "r_S_ecef"))
    iono = _aux(aux, "iono_scale") * C_LIGHT_MPS * klobuchar_l1_s(lat, lon, el, az, _aux(aux, "t_sod"),
                                                                   _aux(aux, "klobuchar"))
    tropo = _aux(aux, "tropo_scale") * saastamoinen_m(lat, h, el)
    return el, az, iono, tropo


def receiver_clock_m(x, aux):
    """c_dt of the signal's constellation (m): GPS clock plus the selected inter-system bias."""
    return x[X["c_dt"].offset] + ca.dot(_aux(aux, "isb_select"), x[X["isb"].slice])


def h_pseudorange(x, aux, p):
    """Predicted pseudorange (m)."""
    r_U, _ = receiver_ecef(x, p)
    r_S = _aux(aux, "r_S_ecef")
    sagnac = OMEGA_IE_RADPS / C_LIGHT_MPS * (r_S[0] * r_U[1] - r_S[1] * r_U[0])
    _, _, iono, tropo = delay_terms(x, aux, p)
    return ca.norm_2(r_S - r_U) + sagnac + receiver_clock_m(x, aux) - _aux(aux, "sat_clock")[0] + iono + tropo


def h_range_rate(x, aux, p):
    """Predicted range rate (m/s), i.e. -lambda times the Doppler."""
    r_U, v_U = receiver_ecef(x, p)
    r_S, v_S = _aux(aux, "r_S_ecef"), _aux(aux, "v_S_ecef")
    los = r_S - r_U
    u = los / ca.norm_2(los)
    sagnac_rate = OMEGA_IE_RADPS / C_LIGHT_MPS * (v_S[0] * r_U[1] + r_S[0] * v_U[1] - v_S[1] * r_U[0] - r_S[1] * v_U[0])
    return ca.dot(u, v_S - v_U) + sagnac_rate + x[X["c_ddt"].offset] - _aux(aux, "sat_clock")[1]


OBSERVABLES = (
    R.Observable("GNSS_PSEUDORANGE", "gnss_pseudorange", 10, h_pseudorange, "m", source="gnss", token="pseudorange",
                 stream="gnss_pseudorange", table="gnss_obs",
                 doc="a real receiver's code pseudorange, any constellation, broadcast atmosphere"),
    R.Observable("GNSS_RANGE_RATE", "gnss_range_rate", 11, h_range_rate, "m/s", source="gnss", token="pseudorange",
                 stream="gnss_range_rate", table="gnss_obs", doc="a real receiver's Doppler as a range rate"),
)
