"""Online sample times of a regular IMU (WitMotion) from its jittered arrival stamps.

The streaming twin of `replay.timebase.regular_sample_times`: the samples are regular in the
sensor's clock, so a sample's time is a straight line through (sample index, arrival stamp),
fitted by least squares on the on-time samples received so far (the latest `window`, after
dropping stamps more than max(5 robust sigmas, 30 ms) off; refitted every `refit_every`
samples or half a second, every sample for the first 50). Stamps are arrival times, only ever late:

- samples that arrive in one read (a host stall) get consecutive indices ending at the last
  one, the only one close to on time (the others are not used in the fit);
- a sample later than the line by more than half a period plus `gap_sigmas` robust sigmas
  starts after a gap: the index jumps by the number of missing periods, and the interval is
  bridged with that sample's rates, as in the replay;
- a gap too small to see against the read jitter (fast sensors, busy hosts) shows later as
  `shift_samples` consecutive samples all late by more than half a period: the index is
  moved on from there (counted as `late_gaps`; the samples in between were placed up to one
  period early).

The batch fit uses every sample of the session, later ones included; this one only the past,
so its first second carries the spread of a short fit.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from leonav.hardware.imu.witmotion import PACKET_LEN as WITMOTION_PACKET_BYTES
from leonav.hardware.uart import serialization_s

OUTLIER_FLOOR_S = 0.03
GAP_QUANTILE = 0.998        # residual quantile a gap must exceed (by half a period)
IMMEDIATE_MAX = 0.9         # immediate gap decisions only while the threshold is below this many periods
REFIT_S = 0.5               # the line is refitted at least every `refit_every` samples and this many seconds


@dataclasses.dataclass
class ImuTimingCounts:
    samples: int = 0
    missing: int = 0          # samples counted missing (gaps)
    late_gaps: int = 0        # gaps found only from the samples after them
    bursts: int = 0           # reads that brought more than one sample
    early: int = 0            # samples clearly earlier than the line (> half a period + the jitter): re-anchored


class _Points:
    """The last `window` (index, stamp) pairs in two arrays (appended in time order)."""

    def __init__(self, window: int) -> None:
        self.window = window
        self.idx = np.zeros(2 * window)
        self.t = np.zeros(2 * window)
        self.s = self.e = 0

    def __len__(self) -> int:
        return self.e - self.s

    def append(self, idx: int, t: float) -> None:
        if self.e == self.idx.size:         # compact: keep the newest window - 1
            keep = min(self.window - 1, self.e - self.s)
            self.idx[:keep], self.t[:keep] = self.idx[self.e - keep:self.e], self.t[self.e - keep:self.e]
            self.s, self.e = 0, keep
        self.idx[self.e], self.t[self.e] = idx, t
        self.e += 1
        if self.e - self.s > self.window:
            self.s += 1

    def pop(self) -> None:
        if self.e > self.s:
            self.e -= 1

    def clear(self) -> None:
        self.s = self.e

    def last(self) -> tuple[int, float]:
        return int(self.idx[self.e - 1]), float(self.t[self.e - 1])

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return self.idx[self.s:self.e], self.t[self.s:self.e]


class OnlineImuTiming:
    """Sample times (host monotonic s, the packet's serialization taken off) for arriving samples."""

    def __init__(self, imu_baud: int | None = None, window: int = 3000, refit_every: int = 16,
                 gap_sigmas: float = 4.0, shift_samples: int = 10) -> None:
        self.serial_s = float(serialization_s(WITMOTION_PACKET_BYTES, imu_baud)) if imu_baud else 0.0
        self._pts = _Points(window)
        self._res = np.zeros(1000)          # recent on-time residuals (ring)
        self._n_res = 0
        self.refit_every = refit_every
        self.gap_sigmas = gap_sigmas
        self.shift_samples = shift_samples
        self.period = math.nan
        self.offset = math.nan      # line: t = offset + period * (idx - idx_ref)
        self.idx_ref = 0
        self.sigma = 0.0            # robust spread of the on-time residuals (s)
        self.gap_threshold_s = math.inf
        self.early_threshold_s = math.inf
        self.prev_idx = -1
        self.last_indices: list[int] = []
        self._last_stamp = math.nan
        self._since_fit = 0
        self._late_run: list[float] = []
        self.counts = ImuTimingCounts()

    def _line(self, idx):
        return self.offset + self.period * (np.asarray(idx, float) - self.idx_ref)

    def _fit(self) -> None:
        idx, t = self._pts.arrays()
        if idx.size < 2 or idx[-1] == idx[0]:
            return
        ref = int(idx[-1])
        keep = np.ones(idx.size, bool)
        for _ in range(2):
            a, b = np.polyfit(idx[keep] - ref, t[keep], 1)
            res = t - (a * (idx - ref) + b)
            mad = float(np.median(np.abs(res[keep] - np.median(res[keep]))))
            new = np.abs(res) <= max(5 * 1.4826 * mad, OUTLIER_FLOOR_S)
            if new.sum() < 2:
                break
            keep = new
        if a <= 0:
            return
        self.period, self.offset, self.idx_ref, self.sigma = float(a), float(b), ref, 1.4826 * mad
        res_recent = self._res[:min(self._n_res, self._res.size)]
        q_hi, q_lo = (np.quantile(res_recent, [GAP_QUANTILE, 1 - GAP_QUANTILE]) if res_recent.size else (0.0, 0.0))
        thr = a / 2 + max(self.gap_sigmas * self.sigma, float(q_hi))
        self.gap_threshold_s = thr if idx.size >= 20 and thr < IMMEDIATE_MAX * a else math.inf
        thr = a / 2 + max(self.gap_sigmas * self.sigma, -float(q_lo))
        self.early_threshold_s = thr if idx.size >= 20 and thr < IMMEDIATE_MAX * a else math.inf

    def add(self, stamp_s: float, n: int = 1) -> list[float]:
        """Times (s) of `n` samples that arrived together at `stamp_s` (one read), oldest first."""
        c = self.counts
        c.samples += n
        c.bursts += n > 1
        last = self.prev_idx + n
        if stamp_s == self._last_stamp:
            # more samples of the read already seen (handed over in parts): the burst goes on,
            # its newest sample is the on-time one
            self._pts.pop()
        elif self.prev_idx >= 0 and not math.isfinite(self.period):
            i0, t0 = self._pts.last()
            if stamp_s > t0:              # first spacing: a provisional period
                self.period, self.offset, self.idx_ref = (stamp_s - t0) / (last - i0), float(stamp_s), last
        elif self.prev_idx >= 0:
            late = stamp_s - float(self._line(last))
            if late > self.gap_threshold_s:
                extra = max(1, int(round((late - self.sigma) / self.period)))
                last += extra
                c.missing += extra
                self._late_run.clear()
            elif late > self.period / 2:
                self._late_run.append(late)
                if len(self._late_run) >= self.shift_samples:   # a gap the read jitter hid
                    extra = max(1, int(round(min(self._late_run) / self.period)))
                    last += extra
                    c.missing += extra
                    c.late_gaps += 1
                    for _ in range(min(len(self._late_run) - 1, len(self._pts))):   # a period off
                        self._pts.pop()
                    self._late_run.clear()
            else:
                self._late_run.clear()
                if late < -self.early_threshold_s:   # earlier than possible: the line was ahead; move it
                    c.early += 1
                    self.offset += late
                    self._pts.clear()
                else:
                    self._res[self._n_res % self._res.size] = late
                    self._n_res += 1
        self.prev_idx = last
        self._last_stamp = stamp_s
        self._pts.append(last, float(stamp_s))
        self._since_fit += 1
        every = max(self.refit_every, int(REFIT_S / self.period)) if math.isfinite(self.period) else 1
        if len(self._pts) < 50 or self._since_fit >= every:
            self._fit()
            self._since_fit = 0
        self.last_indices = list(range(last - n + 1, last + 1))
        if not math.isfinite(self.period):
            return [float(stamp_s) - self.serial_s] * n
        return self.times_of(self.last_indices)

    def times_of(self, indices) -> list[float]:
        """Times (s) of samples by index on the current line (the buffered samples at the start)."""
        return [float(t) - self.serial_s for t in np.atleast_1d(self._line(np.asarray(indices)))]
