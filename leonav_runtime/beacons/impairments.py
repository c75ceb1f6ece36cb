"""Receiver and capture impairments of synthetic beacon captures (off unless configured).

Each is a departure of a real LNB + RTL-SDR capture from the ideal one `synth` writes:

- IQ imbalance: the Q branch's gain differs by `iq_gain_db` and its phase by
  `iq_phase_deg` from quadrature; every tone gets a mirror image at minus its frequency,
  (gain and phase error of 0.5 dB / 3 deg: image ~ -28 dBc);
- DC spike: `SynthConfig.dc_offset_codes` (the RTL-SDR's LO leakage);
- 8-bit clipping: `SynthConfig.noise_rms_codes` is the front-end gain; with ~45 codes rms
  (or a strong interferer) the samples hit the ADC limits;
- LNB LO phase noise: a Wiener phase of 3-dB linewidth `phase_noise_linewidth_hz`;
- LNB LO temperature drift: an exponential warm-up of `lo_temp_step_hz` with time
  constant `lo_temp_tau_s` (not a straight line: the LO fit's linear model is stretched);
- SDR ppm drift: the tuner's crystal error `sdr_ppm` plus `sdr_ppm_rate_per_s` times t,
  times the tuning frequency (a common frequency ramp, like the LO's);
- a strong CW interferer at a fixed baseband frequency `cw_offset_hz` of `cw_cn0_dbhz`;
- overlapping combs of neighbouring satellites: `SynthConfig.tones_per_satellite` = 9 (the
  whole comb, 44 kHz spacing) with `full_comb_in_band = False`, so the combs interleave.

The LO and SDR frequency errors are part of the truth's LO error (`SynthTruth.lo_err_hz`);
the others act on the samples in `apply_to_block`, drawn from their own stream so that a
capture without impairments is unchanged.
"""
from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass
class Impairments:
    """Capture impairments (all off at their defaults); units in the names."""

    iq_gain_db: float = 0.0
    iq_phase_deg: float = 0.0
    phase_noise_linewidth_hz: float = 0.0
    lo_temp_step_hz: float = 0.0
    lo_temp_tau_s: float = 60.0
    sdr_ppm: float = 0.0
    sdr_ppm_rate_per_s: float = 0.0
    cw_offset_hz: float | None = None
    cw_cn0_dbhz: float = 75.0

    def any_on(self) -> bool:
        return self != Impairments()


# Every impairment on at levels a real capture shows: IQ imbalance of a consumer direct-
# conversion path, LNB PLL phase noise of a few Hz linewidth, a warmed-up LNB still
# drifting (3 kHz over a 10 min time constant: 5 Hz/s at the start), an RTL-SDR TCXO of
# 1 ppm drifting 0.002 ppm/s (3 Hz/s at 1.575 GHz), and a CW carrier 30 dB above beacons
# at 30 dB-Hz. The SynthConfig part (ALL_ON_SYNTH): the DC spike, the front-end gain set
# so that noise plus the carrier clip a few per cent of the samples, and whole combs.
ALL_ON = Impairments(iq_gain_db=0.5, iq_phase_deg=3.0, phase_noise_linewidth_hz=5.0, lo_temp_step_hz=3000.0,
                     lo_temp_tau_s=600.0, sdr_ppm=1.0, sdr_ppm_rate_per_s=0.002, cw_offset_hz=61_234.5,
                     cw_cn0_dbhz=60.0)
ALL_ON_SYNTH = {"dc_offset_codes": 0.6, "noise_rms_codes": 30.0, "tones_per_satellite": 9,
                "full_comb_in_band": False}


def lo_error_hz(imp: Impairments, t_s: np.ndarray, tuning_hz: float) -> np.ndarray:
    """The common frequency error (Hz) the LO warm-up and the SDR's crystal add at t_s."""
    warm = imp.lo_temp_step_hz * (1.0 - np.exp(-t_s / imp.lo_temp_tau_s))
    return warm + tuning_hz * 1e-6 * (imp.sdr_ppm + imp.sdr_ppm_rate_per_s * t_s)


class BlockImpairer:
    """Applies the sample-level impairments block by block (state: LO phase, CW phase)."""

    def __init__(self, imp: Impairments, fs: float, noise_sigma: float, seed: int):
        self.imp, self.fs = imp, fs
        self.rng = np.random.default_rng([seed, 7])   # own stream: the ideal capture is unchanged
        self.phase = 0.0
        self.cw_amp = np.sqrt(10 ** (imp.cw_cn0_dbhz / 10) * 2 * noise_sigma**2 / fs)
        self.k = 0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        imp, n = self.imp, x.size
        if imp.phase_noise_linewidth_hz > 0:   # Wiener phase: variance 2 pi linewidth per second
            steps = self.rng.standard_normal(n) * np.sqrt(2 * np.pi * imp.phase_noise_linewidth_hz / self.fs)
            ph = self.phase + np.cumsum(steps)
            self.phase = float(ph[-1])
            x *= np.exp(1j * ph).astype(np.complex64)
        if imp.cw_offset_hz is not None:
            k = self.k + np.arange(n)
            cyc = (imp.cw_offset_hz * k / self.fs) % 1.0
            x += (self.cw_amp * np.exp(2j * np.pi * cyc)).astype(np.complex64)
        self.k += n
        return x

    def iq_imbalance(self, x: np.ndarray) -> np.ndarray:
        """The Q branch with a gain and phase error (after DC: the imbalance is in the mixer)."""
        imp = self.imp
        if imp.iq_gain_db == 0 and imp.iq_phase_deg == 0:
            return x
        g, phi = 10 ** (imp.iq_gain_db / 20), np.radians(imp.iq_phase_deg)
        i, q = x.real, x.imag
        return (i + 1j * g * (q * np.cos(phi) + i * np.sin(phi))).astype(np.complex64)


def image_rejection_db(imp: Impairments) -> float:
    """Image-to-tone power ratio (dB, negative) of the IQ imbalance."""
    g, phi = 10 ** (imp.iq_gain_db / 20), np.radians(imp.iq_phase_deg)
    num = 1 + g**2 - 2 * g * np.cos(phi)
    den = 1 + g**2 + 2 * g * np.cos(phi)
    return float(10 * np.log10(num / den))


# Named impairment sets of `leonav impairments`: (IQ impairments, extra synthesis options).
# Here rather than in impairment_study, so the command line lists them without importing the pipeline.
SETS: dict[str, tuple[Impairments | None, dict]] = {
    "none": (None, {}),
    "iq-imbalance": (Impairments(iq_gain_db=ALL_ON.iq_gain_db, iq_phase_deg=ALL_ON.iq_phase_deg), {}),
    "dc-spike": (None, {"dc_offset_codes": ALL_ON_SYNTH["dc_offset_codes"]}),
    "8-bit-clipping": (None, {"noise_rms_codes": 45.0}),
    "lo-phase-noise": (Impairments(phase_noise_linewidth_hz=ALL_ON.phase_noise_linewidth_hz), {}),
    "lo-temperature": (Impairments(lo_temp_step_hz=ALL_ON.lo_temp_step_hz, lo_temp_tau_s=ALL_ON.lo_temp_tau_s), {}),
    "sdr-ppm-drift": (Impairments(sdr_ppm=ALL_ON.sdr_ppm, sdr_ppm_rate_per_s=ALL_ON.sdr_ppm_rate_per_s), {}),
    "cw-interferer": (Impairments(cw_offset_hz=ALL_ON.cw_offset_hz, cw_cn0_dbhz=ALL_ON.cw_cn0_dbhz), {}),
    "overlapping-combs": (None, {"tones_per_satellite": 9, "full_comb_in_band": False}),
    "all": (ALL_ON, dict(ALL_ON_SYNTH)),
}
