"""The generated C filter stepped on each arriving batch of records, with a fixed-lag window.

Records arrive out of the road's order: an IMU sample is processed when it arrives, but the
fix of the same instant comes ~0.1 s later (after its GST), a Doppler-rate ~1-2 s later (its
fit window). `LagStepper` keeps, for the last `lag_s` seconds, every record with the state
and covariance after it. A batch later than the filter's head is run at once (`EKF.run` on
the batch: the C loop, state and covariance in the EKF's arrays); a record that belongs
before the head is put in its place - the road's merge order: by time, IMU first, then the
streams in `inputs.STREAMS` order, arrival order within a stream - and the window is re-run
from just before it. So the filter sees the stream in exactly the order a batch replay of the
same records would, and its results equal that run to the bit, while the head is always the
latest IMU sample. Records older than the window (the first record kept) are dropped and
counted. Records leave the window in order ("settled") with their results, for the
trajectory files.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import records
from leonav_runtime.inputs import STREAMS
from leonav_runtime.inputs.measurements import FIX_KINDS


@dataclasses.dataclass
class Settled:
    """Records that left the window, with the filter's results after each."""

    recs: np.ndarray
    x: np.ndarray            # (n, NX)
    P_diag: np.ndarray       # (n, NDX)
    status: np.ndarray       # (n,) per-record status (filter.STATUS_*)
    nis: np.ndarray


class LagStepper:
    """EKF over a stream that arrives in batches, out of order by up to `lag_s` (module doc).

    The window is rows [_s, _e) of preallocated arrays (record, x after it, P after it, status,
    nis); settling moves `_s` on, the rows are compacted only when the arrays are full.
    """

    ARRAYS = ("_recs", "_x", "_P", "_status", "_nis")

    def __init__(self, ekf: lfilter.EKF, lag_s: float = 3.5, capacity: int = 4096) -> None:
        self.ekf = ekf
        self.lag_s = float(lag_s)
        lay = ekf.lib.layout
        self.nx, self.ndx = int(lay.NX), int(lay.NDX)
        self._rank = {records.KIND_IMU: 0}
        for name, kind in ekf.lib.meas_ids.items():
            stream = "fix" if name in FIX_KINDS else name
            self._rank[int(kind)] = 1 + (STREAMS.index(stream) if stream in STREAMS else len(STREAMS))
        self._rank_of = np.full(max(self._rank) + 2, 99, np.int64)     # by kind + 1 (IMU is -1)
        for kind, r in self._rank.items():
            self._rank_of[kind + 1] = r
        self._recs = np.zeros(capacity, records.RECORD_DTYPE)
        self._x = np.zeros((capacity, self.nx))
        self._P = np.zeros((capacity, self.ndx, self.ndx))
        self._status = np.zeros(capacity, np.int32)
        self._nis = np.zeros(capacity)
        self._s = self._e = 0
        self.base_x = ekf.x.copy()                 # state before the first record in the window
        self.base_P = np.array(ekf.P, order="C")
        self.settled_t = -np.inf                   # time of the last settled record
        self.counts = {"records": 0, "reruns": 0, "rerun_records": 0, "late_dropped": 0,
                       "applied": 0, "gated": 0, "failed": 0}
        self.late_by_kind: dict[int, int] = {}

    # -- order
    def rank(self, kinds: np.ndarray) -> np.ndarray:
        return self._rank_of[np.asarray(kinds) + 1]

    def _order(self, recs: np.ndarray) -> np.ndarray:
        """Indices that sort `recs` (oldest arrival first) into the road's merge order."""
        return np.lexsort((np.arange(recs.size), self.rank(recs["kind"]), recs["t"]))

    @property
    def head_t(self) -> float:
        return float(self._recs["t"][self._e - 1]) if self._e > self._s else self.settled_t

    @property
    def window_start_t(self) -> float:
        """Time of the oldest record in the window (the head's when empty)."""
        return float(self._recs["t"][self._s]) if self._e > self._s else self.head_t

    @property
    def size(self) -> int:
        return self._e - self._s

    def head(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, P) after the last record (the EKF's own arrays: read, do not keep)."""
        return self.ekf.x, self.ekf.P

    # -- stepping
    def step(self, new: np.ndarray) -> int:
        """Process a batch (any order); returns how many records were dropped as too late."""
        if new.size == 0:
            return 0
        if new.size > 1:
            new = new[self._order(new)]
        s, e = self._s, self._e
        if e > s:
            t0, r0 = self._recs["t"][s], self._rank.get(int(self._recs["kind"][s]), 99)
            too_late = (new["t"] < t0) | ((new["t"] == t0) & (self.rank(new["kind"]) < r0))
        else:
            too_late = new["t"] < self.settled_t
        n_late = int(too_late.sum())
        if n_late:
            for k in new["kind"][too_late]:
                self.late_by_kind[int(k)] = self.late_by_kind.get(int(k), 0) + 1
            self.counts["late_dropped"] += n_late
            new = new[~too_late]
            if new.size == 0:
                return n_late
        i = self._insert_index(new[0])
        if i < e:        # a record that belongs inside the window: re-run from just before it
            tail = np.concatenate([self._recs[i:e], new])
            tail = tail[self._order(tail)]
            self.counts["reruns"] += 1
            self.counts["rerun_records"] += e - i
            self._count_statuses(self._status[i:e], -1)
            if i == s:
                x, P = self.base_x, self.base_P
            else:
                x, P = self._x[i - 1], self._P[i - 1]
            self.ekf.x[:] = x
            self.ekf.P[:, :] = P
            self._e = i
            self._run(tail)
        else:
            self._run(new)
        return n_late

    def _insert_index(self, rec) -> int:
        """Row of the first window record that comes after `rec` in the merge order."""
        s, e = self._s, self._e
        t = self._recs["t"]
        rank_new = self._rank.get(int(rec["kind"]), 99)
        j = s + int(np.searchsorted(t[s:e], rec["t"], side="left"))
        while j < e and t[j] == rec["t"] and self._rank.get(int(self._recs["kind"][j]), 99) <= rank_new:
            j += 1
        return j

    def _count_statuses(self, status: np.ndarray, sign: int) -> None:
        for name, code in (("applied", lfilter.STATUS_APPLIED), ("gated", lfilter.STATUS_GATED),
                           ("failed", lfilter.STATUS_FAILED)):
            self.counts[name] += sign * int(np.count_nonzero(status == code))

    def _run(self, recs: np.ndarray) -> None:
        res = self.ekf.run(recs, full_P=True)
        n = recs.size
        self._room(n)
        a, b = self._e, self._e + n
        self._recs[a:b] = recs
        self._x[a:b] = res.x
        self._P[a:b] = res.P
        self._status[a:b] = res.status
        self._nis[a:b] = res.nis
        self._e = b
        self.counts["records"] += n
        self._count_statuses(res.status, 1)

    def _room(self, n: int) -> None:
        """Make room for n rows after _e: compact to row 0, grow when the window itself needs it."""
        cap = self._recs.size
        if self._e + n <= cap:
            return
        m = self._e - self._s
        new_cap = cap if m + n <= cap // 2 else max(2 * cap, m + n)
        for name in self.ARRAYS:
            old = getattr(self, name)
            arr = old if new_cap == cap else np.zeros((new_cap,) + old.shape[1:], old.dtype)
            arr[:m] = old[self._s:self._e].copy()
            setattr(self, name, arr)
        self._s, self._e = 0, m

    # -- leaving the window
    def settle(self, before_t: float | None = None) -> Settled | None:
        """Records with t < `before_t` (default head - lag_s), all of one time together; None if none."""
        s, e = self._s, self._e
        if e == s:
            return None
        cut_t = self.head_t - self.lag_s if before_t is None else before_t
        k = s + int(np.searchsorted(self._recs["t"][s:e], cut_t, side="left"))
        if k == s:
            return None
        out = Settled(self._recs[s:k].copy(), self._x[s:k].copy(),
                      np.diagonal(self._P[s:k], axis1=1, axis2=2).copy(), self._status[s:k].copy(),
                      self._nis[s:k].copy())
        self.base_x, self.base_P = self._x[k - 1].copy(), self._P[k - 1].copy()
        self.settled_t = float(self._recs["t"][k - 1])
        self._s = k
        return out

    def settle_all(self) -> Settled | None:
        return self.settle(np.inf)

    def window(self) -> tuple[np.ndarray, np.ndarray]:
        """(records, statuses) in the window (views)."""
        return self._recs[self._s:self._e], self._status[self._s:self._e]
