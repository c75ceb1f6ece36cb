"""Online monotonic -> UTC map from the GNSS time tags received so far.

The streaming twin of `replay.timebase.mono_to_utc_function`: `hardware.clock.TimeMap.fit`
on the latest `window` tags (best source first: NAV-PVT > TIMEGPS > RAWX > RMC > ZDA),
refitted when a tag arrives, and shifted by the tag message's own UART serialization
(`hardware.uart.serialization_s`: median length of the RMC/ZDA sentences seen so far + CR LF,
or the NAV-PVT frame, at the GNSS baud) plus a given receiver output latency. The replay fits
once on every tag of the session; here each stamp is mapped with the map known when it is
used, so early stamps carry the spread of the first few tags (a few ms).
"""
from __future__ import annotations

import collections
import math

import numpy as np

from leonav.hardware.clock import TimeMap
from leonav.hardware.records import GnssTimeTag, NmeaSentence
from leonav.hardware.uart import serialization_s
from leonav_runtime.replay.timebase import NMEA_LINE_END_BYTES, UBX_NAV_PVT_FRAME_BYTES

MAP_WINDOW_TAGS = 300          # tags in the running fit (the recorder's live map uses as many)
LENGTH_WINDOW = 300            # tag sentence lengths kept for the serialization median


class StreamingTimeMap:
    """Monotonic stamps (s) -> UTC POSIX seconds from the tags fed so far (`add`)."""

    def __init__(self, gnss_baud: int | None, gnss_latency_s: float = 0.0, window: int = MAP_WINDOW_TAGS) -> None:
        self.baud = gnss_baud if gnss_baud and gnss_baud > 0 else None
        self.gnss_latency_s = float(gnss_latency_s)
        self._tags: collections.deque[GnssTimeTag] = collections.deque(maxlen=window)
        self._lengths: dict[str, collections.deque] = {}
        self.map = TimeMap()
        self.n_tags = 0
        self.late_s = 0.0

    @property
    def valid(self) -> bool:
        return self.map.valid

    def add(self, rec) -> bool:
        """Feed one GNSS record; returns True when the map was refitted (a time tag)."""
        if isinstance(rec, NmeaSentence):
            if rec.sentence_type in ("RMC", "ZDA"):
                self._lengths.setdefault(rec.sentence_type, collections.deque(maxlen=LENGTH_WINDOW)).append(
                    len(rec.text) + NMEA_LINE_END_BYTES)
            return False
        if not isinstance(rec, GnssTimeTag):
            return False
        self._tags.append(rec)
        self.n_tags += 1
        self.map = TimeMap.fit(self._tags)
        self.late_s = self.tag_serialization_s() + self.gnss_latency_s
        return True

    def tag_serialization_s(self) -> float:
        """UART time of the map's tag message (s), as `replay.timebase.tag_serialization_s`."""
        src = self.map.source
        if not self.baud:
            return 0.0
        if src in ("RMC", "ZDA"):
            n = self._lengths.get(src)
            return float(serialization_s(float(np.median(n)), self.baud)) if n else 0.0
        if src == "NAV-PVT":
            return float(serialization_s(UBX_NAV_PVT_FRAME_BYTES, self.baud))
        return 0.0

    def to_utc(self, t_mono_s: float) -> float:
        """UTC POSIX seconds of a monotonic stamp (NaN while no tag has been seen)."""
        if not self.map.valid:
            return math.nan
        return float(self.map.to_utc_unix(t_mono_s)) + self.late_s

    def describe(self) -> dict:
        m = self.map
        return {"source": m.source, "tags": self.n_tags, "tags_in_fit": m.n_tags,
                "residual_std_ms": m.residual_std_s * 1e3 if m.valid else None,
                "shift_ms": self.late_s * 1e3, "gnss_latency_ms": self.gnss_latency_s * 1e3}
