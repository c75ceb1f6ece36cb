"""GNSS observation table on the one road: code pseudoranges and Doppler range rates of
real receivers (RINEX, u-blox RXM-RAWX) for the generated GNSS_PSEUDORANGE and
GNSS_RANGE_RATE observables (tightly coupled modes `pseudorange+imu`,
`pseudorange+leo-alpha+imu`).

The table is made by `leonav_runtime.gnss.coupled` (broadcast satellite states at transmit
time, atmosphere switches, elevation mask and variances from the single-point pass); here
it is only checked, turned into records, and used to start the receiver clock:

- records: one GNSS_PSEUDORANGE record per row (R = sigma_pr_m^2), one GNSS_RANGE_RATE
  record per row with a finite range rate (R = sigma_rr_mps^2), aux as given (satellite
  state, satellite clock, ionosphere / troposphere switches and coefficients; layout
  `gen/state_layout.AUX_*`), sat_id = ord(system letter) * 1000 + PRN;
- clock start (`apply_clock_start`): a real receiver clock is anywhere within a millisecond
  (300 km) and drifts by up to metres per second, so x0's clock bias, drift and
  inter-system biases come from the single-point solutions nearest the filter start (each
  inter-system bias from the nearest one where its constellation was present), and
  the filter's clock PSDs are the loose ones of a receiver clock that is re-estimated every
  epoch (`GNSS_Q_CDT_M2PS`, `GNSS_Q_CDDT_M2PS3`). No other state reads the clock states, so
  the other observables of a run are not affected.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from leonav_runtime.core import records
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.gen import state_layout as LAYOUT
from leonav_runtime.inputs.tables import _bad, check_column

GNSS_STREAMS = tuple(dict.fromkeys(o.stream for o in model.OBSERVABLES if o.table == "gnss_obs"))
"""Record streams of a GNSS receiver's raw observations (the registry's `gnss_obs` observables)."""
GNSS_Q_CDT_M2PS = 1e4
"""m^2/s: receiver clock white-frequency PSD (loose: receiver clocks steer and jump; re-estimated every epoch)."""
GNSS_Q_CDDT_M2PS3 = 1.0
"""m^2/s^3: receiver clock random-walk-frequency PSD (drift changes of receiver TCXOs)."""
CLOCK_START_SIGMA_M = 30.0        # c_dt at the start: single-point clock sigma plus its extrapolation
DRIFT_START_SIGMA_MPS = 10.0      # drift from two single-point clocks, or 0 when there is one
ISB_START_SIGMA_M = 100.0         # an inter-system bias first seen later needs room too


@dataclasses.dataclass
class GnssObservationTable:
    """One row per satellite and epoch (reception time order).

    t (n,) s on the run's time axis (reception); sat_id (n,) int (ord(system) * 1000 + PRN);
    pseudorange_m (n,) raw code pseudorange, m; sigma_pr_m (n,) its 1-sigma, m, > 0;
    range_rate_mps (n,) -lambda D, m/s (NaN: no Doppler); sigma_rr_mps (n,) its 1-sigma,
    m/s, > 0 where range_rate_mps is finite; aux (n, NAUX) inputs of the GNSS observables.
    Clock start (optional, per single-point epoch): clock_t (E,) s, clock_m (E,) c_dt m,
    isb_m (E, 2) m (NaN where a constellation is absent).
    """

    t: np.ndarray
    sat_id: np.ndarray
    pseudorange_m: np.ndarray
    sigma_pr_m: np.ndarray
    range_rate_mps: np.ndarray
    sigma_rr_mps: np.ndarray
    aux: np.ndarray
    clock_t: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    clock_m: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    isb_m: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))

    NAME: ClassVar[str] = "GNSS observation table"

    @classmethod
    def empty(cls) -> "GnssObservationTable":
        return cls(np.zeros(0), np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0),
                   np.zeros((0, LAYOUT.NAUX)))

    def __len__(self) -> int:
        return int(np.shape(self.t)[0])

    def select(self, mask) -> "GnssObservationTable":
        """Rows in `mask`; the clock start is kept whole."""
        return dataclasses.replace(self, t=self.t[mask], sat_id=self.sat_id[mask],
                                   pseudorange_m=self.pseudorange_m[mask], sigma_pr_m=self.sigma_pr_m[mask],
                                   range_rate_mps=self.range_rate_mps[mask], sigma_rr_mps=self.sigma_rr_mps[mask],
                                   aux=self.aux[mask])

    def check(self) -> "GnssObservationTable":
        """One UserInputError naming the field, the first bad row and what was expected."""
        name = self.NAME
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        check_column(name, "t", self.t, (max(n, 0),), unit="s")
        if n > 1 and not (np.diff(self.t) >= 0).all():
            row = int(np.flatnonzero(np.diff(self.t) < 0)[0]) + 1
            raise _bad(name, "t", f"row {row} is earlier than the row before", "reception times in order")
        check_column(name, "sat_id", self.sat_id, (n,), finite=False)
        check_column(name, "pseudorange_m", self.pseudorange_m, (n,), positive=True, unit="m")
        check_column(name, "sigma_pr_m", self.sigma_pr_m, (n,), positive=True, unit="m")
        check_column(name, "range_rate_mps", self.range_rate_mps, (n,), finite=False, unit="m/s")
        has_rr = np.isfinite(self.range_rate_mps)
        check_column(name, "sigma_rr_mps", self.sigma_rr_mps, (n,), finite=False, unit="m/s")
        bad_rr = has_rr & ~(np.isfinite(self.sigma_rr_mps) & (self.sigma_rr_mps > 0))
        if bad_rr.any():
            raise _bad(name, "sigma_rr_mps", f"not a positive number in row {int(np.flatnonzero(bad_rr)[0])}",
                       "a positive 1-sigma (m/s) for every row with a range rate")
        check_column(name, "aux", self.aux, (n, LAYOUT.NAUX), unit="aux units (gen/state_layout.py)")
        e = np.shape(self.clock_t)[0] if np.ndim(self.clock_t) == 1 else -1
        check_column(name, "clock_t", self.clock_t, (max(e, 0),), unit="s")
        check_column(name, "clock_m", self.clock_m, (e,), unit="m")
        check_column(name, "isb_m", self.isb_m, (e, 2), finite=False, unit="m")
        return self


def gnss_records(table: GnssObservationTable, nav) -> tuple[np.ndarray, np.ndarray]:
    """(GNSS_PSEUDORANGE records, GNSS_RANGE_RATE records) of a checked table."""
    if not len(table):
        empty = np.zeros(0, records.RECORD_DTYPE)
        return empty, empty
    pr = records.measurement_records(table.t, nav.kind_id("gnss_pseudorange"), table.pseudorange_m,
                                     table.sigma_pr_m**2, table.aux, table.sat_id)
    k = np.isfinite(table.range_rate_mps)
    rr = records.measurement_records(table.t[k], nav.kind_id("gnss_range_rate"), table.range_rate_mps[k],
                                     table.sigma_rr_mps[k] ** 2, table.aux[k], table.sat_id[k])
    return pr, rr


def apply_clock_start(x0: np.ndarray, P0: np.ndarray, params: np.ndarray, table: GnssObservationTable,
                      t_start: float, layout) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """x0, P0 and params with the receiver clock started from the table's single-point clocks
    (module doc); returns them and a description for `FilterInputs.init`."""
    L = layout
    if not table.clock_t.size:
        raise UserInputError(f"{GnssObservationTable.NAME}: clock_t: empty: expected at least one single-point "
                             "clock to start the receiver clock from")
    x0, P0, params = x0.copy(), P0.copy(), params.copy()
    k = int(np.argmin(np.abs(table.clock_t - t_start)))
    drift = 0.0
    if table.clock_t.size > 1:
        j = k + 1 if k + 1 < table.clock_t.size else k - 1
        drift = float((table.clock_m[j] - table.clock_m[k]) / (table.clock_t[j] - table.clock_t[k]))
    x0[L.X_C_DT] = table.clock_m[k] + drift * (t_start - table.clock_t[k])
    x0[L.X_C_DDT] = drift
    x0[L.X_ISB_SLICE] = nearest_finite(table.clock_t, table.isb_m, t_start)
    for i, s in ((L.DX_DC_DT, CLOCK_START_SIGMA_M), (L.DX_DC_DDT, DRIFT_START_SIGMA_MPS)):
        P0[i, :], P0[:, i], P0[i, i] = 0.0, 0.0, s**2
    isb = np.arange(L.DX_DISB_SLICE.start, L.DX_DISB_SLICE.stop)
    P0[isb, :], P0[:, isb] = 0.0, 0.0
    P0[isb, isb] = ISB_START_SIGMA_M**2
    params[L.P_Q_CDT], params[L.P_Q_CDDT] = GNSS_Q_CDT_M2PS, GNSS_Q_CDDT_M2PS3
    init = {"receiver_clock": f"single-point clock at t={table.clock_t[k]:.3f} s extrapolated to the start, "
                              f"drift from two single-point clocks, sigma {CLOCK_START_SIGMA_M:g} m / "
                              f"{DRIFT_START_SIGMA_MPS:g} m/s; clock PSDs q_cdt {GNSS_Q_CDT_M2PS:g} m^2/s, "
                              f"q_cddt {GNSS_Q_CDDT_M2PS3:g} m^2/s^3",
            "clock_m": float(x0[L.X_C_DT]), "clock_drift_mps": drift}
    return x0, P0, params, init


def nearest_finite(t: np.ndarray, values: np.ndarray, t_start: float) -> np.ndarray:
    """Per column of values (E, m), the finite value at the t nearest t_start (0 where none
    is finite): a constellation absent at the start epoch takes its bias from the nearest
    epoch that saw it, not 0."""
    out = np.zeros(values.shape[1])
    for j in range(values.shape[1]):
        fin = np.flatnonzero(np.isfinite(values[:, j]))
        if fin.size:
            out[j] = values[fin[np.argmin(np.abs(t[fin] - t_start))], j]
    return out

