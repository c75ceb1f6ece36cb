"""One host clock for every record, and its mapping to UTC through GNSS time tags.

Every reader stamps records with `time.monotonic()` (s, never steps, arbitrary origin,
shared by all threads of one process). GNSS messages carry their own UTC (RMC/ZDA date
and time, NAV-PVT, RXM-RAWX week/rcvTow/leapS): pairing each one with its arrival stamp
gives `utc - t_mono` samples, from which `TimeMap` estimates

    utc_unix_s = t_mono_s + offset_s (+ drift * (t_mono_s - t_ref_s))

The fitted offset includes the receiver's output latency (the epoch is computed, then
serialized over the UART and stamped when the sentence/frame *ends*), so mapped times
are late by that latency's mean; the residual spread is its jitter. See
`hardware/README.md` for the expected size and `uart_delay_profile` for the serial part.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from leonav.hardware.errors import UserInputError
from leonav.hardware.records import GnssTimeTag
from leonav.hardware.uart import serialization_s

# Preferred source of time tags: one per navigation epoch, best time quality first.
SOURCE_PRIORITY = ("NAV-PVT", "TIMEGPS", "RAWX", "RMC", "ZDA")
OUTLIER_FLOOR_S = 0.05


def utc_unix(t: _dt.datetime) -> float:
    """POSIX seconds of an aware datetime (naive is taken as UTC)."""
    if t.tzinfo is None:
        t = t.replace(tzinfo=_dt.timezone.utc)
    return t.timestamp()


@dataclass
class TimeMap:
    """Monotonic -> UTC mapping fitted on GNSS time tags of one source.

    `offset_s` (and `drift`, 0 unless fitted with `drift=True`) map t_mono to UTC POSIX
    seconds; `residual_*` describe `utc - map(t_mono)` over the tags used;
    `n_outliers` tags further than max(5 robust sigmas, 50 ms), or 1 s, from the median were left out.
    """

    source: str = ""
    offset_s: float = math.nan
    drift: float = 0.0
    t_ref_s: float = 0.0
    n_tags: int = 0
    n_outliers: int = 0
    residual_median_abs_s: float = math.nan
    residual_std_s: float = math.nan
    residual_max_abs_s: float = math.nan
    per_source: dict = field(default_factory=dict)

    @property
    def valid(self) -> bool:
        return self.n_tags > 0 and math.isfinite(self.offset_s)

    def to_utc_unix(self, t_mono_s: float | np.ndarray) -> float | np.ndarray:
        """UTC POSIX seconds for monotonic stamps (NaN while the map is not fitted)."""
        return t_mono_s + self.offset_s + self.drift * (np.asarray(t_mono_s) - self.t_ref_s)

    @classmethod
    def fit(cls, tags: Iterable[GnssTimeTag], drift: bool = False) -> "TimeMap":
        """Fit on the best available source (SOURCE_PRIORITY); statistics for all sources."""
        by_source: dict[str, list[GnssTimeTag]] = {}
        for tag in tags:
            by_source.setdefault(tag.source, []).append(tag)
        per_source = {}
        for src, items in by_source.items():
            d = np.array([utc_unix(t.utc) - t.t_mono_s for t in items])
            per_source[src] = {"n": len(d), "offset_median_s": float(np.median(d)),
                               "spread_mad_s": float(np.median(np.abs(d - np.median(d))))}
        chosen = next((s for s in SOURCE_PRIORITY if s in by_source), None)
        if chosen is None:
            return cls(per_source=per_source)
        items = by_source[chosen]
        t = np.array([x.t_mono_s for x in items])
        u = np.array([utc_unix(x.utc) for x in items])
        return cls._fit_arrays(t, u, chosen, drift, per_source)

    @classmethod
    def _fit_arrays(cls, t: np.ndarray, u: np.ndarray, source: str, drift: bool,
                    per_source: dict) -> "TimeMap":
        d = u - t
        med = np.median(d)
        mad = np.median(np.abs(d - med))
        # Outliers: beyond 5 robust sigmas, but never closer than OUTLIER_FLOOR_S (host
        # scheduling jitter is real spread, not an outlier), and always beyond 1 s (a stale
        # or misparsed tag).
        keep = np.abs(d - med) <= max(5 * 1.4826 * mad, OUTLIER_FLOOR_S)
        keep &= np.abs(d - med) < 1.0
        if not keep.any():   # two equal groups of tags more than 1 s apart: no majority to trust
            raise UserInputError(
                f"{source} time tags disagree: {len(d)} tags split into groups more than 1 s apart "
                f"(host-minus-receiver offsets {np.min(d):.3f} .. {np.max(d):.3f} s); expected one "
                "consistent receiver time (a restarted receiver or host clock step inside the session?)")
        t_ref = float(np.median(t[keep]))
        slope = 0.0
        if drift and keep.sum() >= 3 and np.ptp(t[keep]) > 0:
            slope, intercept = np.polyfit(t[keep] - t_ref, d[keep], 1)
            offset = float(intercept)
        else:
            offset = float(np.median(d[keep]))
        res = d[keep] - (offset + slope * (t[keep] - t_ref))
        return cls(source=source, offset_s=offset, drift=float(slope), t_ref_s=t_ref,
                   n_tags=int(keep.sum()), n_outliers=int((~keep).sum()),
                   residual_median_abs_s=float(np.median(np.abs(res))),
                   residual_std_s=float(np.std(res)),
                   residual_max_abs_s=float(np.max(np.abs(res))),
                   per_source=per_source)

    def as_dict(self) -> dict:
        return {
            "source": self.source, "offset_s": self.offset_s, "drift": self.drift,
            "t_ref_mono_s": self.t_ref_s, "n_tags": self.n_tags, "n_outliers": self.n_outliers,
            "residual_median_abs_s": self.residual_median_abs_s,
            "residual_std_s": self.residual_std_s, "residual_max_abs_s": self.residual_max_abs_s,
            "per_source": self.per_source,
            "formula": "utc_unix_s = t_mono_s + offset_s + drift * (t_mono_s - t_ref_mono_s)",
        }


def uart_delay_profile(epoch_bytes: Sequence[int], baud: int) -> dict:
    """Serialization delay (s) of the end of each message after the start of its epoch's
    burst, for the byte offsets `epoch_bytes` of message ends (`uart.serialization_s`).

    This is the part of the stamping error the UART alone causes: a message ending n
    bytes into the burst is stamped n*10/baud s after the first byte left the receiver.
    """
    delays = serialization_s(np.asarray(epoch_bytes, float), baud)
    return {"baud": baud, "median_s": float(np.median(delays)), "max_s": float(np.max(delays))}
