"""Phase-coherent synthetic IQ of beacon tones with a known carrier-phase history (test bench).

Unlike `synth` (frequency curves for the ridge pipeline), every sample here carries an exact,
returned truth phase, so a carrier tracker can be scored in cycles.

Per tone, in cycles, at receiver sample n (nominal receiver time t_rx = n / fs):
    Phi(n) = phi0 + Phi_D(t) + f_if t - (lo_offset t + lo_drift t^2 / 2) - ppm 1e-6 f_tune t
             + phi_pn(t) / (2 pi) + slips(t),       t = t_rx / (1 + ppm 1e-6)
- Phi_D: an overhead pass, straight-line flyover at range `altitude_m` at closest approach,
  speed `speed_mps`: rho(t) = sqrt(h^2 + (v (t - t_ca))^2), Phi_D = -(f_c / c)(rho - rho(0)),
  so f_D = -(f_c / c) drho/dt (+-287 kHz far out) and the rate at closest approach is
  -(f_c / c) v^2 / h (-3.96 kHz/s at 550 km, 7.6 km/s, 11.325 GHz);
- one LNB LO shared by every tone: offset and drift (Hz, Hz/s), and phase noise phi_pn with
  the single-sideband density `phase_noise` (dBc/Hz at offsets, log-log interpolated, flat
  below the first point, the last slope continued above the last point; the default is a
  universal PLL LNB: -50 dBc/Hz up to 1 kHz, -75 at 10 kHz, -95 at 100 kHz);
- one RTL-SDR crystal shared by everything: it is `ppm` fast, so its samples are taken at
  true time t_rx / (1 + ppm 1e-6) and its tuner LO is off by ppm 1e-6 f_tune;
- injected slip events: the tone fades by `fade_db` (inf: blocked) for `duration_s` and
  its phase gains `cycles` whole cycles over the fade (smooth step); a tracker coasting
  through the fade on its aiding comes out `cycles` off, so it must flag the event.

Noise: complex white, unit power per sample (N0 = 1 / fs); the tone amplitude is
sqrt(10^(cn0/10) / fs), so C/N0 is exactly `cn0_dbhz` dB-Hz per tone (outside fades).
The phase noise is drawn at min(`PN_RATE_HZ`, fs) and interpolated linearly to fs: offsets
above PN_RATE_HZ / 2 (200 kHz, where the density is below -100 dBc/Hz) are left out.
"""
from __future__ import annotations

import dataclasses
from typing import Iterator, Sequence

import numpy as np
import scipy.fft

from leonav_runtime.gen.constants import C_LIGHT_MPS, STARLINK_BEACON_HZ

LNB_PHASE_NOISE_DBC_HZ = ((1e3, -50.0), (1e4, -75.0), (1e5, -95.0))  # (offset Hz, dBc/Hz)
PN_RATE_HZ = 400e3
TRUTH_STEP_S = 1e-3


@dataclasses.dataclass
class SlipEvent:
    """A fade of `fade_db` (inf: blocked) lasting `duration_s` from `t_s` (receiver time, s)
    over which the tone's phase gains `cycles` whole cycles."""

    t_s: float
    duration_s: float
    cycles: int
    fade_db: float = np.inf


@dataclasses.dataclass
class ToneSpec:
    """One tone: its C/N0, baseband offset and the pass it comes from."""

    cn0_dbhz: float = 30.0
    if_hz: float = 200e3            # tone frequency at baseband when the Doppler is 0
    t_closest_s: float = 0.0        # time of closest approach relative to the capture start
    altitude_m: float = 550e3       # range at closest approach
    speed_mps: float = 7.6e3
    phase0_cycles: float = 0.0
    slips: Sequence[SlipEvent] = ()


@dataclasses.dataclass
class PhaseBenchConfig:
    duration_s: float = 3.0
    sample_rate_hz: float = 2.4e6
    tuning_hz: float = 1.575e9               # RTL-SDR tuning (the LNB's IF)
    f_c_hz: float = STARLINK_BEACON_HZ
    lo_offset_hz: float = 0.0                # LNB LO error at t = 0 (beyond the aiding's estimate)
    lo_drift_hz_s: float = 0.0
    ppm: float = 0.0                         # RTL-SDR crystal error (sample clock and tuner)
    phase_noise: Sequence[tuple[float, float]] | None = LNB_PHASE_NOISE_DBC_HZ  # None: no phase noise
    seed: int = 0
    block_samples: int = 1 << 20


@dataclasses.dataclass
class PhaseCapture:
    """Samples and what went into them; times are receiver times (s since the first sample)."""

    iq: np.ndarray                 # complex64, unit noise power per sample
    sample_rate_hz: float          # nominal (what the receiver believes)
    t_s: np.ndarray                # truth grid, TRUTH_STEP_S apart
    phase_cycles: np.ndarray       # (ntones, nt) true carrier phase at baseband
    freq_hz: np.ndarray            # (ntones, nt) its derivative with respect to receiver time
    tones: list[ToneSpec]
    cfg: PhaseBenchConfig

    def predicted_baseband(self, t_s: np.ndarray, tone: int, ephemeris_dt_s: float = 0.0,
                           lo_error_hz: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Aiding a pipeline would compute: (frequency Hz, rate Hz/s) at baseband, from the
        pass seen `ephemeris_dt_s` late (an element set's along-track error) and a common
        LO estimate (LNB offset + tuner ppm, as the pipeline's LO fit gives) `lo_error_hz`
        off; without LO drift, the sample clock's scaling or phase noise."""
        spec, cfg = self.tones[tone], self.cfg
        f, r = _pass_doppler(np.asarray(t_s, float) + ephemeris_dt_s, spec, cfg.f_c_hz)
        lo = cfg.lo_offset_hz + cfg.ppm * 1e-6 * cfg.tuning_hz
        return f + spec.if_hz - lo - lo_error_hz, r


def _pass_range(t: np.ndarray, spec: ToneSpec) -> np.ndarray:
    return np.hypot(spec.altitude_m, spec.speed_mps * (t - spec.t_closest_s))


def _pass_doppler(t: np.ndarray, spec: ToneSpec, f_c_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Doppler (Hz) and its rate (Hz/s) of the straight-line pass."""
    x = spec.speed_mps * (t - spec.t_closest_s)
    rho = np.hypot(spec.altitude_m, x)
    k = f_c_hz / C_LIGHT_MPS
    return -k * spec.speed_mps * x / rho, -k * spec.speed_mps**2 * spec.altitude_m**2 / rho**3


def phase_noise_density(f_hz: np.ndarray, points: Sequence[tuple[float, float]]) -> np.ndarray:
    """Single-sideband phase-noise density L(f) in rad^2/Hz at offsets f_hz (see module doc)."""
    off = np.log10([p[0] for p in points])
    dbc = np.asarray([p[1] for p in points], float)
    lf = np.log10(np.maximum(np.abs(np.asarray(f_hz, float)), 1e-12))
    out = np.interp(lf, off, dbc)
    if len(points) > 1:
        slope = (dbc[-1] - dbc[-2]) / (off[-1] - off[-2])
        out = np.where(lf > off[-1], dbc[-1] + slope * (lf - off[-1]), out)
    return 10 ** (out / 10)


def draw_phase_noise(n: int, rate_hz: float, points: Sequence[tuple[float, float]],
                     rng: np.random.Generator) -> np.ndarray:
    """Phase (rad) on n samples at rate_hz whose two-sided density is L(|f|) (small angle:
    variance 2 int_0^inf L df), by shaping white noise in the frequency domain."""
    m = scipy.fft.next_fast_len(max(n, 2), real=True)
    w = np.fft.rfft(rng.standard_normal(m))
    f = np.fft.rfftfreq(m, 1.0 / rate_hz)
    h = np.sqrt(phase_noise_density(f, points) * rate_hz)
    h[0] = 0.0
    return np.fft.irfft(w * h, m)[:n]


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _slip_terms(t_rx: np.ndarray, spec: ToneSpec) -> tuple[np.ndarray, np.ndarray]:
    """(extra phase in cycles, amplitude factor) of the tone's slip events at receiver times."""
    extra = np.zeros(t_rx.shape)
    gain = np.ones(t_rx.shape)
    for ev in spec.slips:   # t_rx increases: only the samples inside the event need the step
        i0, i1 = np.searchsorted(t_rx, [ev.t_s, ev.t_s + ev.duration_s])
        extra[i0:i1] += ev.cycles * _smoothstep((t_rx[i0:i1] - ev.t_s) / ev.duration_s)
        extra[i1:] += ev.cycles
        gain[i0:i1] *= 0.0 if np.isinf(ev.fade_db) else 10 ** (-ev.fade_db / 20)
    return extra, gain


class _Truth:
    """Evaluates every tone's truth phase (cycles) at receiver times."""

    def __init__(self, tones: Sequence[ToneSpec], cfg: PhaseBenchConfig, rng: np.random.Generator):
        self.tones, self.cfg = list(tones), cfg
        self.scale = 1.0 / (1.0 + cfg.ppm * 1e-6)
        self.pn_rate = min(PN_RATE_HZ, cfg.sample_rate_hz)   # offsets up to fs / 2 exist in the samples
        n_pn = int(np.ceil(cfg.duration_s * self.pn_rate)) + 2
        self.pn = None
        if cfg.phase_noise:
            self.pn = draw_phase_noise(n_pn, self.pn_rate, cfg.phase_noise, rng) / (2 * np.pi)

    def phase(self, i: int, t_rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cfg, spec = self.cfg, self.tones[i]
        t = t_rx * self.scale
        k = cfg.f_c_hz / C_LIGHT_MPS
        ph = spec.phase0_cycles - k * (_pass_range(t, spec) - _pass_range(np.zeros(1), spec))
        ph += (spec.if_hz - cfg.lo_offset_hz - cfg.ppm * 1e-6 * cfg.tuning_hz) * t - 0.5 * cfg.lo_drift_hz_s * t * t
        if self.pn is not None:   # linear interpolation (np.interp would search the long grid)
            pos = t * self.pn_rate
            j = np.minimum(pos.astype(np.int64), self.pn.size - 2)
            ph += self.pn[j] + (pos - j) * (self.pn[j + 1] - self.pn[j])
        extra, gain = _slip_terms(t_rx, spec)
        return ph + extra, gain


def truth_frequency(truth_t_s: np.ndarray, phase_cycles: np.ndarray) -> np.ndarray:
    """d(phase)/dt (Hz) on the truth grid, central differences."""
    return np.gradient(phase_cycles, truth_t_s, axis=-1)


def _iter_iq(truth: _Truth, rng: np.random.Generator) -> Iterator[np.ndarray]:
    cfg, tones = truth.cfg, truth.tones
    amps = [np.sqrt(10 ** (s.cn0_dbhz / 10) / cfg.sample_rate_hz) for s in tones]
    n_total = int(round(cfg.duration_s * cfg.sample_rate_hz))
    sigma = np.float32(np.sqrt(0.5))
    for k0 in range(0, n_total, cfg.block_samples):
        n = min(cfg.block_samples, n_total - k0)
        x = (rng.standard_normal(n, np.float32) + 1j * rng.standard_normal(n, np.float32)) * sigma
        t_rx = (k0 + np.arange(n)) / cfg.sample_rate_hz
        xr, xi = x.real, x.imag
        for i, amp in enumerate(amps):
            ph, gain = truth.phase(i, t_rx)
            ph -= np.floor(ph)
            rad = (2 * np.pi * ph).astype(np.float32)
            a = (amp * gain).astype(np.float32)
            xr += a * np.cos(rad)
            xi += a * np.sin(rad)
        yield x.astype(np.complex64, copy=False)


def make_capture(tones: Sequence[ToneSpec], cfg: PhaseBenchConfig | None = None) -> PhaseCapture:
    """The whole capture in memory with its truth (short captures: a few seconds)."""
    cfg = cfg or PhaseBenchConfig()
    if not tones:
        raise ValueError("make_capture: no tones given")
    for i, s in enumerate(tones):
        ends = np.array([0.0, cfg.duration_s])   # a straight pass: the Doppler is monotonic
        lo = cfg.lo_offset_hz + cfg.ppm * 1e-6 * cfg.tuning_hz
        f_max = np.max(np.abs(s.if_hz - lo + _pass_doppler(ends, s, cfg.f_c_hz)[0]))
        if f_max + abs(cfg.lo_drift_hz_s) * cfg.duration_s > 0.45 * cfg.sample_rate_hz:
            raise ValueError(f"tone {i}: reaches {f_max:.0f} Hz at baseband, beyond 0.45 x the sample rate "
                             f"{cfg.sample_rate_hz:g} Hz; choose if_hz or t_closest_s so it stays in the band")
    rng = np.random.default_rng(cfg.seed)
    truth = _Truth(tones, cfg, rng)
    iq = np.concatenate(list(_iter_iq(truth, rng)))
    t = np.arange(0.0, cfg.duration_s + 0.5 * TRUTH_STEP_S, TRUTH_STEP_S)
    ph = np.stack([truth.phase(i, t)[0] for i in range(len(tones))])
    return PhaseCapture(iq, cfg.sample_rate_hz, t, ph, truth_frequency(t, ph), list(tones), cfg)


def random_slips(rng: np.random.Generator, duration_s: float, n: int, fade_s: tuple[float, float] = (0.4, 0.8),
                 margin_s: float = 1.0, fade_db: float = np.inf) -> list[SlipEvent]:
    """`n` slip events spread over the capture (one per slot, at least `margin_s` from the ends
    and from each other), 1 or 2 cycles of either sign."""
    slot = (duration_s - margin_s) / n
    if slot < fade_s[1] + margin_s:
        raise ValueError(f"{n} slip events do not fit in {duration_s:g} s with {margin_s:g} s between them")
    out = []
    for k in range(n):
        d = float(rng.uniform(*fade_s))
        t0 = margin_s + k * slot + float(rng.uniform(0.0, slot - d - margin_s))
        cyc = int(rng.choice([-2, -1, 1, 2]))
        out.append(SlipEvent(t0, d, cyc, fade_db))
    return out
