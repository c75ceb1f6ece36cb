"""Carrier tracking, stage 1: aided mix-down and decimation of one tone (vectorised NumPy).

Each block of M samples (M/fs ~ 0.1 ms) is multiplied by the aiding oscillator and summed:
    y_k = sum_m x[kM + m] exp(-j 2 pi (Phi_k + f_k m / fs)),   Phi_{k+1} = Phi_k + f_k M / fs
with f_k the aiding frequency (Hz, baseband: predicted Doppler + tone offset - LO estimate)
at the block's centre. The aiding phase is piecewise linear and continuous, so the signal's
phase is exactly Phi_aid(t) + the residual the loop tracks (`carrier.py`). Within 0.1 ms the
aiding's curvature (4 kHz/s: pi alpha T^2 = 1.3e-4 rad) is neglected, and a residual
frequency df (the aiding error, up to a few hundred Hz) costs sinc(df M / fs) of amplitude
(0.4 % at 500 Hz).

The oscillator is factored, m = a S + b: exp(-j w m) = exp(-j w a S) exp(-j w b), so a block
costs A + S complex exponentials (A S = M) and one complex multiply-add per sample
(a batched matrix product): about 2.5 ms of CPU per tone and second of capture at 2.4 MS/s.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.common.errors import UserInputError

SUB_RATE_HZ = 10e3          # target rate of the decimated samples (+-5 kHz unaliased)
MAX_TONE_FRACTION = 0.45    # a tone beyond 0.45 fs is at the anti-alias filter's edge


def block_factors(sample_rate_hz: float, sub_rate_hz: float = SUB_RATE_HZ) -> tuple[int, int]:
    """(M, S): samples per decimated sample and the inner factor (S divides M)."""
    ratio = sample_rate_hz / sub_rate_hz
    if ratio >= 16:
        m = 16 * max(1, int(round(ratio / 16)))
        return m, 16
    m = max(1, int(round(ratio)))
    return m, m


def validate_rate(sample_rate_hz: float, acq_range_hz: float, sub_rate_hz: float = SUB_RATE_HZ) -> None:
    """UserInputError when the sample rate cannot hold the loop's decimated band."""
    if not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise UserInputError(f"carrier tracking: sample rate {sample_rate_hz!r} Hz; expected a positive number")
    m, _ = block_factors(sample_rate_hz, sub_rate_hz)
    f_sub = sample_rate_hz / m
    if f_sub < 4 * acq_range_hz:
        raise UserInputError(f"carrier tracking: sample rate {sample_rate_hz:g} Hz gives decimated samples at "
                             f"{f_sub:g} Hz; expected at least {4 * acq_range_hz:g} Hz (4 x the acquisition "
                             "range) to hold the loop")


@dataclasses.dataclass
class Aiding:
    """Predicted baseband frequency of one tone on a time grid (s since the capture start, Hz)."""

    t_s: np.ndarray
    f_hz: np.ndarray
    label: str = "tone"

    def __post_init__(self):
        self.t_s = np.asarray(self.t_s, float)
        self.f_hz = np.asarray(self.f_hz, float)
        if self.t_s.ndim != 1 or self.t_s.shape != self.f_hz.shape or self.t_s.size < 2:
            raise UserInputError(f"{self.label}: aiding needs matching time and frequency arrays of at least 2 "
                                 f"points; got {self.t_s.shape} and {self.f_hz.shape}")
        if not (np.all(np.isfinite(self.t_s)) and np.all(np.isfinite(self.f_hz)) and np.all(np.diff(self.t_s) > 0)):
            raise UserInputError(f"{self.label}: aiding times must increase and values be finite")

    def at(self, t_s: np.ndarray) -> np.ndarray:
        return np.interp(t_s, self.t_s, self.f_hz)

    def check_covers(self, duration_s: float, sample_rate_hz: float) -> None:
        if self.t_s[0] > 0 or self.t_s[-1] < duration_s:
            raise UserInputError(f"{self.label}: aiding covers {self.t_s[0]:.3f}..{self.t_s[-1]:.3f} s; the capture "
                                 f"needs 0..{duration_s:.3f} s")
        inside = (self.t_s >= 0) & (self.t_s <= duration_s)
        f_max = float(np.max(np.abs(self.f_hz[inside]))) if inside.any() else float(np.max(np.abs(self.f_hz)))
        if f_max > MAX_TONE_FRACTION * sample_rate_hz:
            raise UserInputError(f"{self.label}: predicted at {f_max:.0f} Hz from the centre, beyond "
                                 f"{MAX_TONE_FRACTION} x the sample rate {sample_rate_hz:g} Hz: the capture "
                                 "cannot hold this tone")


def _phasor(angle_rad: np.ndarray) -> np.ndarray:
    """exp(-j angle) as complex64 from float32 cos/sin (6x faster than a complex128 exp);
    the callers keep |angle| below ~100 rad, so float32 rounding stays below 1e-5 rad."""
    a = np.asarray(angle_rad, np.float32)
    out = np.empty(a.shape, np.complex64)
    parts = out.view(np.float32).reshape(*a.shape, 2)
    np.cos(a, out=parts[..., 0])
    np.sin(a, out=parts[..., 1])
    np.negative(parts[..., 1], out=parts[..., 1])
    return out


class FrontEnd:
    """Streaming aided mix-down of one tone: feed sample blocks, get decimated samples.

    Samples left over at the end of a block (fewer than M) wait for the next one.
    """

    def __init__(self, aiding: Aiding, sample_rate_hz: float, sub_rate_hz: float = SUB_RATE_HZ):
        self.aiding, self.fs = aiding, float(sample_rate_hz)
        self.m, self.s = block_factors(sample_rate_hz, sub_rate_hz)
        self.a = self.m // self.s
        self.sub_rate_hz = self.fs / self.m
        self.k = 0                    # decimated samples produced so far
        self.phase = 0.0              # aiding phase (cycles) at the next block's first sample
        self._rest = np.zeros(0, np.complex64)
        self._b = np.arange(self.s, dtype=np.float32)
        self._a_idx = np.arange(self.a, dtype=np.float32)

    @property
    def next_sample(self) -> int:
        """Capture index of the next sample this front end takes (whole blocks made, plus the pending ones)."""
        return self.k * self.m + self._rest.size

    def feed(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(y complex64, Phi_k cycles at each block start, f_k Hz) for the whole blocks available."""
        parts = []
        if self._rest.size:   # complete the pending block without copying the whole of x
            need = self.m - self._rest.size
            if x.size < need:
                self._rest = np.concatenate([self._rest, x])
                return np.zeros(0, np.complex64), np.zeros(0), np.zeros(0)
            parts.append(self._mix(np.concatenate([self._rest, x[:need]])))
            x = x[need:]
        nb = x.size // self.m
        self._rest = x[nb * self.m:].copy()
        if nb:
            parts.append(self._mix(x[:nb * self.m]))
        if not parts:
            return np.zeros(0, np.complex64), np.zeros(0), np.zeros(0)
        if len(parts) == 1:
            return parts[0]
        return tuple(np.concatenate(c) for c in zip(*parts))

    def _mix(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nb = x.size // self.m
        t_mid = ((self.k + np.arange(nb)) * self.m + 0.5 * (self.m - 1)) / self.fs
        f = self.aiding.at(t_mid)
        step = f * (self.m / self.fs)
        phi = self.phase + np.concatenate([[0.0], np.cumsum(step[:-1])])
        self.phase = float(phi[-1] + step[-1])
        self.k += nb
        w = (2 * np.pi / self.fs) * f                       # rad per sample, |w| < 2.9
        pb = _phasor(np.outer(w.astype(np.float32), self._b))
        ws = np.remainder(w * self.s, 2 * np.pi).astype(np.float32)   # per inner block, reduced
        frac = (2 * np.pi * (phi - np.floor(phi))).astype(np.float32)
        pa = _phasor(np.outer(ws, self._a_idx) + frac[:, None])
        xr = np.asarray(x, np.complex64).reshape(nb, self.a, self.s)
        inner = np.matmul(xr, pb[:, :, None])[..., 0]
        return np.einsum("ka,ka->k", inner, pa), phi, f
