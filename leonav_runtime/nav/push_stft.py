"""The batch STFT (`beacons.waterfall.iter_spectra`) driven by pushed sample blocks, for the
beacon stream (`nav.beacon_stream`)."""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.beacons.waterfall import StftConfig, iter_spectra


class PushStft:
    """`waterfall.iter_spectra` driven by pushed sample blocks: the same slices (and times since the
    capture start) as the batch STFT of the whole capture, emitted as soon as a block of
    `slices_per_block` slices is complete."""

    def __init__(self, stft: StftConfig, sample_rate_hz: float, slices_per_block: int = 64) -> None:
        self.stft, self.fs, self.per_block = stft, sample_rate_hz, slices_per_block
        self.need = stft.fft_size + (slices_per_block - 1) * stft.hop
        self.step = slices_per_block * stft.hop
        self._parts: list[np.ndarray] = []    # pushed pieces not yet joined (joined once per block)
        self._n = 0
        self._start = 0                 # sample index of the first buffered sample

    def _joined(self) -> np.ndarray:
        if len(self._parts) > 1:
            self._parts = [np.concatenate(self._parts)]
        return self._parts[0] if self._parts else np.zeros(0, np.complex64)

    def push(self, samples: np.ndarray) -> list:
        self._parts.append(samples)
        self._n += samples.size
        out = []
        while self._n >= self.need:
            buf = self._joined()
            out.append(self._emit(buf[:self.need]))
            self._parts = [buf[self.step:]]
            self._n -= self.step
            self._start += self.step
        return out

    def flush(self) -> list:
        buf = self._joined()
        out = [self._emit(buf)] if buf.size >= self.stft.fft_size else []
        self._parts, self._n = [], 0
        return out

    def _emit(self, block: np.ndarray):
        spec = next(iter_spectra([block], self.stft, self.fs, slices_per_block=self.per_block))
        # slice centres since the capture start, written as iter_spectra writes them (same rounding)
        t = (self._start + np.arange(spec.t_s.size) * self.stft.hop + self.stft.fft_size / 2) / self.fs
        return dataclasses.replace(spec, t_s=t)
