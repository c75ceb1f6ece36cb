"""Front-end realism of the beacon carrier phase: what the LNB, the SDR and the tracking loop do
to a time-differenced phase that the filter's model does not (scenario section `[front_end]`).

- C/N0 per record from the satellite's elevation, linear from `cn0_dbhz[0]` at the Starlink
  mask to `cn0_dbhz[1]` at the zenith, and the loop's thermal jitter from it,
  sigma_phi^2 = B_n / (C/N0) (1 + 1 / (2 T_i C/N0)) rad^2 (T_i the 1 ms coherent integration),
  sqrt(2) of it in a difference: each record's sigma (the tracker reports its own, so the
  filter's R follows it too). The trial's noise is drawn at the scenario's
  `carrier_phase_sigma_cyc` first; a record whose own sigma is larger gets the excess added
  (so that key is the strongest tone's sigma, 0.0136 cycles at 35 dB-Hz and B_n = 10 Hz).
- LO phase noise: the LNB's SSB phase noise `lo_phase_noise_dbc_hz` at `lo_phase_noise_offset_hz`,
  taken as white frequency noise (-20 dB/decade, S_nu = f^2 2 L(f) Hz^2/Hz). Its phase over one
  epoch is a Wiener increment of variance S_nu T / 2 cycles^2, common to every satellite of the
  epoch (one LO for all tones), independent between epochs. The filter follows it through
  b_lo only if its LO random walk is as fast: `compensate = true` sets q_blo to S_nu / T^2,
  the walk whose step over T has the increment's variance of a mean frequency.
- Cycle slips below `slip_below_dbhz`: each epoch slips with probability `slip_probability`;
  the tracker detects `slips_detected` of them (its epoch is dropped and counted, as the road
  drops a flagged epoch), an undetected one adds a whole cycle of either sign.

Draws come from streams of their own (front_end:lo, front_end:slips), so a trial's other
draws are unchanged by this switch.
"""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.simulation.sensor_errors import own_stream

COHERENT_S = 1e-3   # the tracker's coherent integration (beacons/carrier_loop.py: 1 ms blocks)


def elevation_rad(setup, rows: np.ndarray, series) -> np.ndarray:
    """Elevation (rad) of each row's satellite above the truth receiver at its epoch, as the
    visibility mask measures it (geodetic horizon of the site)."""
    from leonav_runtime.simulation.visibility import _receiver_ecef

    k = np.rint(series.t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    r_U = _receiver_ecef(setup.scn, setup.x_true[k, 0:3])
    return geometry.az_el_range(series.sat_ecef[rows, 0:3], r_U, setup.scn.lat_rad, setup.scn.lon_rad)[1]


def cn0_dbhz(cfg: dict, elevation: np.ndarray, mask_rad: float) -> np.ndarray:
    lo, hi = cfg["cn0_dbhz"]
    frac = np.clip((elevation - mask_rad) / (math.pi / 2 - mask_rad), 0.0, 1.0)
    return lo + (hi - lo) * frac


def difference_sigma_cyc(cn0: np.ndarray, bn_hz: float) -> np.ndarray:
    """1-sigma (cycles) of a phase difference from the loop's thermal jitter at C/N0 (dB-Hz)."""
    c = 10.0 ** (np.asarray(cn0) / 10.0)
    var_rad2 = bn_hz / c * (1.0 + 1.0 / (2.0 * COHERENT_S * c))
    return math.sqrt(2.0) * np.sqrt(var_rad2) / (2.0 * math.pi)


def lo_frequency_psd(cfg: dict) -> float:
    """S_nu (Hz^2/Hz, one-sided) of the LO's white frequency noise from its phase-noise figure."""
    f = cfg["lo_phase_noise_offset_hz"]
    return f * f * 2.0 * 10.0 ** (cfg["lo_phase_noise_dbc_hz"] / 10.0)


def filter_q_blo(cfg: dict, interval_s: float) -> float:
    """The LO random-walk PSD (Hz^2/s) that follows the LO's white FM at the epoch interval."""
    return lo_frequency_psd(cfg) / interval_s**2


def apply(setup, rng: np.random.Generator, part: list, series) -> dict[str, int]:
    """One trial's front-end errors on a carrier-phase part [kind_name, rows, z, sigma], in
    place (rows of a detected slip removed); returns the counts of slips and drops."""
    cfg, scn = setup.scn.realism["front_end"], setup.scn
    rows, z = part[1], np.asarray(part[2], float)
    cn0 = cn0_dbhz(cfg, elevation_rad(setup, rows, series), scn.starlink["elevation_mask_rad"])
    sigma = difference_sigma_cyc(cn0, cfg["pll_bandwidth_hz"])
    nominal = part[3]   # the scenario's sigma, the trial's noise already drawn at it: add the excess
    t = series.t_s[rows]
    epochs, index = np.unique(t, return_inverse=True)
    T = series.interval_s[rows]
    lo = own_stream(rng, "front_end:lo").standard_normal(epochs.size) * math.sqrt(lo_frequency_psd(cfg) / 2.0)
    z = z + lo[index] * np.sqrt(T)
    extra = np.sqrt(np.maximum(sigma**2 - nominal**2, 0.0))
    z = z + extra * own_stream(rng, "front_end:thermal").standard_normal(z.size)
    slips = own_stream(rng, "front_end:slips")
    weak = cn0 < cfg["slip_below_dbhz"]
    slip = weak & (slips.random(z.size) < cfg["slip_probability"])
    detected = slip & (slips.random(z.size) < cfg["slips_detected"])
    undetected = slip & ~detected
    z = z + undetected * np.where(slips.random(z.size) < 0.5, -1.0, 1.0)
    keep = ~detected
    part[1], part[2], part[3] = rows[keep], z[keep], np.maximum(sigma, nominal)[keep]
    return {"slips": int(slip.sum()), "slips_detected": int(detected.sum()), "epochs_dropped": int(detected.sum())}
