"""Vectorized SGP4 of many satellites over a time grid, in Earth-fixed ECEF (SI units).

`propagate_ecef` runs `sgp4.api.SatrecArray.sgp4` once over (satellites x times), rotates
TEME to ECEF with IAU-82 GMST (`teme.py`) and adds the ECEF acceleration.

Acceleration choice: an analytic gravity model evaluated at the SGP4 position, with the
rotating-frame terms from r and v in ECEF,

    a_ecef = g(r) - 2 w x v_ecef - w x (w x r_ecef),

where g is point mass + zonal J2, J3, J4 with the WGS-72 constants SGP4 is built on. It
costs about a tenth of the SGP4 call (central differences would cost 2 more SGP4
calls). What it leaves out, and what a second difference of SGP4 positions contains, is
the drag term of SGP4, tesseral harmonics, Sun/Moon (deep-space satellites) and SGP4's
own truncation; in tests this stays below 1e-4 m/s^2 for LEO and GPS orbits, against
9.8e-3 m/s^2 for a Starlink satellite's total acceleration at 8 m/s^2 of central gravity.

Failed satellites: SGP4 error codes are turned into words. A satellite with an error at
any epoch has `ok = False`, is listed once in `failures` (name, NORAD id, reason with the
first failing time), and its rows are NaN at the failing epochs and at every later one
(SGP4 can return numbers again after a decay, but they mean nothing); rows before the
first failure are kept. Shapes stay (nsat, nt, 3) so indices match `elements`.
"""
from __future__ import annotations

import datetime as _dt
import logging
import warnings
from dataclasses import dataclass

import numpy as np
from sgp4.api import SGP4_ERRORS

from leonav_runtime.orbits.elements import ElementSet, as_utc, julian_date_split
from leonav_runtime.orbits.eop import EopTable
from leonav_runtime.orbits.eop import default_table as eop_default_table
from leonav_runtime.orbits.teme import DAY_S, OMEGA_EARTH_RADPS, gmst82_rad, teme_to_ecef
from leonav_runtime.gen.constants import WGS72_J2, WGS72_J3, WGS72_J4, WGS72_MU_M3PS2, WGS72_RE_M

log = logging.getLogger("leonav.orbits")

# WGS-72: the gravity model of SGP4 and of the element sets fitted for it
MU_WGS72_M3PS2, RE_WGS72_M = WGS72_MU_M3PS2, WGS72_RE_M
J2_WGS72, J3_WGS72, J4_WGS72 = WGS72_J2, WGS72_J3, WGS72_J4

SGP4_ERROR_WORDS = {
    1: "mean eccentricity outside 0..1 (element set not usable)",
    2: "mean motion became negative (element set not usable)",
    3: "perturbed eccentricity outside 0..1 (orbit degenerated, e.g. after long propagation)",
    4: "semi-latus rectum negative (orbit degenerated)",
    5: "epoch elements are sub-orbital (error 5)",
    6: "satellite has decayed (orbit radius below one Earth radius)",
}


_BLOCK_ELEMENTS = 8192  # satellite-epochs per post-processing block (~200 kB per temporary)


class StaleElementsWarning(UserWarning):
    """Element sets are older (or newer) than `stale_after_days` at the scenario epoch."""


@dataclass
class SatStates:
    """ECEF states of `elements` at `epoch_utc + t_s`.

    r_ecef_m, v_ecef_mps, a_ecef_mps2: (nsat, nt, 3) in m, m/s, m/s^2 (ECEF/ITRF, WGS-72
    SGP4); a_ecef_mps2 is None when not requested. ok: (nsat,) False for a satellite SGP4
    failed on at some epoch (NaN rows there). failures: [(name, norad_id, reason)].
    """

    r_ecef_m: np.ndarray
    v_ecef_mps: np.ndarray
    a_ecef_mps2: np.ndarray | None
    t_s: np.ndarray
    epoch_utc: _dt.datetime
    ok: np.ndarray
    failures: list[tuple[str, int, str]]
    elements: ElementSet


def gravity_ecef_mps2(r_ecef_m: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Point mass + J2 + J3 + J4 (WGS-72) gravitational acceleration at r (..., 3), m/s^2."""
    x, y, z = r_ecef_m[..., 0], r_ecef_m[..., 1], r_ecef_m[..., 2]
    r2 = x * x
    r2 += y * y
    r2 += z * z
    inv_r2 = 1.0 / r2
    s2 = z * z * inv_r2  # sin^2 of geocentric latitude
    q = RE_WGS72_M * RE_WGS72_M * inv_r2  # (Re/r)^2
    mu_r3 = MU_WGS72_M3PS2 * inv_r2 * np.sqrt(inv_r2)
    s = z * np.sqrt(inv_r2) * (RE_WGS72_M * np.sqrt(inv_r2))  # (z/r)(Re/r)
    # common factor of x and y (radial-equatorial part), and of z
    j2 = 1.5 * J2_WGS72 * q
    j4 = 0.625 * J4_WGS72 * q * q  # 15/8 J4 (Re/r)^4 / 3, written with 3 and 42 and 63 below
    fxy = -1.0 - j2 * (1.0 - 5.0 * s2) - 2.5 * J3_WGS72 * q * s * (3.0 - 7.0 * s2) \
        + j4 * (3.0 - 42.0 * s2 + 63.0 * s2 * s2)
    fz = -1.0 - j2 * (3.0 - 5.0 * s2) + j4 * (15.0 - 70.0 * s2 + 63.0 * s2 * s2)
    fzc = -2.5 * J3_WGS72 * q * (RE_WGS72_M * np.sqrt(inv_r2)) * (6.0 * s2 - 7.0 * s2 * s2 - 0.6)
    g = np.empty_like(r_ecef_m) if out is None else out
    fxy *= mu_r3
    np.multiply(x, fxy, out=g[..., 0])
    np.multiply(y, fxy, out=g[..., 1])
    # z component: mu/r^3 * z * fz  +  mu/r^2 * fzc (the J3 term not proportional to z)
    np.multiply(z, fz * mu_r3, out=g[..., 2])
    g[..., 2] += fzc * MU_WGS72_M3PS2 * inv_r2
    return g


def acceleration_ecef_mps2(r_ecef_m: np.ndarray, v_ecef_mps: np.ndarray,
                           out: np.ndarray | None = None) -> np.ndarray:
    """Gravity plus Coriolis and centrifugal terms of the Earth-fixed frame, m/s^2."""
    a = gravity_ecef_mps2(r_ecef_m, out=out)
    w = OMEGA_EARTH_RADPS
    a[..., 0] += (2.0 * w) * v_ecef_mps[..., 1] + (w * w) * r_ecef_m[..., 0]
    a[..., 1] += (w * w) * r_ecef_m[..., 1] - (2.0 * w) * v_ecef_mps[..., 0]
    return a


# What stale sets cost, per constellation: SGP4 error grows ~1-3 km/day for LEO, which is what
# limits Doppler/Doppler-rate; for GPS the cost is the geometry (the real sky differs).
_STALE_CONSEQUENCE = {"starlink": "stale elements dominate the LEO Doppler error"}
_STALE_OTHER = "their satellites are kilometres from where they really are at that epoch"


def warn_if_stale(elements: ElementSet, epoch_utc: _dt.datetime, t_s: np.ndarray) -> None:
    """Warn when element epochs are more than `stale_after_days` from the scenario span.

    The count is over `elements` as given: callers pass the whole set a user loaded, not the
    visible subset they propagate (see warn_stale of propagate_ecef).
    """
    if len(elements) == 0:
        return
    ages_s = elements.ages_s(epoch_utc)
    limit_s = elements.stale_after_days * DAY_S
    t_lo = float(np.min(t_s)) if len(t_s) else 0.0
    t_hi = float(np.max(t_s)) if len(t_s) else 0.0
    # distance of the element epoch from the scenario time span, either direction
    worst = np.maximum(ages_s + t_hi, -(ages_s + t_lo))
    stale = worst > limit_s
    if np.any(stale):
        k = int(np.argmax(worst))
        which = "" if elements.constellation == "unknown" else f"{elements.constellation} "
        message = (
            f"{int(stale.sum())} of {len(elements)} {which}element sets are more than "
            f"{elements.stale_after_days:g} days from the scenario epoch "
            f"{as_utc(epoch_utc).isoformat()} (worst {worst[k] / DAY_S:.1f} days: {elements.names[k]}, "
            f"element epoch {elements.epochs_utc[k].isoformat()}); {_STALE_CONSEQUENCE.get(elements.constellation, _STALE_OTHER)}, "
            "fetch fresh ones (`leonav tle fetch`)"
        )
        # one channel only: a warning (the CLI prints it once, as one line without a source path)
        warnings.warn(message, StaleElementsWarning, stacklevel=3)


def propagate_teme(
    elements: ElementSet, epoch_utc: _dt.datetime, t_s: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(err (nsat, nt) SGP4 error codes, r_teme_km (nsat, nt, 3), v_teme_kmps): raw SGP4 TEME output."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    jd_whole, jd_frac = julian_date_split(epoch_utc)
    jd = np.full(t_s.shape, jd_whole)
    fr = jd_frac + t_s / DAY_S
    return elements.satrec_array.sgp4(jd, fr)


def earth_orientation(epoch_utc: _dt.datetime, t_s: np.ndarray, ut1_utc_s: float | None = None,
                      xp_rad: float | None = None, yp_rad: float | None = None,
                      eop: EopTable | None = None) -> tuple[np.ndarray | float, float, float]:
    """UT1-UTC (s, per epoch) and polar motion (rad, at the middle epoch) for TEME -> ECEF.

    Values given explicitly win; the others come from `eop` (default: the IERS table).
    Polar motion changes by a few milliarcseconds a day, so one value serves a run.
    """
    if ut1_utc_s is not None and xp_rad is not None and yp_rad is not None:
        return ut1_utc_s, xp_rad, yp_rad
    table = eop if eop is not None else eop_default_table()
    values = table.at(epoch_utc, t_s)
    mid = values.ut1_utc_s.size // 2
    return (values.ut1_utc_s if ut1_utc_s is None else ut1_utc_s,
            float(values.xp_rad[mid]) if xp_rad is None else xp_rad,
            float(values.yp_rad[mid]) if yp_rad is None else yp_rad)


def propagate_ecef(
    elements: ElementSet,
    epoch_utc: _dt.datetime,
    t_s: np.ndarray | float,
    *,
    ut1_utc_s: float | None = None,
    xp_rad: float | None = None,
    yp_rad: float | None = None,
    eop: EopTable | None = None,
    acceleration: bool = True,
    warn_stale: bool = True,
) -> SatStates:
    """ECEF position, velocity and (optionally) acceleration of every satellite at every time.

    epoch_utc: scenario epoch (UTC; naive datetimes are taken as UTC); t_s: (nt,) seconds
    since it. Earth orientation: UT1-UTC per epoch and polar motion at the middle epoch
    from `eop` (default: the IERS table of `orbits.eop.default_table()`); explicit
    ut1_utc_s (s) / xp_rad, yp_rad (rad) override it (0, 0, 0 reproduces GMST on UTC).
    Warns (StaleElementsWarning) about element sets older than `elements.stale_after_days`;
    callers that propagate one set in chunks pass warn_stale=False and call
    `warn_if_stale(elements, epoch_utc, t_s)` once themselves.
    """
    epoch_utc = as_utc(epoch_utc)
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    nsat, nt = len(elements), len(t_s)
    if warn_stale:
        warn_if_stale(elements, epoch_utc, t_s)
    if nsat == 0:
        empty = np.empty((0, nt, 3))
        return SatStates(empty, empty.copy(), empty.copy() if acceleration else None, t_s, epoch_utc,
                         np.zeros(0, bool), [], elements)

    err, r_teme_km, v_teme_kmps = propagate_teme(elements, epoch_utc, t_s)

    ut1_utc_s, xp_rad, yp_rad = earth_orientation(epoch_utc, t_s, ut1_utc_s, xp_rad, yp_rad, eop)
    jd_whole, jd_frac = julian_date_split(epoch_utc)
    gmst = gmst82_rad(jd_whole, jd_frac + (t_s + ut1_utc_s) / DAY_S)
    # Work in blocks of satellites so the temporaries stay in the CPU cache: this makes the
    # rotation + gravity several times cheaper than whole-array NumPy passes.
    r_ecef_m = np.empty_like(r_teme_km)
    v_ecef_mps = np.empty_like(v_teme_kmps)
    a_ecef = np.empty_like(r_teme_km) if acceleration else None
    block = max(1, _BLOCK_ELEMENTS // nt)
    for i in range(0, nsat, block):
        rows = slice(i, i + block)
        teme_to_ecef(r_teme_km[rows], v_teme_kmps[rows], gmst, xp_rad=xp_rad, yp_rad=yp_rad,
                     scale=1000.0, out=(r_ecef_m[rows], v_ecef_mps[rows]))
        if a_ecef is not None:
            acceleration_ecef_mps2(r_ecef_m[rows], v_ecef_mps[rows], out=a_ecef[rows])

    # a state that is not finite without an SGP4 error code (e.g. elements that decode to
    # extreme values) is a failure too, never a silent NaN downstream
    bad = (err != 0) | ~np.isfinite(r_ecef_m).all(axis=-1) | ~np.isfinite(v_ecef_mps).all(axis=-1)
    ok = ~bad.any(axis=1)
    failures: list[tuple[str, int, str]] = []
    if not ok.all():
        for i in np.flatnonzero(~ok):
            j = int(np.argmin(np.where(bad[i], t_s, np.inf)))  # earliest failing time
            code = int(err[i, j])
            words = (SGP4_ERROR_WORDS.get(code, SGP4_ERRORS.get(code, f"SGP4 error {code}")) if code
                     else "non-finite position or velocity without an SGP4 error code (check the element set)")
            failures.append((elements.names[i], int(elements.norad_ids[i]),
                             f"SGP4 error {code}: {words}; first at t = {t_s[j]:g} s "
                             f"({int(bad[i].sum())} of {nt} epochs)"))
            # a decayed/degenerated orbit does not come back: blank everything after it too
            bad[i] |= t_s >= t_s[j]
        r_ecef_m[bad] = np.nan
        v_ecef_mps[bad] = np.nan
        if a_ecef is not None:
            a_ecef[bad] = np.nan
        message = f"SGP4 failed for {len(failures)} of {nsat} satellites: " + "; ".join(
            f"{n} ({i}): {why}" for n, i, why in failures[:5]) + (" ..." if len(failures) > 5 else "")
        log.warning(message)
    return SatStates(r_ecef_m, v_ecef_mps, a_ecef, t_s, epoch_utc, ok, failures, elements)
