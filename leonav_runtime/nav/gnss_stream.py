"""GNSS records as they arrive -> complete fix epochs -> `inputs.FixTable` rows.

A receiver sends one epoch as several messages (u-blox NMEA: RMC, GGA, GST; or NAV-PVT),
and the fix (GGA) comes before its sigmas (GST). `FixAssembler` groups the records of an
epoch by the receiver's time of day and hands the epoch on when it is complete:
- its GST has arrived;
- or a record of a later epoch arrives, or `timeout_s` passed since the fix (then the fix
  goes on without GST: NAV-PVT accuracy or HDOP, as in the replay);
- at once once the stream has shown that it carries no GST (an epoch with a fix ended
  without one before any GST was seen), and for a fix without a date (a GGA before any RMC).

The epoch's records are turned into fix rows by the replay's own `gnss_table.fix_table`
(ENU at the origin, 1-sigma from GST / NAV-PVT / HDOP, velocity from NAV-PVT or RMC), so
live and batch use one rule.
"""
from __future__ import annotations

import datetime as _dt
from typing import Callable

from leonav.hardware.records import GnssFix, NmeaSentence
from leonav_runtime.inputs import FixTable
from leonav_runtime.replay.gnss_table import fix_table


def _tod_cs(t: _dt.time | _dt.datetime | None) -> int | None:
    """Time of day in hundredths of a second (the NMEA resolution), None without a time."""
    if t is None:
        return None
    return round((t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6) * 100)


class FixAssembler:
    """Group GNSS records into epochs (module doc); `add` / `poll` return completed epochs
    as lists of records, oldest first."""

    def __init__(self, timeout_s: float = 0.3) -> None:
        self.timeout_s = timeout_s
        self._epochs: dict[int, dict] = {}      # key -> {"recs": [...], "fix_at": mono or None, "gst": bool}
        self.stream_has_gst: bool | None = None  # unknown until a GST arrives or an epoch ends without one
        self.counts = {"epochs": 0, "epochs_without_gst": 0, "epochs_dropped_without_fix": 0}

    def _entry(self, key: int) -> dict:
        return self._epochs.setdefault(key, {"recs": [], "fix_at": None, "gst": False})

    def add(self, rec) -> list[list]:
        out: list[list] = []
        if isinstance(rec, NmeaSentence) and rec.sentence_type in ("RMC", "GST") and rec.msg is not None:
            key = _tod_cs(getattr(rec.msg, "timestamp", None))
            if key is None:
                return out
            out += self._flush_before(key)
            e = self._entry(key)
            e["recs"].append(rec)
            if rec.sentence_type == "GST":
                self.stream_has_gst = e["gst"] = True
                if e["fix_at"] is not None:
                    out.append(self._pop(key))
        elif isinstance(rec, GnssFix):
            key = _tod_cs(rec.utc)
            if key is None:
                self.counts["epochs"] += 1
                return out + [[rec]]
            out += self._flush_before(key)
            e = self._entry(key)
            e["recs"].append(rec)
            e["fix_at"] = rec.t_mono_s
            if e["gst"] or self.stream_has_gst is False:
                out.append(self._pop(key))
        return out

    def poll(self, now_mono_s: float) -> list[list]:
        """Epochs whose fix has waited `timeout_s` for its GST."""
        due = [k for k, e in self._epochs.items() if e["fix_at"] is not None and now_mono_s - e["fix_at"] >= self.timeout_s]
        return [self._pop(k) for k in sorted(due)]

    def flush(self) -> list[list]:
        """Every pending epoch with a fix (end of stream)."""
        return self._flush_before(None)

    def _flush_before(self, key: int | None) -> list[list]:
        out = []
        # a day rollover makes the new key small: every old key counts as earlier then
        older = [k for k in sorted(self._epochs) if key is None or k < key or k - key > 4_320_000]
        for k in older:
            if self._epochs[k]["fix_at"] is not None:
                out.append(self._pop(k))
            else:
                del self._epochs[k]
                self.counts["epochs_dropped_without_fix"] += 1
        return out

    def _pop(self, key: int) -> list:
        e = self._epochs.pop(key)
        if not e["gst"] and self.stream_has_gst is None:
            self.stream_has_gst = False
        self.counts["epochs"] += 1
        self.counts["epochs_without_gst"] += not e["gst"]
        return e["recs"]


def epoch_fixes(records: list, to_utc: Callable, epoch_unix: float, origin, notes: list[str]) -> tuple[FixTable, dict]:
    """Fix rows (t s since `epoch_unix`, ENU at `origin`) of one completed epoch (`gnss_table.fix_table`)."""
    return fix_table(records, to_utc, epoch_unix, origin, notes)
