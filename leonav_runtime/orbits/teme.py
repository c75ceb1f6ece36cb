"""TEME (SGP4's frame) to Earth-fixed ECEF/ITRF, as in Vallado's teme2ecef (AIAA 2006-6753).

r_pef = R3(gmst) r_teme,  v_pef = R3(gmst) v_teme - w x r_pef,  r_ecef = PM^T r_pef,
with GMST from the IAU-1982 expression evaluated at UT1 = UTC + (UT1-UTC), Earth rate
w = 7.292115146706979e-5 rad/s and the polar-motion matrix PM = R1(yp) R2(xp).
"""
from __future__ import annotations

import numpy as np
from leonav_runtime.gen.constants import OMEGA_EARTH_TEME_RADPS

OMEGA_EARTH_RADPS = OMEGA_EARTH_TEME_RADPS  # Vallado's teme2ecef (LOD = 0)
JD_J2000 = 2451545.0
DAY_S = 86400.0


def gmst82_rad(jd_ut1_whole: np.ndarray | float, jd_ut1_frac: np.ndarray | float) -> np.ndarray:
    """Greenwich mean sidereal time (IAU 1982), rad in [0, 2 pi), from a split UT1 Julian date.

    The 36525-day-per-century term of the polynomial is a whole number of turns plus the
    fraction of the day, so it is added as `frac(jd)`; the rest is tiny and keeps full
    precision (the split JD avoids the ~40 us resolution of a single float JD).
    """
    whole = np.asarray(jd_ut1_whole, dtype=float)
    frac = np.asarray(jd_ut1_frac, dtype=float)
    t = ((whole - JD_J2000) + frac) / 36525.0
    g_s = 67310.54841 + (8640184.812866 + (0.093104 - 6.2e-6 * t) * t) * t
    turns = np.mod(whole, 1.0) + np.mod(frac, 1.0) + np.mod(g_s / DAY_S, 1.0)
    return np.mod(turns, 1.0) * (2.0 * np.pi)


def polar_motion_matrix(xp_rad: float, yp_rad: float) -> np.ndarray:
    """Vallado's PM (IAU-76/FK5 form): ECEF = PM^T PEF; identity when xp = yp = 0."""
    cx, sx, cy, sy = np.cos(xp_rad), np.sin(xp_rad), np.cos(yp_rad), np.sin(yp_rad)
    return np.array([
        [cx, 0.0, -sx],
        [sx * sy, cy, cx * sy],
        [sx * cy, -sy, cx * cy],
    ])


def teme_to_ecef(
    r_teme: np.ndarray,
    v_teme: np.ndarray,
    gmst_rad: np.ndarray,
    *,
    xp_rad: float = 0.0,
    yp_rad: float = 0.0,
    scale: float = 1.0,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Rotate TEME states (..., nt, 3) with one GMST per time (nt,) into ECEF.

    `scale` multiplies the result (1000 turns SGP4's km into m at no extra cost).
    Returns r_ecef, v_ecef of the input shape (written into `out` when given).
    """
    c = np.cos(gmst_rad) * scale
    s = np.sin(gmst_rad) * scale
    r_ecef, v_ecef = out if out is not None else (np.empty_like(r_teme), np.empty_like(v_teme))
    x, y = r_teme[..., 0], r_teme[..., 1]
    xe = r_ecef[..., 0]
    ye = r_ecef[..., 1]
    np.multiply(x, c, out=xe)
    xe += y * s
    np.multiply(y, c, out=ye)
    ye -= x * s
    np.multiply(r_teme[..., 2], scale, out=r_ecef[..., 2])
    vx, vy = v_teme[..., 0], v_teme[..., 1]
    vxe = v_ecef[..., 0]
    vye = v_ecef[..., 1]
    # v_pef = R3 v_teme - w x r_pef: (-w*(-y), -w*x) -> vx + w y, vy - w x
    np.multiply(vx, c, out=vxe)
    vxe += vy * s
    vxe += OMEGA_EARTH_RADPS * ye
    np.multiply(vy, c, out=vye)
    vye -= vx * s
    vye -= OMEGA_EARTH_RADPS * xe
    np.multiply(v_teme[..., 2], scale, out=v_ecef[..., 2])
    if xp_rad or yp_rad:
        pm = polar_motion_matrix(xp_rad, yp_rad)
        r_ecef[...] = r_ecef @ pm  # row vectors: (PM^T r)^T = r^T PM
        v_ecef[...] = v_ecef @ pm
    return r_ecef, v_ecef
