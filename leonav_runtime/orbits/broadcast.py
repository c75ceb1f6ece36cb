"""Satellite position, velocity and clock from broadcast ephemerides (GPS LNAV, Galileo,
BeiDou incl. GEO, QZSS), vectorized over rows of `leonav_runtime.gnss.ephemeris.EPH_DTYPE`.

Equations: IS-GPS-200 Table 20-IV (user algorithm for ephemeris determination, with the
velocity terms of the same table), 20.3.3.3.3.1 (clock, relativistic correction, TGD);
Galileo OS SIS ICD 5.1.1-5.1.5 (same orbit algorithm with Galileo's mu, BGD); BDS-SIS-ICD
5.2.4.12 (MEO/IGSO as GPS with CGCS2000 mu and Omega_e; GEO computed in the inertial
frame and rotated by Rx(-5 deg) then Rz(Omega_e t_k)). Each system uses its ICD's
constants (models/constants.py, GNSS block).

Output frame: ECEF (WGS84/ITRF for GPS, GTRF for Galileo, CGCS2000 for BeiDou; they agree
at the cm level) at the epoch t, i.e. a position computed at transmit time is in the
Earth-fixed frame of the transmit epoch (the pseudorange model adds the Earth rotation
during the signal flight). Clock: `clock_bias_s` = af0 + af1 dt + af2 dt^2 + Delta t_r
(relativistic, F e sqrt(A) sin E_k), without the group delay; `group_delay_s(rows,
signal)` gives the TGD/BGD term a single-frequency user of that signal subtracts.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leonav_runtime.gen.constants import (
    BDS_F_REL_S_PER_SQRTM,
    BDS_GEO_TILT_RAD,
    BDS_MU_M3PS2,
    BDS_OMEGA_E_RADPS,
    BDS_B1I_HZ,
    BDS_B3I_HZ,
    C_LIGHT_MPS,
    GAL_E5B_HZ,
    GAL_F_REL_S_PER_SQRTM,
    GAL_MU_M3PS2,
    GAL_OMEGA_E_RADPS,
    GPS_F_REL_S_PER_SQRTM,
    GPS_L1_HZ,
    GPS_L2_HZ,
    GPS_L5_HZ,
    GPS_MU_M3PS2,
    GPS_OMEGA_E_RADPS,
)

KEPLER_TOL_RAD = 1e-14
KEPLER_MAX_ITER = 30


@dataclass
class BroadcastStates:
    """States of n (row, time) pairs. r, v: (n, 3) ECEF m, m/s; clock terms (n,) in s, s/s."""

    r_ecef_m: np.ndarray
    v_ecef_mps: np.ndarray
    clock_bias_s: np.ndarray       # af polynomial + relativistic correction (no TGD)
    clock_drift_sps: np.ndarray    # its time derivative
    relativistic_s: np.ndarray     # Delta t_r alone
    t_gps_s: np.ndarray


def _constants(system: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mu, Omega_e, F) per row from the system letter (G and J: IS-GPS-200)."""
    is_e, is_c = system == "E", system == "C"
    mu = np.where(is_e, GAL_MU_M3PS2, np.where(is_c, BDS_MU_M3PS2, GPS_MU_M3PS2))
    we = np.where(is_e, GAL_OMEGA_E_RADPS, np.where(is_c, BDS_OMEGA_E_RADPS, GPS_OMEGA_E_RADPS))
    f = np.where(is_e, GAL_F_REL_S_PER_SQRTM, np.where(is_c, BDS_F_REL_S_PER_SQRTM, GPS_F_REL_S_PER_SQRTM))
    return mu, we, f


def eccentric_anomaly(m: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Solve Kepler's equation M = E - e sin E by Newton iteration (vectorized)."""
    ecc = np.array(m, dtype=float, copy=True)
    for _ in range(KEPLER_MAX_ITER):
        d = (ecc - e * np.sin(ecc) - m) / (1.0 - e * np.cos(ecc))
        ecc -= d
        if np.all(np.abs(d) < KEPLER_TOL_RAD):
            break
    return ecc


def clock_polynomial_s(rows: np.ndarray, t_gps_s) -> np.ndarray:
    """af0 + af1 (t - toc) + af2 (t - toc)^2 (s), without the relativistic term."""
    dt = np.asarray(t_gps_s, dtype=float) - rows["toc"]
    return rows["af0"] + dt * (rows["af1"] + dt * rows["af2"])


def satellite_states(rows: np.ndarray, t_gps_s) -> BroadcastStates:
    """Position, velocity and clock of each ephemeris row at its time t (continuous GPS s).

    `rows` (n,) EPH_DTYPE and `t_gps_s` (n,) or scalar. t_k = t - toe is taken as given:
    the caller selects an ephemeris whose fit interval covers t (`Ephemerides.select`).
    """
    rows = np.atleast_1d(rows)
    t = np.broadcast_to(np.asarray(t_gps_s, dtype=float), rows.shape).copy()
    system = rows["system"]
    mu, we, f_rel = _constants(system)
    a = rows["sqrt_a"] ** 2
    e = rows["e"]
    n0 = np.sqrt(mu / a**3)
    tk = t - rows["toe"]
    n = n0 + rows["delta_n"]
    mk = rows["m0"] + n * tk
    ek = eccentric_anomaly(mk, e)
    sin_e, cos_e = np.sin(ek), np.cos(ek)
    one_m_ecos = 1.0 - e * cos_e
    sq1e2 = np.sqrt(1.0 - e * e)
    vk = np.arctan2(sq1e2 * sin_e, cos_e - e)
    phi = vk + rows["omega"]
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    uk = phi + rows["cus"] * s2 + rows["cuc"] * c2
    rk = a * one_m_ecos + rows["crs"] * s2 + rows["crc"] * c2
    ik = rows["i0"] + rows["cis"] * s2 + rows["cic"] * c2 + rows["idot"] * tk
    cos_u, sin_u = np.cos(uk), np.sin(uk)
    xp, yp = rk * cos_u, rk * sin_u
    # rates (IS-GPS-200 Table 20-IV, velocity part)
    ek_dot = n / one_m_ecos
    vk_dot = ek_dot * sq1e2 / one_m_ecos
    ik_dot = rows["idot"] + 2.0 * vk_dot * (rows["cis"] * c2 - rows["cic"] * s2)
    uk_dot = vk_dot + 2.0 * vk_dot * (rows["cus"] * c2 - rows["cuc"] * s2)
    rk_dot = e * a * ek_dot * sin_e + 2.0 * vk_dot * (rows["crs"] * c2 - rows["crc"] * s2)
    xp_dot = rk_dot * cos_u - yp * uk_dot
    yp_dot = rk_dot * sin_u + xp * uk_dot

    geo = rows["geo"] & (system == "C")
    # Earth-fixed longitude of the node; BeiDou GEO: inertial (no -Omega_e t_k), rotated below
    omega_rate = np.where(geo, rows["omega_dot"], rows["omega_dot"] - we)
    om = rows["omega0"] + omega_rate * tk - we * rows["toe_sow"]
    cos_o, sin_o = np.cos(om), np.sin(om)
    cos_i, sin_i = np.cos(ik), np.sin(ik)
    x = xp * cos_o - yp * cos_i * sin_o
    y = xp * sin_o + yp * cos_i * cos_o
    z = yp * sin_i
    vx = -xp * omega_rate * sin_o + xp_dot * cos_o - yp_dot * sin_o * cos_i \
        - yp * (omega_rate * cos_o * cos_i - ik_dot * sin_o * sin_i)
    vy = xp * omega_rate * cos_o + xp_dot * sin_o + yp_dot * cos_o * cos_i \
        - yp * (omega_rate * sin_o * cos_i + ik_dot * cos_o * sin_i)
    vz = yp_dot * sin_i + yp * ik_dot * cos_i
    r = np.stack([x, y, z], axis=-1)
    v = np.stack([vx, vy, vz], axis=-1)
    if np.any(geo):
        r[geo], v[geo] = _bds_geo_to_ecef(r[geo], v[geo], tk[geo], we[geo])

    dt_clk = t - rows["toc"]
    rel = f_rel * e * rows["sqrt_a"] * sin_e
    rel_dot = f_rel * e * rows["sqrt_a"] * cos_e * ek_dot
    bias = rows["af0"] + dt_clk * (rows["af1"] + dt_clk * rows["af2"]) + rel
    drift = rows["af1"] + 2.0 * rows["af2"] * dt_clk + rel_dot
    return BroadcastStates(r, v, bias, drift, rel, t)


def _bds_geo_to_ecef(r_g: np.ndarray, v_g: np.ndarray, tk: np.ndarray, we: np.ndarray):
    """BeiDou GEO: [X Y Z] = Rz(Omega_e t_k) Rx(-5 deg) [X_GK Y_GK Z_GK] and its derivative.

    Rx(p) = [[1, 0, 0], [0, cos p, sin p], [0, -sin p, cos p]],
    Rz(p) = [[cos p, sin p, 0], [-sin p, cos p, 0], [0, 0, 1]] (BDS-SIS-ICD 5.2.4.12).
    """
    cp, sp = np.cos(BDS_GEO_TILT_RAD), np.sin(BDS_GEO_TILT_RAD)

    def rx(vec):
        return np.stack([vec[:, 0], cp * vec[:, 1] + sp * vec[:, 2], -sp * vec[:, 1] + cp * vec[:, 2]], axis=-1)

    rt, vt = rx(r_g), rx(v_g)
    ang = we * tk
    ca, sa = np.cos(ang), np.sin(ang)
    r = np.stack([ca * rt[:, 0] + sa * rt[:, 1], -sa * rt[:, 0] + ca * rt[:, 1], rt[:, 2]], axis=-1)
    # d/dt Rz(we t) = we * [[-sin, cos, 0], [-cos, -sin, 0], [0, 0, 0]]
    v = np.stack([ca * vt[:, 0] + sa * vt[:, 1] + we * (-sa * rt[:, 0] + ca * rt[:, 1]),
                  -sa * vt[:, 0] + ca * vt[:, 1] + we * (-ca * rt[:, 0] - sa * rt[:, 1]),
                  vt[:, 2]], axis=-1)
    return r, v


def group_delay_s(rows: np.ndarray, signal) -> np.ndarray:
    """Group-delay term (s) a single-frequency user of `signal` subtracts from the clock.

    `signal` is the RINEX 3 observation code (band digit first: "1C", "2W", "5Q", "7I"),
    per row or one for all. GPS/QZSS: L1 TGD, L2 (f1/f2)^2 TGD, L5 (f1/f5)^2 TGD (LNAV has
    no ISC). Galileo: E1 with an I/NAV clock BGD(E1,E5b), with an F/NAV clock BGD(E1,E5a);
    E5a (f1/f5a)^2 BGD(E1,E5a); E5b (f1/f5b)^2 BGD(E1,E5b). BeiDou (B3I is the clock
    reference): B1I TGD1, B2I TGD2, B3I 0. Other bands: 0.
    """
    rows = np.atleast_1d(rows)
    band = np.broadcast_to(np.asarray(signal, dtype="U3"), rows.shape)
    band = np.char.ljust(band, 1).astype("U1")
    system = rows["system"]
    tgd, tgd2 = rows["tgd"], rows["tgd2"]
    out = np.zeros(rows.shape)
    gj = (system == "G") | (system == "J")
    out = np.where(gj & (band == "1"), tgd, out)
    out = np.where(gj & (band == "2"), (GPS_L1_HZ / GPS_L2_HZ) ** 2 * tgd, out)
    out = np.where(gj & (band == "5"), (GPS_L1_HZ / GPS_L5_HZ) ** 2 * tgd, out)
    ge = system == "E"
    inav = (rows["data_sources"] & 0b101) != 0
    fnav_clock = ((rows["data_sources"] & 0x100) != 0) | (~inav & ((rows["data_sources"] & 0b10) != 0))
    e1 = np.where(fnav_clock, tgd, tgd2)
    out = np.where(ge & (band == "1"), e1, out)
    out = np.where(ge & (band == "5"), (GPS_L1_HZ / GPS_L5_HZ) ** 2 * tgd, out)
    out = np.where(ge & (band == "7"), (GPS_L1_HZ / GAL_E5B_HZ) ** 2 * tgd2, out)
    gc = system == "C"
    out = np.where(gc & (band == "2"), tgd, out)
    out = np.where(gc & (band == "7"), tgd2, out)
    return out


def signal_frequency_hz(system, signal) -> np.ndarray:
    """Carrier frequency of a RINEX 3 signal code (GLONASS FDMA: NaN, it needs the slot)."""
    system = np.asarray(system, dtype="U1")
    band = np.char.ljust(np.asarray(signal, dtype="U3"), 1).astype("U1")
    shape = np.broadcast_shapes(system.shape, band.shape)
    system, band = np.broadcast_to(system, shape), np.broadcast_to(band, shape)
    f = np.full(shape, np.nan)
    f = np.where(band == "1", GPS_L1_HZ, f)
    f = np.where(band == "2", GPS_L2_HZ, f)
    f = np.where(band == "5", GPS_L5_HZ, f)
    f = np.where(band == "7", GAL_E5B_HZ, f)
    f = np.where((system == "C") & (band == "2"), BDS_B1I_HZ, f)
    f = np.where((system == "C") & (band == "6"), BDS_B3I_HZ, f)
    f = np.where(system == "R", np.nan, f)
    return f


def transmit_time(rows: np.ndarray, t_rx_gps_s, pseudorange_m) -> np.ndarray:
    """Transmit time by the satellite clock: t_rx - P/c - dt_sv(t), dt_sv the clock polynomial
    at the transmit time (two fixed-point passes; the relativistic term and TGD stay out,
    they are nanoseconds, 0.1 mm of satellite motion)."""
    t = np.asarray(t_rx_gps_s, dtype=float) - np.asarray(pseudorange_m, dtype=float) / C_LIGHT_MPS
    dt = clock_polynomial_s(rows, t)
    dt = clock_polynomial_s(rows, t - dt)
    return t - dt
