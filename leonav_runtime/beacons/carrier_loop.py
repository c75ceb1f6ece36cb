"""Carrier tracking, stage 2: FFT acquisition and the FLL-assisted third-order PLL.

Works on the decimated, aided samples of `carrier_front` (about 10 kHz), so it tracks only
the residual: the signal phase minus the aiding phase (LO error, element-set error, LO
phase noise below the loop bandwidth).

Loop design (defaults, and why):
- integration (prompt) time T = 10 ms. The beacon is an unmodulated tone, so nothing bounds
  T but the dynamics; 10 ms gives a predetection SNR C/N0 T of 0 dB at 20 dB-Hz, where the
  four-quadrant discriminator still works, and B_n T = 0.1 keeps the discrete loop close to
  its analogue design;
- discriminator: atan2(Q, I) of the prompt, a pure PLL (no data bits: +-180 deg linear
  range, no Costas squaring loss);
- third order, B_n = 10 Hz, boxcar-integrator form (Kaplan & Hegarty, Understanding GPS,
  table 5.6): w0 = B_n / 0.7845, a3 = 1.1, b3 = 2.4. A third-order loop follows a constant
  Doppler rate with no steady-state error, so the 4 kHz/s of an overhead pass left over by
  an aiding error is followed; what remains is the jerk over w0^3 (50 Hz/s^2 unaided:
  0.15 rad). Thermal jitter sigma^2 = B_n / (C/N0) (1 + 1 / (2 T C/N0)) rad^2: 22 deg at
  20 dB-Hz, 5.9 deg at 30 (18 and 5.7 without the low-SNR term); loop SNR C/N0 / B_n = 10
  at 20 dB-Hz, above the ~4 lock needs;
- FLL assist for the first `fll_s` (0.3 s) of the pull-in after an acquisition: frequency
  discriminator atan2(cross, dot) / T of consecutive prompts (+-1 / (2T) = +-50 Hz),
  second-order FLL of B_f = 2 Hz (w0f = B_f / 0.53, a2 = 1.414) feeding the same
  integrators. The FFT has the frequency to ~1 Hz already; at 20 dB-Hz a longer-running FLL
  integrates its own noise into a runaway. A pull-in not locked after settle_s + reacq_s
  (1.4 s) acquires again;
- lost lock (a fade, a blockage): the loop's frequency is set to the slope of its phase
  over the 0.4 s before the last two lock windows (its own state integrated noise while
  the detector made up its mind, up to ~20 Hz/s of rate in 0.2 s), its rate to 0 (the
  aiding carries the dynamics), and it coasts while the prompts' power says the tone is
  absent (prompt powers over 0.2 s below 1.5 x noise); once back, the PLL pulls in from
  there (no FLL: at 20 dB-Hz its noise would undo the held frequency), so a signal back within
  `reacq_s` is locked again in a few tenths of a second;
- acquisition: FFT of the first `acq_s` (0.4 s) of samples summed to 2 kHz, over
  +-`acq_range_hz` (1 kHz, the element-set error at zenith: 4 kHz/s x 0.13 s of along-track
  error), 4x zero padding, the peak accepted at `acq_threshold` (16) x the noise power of
  a bin (false peak among ~800 bins: 1e-4), parabolic interpolation of the peak.
- lock: on a sliding 10-prompt (0.1 s) coherent sum Z, d = Re(Z) / sqrt(10 sigma_z^2 / 2)
  (unit variance in noise alone; 14 at 30 dB-Hz, ~4 at 20). Locked after 10 prompts with
  d >= 3 and |arg Z| < 45 deg, and no sooner than `settle_s` (0.4 s) after an acquisition
  (the pull-in transient can slip a cycle at 20 dB-Hz); lost after 10 prompts with d < 1.5,
  or 3 with d < 0; after `reacq_s` (1 s) lost, acquisition again. Each lock starts a new
  arc (new ambiguity).
- C/N0: sigma_z^2 (noise per prompt) from the first differences of the loop-rotated
  decimated samples (the residual carrier hardly changes in 0.1 ms, so they are noise;
  before the first prompt, from the acquisition spectrum's median bin), and
  C/N0 = (mean |z|^2 - sigma_z^2) / (sigma_z^2 T), unbiased without lock.
"""
from __future__ import annotations

import cmath
import collections
import dataclasses
import math

import numpy as np

ACQ, PULL, LOCK, LOST = 0, 1, 2, 3


@dataclasses.dataclass
class LoopConfig:
    """Loop settings; units in the names."""

    bn_hz: float = 10.0
    t_coh_s: float = 0.01
    fll_bn_hz: float = 2.0
    acq_s: float = 0.4
    acq_range_hz: float = 1000.0
    acq_threshold: float = 16.0
    lock_window: int = 10          # prompts in the lock detector's coherent sum
    lock_on_d: float = 3.0
    lock_on_deg: float = 45.0
    lock_off_d: float = 1.5
    settle_s: float = 0.4          # no lock declared sooner after an acquisition (FLL-to-PLL handover)
    fll_s: float = 0.3             # FLL assist for this long after an acquisition
    reacq_s: float = 1.0
    # the loop chosen from the first acquisition's C/N0: a weaker tone than `weak_below_dbhz` is
    # tracked with the narrower, longer loop (better below it, docs/carrier.md table 1b; its jerk
    # margin, jerk / w0^3, is 8x smaller, so it is kept for weak tones only); None: never
    weak_below_dbhz: float | None = 22.5
    weak_bn_hz: float = 5.0
    weak_t_coh_s: float = 0.02


def coefficients(cfg: LoopConfig) -> tuple[float, float, float, float, float]:
    """(w0^3, a3 w0^2, b3 w0, w0f^2, a2 w0f) of the loop filter (rad/s units)."""
    w0 = cfg.bn_hz / 0.7845
    w0f = cfg.fll_bn_hz / 0.53
    return w0**3, 1.1 * w0**2, 2.4 * w0, w0f**2, 1.414 * w0f


def noise_bandwidth_hz(cfg: LoopConfig, n: int = 4000) -> float:
    """Noise bandwidth (Hz, one-sided) of the discrete loop as implemented: white
    discriminator noise of variance s2 per prompt gives NCO phase variance
    s2 sum h_k^2, with h the closed-loop impulse response (input phase -> NCO phase; the
    noise enters where the input does); B_n = sum h_k^2 / (2 T)."""
    k3, k2, k1, _, _ = coefficients(cfg)
    t = cfg.t_coh_s
    w1 = w2 = phi = 0.0
    h = np.zeros(n)
    for i in range(n):
        e = (1.0 if i == 0 else 0.0) - phi       # unit impulse of the input phase
        w2 += t * k3 * e
        w1 += t * (w2 + k2 * e)
        phi += (w1 + k1 * e) * t
        h[i] = phi
    return float(np.sum(h**2) / (2 * t))


def acquisition_cn0_dbhz(ratio: float, acq_s: float) -> float:
    """C/N0 (dB-Hz) from an acquisition's peak-to-noise power ratio over `acq_s` of samples: the
    peak holds the tone's energy plus one bin of noise, a bin of noise is N0 / acq_s of it."""
    return 10 * math.log10(max(ratio - 1.0, 1e-12) / acq_s)


def acquire(y: np.ndarray, sub_rate_hz: float, cfg: LoopConfig) -> tuple[float, float, float] | None:
    """(residual frequency Hz, peak-to-noise power ratio, noise power per sample of y) of the
    strongest tone in `y`, or None when no peak clears the threshold. The noise level is the
    median bin over ln 2 (the median of an exponential variable), so the tone does not bias it."""
    dec = max(1, int(sub_rate_hz // (2 * cfg.acq_range_hz)))
    n = (y.size // dec) * dec
    if n < 8 * dec:
        return None
    z = y[:n].reshape(-1, dec).sum(axis=1)
    rate = sub_rate_hz / dec
    nfft = 4 * (1 << int(np.ceil(np.log2(z.size))))
    spec = np.abs(np.fft.fft(z, nfft)) ** 2
    f = np.fft.fftfreq(nfft, 1.0 / rate)
    spec[np.abs(f) > cfg.acq_range_hz] = 0.0
    noise_bin = float(np.median(spec[np.abs(f) <= cfg.acq_range_hz])) / math.log(2)
    k = int(np.argmax(spec))
    ratio = float(spec[k] / noise_bin) if noise_bin > 0 else 0.0
    if ratio < cfg.acq_threshold:
        return None
    a, b, c = np.log(spec[(k - 1) % nfft] + 1e-30), np.log(spec[k]), np.log(spec[(k + 1) % nfft] + 1e-30)
    den = a - 2 * b + c
    shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(f[k] + shift * rate / nfft), ratio, noise_bin / (z.size * dec)


class Loop:
    """The PLL with its acquisition and lock state, run prompt by prompt.

    `run(y, start, offset)` processes whole prompts of the decimated samples y from index
    `start` and appends per-prompt records: index of the first sample (+ `offset`: where y
    starts among all samples), state, NCO phase at the
    prompt start (rad, residual, continuous), NCO frequency (rad/s), the prompt z and the
    lock statistic d. It returns the index it stopped at.
    """

    def __init__(self, cfg: LoopConfig, sub_rate_hz: float):
        self.rate = sub_rate_hz
        self._configure(cfg)
        self.chosen = cfg.weak_below_dbhz is None     # the loop is chosen at the first acquisition
        self.weak = False
        self.cn0_acq_dbhz = math.nan
        self.mode = ACQ
        self.phi = self.w1 = self.w2 = 0.0
        self.w = 0.0
        self.prev_e = None
        self.sigma2_y = math.nan
        self.noise_sum, self.noise_n = 0.0, 0
        self.on = self.off = self.neg = 0
        self.lost_prompts = self.since_acq = 0
        self.arc = -1
        self.rec: dict[str, list] = {k: [] for k in ("i0", "mode", "phi", "w", "z", "d", "arc", "noise")}
        self.acquisitions = 0

    def _configure(self, cfg: LoopConfig) -> None:
        self.cfg = cfg
        self.p = max(1, int(round(cfg.t_coh_s * self.rate)))
        self.t = self.p / self.rate
        self.k3, self.k2, self.k1, self.f2, self.f1 = coefficients(cfg)
        self.tau = (np.arange(self.p) + 0.5) / self.rate
        # the lock and presence detectors' buffers, sized in prompts (empty: the loop is configured
        # before its first prompt, at the start and at the first acquisition)
        self.ring = [0j] * cfg.lock_window
        self.ring_i, self.zsum = 0, 0j
        self.pring, self.psum, self.pring_i, self.present = [0.0] * (2 * cfg.lock_window), 0.0, 0, 0
        self.hist: collections.deque = collections.deque(maxlen=6 * cfg.lock_window)

    def _choose(self, ratio: float) -> None:
        """At the first acquisition that finds the tone: the weak-tone loop below its C/N0."""
        self.chosen = True
        self.cn0_acq_dbhz = acquisition_cn0_dbhz(ratio, self.cfg.acq_s)
        self.weak = self.cn0_acq_dbhz < self.cfg.weak_below_dbhz
        if self.weak:   # the lock detector's window keeps its length in time (0.1 s), not in prompts
            window = max(3, int(round(self.cfg.lock_window * self.cfg.t_coh_s / self.cfg.weak_t_coh_s)))
            self._configure(dataclasses.replace(self.cfg, bn_hz=self.cfg.weak_bn_hz, t_coh_s=self.cfg.weak_t_coh_s,
                                                lock_window=window))

    def _noise(self) -> float:
        return self.noise_sum / self.noise_n if self.noise_n else self.sigma2_y

    def run(self, y: np.ndarray, start: int, offset: int = 0) -> int:
        cfg, p = self.cfg, self.p
        i = start
        n_acq = int(round(cfg.acq_s * self.rate))
        while i + p <= y.size:
            if self.mode == ACQ:
                if i + n_acq > y.size:
                    break
                self.acquisitions += 1
                got = acquire(y[i:i + n_acq], self.rate, cfg)
                if got is None:
                    for j in range(i, i + n_acq - p + 1, p):   # nothing found: these prompts unlocked
                        self._record(offset + j, 0j, 0.0)
                    i += (n_acq // p) * p
                    continue
                if not self.chosen:
                    self._choose(got[1])
                    cfg, p = self.cfg, self.p
                self.w1, self.w2, self.w, self.prev_e = 2 * math.pi * got[0], 0.0, 2 * math.pi * got[0], None
                if not self.noise_n:
                    self.sigma2_y = got[2]
                self.mode, self.on, self.off, self.neg, self.lost_prompts = PULL, 0, 0, 0, 0
                self.since_acq = 0
                self.ring = [0j] * cfg.lock_window
                self.zsum = 0j
            self._prompt(y[i:i + p], offset + i)
            i += p
        return i

    def _prompt(self, ys: np.ndarray, i0: int) -> None:
        cfg = self.cfg
        rot = np.exp(-1j * (self.phi + self.w * self.tau))
        yc = ys * rot
        z = complex(yc.sum())
        d_y = np.diff(yc)
        self.noise_sum = 0.999 * self.noise_sum + float(np.vdot(d_y, d_y).real) / 2
        self.noise_n = 0.999 * self.noise_n + d_y.size
        e = math.atan2(z.imag, z.real)
        # lock detector on the sliding coherent sum
        self.zsum += z - self.ring[self.ring_i]
        self.ring[self.ring_i] = z
        self.ring_i = (self.ring_i + 1) % cfg.lock_window
        s2z = self._noise() * self.p
        d = self.zsum.real / math.sqrt(cfg.lock_window * s2z / 2) if s2z > 0 else 0.0
        self._record(i0, z, d)
        self._lock_logic(d, abs(math.degrees(cmath.phase(self.zsum))))
        # signal present: prompt powers over two windows 1.8 dB above the noise (a frequency
        # error would cancel a coherent sum; noise alone passes 1 %), 5 prompts in a row
        pw = abs(z) ** 2
        self.psum += pw - self.pring[self.pring_i]
        self.pring[self.pring_i] = pw
        self.pring_i = (self.pring_i + 1) % len(self.pring)
        loud = s2z > 0 and self.psum > 1.5 * len(self.pring) * s2z
        self.present = self.present + 1 if loud else 0
        present = self.present >= 5
        ef = 0.0
        if self.mode == PULL and self.prev_e is not None and self.since_acq * self.t < cfg.fll_s:
            ef = ((e - self.prev_e + math.pi) % (2 * math.pi) - math.pi) / self.t
        self.prev_e = e
        t = self.t
        if self.mode == LOST and not present:   # coast on the held frequency and rate
            self.w1 += t * self.w2
            e = 0.0
        else:
            self.w2 += t * (self.k3 * e + self.f2 * ef)
            self.w1 += t * (self.w2 + self.k2 * e + self.f1 * ef)
        self.phi += self.w * t
        self.w = self.w1 + self.k1 * e
        self.hist.append(self.phi)

    def _lock_logic(self, d: float, arg_deg: float) -> None:
        cfg = self.cfg
        if self.mode == LOCK:
            self.off = self.off + 1 if d < cfg.lock_off_d else 0
            self.neg = self.neg + 1 if d < 0 else 0
            if self.off >= cfg.lock_window or self.neg >= 3:
                self.mode, self.on, self.lost_prompts = LOST, 0, 0
                # the filter integrated noise while the detector made up its mind: take its
                # frequency and rate back to before (the prompts `carrier` takes back too)
                self.w1, self.w2 = self._held_frequency(), 0.0
            return
        self.on = self.on + 1 if (d >= cfg.lock_on_d and arg_deg < cfg.lock_on_deg) else 0
        self.since_acq += 1
        if self.on >= cfg.lock_window and self.since_acq * self.t >= cfg.settle_s:
            self.mode, self.off, self.neg = LOCK, 0, 0
            self.arc += 1
            return
        if self.mode == LOST:
            self.lost_prompts += 1
            if self.lost_prompts * self.t >= cfg.reacq_s:
                self.mode = ACQ
        elif self.since_acq * self.t >= cfg.settle_s + cfg.reacq_s:   # a pull-in that never locked
            self.mode = ACQ

    def _held_frequency(self) -> float:
        """NCO frequency (rad/s) to coast on: slope of a line through the NCO phase over the
        history before the last two lock windows (the filter's own frequency state is noisy,
        +-10 Hz at 20 dB-Hz, and integrated noise while the detector made up its mind)."""
        ph = np.asarray(self.hist)[:len(self.hist) - 2 * self.cfg.lock_window]
        if ph.size < 3:
            return self.w1
        return float(np.polyfit(np.arange(ph.size) * self.t, ph, 1)[0])

    def _record(self, i0: int, z: complex, d: float) -> None:
        r = self.rec
        r["i0"].append(i0)
        r["mode"].append(self.mode)
        r["phi"].append(self.phi)
        r["w"].append(self.w)
        r["z"].append(z)
        r["d"].append(d)
        r["arc"].append(self.arc if self.mode == LOCK else -1)
        r["noise"].append(self._noise())
