"""One observation table for every GNSS measurement source (RINEX 2/3, u-blox RXM-RAWX).

A row is one signal of one satellite at one epoch: time (continuous GPS seconds, see
`leonav_runtime.gnss.time`), system letter, PRN, RINEX 3 signal code ("1C", "1W", "2W",
"5Q", "2I", ...), and whatever that signal has: pseudorange (m), carrier phase (cycles),
Doppler (Hz, positive when the satellite approaches, the RINEX and u-blox convention),
C/N0 (dB-Hz; RINEX 2 'S' values as the receiver wrote them), pseudorange sigma (m, from
RAWX prStdev; NaN when the source gives none), LLI and SSI (RINEX), and `flags` (bits
below). Missing values are NaN. The filter inputs are built from this table later.

Rejections are counted in `counts` and, where a file line is at fault, listed in
`rejected` (file, line, field, reason); rows without any usable value are dropped.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.gnss.ephemeris import Rejection

# flags bits
FLAG_PR_VALID = 0x01        # pseudorange present, finite, non-zero (and RAWX prValid)
FLAG_CP_VALID = 0x02        # carrier phase present (and RAWX cpValid)
FLAG_HALF_CYCLE = 0x04      # half-cycle ambiguity not resolved (RAWX halfCyc = 0; RINEX LLI bit 1)
FLAG_LOSS_OF_LOCK = 0x08    # RINEX LLI bit 0 (lost lock since the previous observation)
FLAG_POWER_FAILURE = 0x10   # RINEX epoch flag 1 (power failure between previous and this epoch)
FLAG_SUB_HALF_CYCLE = 0x20  # RAWX subHalfCyc: a half cycle was subtracted from the phase
FLAG_ANTISPOOFING = 0x40    # RINEX LLI bit 2 (tracked under anti-spoofing / BOC)
FLAG_NAMES = {FLAG_PR_VALID: "pr_valid", FLAG_CP_VALID: "cp_valid", FLAG_HALF_CYCLE: "half_cycle_unresolved",
              FLAG_LOSS_OF_LOCK: "loss_of_lock", FLAG_POWER_FAILURE: "power_failure_epoch",
              FLAG_SUB_HALF_CYCLE: "sub_half_cycle", FLAG_ANTISPOOFING: "antispoofing"}

COLUMNS = (
    ("t_gps_s", np.float64), ("system", "U1"), ("prn", np.int16), ("signal", "U3"),
    ("pseudorange_m", np.float64), ("carrier_phase_cyc", np.float64), ("doppler_hz", np.float64),
    ("cn0_dbhz", np.float64), ("sigma_pr_m", np.float64), ("lli", np.int8), ("ssi", np.int8),
    ("flags", np.uint16), ("freq_slot", np.int8),
)


@dataclass
class ObservationTable:
    """Columns as NumPy arrays of one length (see COLUMNS); `source`, `rejected`, `counts`."""

    t_gps_s: np.ndarray
    system: np.ndarray
    prn: np.ndarray
    signal: np.ndarray
    pseudorange_m: np.ndarray
    carrier_phase_cyc: np.ndarray
    doppler_hz: np.ndarray
    cn0_dbhz: np.ndarray
    sigma_pr_m: np.ndarray
    lli: np.ndarray
    ssi: np.ndarray
    flags: np.ndarray
    freq_slot: np.ndarray
    source: str = ""
    rejected: list[Rejection] = field(default_factory=list)
    counts: Counter = field(default_factory=Counter)
    approx_position_ecef_m: np.ndarray | None = None  # RINEX header APPROX POSITION XYZ

    def __post_init__(self) -> None:
        n = None
        for name, dtype in COLUMNS:
            arr = np.asarray(getattr(self, name), dtype=dtype).reshape(-1)
            setattr(self, name, arr)
            if n is None:
                n = arr.size
            elif arr.size != n:
                raise ValueError(f"ObservationTable column {name} has {arr.size} rows, expected {n}")

    def __len__(self) -> int:
        return self.t_gps_s.size

    def __repr__(self) -> str:
        return (f"ObservationTable({len(self)} rows, {self.epochs().size} epochs, "
                f"systems {dict(Counter(self.system.tolist()))}, {len(self.rejected)} rejected, source={self.source!r})")

    @classmethod
    def from_rows(cls, rows: dict[str, list], **meta) -> "ObservationTable":
        return cls(**{name: np.asarray(rows[name], dtype=dtype) if len(rows[name]) else np.zeros(0, dtype)
                      for name, dtype in COLUMNS}, **meta)

    @classmethod
    def empty(cls, **meta) -> "ObservationTable":
        return cls.from_rows({name: [] for name, _ in COLUMNS}, **meta)

    def column_dict(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name, _ in COLUMNS}

    def take(self, index) -> "ObservationTable":
        """Rows by mask, indices or slice (metadata kept)."""
        return ObservationTable(**{n: c[index] for n, c in self.column_dict().items()}, source=self.source,
                                rejected=list(self.rejected), counts=Counter(self.counts),
                                approx_position_ecef_m=self.approx_position_ecef_m)

    def concat(self, other: "ObservationTable") -> "ObservationTable":
        cols = {n: np.concatenate([getattr(self, n), getattr(other, n)]) for n, _ in COLUMNS}
        return ObservationTable(**cols, source=";".join(s for s in (self.source, other.source) if s),
                                rejected=self.rejected + other.rejected, counts=self.counts + other.counts,
                                approx_position_ecef_m=self.approx_position_ecef_m)

    def sorted(self) -> "ObservationTable":
        """Rows ordered by time, system, PRN, signal (stable)."""
        order = np.lexsort((self.signal, self.prn, self.system, self.t_gps_s))
        return self.take(order)

    def epochs(self) -> np.ndarray:
        return np.unique(self.t_gps_s)

    def to_structured(self) -> np.ndarray:
        out = np.zeros(len(self), dtype=[(n, d) for n, d in COLUMNS])
        for n, _ in COLUMNS:
            out[n] = getattr(self, n)
        return out

    def has_flag(self, flag: int) -> np.ndarray:
        return (self.flags & flag) != 0

    def summary(self) -> dict:
        return {"rows": len(self), "epochs": int(self.epochs().size),
                "rows_per_system": dict(sorted(Counter(self.system.tolist()).items())),
                "rows_per_signal": dict(sorted(Counter((np.char.add(self.system, self.signal)).tolist()).items())),
                "with_pseudorange": int(np.isfinite(self.pseudorange_m).sum()),
                "rejected": len(self.rejected), "counts": dict(sorted(self.counts.items()))}


class RowBuilder:
    """Accumulates rows as Python lists (readers append, `table()` converts once)."""

    def __init__(self) -> None:
        self.rows: dict[str, list] = {name: [] for name, _ in COLUMNS}

    def add(self, t: float, system: str, prn: int, signal: str, pr: float, cp: float, dop: float, cn0: float,
            sigma: float, lli: int, ssi: int, flags: int, slot: int = 0) -> None:
        r = self.rows
        r["t_gps_s"].append(t)
        r["system"].append(system)
        r["prn"].append(prn)
        r["signal"].append(signal)
        r["pseudorange_m"].append(pr)
        r["carrier_phase_cyc"].append(cp)
        r["doppler_hz"].append(dop)
        r["cn0_dbhz"].append(cn0)
        r["sigma_pr_m"].append(sigma)
        r["lli"].append(lli)
        r["ssi"].append(ssi)
        r["flags"].append(flags)
        r["freq_slot"].append(slot)

    def table(self, **meta) -> ObservationTable:
        return ObservationTable.from_rows(self.rows, **meta)


# ------------------------------------------------------------------ u-blox RXM-RAWX

UBX_GNSS = {0: "G", 1: "S", 2: "E", 3: "C", 5: "J", 6: "R", 7: "I"}
# (gnssId, sigId) -> RINEX 3 signal code (u-blox F9 interface description, signal identifiers;
# M8 firmware reports sigId 0, which maps to the one L1 signal it tracks)
UBX_SIGNALS = {
    (0, 0): "1C", (0, 3): "2L", (0, 4): "2S", (0, 6): "5I", (0, 7): "5Q",
    (1, 0): "1C",
    (2, 0): "1C", (2, 1): "1B", (2, 3): "5I", (2, 4): "5Q", (2, 5): "7I", (2, 6): "7Q",
    (3, 0): "2I", (3, 1): "2I", (3, 2): "7I", (3, 3): "7I", (3, 5): "1P", (3, 6): "1D", (3, 7): "5P", (3, 8): "5D",
    (5, 0): "1C", (5, 1): "1Z", (5, 4): "2S", (5, 5): "2L", (5, 8): "5I", (5, 9): "5Q",
    (6, 0): "1C", (6, 2): "2C",
    (7, 0): "5A",
}


def rawx_to_table(epochs, source: str = "") -> ObservationTable:
    """RXM-RAWX epochs (`hardware.records.RxmRawx`, as `hardware.gnss.ubx.decode_rxm_rawx`
    returns them) -> ObservationTable, one row per measurement.

    Time: week * 604800 + rcvTow (the receiver's GPS time tag of the epoch). Pseudorange
    NaN unless prValid and finite and non-zero; carrier phase NaN unless cpValid; Doppler NaN
    when not finite or exactly 0 (no validity flag; counted `doppler_zero`); sigma_pr
    from prStdev (0.01 * 2^n m). GLONASS satellites with an unknown slot (svId 255) and
    unknown gnssId/sigId pairs are dropped and counted.
    """
    b = RowBuilder()
    counts: Counter = Counter()
    for ep in epochs:
        counts["epochs"] += 1
        t = ep.week * 604800.0 + ep.rcv_tow_s
        for m in ep.measurements:
            counts["measurements"] += 1
            system = UBX_GNSS.get(m.gnss_id)
            signal = UBX_SIGNALS.get((m.gnss_id, m.sig_id))
            if system is None or signal is None:
                counts["unknown_signal"] += 1
                continue
            if system == "R" and m.sv_id == 255:
                counts["glonass_unknown_slot"] += 1
                continue
            flags = 0
            pr = float(m.pseudorange_m)
            if not m.pr_valid:
                counts["pr_invalid"] += 1
                pr = np.nan
            elif not np.isfinite(pr) or pr == 0.0:
                counts["pr_nan_or_zero"] += 1
                pr = np.nan
            else:
                flags |= FLAG_PR_VALID
            cp = float(m.carrier_phase_cyc) if m.cp_valid and np.isfinite(m.carrier_phase_cyc) else np.nan
            if np.isfinite(cp) and cp != 0.0:
                flags |= FLAG_CP_VALID
                if not m.half_cyc:
                    flags |= FLAG_HALF_CYCLE
                if m.sub_half_cyc:
                    flags |= FLAG_SUB_HALF_CYCLE
            else:
                cp = np.nan
            dop = float(m.doppler_hz)
            if not np.isfinite(dop):
                counts["doppler_nan"] += 1
                dop = np.nan
            elif dop == 0.0:   # RAWX has no Doppler validity flag: an exact 0 is "none" (as a zero in RINEX)
                counts["doppler_zero"] += 1
                dop = np.nan
            if np.isnan(pr) and np.isnan(cp) and np.isnan(dop):
                counts["rows_without_values"] += 1
                continue
            slot = m.freq_id - 7 if system == "R" else 0
            prn = m.sv_id
            b.add(t, system, prn, signal, pr, cp, dop, float(m.cno_dbhz) if m.cno_dbhz > 0 else np.nan,
                  float(m.pr_std_m) if np.isfinite(pr) else np.nan, 0, 0, flags, slot)
    table = b.table(source=source, counts=counts)
    table.counts["rows"] = len(table)
    return table

