"""Broadcast ephemeris records (GPS LNAV, Galileo I/NAV and F/NAV, BeiDou D1/D2, QZSS)
as one NumPy structured array, with ephemeris selection by toe, age and health.

The RINEX navigation reader and the LNAV subframe decoder both fill `EPH_DTYPE` rows, so
the satellite equations (`leonav_runtime.orbits.broadcast`) see one table whatever the
source. Units: SI and radians (RINEX's units; LNAV semicircles are converted with the
ICD's pi). Epochs are continuous GPS seconds (`leonav_runtime.gnss.time`): toc, toe and
the transmission time of BeiDou records are converted from BDT (+14 s), so
`t_gps - toe` is the ICD's t_k in every system.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.gen.constants import (
    BDS_EPH_VALIDITY_S,
    GAL_EPH_VALIDITY_S,
    GPS_FIT_INTERVAL_DEFAULT_S,
)

SYSTEMS = {"G": "GPS", "E": "Galileo", "C": "BeiDou", "J": "QZSS", "R": "GLONASS", "S": "SBAS", "I": "NavIC"}
ORBIT_SYSTEMS = ("G", "E", "C", "J")  # systems with Keplerian broadcast orbits handled here

EPH_FIELDS = (
    # name, dtype, unit / meaning
    ("system", "U1", "G GPS, E Galileo, C BeiDou, J QZSS"),
    ("prn", "i2", "satellite number within the system"),
    ("toc", "f8", "clock reference time, continuous GPS s"),
    ("toe", "f8", "ephemeris reference time, continuous GPS s"),
    ("toe_sow", "f8", "toe as broadcast: seconds of the system's week"),
    ("week", "i4", "week as in the source (GPS week, GAL week = GPS week, BDT week)"),
    ("transmit", "f8", "transmission time of the message, continuous GPS s (NaN: unknown)"),
    ("af0", "f8", "clock bias, s"),
    ("af1", "f8", "clock drift, s/s"),
    ("af2", "f8", "clock drift rate, s/s^2"),
    ("iode", "i4", "issue of data ephemeris (Galileo IODnav, BeiDou AODE)"),
    ("iodc", "i4", "issue of data clock (BeiDou AODC; -1 if none)"),
    ("crs", "f8", "m"), ("delta_n", "f8", "rad/s"), ("m0", "f8", "rad"),
    ("cuc", "f8", "rad"), ("e", "f8", "-"), ("cus", "f8", "rad"), ("sqrt_a", "f8", "m^0.5"),
    ("cic", "f8", "rad"), ("omega0", "f8", "rad"), ("cis", "f8", "rad"),
    ("i0", "f8", "rad"), ("crc", "f8", "m"), ("omega", "f8", "rad"), ("omega_dot", "f8", "rad/s"),
    ("idot", "f8", "rad/s"),
    ("tgd", "f8", "GPS/QZSS TGD, Galileo BGD(E1,E5a), BeiDou TGD1 (B1I), s"),
    ("tgd2", "f8", "Galileo BGD(E1,E5b), BeiDou TGD2 (B2I), s; 0 for GPS"),
    ("health", "i4", "SV health word (GPS 6 bits, Galileo health bits, BeiDou SatH1); 0 = healthy"),
    ("accuracy_m", "f8", "URA / SISA / URA, m"),
    ("fit_s", "f8", "span (s) centred on toe over which the ephemeris is used"),
    ("fit_flag", "i1", "GPS fit interval flag (0: 4 h), -1 where not broadcast"),
    ("codes_l2", "i1", "GPS codes on L2; Galileo: low byte of the data-source bits"),
    ("l2p_flag", "i1", "GPS L2 P data flag"),
    ("data_sources", "i2", "Galileo data sources (bit 0 I/NAV E1-B, 1 F/NAV E5a, 2 I/NAV E5b, 8 clock E1,E5a, 9 clock E1,E5b)"),
    ("geo", "?", "BeiDou GEO satellite (orbit in the -5 deg tilted frame)"),
)
EPH_DTYPE = np.dtype([(name, dt) for name, dt, _ in EPH_FIELDS])

# selection status
OK, NO_EPHEMERIS, STALE, UNHEALTHY = 0, 1, 2, 3
STATUS_WORDS = {OK: "ok", NO_EPHEMERIS: "no ephemeris for the satellite", STALE: "nearest ephemeris too old/new",
                UNHEALTHY: "only unhealthy ephemerides in the fit interval"}


def is_bds_geo(prn: int | np.ndarray) -> np.ndarray:
    """BeiDou GEO satellites: C01-C05 (BDS-2) and C59-C63 (BDS-3)."""
    prn = np.asarray(prn)
    return (prn <= 5) | ((prn >= 59) & (prn <= 63))


def default_fit_s(system: str, fit_hours: float) -> float:
    """Use span of an ephemeris: GPS fit interval hours (0/blank -> 4 h), else the system's."""
    if system == "G":
        return fit_hours * 3600.0 if fit_hours and fit_hours > 0 else GPS_FIT_INTERVAL_DEFAULT_S
    if system == "J":  # RINEX 3 QZSS: fit flag 0 -> 2 h, 1 -> more than 2 h (use 4 h)
        return 2 * 3600.0 if not fit_hours else 4 * 3600.0
    if system == "E":
        return GAL_EPH_VALIDITY_S
    if system == "C":
        return BDS_EPH_VALIDITY_S
    return GPS_FIT_INTERVAL_DEFAULT_S


@dataclass(frozen=True)
class Rejection:
    """One rejected record, line or field: where (file, 1-based line, field) and why."""

    source: str
    line: int
    field: str
    reason: str

    def __str__(self) -> str:
        where = f"{self.source}:{self.line}" if self.line else self.source
        return f"{where}: {self.field}: {self.reason}" if self.field else f"{where}: {self.reason}"


def sat_key(system, prn) -> np.ndarray:
    """Integer key of (system letter, prn): ord(letter) * 1000 + prn."""
    sys_arr = np.ascontiguousarray(np.asarray(system, dtype="U1"))
    return sys_arr.view(np.int32).astype(np.int64).reshape(sys_arr.shape) * 1000 + np.asarray(prn, dtype=np.int64)


@dataclass
class Ephemerides:
    """Broadcast ephemerides: `data` (EPH_DTYPE rows), `sources` ("file:line" per row),
    `rejected` (records that could not be used), `counts` (what was read and skipped)."""

    data: np.ndarray
    sources: list[str] = field(default_factory=list)
    rejected: list[Rejection] = field(default_factory=list)
    counts: Counter = field(default_factory=Counter)

    def __post_init__(self) -> None:
        self.data = np.asarray(self.data, dtype=EPH_DTYPE).reshape(-1)
        if not self.sources:
            self.sources = [""] * len(self.data)
        if len(self.sources) != len(self.data):
            raise ValueError("Ephemerides: one source per row")

    def __len__(self) -> int:
        return len(self.data)

    def __repr__(self) -> str:
        systems = Counter(self.data["system"].tolist())
        return f"Ephemerides({len(self)} records {dict(systems)}, {len(self.rejected)} rejected)"

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name]

    @classmethod
    def empty(cls) -> "Ephemerides":
        return cls(np.zeros(0, EPH_DTYPE))

    def concat(self, other: "Ephemerides") -> "Ephemerides":
        return Ephemerides(np.concatenate([self.data, other.data]), self.sources + other.sources,
                           self.rejected + other.rejected, self.counts + other.counts)

    def take(self, index) -> "Ephemerides":
        index = np.atleast_1d(np.arange(len(self))[index])
        return Ephemerides(self.data[index], [self.sources[i] for i in index], list(self.rejected),
                           Counter(self.counts))

    def satellites(self) -> list[tuple[str, int]]:
        pairs = sorted(set(zip(self.data["system"].tolist(), self.data["prn"].tolist())))
        return [(s, int(p)) for s, p in pairs]

    def deduplicate(self) -> "Ephemerides":
        """Drop repeated records (merged IGS files repeat one broadcast many times):
        same satellite, toe, toc, issue of data and clock/orbit terms. Keeps the first; counts
        the dropped ones under 'duplicate'."""
        if len(self) == 0:
            return self
        d = self.data
        cols = ("toe", "toc", "iode", "af0", "af1", "sqrt_a", "m0", "e", "omega0", "i0", "omega")
        keys = [sat_key(d["system"], d["prn"])] + [d[c] for c in cols]
        order = np.lexsort(keys[::-1])
        same = np.ones(len(d) - 1, bool)
        for k in keys:
            ks = k[order]
            same &= ks[1:] == ks[:-1]
        drop = order[1:][same]
        if drop.size == 0:
            return self
        keep = np.setdiff1d(np.arange(len(d)), drop)
        out = self.take(keep)
        out.counts["duplicate"] += int(drop.size)
        return out

    def select(self, system, prn, t_gps_s, *, max_age_s: float | None = None,
               allow_unhealthy: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Ephemeris index for each (system, prn, t): the record nearest in toe among those
        whose use span (fit interval, or +-max_age_s) covers t and that are healthy.

        Ties in toe go to the later transmission. Returns (index, status): index -1 where
        nothing fits; status OK, NO_EPHEMERIS, STALE (nearest toe outside the span) or
        UNHEALTHY (only unhealthy records cover t). Vectorized per satellite.
        """
        t = np.atleast_1d(np.asarray(t_gps_s, dtype=np.float64))
        shape = np.broadcast_shapes(t.shape, np.shape(system), np.shape(prn))
        t = np.broadcast_to(t, shape).reshape(-1)
        keys = sat_key(np.broadcast_to(np.asarray(system, dtype="U1"), shape),
                       np.broadcast_to(prn, shape)).reshape(-1)
        index = np.full(t.size, -1, np.int64)
        status = np.full(t.size, NO_EPHEMERIS, np.int8)
        if len(self) == 0 or t.size == 0:
            return index.reshape(shape), status.reshape(shape)
        d = self.data
        rec_keys = sat_key(d["system"], d["prn"])
        # records by satellite, then toe ascending, then later transmission first
        transmit = np.where(np.isfinite(d["transmit"]), d["transmit"], -np.inf)
        order = np.lexsort((-transmit, d["toe"], rec_keys))
        sorted_keys = rec_keys[order]
        for key in np.unique(keys):
            q = np.flatnonzero(keys == key)
            lo, hi = np.searchsorted(sorted_keys, key, "left"), np.searchsorted(sorted_keys, key, "right")
            if lo == hi:
                continue
            recs = order[lo:hi]
            half = np.full(recs.size, max_age_s, float) if max_age_s is not None else d["fit_s"][recs] / 2.0
            healthy = (d["health"][recs] == 0) | allow_unhealthy
            for start in range(0, q.size, 4096):  # bounded (queries x records) temporaries
                qq = q[start:start + 4096]
                dt = np.abs(t[qq, None] - d["toe"][recs][None, :])
                inside = dt <= half[None, :]
                usable = inside & healthy[None, :]
                best = np.argmin(np.where(usable, dt, np.inf), axis=1)
                ok = usable[np.arange(qq.size), best]
                index[qq[ok]] = recs[best[ok]]
                status[qq[ok]] = OK
                any_inside = inside.any(axis=1)
                status[qq[~ok & any_inside]] = UNHEALTHY
                status[qq[~ok & ~any_inside]] = STALE
        return index.reshape(shape), status.reshape(shape)
