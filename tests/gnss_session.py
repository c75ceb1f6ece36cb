"""Sessions with u-blox raw GNSS measurements for the tightly coupled replay tests.

`write_rawx_session` writes a `leonav record` session (through `session_synth`, so the
bytes, serial timing and files are the recorder's) of a static receiver whose GNSS port
sends UBX RXM-SFRBX (GPS LNAV subframes 1-3 of every broadcast ephemeris, once at the
start) and one RXM-RAWX per observation epoch, and no NMEA (so the replay has to start from
its own single-point solution). The IMU is the synthetic static WT901 of `session_synth`
at the site: gravity and Earth rate only, plus the WT901 profile's biases and noise.

RXM-RAWX is encoded with the layout `hardware.gnss.ubx.decode_rxm_rawx` reads (checked
against pyubx2 on real logs in tests/test_gnss_rawx.py): GPS L1 C/A (gnssId 0, sigId 0),
prValid set, carrier phase not valid, Doppler 0 when there is none (the reader counts a
zero Doppler as missing), C/N0 0 when unknown.
"""
from __future__ import annotations

import datetime as _dt
import math
import struct
from pathlib import Path

import numpy as np

from leonav.hardware.gnss.ubx import build_frame
from leonav_runtime.orbits import geometry
from leonav_runtime.gnss import sfrbx
from leonav_runtime.gnss import time as gtime
from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

PR_STDEV_CODE = 5   # 0.01 * 2^5 = 0.32 m (the reader's sigma_pr_m; the filter uses its own error model)


def rawx_frame(t_gps_s: float, prn, pseudorange_m, doppler_hz, cn0_dbhz, leap_s: int,
               leap_valid: bool = True) -> bytes:
    """One RXM-RAWX frame of GPS L1 C/A measurements received at GPS time t_gps_s (recStat
    bit 0 = leap_valid)."""
    week, tow = gtime.week_tow(t_gps_s)
    out = [struct.pack("<dHbBBB2x", float(tow), int(week), leap_s, len(prn), int(leap_valid), 1)]
    for p, pr, do, cn0 in zip(prn, pseudorange_m, doppler_hz, cn0_dbhz):
        do = 0.0 if not math.isfinite(do) else do
        cn0 = 0 if not math.isfinite(cn0) else int(round(cn0))
        out.append(struct.pack("<ddfBBBBHBBBBBx", float(pr), 0.0, do, 0, int(p), 0, 0, 10000, cn0,
                               PR_STDEV_CODE, 0, 5, 0x01))
    return build_frame(0x02, 0x15, b"".join(out))


def sfrbx_frames(eph_rows, klobuchar=None, tow_count: int = 100) -> bytes:
    """RXM-SFRBX frames of subframes 1-3 of every GPS ephemeris row, and with `klobuchar`
    (8 coefficients) a subframe 4 page 18 carrying them."""
    frames = []
    if klobuchar is not None:
        words = sfrbx.encode_iono_page(klobuchar, tow_count)
        frames.append(build_frame(sfrbx.SFRBX_CLASS, sfrbx.SFRBX_ID, sfrbx.sfrbx_payload(int(eph_rows[0]["prn"]),
                                                                                          words)))
    for row in eph_rows:
        if row["system"] != "G":
            continue
        for words in sfrbx.encode_ephemeris(row):
            frames.append(build_frame(sfrbx.SFRBX_CLASS, sfrbx.SFRBX_ID, sfrbx.sfrbx_payload(int(row["prn"]), words)))
    return b"".join(frames)


def write_rawx_session(folder: Path, t_gps_s, prn, pseudorange_m, doppler_hz, cn0_dbhz, eph_rows, site_ecef_m,
                       *, klobuchar=None, imu_rate_hz: float = 2.0, lead_s: float = 1.0, seed: int = 0,
                       nmea: bool = False, sdr: bool = False, elements=None, nav=None, leap_valid: bool = True):
    """A session of a static receiver at `site_ecef_m` (module doc). Per-row arrays: reception
    GPS time (s), PRN, pseudorange (m), Doppler (Hz, NaN none), C/N0 (dB-Hz, NaN unknown);
    klobuchar: coefficients sent in a page 18; nmea: also the NMEA fixes of `session_synth`
    (truth plus noise) at 1 Hz; sdr: also its Starlink beacon capture (of `elements`, default
    the built-in Walker set at the start); leap_valid False: RAWX recStat says leapS is not
    valid yet and leapS holds a wrong value (a receiver before it has decoded UTC parameters).
    Returns (SyntheticSession, epoch_utc)."""
    t_gps_s = np.asarray(t_gps_s, float)
    epochs = np.unique(t_gps_s)
    leap = gtime.leap_seconds_at_gps(float(epochs[0]))
    epoch_utc = gtime.gps_seconds_to_utc(float(epochs[0]) - lead_s).replace(tzinfo=_dt.timezone.utc)
    t0 = float(epochs[0]) - lead_s
    lat, lon, h = (float(v) for v in geometry.ecef_to_geodetic(np.asarray(site_ecef_m, float)))
    seconds = float(epochs[-1] - t0) + 1.0
    extra = [(0.2, sfrbx_frames(eph_rows, klobuchar))]
    for t in epochs:
        k = t_gps_s == t
        extra.append((float(t - t0), rawx_frame(float(t), np.asarray(prn)[k], np.asarray(pseudorange_m)[k],
                                                np.asarray(doppler_hz)[k], np.asarray(cn0_dbhz)[k],
                                                leap if leap_valid else leap - 3, leap_valid)))
    cfg = SynthSessionConfig(seconds=seconds, seed=seed, epoch_utc=epoch_utc, lat_deg=math.degrees(lat),
                             lon_deg=math.degrees(lon), alt_m=h, imu_rate_hz=imu_rate_hz,
                             gnss_rate_hz=1.0 if nmea else imu_rate_hz,
                             gnss_start_s=0.0 if nmea else seconds + 10.0, sdr=sdr, sdr_rate_hz=200e3,
                             gnss_baud=115200)
    return write_synthetic_session(folder, cfg, elements, nav=nav, extra_gnss=extra), epoch_utc


def simulated_pseudoranges(obs, eph, klobuchar, r_ecef_m, clock_m, clock_drift_mps, rng, nav):
    """(pseudorange m, Doppler Hz, sigma m) of the primary GPS rows of `obs` made by the
    generated GNSS_PSEUDORANGE / GNSS_RANGE_RATE models at a static receiver r_ecef_m with
    receiver clock clock_m + clock_drift_mps * (t - t_first), plus white noise of the filters'
    error model's sigma (`signals.filter_pseudorange_variance`, pseudorange) and
    RANGE_RATE_SIGMA_MPS (range rate).
    Satellite states depend on the pseudorange (transmit time), so the rows are made again
    from the simulated values until they agree (three passes: < 1 um).
    Returns (observation table of the primary rows with the simulated values, sigma_m)."""
    from leonav_runtime.gen import constants as K
    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.gnss import spp as _spp
    from leonav_runtime.gnss.signals import filter_pseudorange_variance, gnss_rows, primary_rows
    from leonav_runtime.core.params import params_array

    rows_idx, _ = primary_rows(obs, "G")
    o = obs.take(rows_idx)
    lat, lon, h = (float(v) for v in geometry.ecef_to_geodetic(np.asarray(r_ecef_m, float)))
    params = params_array(lat, lon, h)
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    x[L.X_C_DDT] = clock_drift_mps
    t_first = float(o.t_gps_s[0])
    saved, nav.params = nav.params, params
    for _pass in range(3):
        rows = gnss_rows(o, eph, klobuchar=klobuchar, systems="G")
        z, zr = np.full(len(o), np.nan), np.full(len(o), np.nan)
        for i in np.flatnonzero(rows.status == 0):
            x[L.X_C_DT] = clock_m + clock_drift_mps * (o.t_gps_s[i] - t_first)
            z[i] = nav.h("gnss_pseudorange", x, rows.aux[i])[0]
            zr[i] = nav.h("gnss_range_rate", x, rows.aux[i])[0]
        o.pseudorange_m[:] = z
    nav.params = saved
    res = _spp.solve(rows, nav=nav)
    var = filter_pseudorange_variance(res.el_rad, res.iono_m, rows.iono_on, rows.tropo_on)
    sigma = np.where(np.isfinite(var), np.sqrt(var), 3.0)
    ok = np.isfinite(z)
    o.pseudorange_m[ok] = z[ok] + sigma[ok] * rng.standard_normal(int(ok.sum()))
    lam = K.C_LIGHT_MPS / K.GPS_L1_HZ
    o.doppler_hz[:] = -(zr + K.RANGE_RATE_SIGMA_MPS * rng.standard_normal(len(o))) / lam
    return o.take(np.flatnonzero(ok)), sigma[ok]
