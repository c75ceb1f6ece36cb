"""Synthetic beacon captures: real files (RTL-SDR cu8, SigMF, cf32) from predicted Doppler.

Signal at baseband (Hz, s since the capture start):
    f_s(t) = D_s(t) + (tone_rf + k*comb_spacing) - rf_center - lo_err(t)
with D_s the Doppler of satellite s from the symbolic model (`predict.evaluate_model`),
rf_center = SDR tuning + nominal LNB LO, and lo_err(t) = offset + drift*t + random walk
the error of the LNB LO (true LO = nominal + lo_err). The phase is the exact integral of
f_s (cubic spline of the frequency on a 0.25 s grid, integrated analytically).

SNR definition: carrier-to-noise density C/N0 in dB-Hz per tone. Complex white noise of
`noise_rms_codes` ADC codes per I and Q component has total power N = 2 sigma^2 over the
sample rate fs, so N0 = N / fs and the tone amplitude is sqrt(10^(cn0/10) * N0). The
per-bin SNR of an STFT with bins of width df is then cn0 - 10 log10(df) dB, minus the
Hann window's 1.76 dB processing loss (e.g. 40 dB-Hz -> ~19.6 dB in 73 Hz bins).

8-bit quantization as `rtl_sdr` writes it: value*127.5 + 127.5 rounded and clipped to
0..255, with the noise at ~10 codes rms (the AGC-off gain a user would set so the
noise fills a few bits without clipping). An optional DC offset (codes) reproduces the
RTL-SDR DC spike. `impairments` adds the rest of a real capture's departures (IQ
imbalance, LO phase noise and warm-up, SDR ppm drift, a CW interferer; `impairments.py`).

Tones of the comb beyond `passband_fraction * fs / 2` are left out (block by block), as the
SDR's anti-alias filter would, instead of aliasing back into the band.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from leonav_runtime.beacons import capture_io
from leonav_runtime.beacons.impairments import BlockImpairer, Impairments, lo_error_hz
from leonav_runtime.beacons.predict import Predictions, Site, STARLINK_BEACON_HZ, predict_visible

from leonav_runtime.beacons.comb import COMB_SPACING_HZ  # noqa: F401  (re-exported: spacing of the ~9 tones)
from leonav_runtime.gen.constants import STARLINK_MASK_DEG


@dataclasses.dataclass
class SynthConfig:
    duration_s: float = 20.0
    sample_rate_hz: float = 2.4e6
    center_freq_hz: float = 1.575e9       # SDR tuning (IF)
    lnb_lo_hz: float = 9.75e9             # nominal LNB LO
    f_c_hz: float = STARLINK_BEACON_HZ
    cn0_dbhz: float | Sequence[float] = 40.0
    lo_offset_hz: float = 35e3            # LNB LO error at t = 0
    lo_drift_hz_s: float = 0.3            # linear LO drift
    lo_rw_hz2_s: float = 0.05             # LO frequency random-walk PSD
    noise_rms_codes: float = 10.0         # per I/Q component, in 8-bit ADC codes
    tones_per_satellite: int = 1          # 1: central tone only; 3: centre +/- one comb step...
    dc_offset_codes: float = 0.0
    n_satellites: int = 5
    band_fraction: float = 0.8            # keep chosen tones within this fraction of the band
    full_comb_in_band: bool = True        # False: only the central tone must stay in the band
    passband_fraction: float = 0.9        # tones beyond this fraction of fs/2 are not generated
    seed: int = 0
    impairments: Impairments | None = None  # receiver/capture impairments (`impairments.py`)


@dataclasses.dataclass
class SynthTruth:
    """What was put into the capture."""

    start_utc: _dt.datetime
    sat_index: np.ndarray      # indices into the element set
    names: list[str]
    norad_ids: np.ndarray
    cn0_dbhz: np.ndarray
    t_grid_s: np.ndarray       # grid of the truth curves
    doppler_hz: np.ndarray     # (nsat, nt) true Doppler (no LO error)
    rate_hz_s: np.ndarray
    lo_err_hz: np.ndarray      # (nt,) LO error on the same grid
    baseband_hz: np.ndarray    # (nsat, nt) central-tone frequency at baseband

    def describe(self) -> dict:
        return {"start_utc": self.start_utc, "norad_ids": self.norad_ids, "names": self.names,
                "cn0_dbhz": self.cn0_dbhz, "lo_err_hz_start": float(self.lo_err_hz[0])}


def choose_satellites(pred: Predictions, cfg: SynthConfig, rf_center_hz: float,
                      rng: np.random.Generator) -> np.ndarray:
    """Rows of `pred` whose tone stays in the band and above the mask all window long."""
    inside = (pred.t_s >= 0) & (pred.t_s <= cfg.duration_s)
    bb = pred.doppler_hz[:, inside] + cfg.f_c_hz - rf_center_hz - cfg.lo_offset_hz
    half = cfg.band_fraction * cfg.sample_rate_hz / 2
    if cfg.full_comb_in_band:
        half -= (cfg.tones_per_satellite // 2) * COMB_SPACING_HZ
    ok = (np.abs(bb).max(axis=1) < half) & (pred.elevation_rad[:, inside].min(axis=1) > 0)
    rows = np.nonzero(ok)[0]
    if rows.size < cfg.n_satellites:
        raise ValueError(f"only {rows.size} satellites fit the band; asked for {cfg.n_satellites}")
    return np.sort(rng.choice(rows, cfg.n_satellites, replace=False))


def build_truth(elements, site: Site, start_utc: _dt.datetime, cfg: SynthConfig,
                sat_index: Sequence[int] | None = None, mask_deg: float = STARLINK_MASK_DEG) -> SynthTruth:
    """Pick satellites (or use `sat_index`) and compute their true curves and the LO error."""
    rng = np.random.default_rng(cfg.seed)
    pred = predict_visible(elements, site, start_utc, cfg.duration_s, step_s=0.25, mask_deg=mask_deg,
                           f_c_hz=cfg.f_c_hz, margin_s=1.0)
    rf_center = cfg.center_freq_hz + cfg.lnb_lo_hz
    if sat_index is None:
        rows = choose_satellites(pred, cfg, rf_center, rng)
    else:
        lookup = {int(s): i for i, s in enumerate(pred.sat_index)}
        missing = [int(s) for s in sat_index if int(s) not in lookup]
        if missing:
            raise ValueError(f"satellites {missing} are not above the mask in the window")
        rows = np.asarray([lookup[int(s)] for s in sat_index], int)
    t = pred.t_s
    lo = cfg.lo_offset_hz + cfg.lo_drift_hz_s * t
    if cfg.lo_rw_hz2_s > 0:
        steps = rng.normal(0.0, np.sqrt(cfg.lo_rw_hz2_s * np.diff(t)))
        lo = lo + np.concatenate([[0.0], np.cumsum(steps)])
    if cfg.impairments is not None:   # LNB warm-up and SDR crystal: a common frequency error
        lo = lo + lo_error_hz(cfg.impairments, t, cfg.center_freq_hz)
    cn0 = np.broadcast_to(np.asarray(cfg.cn0_dbhz, float), (rows.size,)).copy()
    bb = pred.doppler_hz[rows] + cfg.f_c_hz - rf_center - lo[None, :]
    return SynthTruth(start_utc, pred.sat_index[rows], [pred.names[i] for i in rows], pred.norad_ids[rows],
                      cn0, t, pred.doppler_hz[rows], pred.rate_hz_s[rows], lo, bb)


def iter_synthetic_iq(truth: SynthTruth, cfg: SynthConfig) -> Iterator[np.ndarray]:
    """Complex baseband samples (units of ADC full scale), one block per truth-grid interval.

    Each block lies inside one piece of the phase spline, so the phase is that piece's
    polynomial evaluated by Horner's rule (no per-sample interval search).
    """
    rng = np.random.default_rng(cfg.seed + 1)
    fs = cfg.sample_rate_hz
    sigma = cfg.noise_rms_codes / 127.5          # per component, full-scale units
    n0 = 2 * sigma**2 / fs
    amps = np.sqrt(10 ** (truth.cn0_dbhz / 10) * n0)
    offsets = (np.arange(cfg.tones_per_satellite) - cfg.tones_per_satellite // 2) * COMB_SPACING_HZ
    cycles = [CubicSpline(truth.t_grid_s, truth.baseband_hz[i]).antiderivative() for i in range(len(amps))]
    phase0 = rng.uniform(0, 1, (len(amps), offsets.size))
    dc = cfg.dc_offset_codes / 127.5 * (1 + 1j)
    n_total = int(round(cfg.duration_s * fs))
    imp = cfg.impairments if cfg.impairments is not None and cfg.impairments.any_on() else None
    impair = BlockImpairer(imp, fs, sigma, cfg.seed) if imp else None
    k0 = 0
    while k0 < n_total:
        t_first = k0 / fs
        piece = int(np.clip(np.searchsorted(truth.t_grid_s, t_first, side="right") - 1, 0, truth.t_grid_s.size - 2))
        t_end = truth.t_grid_s[piece + 1]
        n = int(min(n_total - k0, max(1, np.ceil((t_end - t_first) * fs))))
        tau = (k0 + np.arange(n)) / fs - truth.t_grid_s[piece]
        x = (rng.standard_normal(n, np.float32) + 1j * rng.standard_normal(n, np.float32)).astype(np.complex64)
        x *= sigma
        xr, xi = x.real, x.imag  # views: add in place, no complex temporaries
        for i, amp in enumerate(amps):
            base = np.polyval(cycles[i].c[:, piece], tau)
            f_block = truth.baseband_hz[i, piece: piece + 2]
            for j, off in enumerate(offsets):
                if np.max(np.abs(f_block + off)) > cfg.passband_fraction * fs / 2:
                    continue  # outside the SDR's passband
                c = base + (off * (tau + truth.t_grid_s[piece]) + phase0[i, j])
                c -= np.floor(c)
                ph = (2 * np.pi * c).astype(np.float32)
                xr += amp * np.cos(ph)
                xi += amp * np.sin(ph)
        if impair:
            x = impair(x)
        x += dc
        yield impair.iq_imbalance(x) if impair else x
        k0 += n


def write_synthetic_capture(path: str | Path, elements, site: Site, start_utc: _dt.datetime,
                            cfg: SynthConfig, fmt: str = "cu8", sat_index: Sequence[int] | None = None,
                            progress: Callable[[int], None] | None = None) -> tuple[capture_io.CaptureInfo, SynthTruth]:
    """Write a capture file and its metadata; returns (CaptureInfo of the written file, truth).

    fmt: 'cu8' (rtl_sdr raw + `<path>.json` side file), 'cf32' (+ side file) or 'sigmf'
    (`<path>.sigmf-data` cu8 + `.sigmf-meta`). `progress(n)` is called with samples written.
    """
    truth = build_truth(elements, site, start_utc, cfg, sat_index)
    path = Path(path)
    if fmt == "sigmf":
        base = Path(str(path).removesuffix(".sigmf-data").removesuffix(".sigmf-meta"))
        data_path = Path(str(base) + ".sigmf-data")
    else:
        data_path = path
    data_path.parent.mkdir(parents=True, exist_ok=True)
    with open(data_path, "wb") as fh:
        for x in iter_synthetic_iq(truth, cfg):
            if fmt == "cf32":
                fh.write(x.astype(np.complex64).tobytes())
            else:
                fh.write(capture_io.quantize_cu8(x, 1.0).tobytes())
            if progress:
                progress(x.size)
    extra = {"synthetic": True, "synthetic_norad_ids": [int(i) for i in truth.norad_ids],
             "synthetic_cn0_dbhz": [float(c) for c in truth.cn0_dbhz]}
    if fmt == "sigmf":
        capture_io.write_sigmf_meta(base, "cu8", cfg.sample_rate_hz, cfg.center_freq_hz, cfg.lnb_lo_hz,
                                    start_utc, "leonav synthetic Starlink beacon capture", extra)
        info = capture_io.open_capture(str(base) + ".sigmf-meta")
    else:
        capture_io.write_side_json(data_path, cfg.sample_rate_hz, cfg.center_freq_hz, cfg.lnb_lo_hz, start_utc, extra)
        info = capture_io.open_capture(data_path, fmt)
    return info, truth
