"""GNSS signal geometry at the receiver and the broadcast atmosphere models (CasADi SX).

* `look_angles(r_U, r_S)`: receiver geodetic latitude, longitude, height (WGS84, Bowring's
  closed form, `models.frames.geodetic_from_ecef`) and the satellite's elevation and azimuth
  in the receiver's own local level frame (the ellipsoid normal at the receiver, not at the
  ENU origin), from ECEF positions (m).
* `klobuchar_l1_s`: the GPS broadcast ionosphere model, IS-GPS-200 20.3.3.5.2.5 (Figure
  20-4), vertical delay mapped with the ICD's obliquity factor, delay on L1 in seconds. Other
  frequencies scale it by (f_L1 / f)^2 (first-order dispersion).
* `saastamoinen_m`: Saastamoinen's zenith delays (J. Saastamoinen, "Atmospheric correction
  for the troposphere and stratosphere in radio ranging of satellites", AGU Geophysical
  Monograph 15, 1972) with the refinement of the hydrostatic term by Davis et al. (Radio
  Science 20, 1985): ZHD = 0.0022768 P / (1 - 0.00266 cos 2 lat - 0.00028 H_km), ZWD =
  0.002277 (1255 / T + 0.05) e; P, T, e of the standard atmosphere at the receiver height
  (models.constants STD_*), e the water-vapour pressure at the assumed relative humidity
  (saturation pressure 6.108 exp((17.15 T - 4684) / (T - 38.45)) hPa, T in K). Mapping:
  1 / sin(el) for both parts (the simple form single-point software such as RTKLIB uses;
  Niell's hydrostatic mapping function is below it by ~1.6 % at 15 deg, ~3.6 % at 10 deg and
  ~13 % at 5 deg, the order of the standard atmosphere's own error at single-point masks;
  docs/gnss.md). Zero outside
  TROPO_MIN_HEIGHT_M..TROPO_MAX_HEIGHT_M and for el <= 0.

Units: rad, m, s, hPa, K. The ICD's own constants (0.0137, 0.11, 0.416, 1.617, 50400 s,
72000 s, ...) are written where the ICD writes them.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import constants as K
from leonav.models import frames

SECONDS_PER_DAY = 86400.0


def look_angles(r_U, r_S):
    """(lat, lon, h, el, az) of the receiver at r_U and a satellite at r_S (ECEF, m).

    lat, lon (rad), h (m, WGS84 ellipsoidal) of the receiver; elevation (rad) above the
    receiver's local horizon (plane normal to the ellipsoid normal) and azimuth (rad, from
    North towards East, in (-pi, pi]) of the line of sight r_S - r_U.
    """
    lat, lon, h = frames.geodetic_from_ecef(r_U)
    los = r_S - r_U
    enu = frames.C_n_e(lat, lon).T @ (los / ca.norm_2(los))
    return lat, lon, h, ca.asin(enu[2]), ca.atan2(enu[0], enu[1])


def klobuchar_l1_s(lat, lon, el, az, t_sod, coeffs):
    """Ionospheric group delay on L1 (s), IS-GPS-200 20.3.3.5.2.5.

    lat, lon (rad): receiver geodetic position; el, az (rad); t_sod (s): GPS time of day of
    reception; coeffs: alpha0..3, beta0..3 as broadcast (s/semicircle^n). Angles become
    semicircles (rad / pi) as the ICD's algorithm wants them.
    """
    sc = 1.0 / K.GPS_PI
    phi_u, lam_u, E = lat * sc, lon * sc, el * sc
    psi = 0.0137 / (E + 0.11) - 0.022                      # Earth's central angle (semicircles)
    phi_i = ca.fmin(ca.fmax(phi_u + psi * ca.cos(az), -0.416), 0.416)   # ionospheric point latitude
    lam_i = lam_u + psi * ca.sin(az) / ca.cos(phi_i * K.GPS_PI)        # and longitude
    phi_m = phi_i + 0.064 * ca.cos((lam_i - 1.617) * K.GPS_PI)         # geomagnetic latitude
    t = 4.32e4 * lam_i + t_sod                             # local time (s), wrapped into one day
    t = t - SECONDS_PER_DAY * ca.floor(t / SECONDS_PER_DAY)
    F = 1.0 + 16.0 * (0.53 - E) ** 3                       # obliquity factor
    amp = ca.fmax(coeffs[0] + phi_m * (coeffs[1] + phi_m * (coeffs[2] + phi_m * coeffs[3])), 0.0)
    per = ca.fmax(coeffs[4] + phi_m * (coeffs[5] + phi_m * (coeffs[6] + phi_m * coeffs[7])), 72000.0)
    x = 2.0 * ca.pi * (t - 50400.0) / per                  # phase (rad)
    day = amp * (1.0 + x * x * (-0.5 + x * x / 24.0))
    return F * (5.0e-9 + ca.if_else(ca.fabs(x) < 1.57, day, 0.0))


def saastamoinen_m(lat, h, el):
    """Slant tropospheric delay (m): Saastamoinen zenith delays of the standard atmosphere at
    height h (m, clamped to >= 0), mapped with 1 / sin(el); 0 when el <= 0 or h is outside
    TROPO_MIN_HEIGHT_M..TROPO_MAX_HEIGHT_M."""
    hc = ca.fmin(ca.fmax(h, 0.0), K.TROPO_MAX_HEIGHT_M)
    pressure = K.STD_PRESSURE_HPA * (1.0 - 2.2557e-5 * hc) ** 5.2568
    temp = K.STD_TEMPERATURE_K - K.STD_LAPSE_RATE_KPM * hc
    e_w = 6.108 * K.STD_REL_HUMIDITY * ca.exp((17.15 * temp - 4684.0) / (temp - 38.45))
    zhd = 0.0022768 * pressure / (1.0 - 0.00266 * ca.cos(2.0 * lat) - 0.00028 * hc / 1e3)
    zwd = 0.002277 * (1255.0 / temp + 0.05) * e_w
    inside = ca.logic_and(ca.logic_and(el > 0, h >= K.TROPO_MIN_HEIGHT_M), h <= K.TROPO_MAX_HEIGHT_M)
    return ca.if_else(inside, (zhd + zwd) / ca.sin(ca.fmax(el, 1e-3)), 0.0)
