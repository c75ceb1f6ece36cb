"""EME2000 (J2000 mean equator and equinox, "MEME") <-> Earth-fixed ECEF/ITRF, SI units.

Operator ephemerides (Starlink's public files) give inertial states in EME2000; the rest of
the project carries satellites in ECEF, reached from SGP4's TEME through `teme.teme_to_ecef`
(GMST 1982 on UT1, polar motion from the IERS table). This module joins EME2000 to that
same path so both kinds of satellite state leave through one rotation:

    r_tod  = NPB(TT) B^T r_eme2000         (frame bias B, IAU 2006/2000A precession-nutation)
    r_teme = R3(GAST(UT1, TT) - GMST82(UT1)) r_tod
    r_ecef = teme_to_ecef(r_teme)          (R3(GMST82), Earth rate, polar motion)

so r_pef = R3(GAST) r_tod exactly, as the equinox-based IERS transformation has it. The
matrices come from ERFA (the IAU SOFA routines: bp06, pnm06a, gst06a, utctai/taitt). The
precession-nutation matrix moves by ~1e-11 rad/s, so velocities are rotated by the same
matrix and its rate is left out (below 1e-4 m/s at LEO radius). The celestial-pole offsets
(dX, dY of the IERS bulletins, ~0.1-0.3 mas, about 1 cm at 7000 km) are left out.
"""
from __future__ import annotations

import datetime as _dt

import erfa
import numpy as np

from leonav_runtime.orbits.elements import as_utc, julian_date_split
from leonav_runtime.orbits.eop import EopTable
from leonav_runtime.orbits.propagate import earth_orientation
from leonav_runtime.orbits.teme import DAY_S, gmst82_rad, teme_to_ecef


def _r3(angle_rad: np.ndarray) -> np.ndarray:
    """(n, 3, 3) coordinate rotations about z by angle (n,): R3 = [[c, s, 0], [-s, c, 0], [0, 0, 1]]."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    m = np.zeros(angle_rad.shape + (3, 3))
    m[..., 0, 0], m[..., 0, 1], m[..., 1, 0], m[..., 1, 1], m[..., 2, 2] = c, s, -s, c, 1.0
    return m


GRID_S = 600.0   # M is evaluated on this grid and interpolated linearly for long time series


def eme2000_to_teme_matrix(epoch_utc: _dt.datetime, t_s: np.ndarray,
                           ut1_utc_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """(M (nt, 3, 3) with r_teme = M r_eme2000, GMST82 (nt,) rad) at epoch_utc + t_s (UTC
    seconds), UT1-UTC in s. The "TEME" here is the frame `teme_to_ecef` turns into PEF with
    GMST82, so M folds the equation of the equinoxes (GAST - GMST82) into it.

    M moves by parts in 1e11 per second (precession, nutation, the GAST - GMST82 drift): for
    more times than grid points it is evaluated every GRID_S seconds and interpolated
    linearly, which departs from the direct value by 8e-13 at most (measured over 3 days:
    6 um at 7000 km) and costs a thirtieth; GMST82 is always evaluated directly."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    ut1 = np.broadcast_to(np.asarray(ut1_utc_s, dtype=float), t_s.shape)
    span = float(t_s.max() - t_s.min()) if t_s.size else 0.0
    n_grid = int(np.ceil(span / GRID_S)) + 1
    if t_s.size <= 2 * n_grid:
        return _teme_matrix_direct(epoch_utc, t_s, ut1)
    grid = t_s.min() + np.arange(n_grid + 1) * GRID_S
    order = np.argsort(t_s)
    # M depends on UT1 only through GAST - GMST82 (~1e-11 rad per s of UT1): interpolated UT1 is ample
    m_grid, _ = _teme_matrix_direct(epoch_utc, grid, np.interp(grid, t_s[order], ut1[order]))
    k = np.clip(((t_s - grid[0]) // GRID_S).astype(int), 0, n_grid - 1)
    w = ((t_s - grid[k]) / GRID_S)[:, None, None]
    jd_whole, jd_frac = julian_date_split(as_utc(epoch_utc))
    gmst = gmst82_rad(np.full(t_s.shape, jd_whole), jd_frac + (t_s + ut1) / DAY_S)
    return (1.0 - w) * m_grid[k] + w * m_grid[k + 1], gmst


def _teme_matrix_direct(epoch_utc: _dt.datetime, t_s: np.ndarray, ut1_utc_s: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    jd_whole, jd_frac = julian_date_split(as_utc(epoch_utc))
    utc1 = np.full(t_s.shape, jd_whole)
    utc2 = jd_frac + t_s / DAY_S
    tai1, tai2 = erfa.utctai(utc1, utc2)          # leap seconds from ERFA's table
    tt1, tt2 = erfa.taitt(tai1, tai2)
    ut2 = utc2 + np.asarray(ut1_utc_s, dtype=float) / DAY_S
    gmst = gmst82_rad(utc1, ut2)
    gast = erfa.gst06a(utc1, ut2, tt1, tt2)
    rb, _, _ = erfa.bp06(tt1, tt2)                 # GCRS -> J2000 mean (the frame bias)
    npb = erfa.pnm06a(tt1, tt2)                    # GCRS -> true equator and equinox of date
    m_tod = npb @ np.swapaxes(rb, -1, -2)
    return _r3(gast - gmst) @ m_tod, gmst


def eme2000_to_ecef(r_eme2000_m: np.ndarray, v_eme2000_mps: np.ndarray, epoch_utc: _dt.datetime,
                    t_s: np.ndarray, *, eop: EopTable | None = None, ut1_utc_s: float | None = None,
                    xp_rad: float | None = None, yp_rad: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """ECEF position (m) and velocity (m/s) of EME2000 states (..., nt, 3) at epoch_utc + t_s (nt,).

    Earth orientation as `propagate.propagate_ecef`: UT1-UTC per time and polar motion at the
    middle time from `eop` (default: the IERS table); explicit values override it."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    ut1_utc, xp, yp = earth_orientation(as_utc(epoch_utc), t_s, ut1_utc_s, xp_rad, yp_rad, eop)
    m, gmst = eme2000_to_teme_matrix(epoch_utc, t_s, ut1_utc)
    r_teme = np.einsum("tij,...tj->...ti", m, r_eme2000_m)
    v_teme = np.einsum("tij,...tj->...ti", m, v_eme2000_mps)
    return teme_to_ecef(r_teme, v_teme, gmst, xp_rad=xp, yp_rad=yp)


def ecef_to_eme2000(r_ecef_m: np.ndarray, v_ecef_mps: np.ndarray, epoch_utc: _dt.datetime,
                    t_s: np.ndarray, *, eop: EopTable | None = None, ut1_utc_s: float | None = None,
                    xp_rad: float | None = None, yp_rad: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of `eme2000_to_ecef` (writing operator files from simulated ECEF orbits).

    The forward map is linear in (r, v) at a fixed time: its 6 x 6 matrix per time is solved."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    T = ecef_jacobian(epoch_utc, t_s, eop=eop, ut1_utc_s=ut1_utc_s, xp_rad=xp_rad, yp_rad=yp_rad)
    x = np.concatenate([r_ecef_m, v_ecef_mps], axis=-1)
    y = np.einsum("tij,...tj->...ti", np.linalg.inv(T), x)
    return y[..., 0:3], y[..., 3:6]


def ecef_jacobian(epoch_utc: _dt.datetime, t_s: np.ndarray, **eop_kw) -> np.ndarray:
    """(nt, 6, 6) T with [r, v]_ecef = T [r, v]_eme2000 at each time: the rotation of the
    position and velocity blocks and the Earth-rate term -w x r in the velocity (the map is
    linear, so its columns are the images of the six unit states)."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    basis = np.broadcast_to(np.eye(6)[:, None, :], (6, t_s.size, 6))
    r_e, v_e = eme2000_to_ecef(basis[..., 0:3], basis[..., 3:6], epoch_utc, t_s, **eop_kw)
    cols = np.concatenate([r_e, v_e], axis=-1)     # (6 columns, nt, 6 rows)
    return np.transpose(cols, (1, 2, 0))
