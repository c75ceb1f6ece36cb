"""Short-time Fourier transform of a capture, restricted to the beacon band.

Resolution trade-off (why the defaults): a slice of N samples at rate fs lasts T = N/fs
and has bins of width df = fs/N = 1/T. A tone whose Doppler changes at alpha Hz/s sweeps
alpha*T Hz during one slice; the peak stays sharp while alpha*T <= df, i.e.
T <= 1/sqrt(|alpha|). Near zenith |alpha| reaches ~4 kHz/s at 11.325 GHz, which gives
T ~ 16 ms. `default_fft_size` picks the power of two closest to fs*16 ms: 2^15 at
2.4 MS/s (13.7 ms, 73 Hz bins). Longer slices gain per-bin SNR (+3 dB per doubling)
but smear fast ridges; shorter ones lose SNR and frequency resolution. Slices overlap
by half (hop N/2, Hann window) so a sample's energy is not lost at the window edges.

Only the bins within `band_hz` of the centre are kept (the tones region: Doppler
+/-260 kHz plus the LNB LO offset), which is the FFT-domain equivalent of decimating
around the tones first, at no extra filtering cost.
"""
from __future__ import annotations

import dataclasses
from typing import Iterable, Iterator

import numpy as np

from leonav_runtime.beacons.row_fft import row_fft

# Noise-only power per bin is exponential with mean mu: median mu*ln 2, MAD mu*ln(phi)
# (phi the golden ratio, ln(phi) = 0.481).
_LN2 = float(np.log(2.0))

ALPHA_DESIGN_HZ_S = 4000.0  # |Doppler rate| near zenith at 11.325 GHz (design value)


def default_fft_size(sample_rate_hz: float, alpha_hz_s: float = ALPHA_DESIGN_HZ_S) -> int:
    """Power-of-two FFT length whose slice duration is closest to 1/sqrt(alpha)."""
    target = sample_rate_hz / np.sqrt(alpha_hz_s)
    return int(2 ** int(np.clip(np.round(np.log2(target)), 8, 20)))


@dataclasses.dataclass
class StftConfig:
    """STFT parameters (samples, Hz)."""

    fft_size: int
    hop: int
    band_hz: float          # keep |f| <= band_hz / 2 around the centre
    dc_notch_hz: float = 0.0  # zero bins within this of 0 Hz (RTL-SDR DC spike)

    @classmethod
    def for_rate(cls, sample_rate_hz: float, band_hz: float | None = None, fft_size: int | None = None,
                 overlap: float = 0.5, dc_notch_hz: float = 0.0) -> "StftConfig":
        n = int(fft_size or default_fft_size(sample_rate_hz))
        band = float(min(band_hz or sample_rate_hz, sample_rate_hz))
        return cls(n, max(1, int(round(n * (1.0 - overlap)))), band, dc_notch_hz)

    def bin_hz(self, sample_rate_hz: float) -> float:
        return sample_rate_hz / self.fft_size


@dataclasses.dataclass
class SpectrumBlock:
    """Consecutive STFT slices of the kept band."""

    t_s: np.ndarray         # (ns,) slice centre times since the capture start
    power: np.ndarray       # (ns, nb) |X|^2, float32, bins in ascending frequency
    noise_median: np.ndarray  # (ns,) median power over the band (noise floor)
    noise_mad: np.ndarray     # (ns,) median absolute deviation of the power

    @property
    def noise_mean(self) -> np.ndarray:
        """Mean noise power per bin: for exponential (noise-only) power, mean = median / ln 2."""
        return self.noise_median / _LN2


def band_bins(cfg: StftConfig, sample_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(FFT bin indices, their frequencies in Hz) of the kept band, ascending frequency."""
    n = cfg.fft_size
    k = np.arange(-(n // 2), n - n // 2)
    f = k * sample_rate_hz / n
    keep = np.abs(f) <= cfg.band_hz / 2
    return np.mod(k[keep], n), f[keep]


def iter_spectra(blocks: Iterable[np.ndarray], cfg: StftConfig, sample_rate_hz: float,
                 slices_per_block: int = 64, workers: int = 2) -> Iterator[SpectrumBlock]:
    """Stream STFT slices from consecutive complex64 sample blocks.

    Slices straddle block boundaries; memory is bounded by `slices_per_block * fft_size`
    samples (fewer slices per block above 2^15-sample FFTs). The input blocks are read, never
    written: a yielded block's slices may come from a view of them.
    """
    n, hop = cfg.fft_size, cfg.hop
    # long FFTs: fewer slices per block, so a block stays near 2^21 samples (tens of MB)
    slices_per_block = max(1, min(slices_per_block, (1 << 21) // n))
    idx, f_hz = band_bins(cfg, sample_rate_hz)
    notch = np.abs(f_hz) < cfg.dc_notch_hz
    # complex64 with zero imaginary parts: a complex64 x complex64 multiply has a SIMD loop, while
    # a float32 window is cast to complex per element first (the products are the same)
    window = np.hanning(n).astype(np.float32).astype(np.complex64)
    floor_step = max(1, idx.size // 4096)  # noise statistics from a subset of bins (speed)
    buf = np.zeros(0, np.complex64)
    buf_start = 0  # sample index of buf[0]
    # windowed frames go into one reused buffer: a fresh array per block costs page faults
    frames = np.empty((slices_per_block, n), np.complex64)
    any_notch = bool(notch.any())
    # the kept bins are one or two runs of consecutive FFT bins (negative frequencies, then 0 and
    # positive): |X|^2 is computed from those slices of the spectrum in place of a gathered copy
    cut = np.flatnonzero(np.diff(idx) != 1) + 1
    runs = [(int(r[0]), int(r[-1]) + 1, int(o)) for r, o in zip(np.split(idx, cut), np.r_[0, cut]) if r.size]

    def emit(b: np.ndarray, start: int) -> SpectrumBlock:
        ns = 1 + (b.size - n) // hop
        fr = frames[:ns]
        np.multiply(np.lib.stride_tricks.sliding_window_view(b, n)[::hop][:ns], window, out=fr)
        # in place: the frames buffer is refilled for every block, and a fresh 8 MB spectrum per block
        # would cost its page faults again
        spec = row_fft(fr, workers)
        p = np.empty((ns, idx.size), np.float32)   # |X|^2 of the complex64 spectrum, float32
        for lo, hi, at in runs:
            part = p[:, at:at + hi - lo]
            np.square(spec[:, lo:hi].real, out=part)
            part += np.square(spec[:, lo:hi].imag)
        if any_notch:
            p[:, notch] = 0.0
        sub = p[:, ::floor_step]
        med = row_median(sub)
        mad = row_median(np.abs(sub - med[:, None]))
        t = (start + np.arange(ns) * hop + n / 2) / sample_rate_hz
        return SpectrumBlock(t, p, med, mad)

    skip = 0  # samples still to pass before the next slice starts (a hop longer than the FFT)
    for block in blocks:
        if skip:
            drop = min(skip, block.size)
            block, skip = block[drop:], skip - drop
        if buf.size:
            # the few slices that start in the carried samples come from them and this block's
            # head, joined; the rest from the block itself, not from a copy of it joined whole
            k = 1 + (buf.size - 1) // hop        # slices starting in the carried samples
            need = (k - 1) * hop + n - buf.size  # samples of the block the last of them reaches
            # (need < 0: a hop longer than the FFT, the carried samples hold a whole slice)
            if 0 <= need and k <= slices_per_block and block.size >= need + n:
                yield emit(np.concatenate([buf, block[:need]]), buf_start)
                advance = k * hop - buf.size
                skip = max(0, advance - block.size)
                block, buf_start = block[advance:], buf_start + k * hop
            else:  # a short block (or many slices per carried sample): joined whole
                block = np.concatenate([buf, block])
        buf = block
        # every whole slice the buffer holds, in blocks of 2..slices_per_block slices (the tracker
        # takes the slice spacing from its first block; a join above may yield a single slice
        # later): what is carried to the next chunk is then under two slices. Slices are
        # per-slice computations, so where the blocks split them changes no value.
        while buf.size >= n + hop:
            ns = min(slices_per_block, 1 + (buf.size - n) // hop)
            yield emit(buf[: n + (ns - 1) * hop], buf_start)
            skip = max(0, ns * hop - buf.size)
            buf, buf_start = buf[ns * hop:], buf_start + ns * hop
    if buf.size >= n:
        yield emit(buf, buf_start)


def row_median(x: np.ndarray) -> np.ndarray:
    """Median of each row of a 2-D float array, equal to `np.median(x, axis=1)` (same dtype and
    values) at about a third of its cost: one partition at the middle element instead of two."""
    m = x.shape[1]
    h = m // 2
    q = np.partition(x, h if m % 2 else h - 1, axis=1)
    if m % 2:
        return q[:, h]
    # the upper middle value is the smallest of the upper half; the mean of the two as np.median takes it
    return (q[:, h - 1] + q[:, h:].min(axis=1)) / x.dtype.type(2)


def n_slices(n_samples: int, cfg: StftConfig) -> int:
    """STFT slices `iter_spectra` makes of a capture of `n_samples` samples."""
    return 0 if n_samples < cfg.fft_size else 1 + (n_samples - cfg.fft_size) // cfg.hop


class WaterfallImage:
    """Down-sampled waterfall (dB) kept for the PNG: max over frequency groups, mean over time.

    Memory does not grow with the capture: with `total_rows` (the number of slices that
    will be added, `n_slices`) every `g = ceil(total_rows / max_rows)` consecutive rows are
    averaged as they arrive and only the averages are kept (at most `max_rows`); the result
    equals averaging the whole image afterwards. Without it, rows are averaged in pairs
    whenever more than `2 * max_rows` are held.
    """

    def __init__(self, f_hz: np.ndarray, max_cols: int = 2048, total_rows: int | None = None,
                 max_rows: int = 800):
        self.group = max(1, int(np.ceil(f_hz.size / max_cols)))
        ncol = f_hz.size // self.group
        self.f_hz = f_hz[: ncol * self.group].reshape(ncol, self.group).mean(axis=1)
        self.max_rows = max_rows
        self.total_rows = total_rows
        self.g = max(1, int(np.ceil(total_rows / max_rows))) if total_rows else 1
        self.n_out = (total_rows // self.g) if total_rows else None  # rows of the final image
        self.rows: list[np.ndarray] = []   # finished (averaged) rows
        self.t_s: list[float] = []
        self._pend_rows: list[np.ndarray] = []  # rows of the group being filled
        self._pend_t: list[np.ndarray] = []
        self._pending = 0

    def add(self, blk: SpectrumBlock) -> None:
        ncol = self.f_hz.size
        groups = blk.power[:, : ncol * self.group].reshape(blk.power.shape[0], ncol, self.group)
        # the max over each group as group-1 strided maximum passes: a reduction over a short inner
        # axis (.max(axis=2)) costs ~2.6x as much for the same values
        p = groups[:, :, 0].copy()
        for j in range(1, self.group):
            np.maximum(p, groups[:, :, j], out=p)
        db = (10 * np.log10(p / blk.noise_mean[:, None] + 1e-12)).astype(np.float32)
        self._pend_rows.append(db)
        self._pend_t.append(np.asarray(blk.t_s, float))
        self._pending += db.shape[0]
        self._flush()

    def _flush(self) -> None:
        g = self.g
        if self._pending < g:
            return
        rows = np.concatenate(self._pend_rows) if len(self._pend_rows) > 1 else self._pend_rows[0]
        ts = np.concatenate(self._pend_t) if len(self._pend_t) > 1 else self._pend_t[0]
        full = (rows.shape[0] // g) * g
        for k in range(0, full, g):
            if self.n_out is not None and len(self.rows) >= self.n_out:
                break  # the tail beyond whole groups is dropped, as averaging afterwards does
            self.rows.append(rows[k: k + g].mean(axis=0) if g > 1 else rows[k])
            self.t_s.append(float(ts[k: k + g].mean()) if g > 1 else float(ts[k]))
        self._pend_rows, self._pend_t = [rows[full:]], [ts[full:]]
        self._pending = rows.shape[0] - full
        if self.total_rows is None and len(self.rows) > 2 * self.max_rows:
            self._halve()

    def _halve(self) -> None:
        n = len(self.rows) // 2 * 2
        img = np.stack(self.rows[:n])
        t = np.asarray(self.t_s[:n])
        self.rows = list(img.reshape(n // 2, 2, -1).mean(axis=1)) + self.rows[n:]
        self.t_s = list(t.reshape(n // 2, 2).mean(axis=1)) + self.t_s[n:]
        self.g *= 2
        self._pend_rows, self._pend_t, self._pending = [], [], 0  # a partial group is dropped

    def image(self, max_rows: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t_s, f_hz, dB above the noise floor) with at most `max_rows` rows."""
        max_rows = max_rows or self.max_rows
        if not self.rows:
            return np.zeros(0), self.f_hz, np.zeros((0, self.f_hz.size), np.float32)
        img = np.stack(self.rows)
        self.rows = list(img)  # views into img: the rows are not held twice
        t = np.asarray(self.t_s, float)
        g = max(1, int(np.ceil(img.shape[0] / max_rows)))
        nr = img.shape[0] // g
        if g == 1:
            return t, self.f_hz, img
        return (t[: nr * g].reshape(nr, g).mean(axis=1), self.f_hz,
                img[: nr * g].reshape(nr, g, -1).mean(axis=1))
