"""Differential corrections on the road into the filter (issue 22, ephemeris method 3).

A base receiver at a known position measures the same beacons as the rover; per satellite and
observable it sends correction = measured - predicted(element set, known position)
(`leonav base`, docs/corrections.md). Over the base-rover distance (tens of km against ~550 km
and more to the satellite) the ephemeris error's effect on a Doppler or Doppler-rate is nearly
common, so the rover subtracts the correction from its own measurement before the update:

    z_corrected = z - c,    sigma_corrected^2 = sigma^2 + sigma_c^2

This module is the one place where that happens: `satellite_records` (inputs/measurements.py)
calls `DifferentialCorrections.apply` on every satellite table it turns into records, so the
simulator, `leonav replay` and `leonav nav` (which all go through it) correct the same way.

Which correction a measurement takes: of its satellite's corrections (same constellation,
NORAD id, observable) the latest whose base time is at most `MATCH_TOLERANCE_S` after the
measurement's time (epochs of two receivers are not aligned). Its age is the measurement's UTC
time minus the correction's base time. Older than `max_age_s`: not used (counted `stale`); no
correction at all for that satellite: counted `none`; either way the measurement goes to the
filter uncorrected (the fallback), and the store's `state` says `fallback` while a table's
measurements find no usable correction at all (`applied` when some do). Corrections for another constellation
or observable are refused when they arrive (counted); one that arrives when the rover's
measurements are already more than `max_age_s` past it is refused as `late`.

Thread-safe: a network reader thread `add`s while the road `apply`s.
"""
from __future__ import annotations

import bisect
import collections
import dataclasses
import math
import threading

import numpy as np

from leonav_runtime.core import model

DEFAULT_MAX_AGE_S = 10.0
"""Default oldest usable correction (s). The ephemeris error's effect on a Doppler-rate changes
with the geometry over a pass (minutes): at 6 h element age it is ~3 Hz/s and changes by ~0.01-0.02
Hz/s per second, so 10 s of age costs ~0.1-0.2 Hz/s, well under the 1.2 Hz/s measurement noise;
much older and the correction starts to cost more than it removes (and a stopped stream would be
noticed late)."""
MATCH_TOLERANCE_S = 0.5
"""A correction at most this much later than the measurement still applies to it (s): the base's
and the rover's epochs are not aligned, and the correction changes little over half a second."""
KEEP_S = 120.0
"""Corrections kept per satellite (s of base time behind the newest one)."""
MAX_LOG_ROWS = 1_000_000
CORRECTABLE = ("doppler_rate", "doppler")
LOG_COLUMNS = ["t_utc_s", "constellation", "norad_id", "observable", "z", "correction", "sigma_correction",
               "age_s", "status"]


@dataclasses.dataclass
class _Entry:
    t: list = dataclasses.field(default_factory=list)       # base times, UTC s, increasing
    value: list = dataclasses.field(default_factory=list)
    sigma: list = dataclasses.field(default_factory=list)


class DifferentialCorrections:
    """Per-satellite corrections received so far, and their use (module doc).

    max_age_s: oldest correction applied (s); constellations: accepted constellation names
    (element-set names, lower case); epoch_unix: UTC (s) of the tables' t = 0, set by the
    source before the first `apply`."""

    def __init__(self, max_age_s: float = DEFAULT_MAX_AGE_S, constellations: tuple[str, ...] = ("starlink",),
                 epoch_unix: float = math.nan, log: bool = True) -> None:
        if not (math.isfinite(max_age_s) and max_age_s > 0):
            raise ValueError(f"max_age_s {max_age_s!r}: expected a positive number of seconds")
        self.max_age_s = float(max_age_s)
        self.constellations = tuple(c.lower() for c in constellations)
        self.epoch_unix = epoch_unix
        self.counts: collections.Counter = collections.Counter()
        self.first_rejection: dict[str, str] = {}
        self._by_key: dict[tuple, _Entry] = {}
        self._lock = threading.Lock()
        self._log = [] if log else None
        self._ages: collections.deque = collections.deque(maxlen=100_000)
        self.last_age_s = math.nan            # age of the last correction applied
        self.last_applied_t_utc = math.nan    # measurement time it was applied at
        self.newest_measurement_utc = -math.inf
        self.state = "waiting"                # waiting (no measurement yet) | applied | fallback (none usable)

    # -- arriving corrections
    def add(self, constellation: str, norad_id: int, observable: str, t_utc_s: float, value: float,
            sigma: float) -> bool:
        """Keep one correction (value, sigma in the observable's unit; t_utc_s the base's
        measurement time); False (and counted) when refused."""
        constellation = constellation.lower()
        if constellation not in self.constellations:
            self.reject("other_constellation", f"constellation {constellation!r}: this rover uses "
                                               f"{', '.join(self.constellations)}")
            return False
        if observable not in CORRECTABLE:
            self.reject("observable", f"observable {observable!r}: expected {', '.join(CORRECTABLE)}")
            return False
        if not (math.isfinite(t_utc_s) and math.isfinite(value) and math.isfinite(sigma) and sigma > 0):
            self.reject("garbled", "non-finite time, value or sigma <= 0")
            return False
        with self._lock:
            if t_utc_s < self.newest_measurement_utc - self.max_age_s:
                self.counts["rejected_late"] += 1
                self.first_rejection.setdefault("late", f"correction at {t_utc_s:.3f} arrived after the rover's "
                                                        f"measurements had passed it by more than {self.max_age_s:g} s")
                return False
            e = self._by_key.setdefault((constellation, int(norad_id), observable), _Entry())
            k = bisect.bisect_left(e.t, t_utc_s)
            if k < len(e.t) and e.t[k] == t_utc_s:       # a repeat of the same epoch replaces it
                e.value[k], e.sigma[k] = value, sigma
                self.counts["replaced"] += 1
            else:
                e.t.insert(k, t_utc_s)
                e.value.insert(k, value)
                e.sigma.insert(k, sigma)
            drop = bisect.bisect_left(e.t, e.t[-1] - KEEP_S)
            if drop:
                del e.t[:drop], e.value[:drop], e.sigma[:drop]
            self.counts["received"] += 1
        return True

    def reject(self, reason: str, text: str) -> None:
        """Count a refused line or correction under `reason`; the first text of each reason is kept."""
        with self._lock:
            self.counts[f"rejected_{reason}"] += 1
            self.first_rejection.setdefault(reason, text)

    # -- use
    def lookup(self, constellation: str, norad_id: int, observable: str, t_utc_s: float
               ) -> tuple[float, float, float] | None:
        """(value, sigma, age s) of the correction a measurement at t_utc_s takes, or None."""
        e = self._by_key.get((constellation, int(norad_id), observable))
        if e is None or not e.t:
            return None
        k = bisect.bisect_right(e.t, t_utc_s + MATCH_TOLERANCE_S) - 1
        if k < 0:
            return None
        return e.value[k], e.sigma[k], t_utc_s - e.t[k]

    def apply(self, table):
        """The satellite table with its rows corrected where a usable correction exists (module
        doc); tables of other observables are returned as they are."""
        kind = table.KIND
        if kind not in CORRECTABLE or not table.t.size:
            return table
        const = model.observable(kind).constellation
        if not math.isfinite(self.epoch_unix):
            raise RuntimeError("DifferentialCorrections.apply: epoch_unix not set by the source")
        z = np.array(table.z, float)
        sigma = np.broadcast_to(np.asarray(table.sigma, float), z.shape).copy()
        t_utc = self.epoch_unix + np.asarray(table.t, float)
        n_applied = 0
        with self._lock:
            self.newest_measurement_utc = max(self.newest_measurement_utc, float(t_utc.max()))
            for k in range(z.size):
                found = self.lookup(const, int(table.sat_id[k]), kind, float(t_utc[k]))
                if found is None:
                    status, value, sig_c, age = "none", math.nan, math.nan, math.nan
                else:
                    value, sig_c, age = found
                    status = "stale" if age > self.max_age_s else "applied"
                if status == "applied":
                    raw = z[k]
                    z[k] = raw - value
                    sigma[k] = math.hypot(sigma[k], sig_c)
                    n_applied += 1
                    self._ages.append(age)
                    self.last_age_s, self.last_applied_t_utc = age, float(t_utc[k])
                else:
                    raw = z[k]
                self.counts[f"{kind}_{status}"] += 1
                if self._log is not None and len(self._log) < MAX_LOG_ROWS:
                    self._log.append((float(t_utc[k]), const, int(table.sat_id[k]), kind, float(raw), value, sig_c,
                                      age, status))
            self.state = "applied" if n_applied else "fallback"
        out = table.select(np.ones(z.size, bool))
        out.z, out.sigma = z, sigma
        return out

    # -- reports
    def age_summary(self) -> dict:
        """Ages (s) of the corrections applied: count, median, 95th percentile, max, last."""
        with self._lock:
            a = np.array(self._ages, float)
        if not a.size:
            return {"applied": 0}
        return {"applied": int(a.size), "median_s": float(np.median(a)), "p95_s": float(np.percentile(a, 95)),
                "max_s": float(a.max()), "last_s": float(self.last_age_s)}

    def describe(self) -> dict:
        """What nav.json / metrics.json say about the corrections."""
        with self._lock:
            counts = dict(self.counts)
            rejections = dict(self.first_rejection)
            sats = len(self._by_key)
        return {"max_age_s": self.max_age_s, "state": self.state, "satellites_with_corrections": sats,
                "counts": counts, "first_rejection": rejections, "age": self.age_summary()}

    def log_rows(self) -> list[tuple]:
        """One row per measurement seen (`LOG_COLUMNS`): what it was, what it took, its status."""
        with self._lock:
            return list(self._log or [])
