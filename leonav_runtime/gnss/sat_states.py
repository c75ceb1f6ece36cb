"""Satellite states at signal transmit time for every row of an observation table.

For each row: select the broadcast ephemeris of the satellite at the receive time
(`Ephemerides.select`: fit interval, health), compute the transmit time from the
pseudorange and the satellite clock, then position/velocity (ECEF of the transmit
epoch) and the clock for the row's signal (relativistic correction and TGD/BGD
included). Rows that get no state are counted by reason in `counts` and carry NaN:
"no_ephemeris", "stale_ephemeris", "unhealthy", "no_pseudorange".
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from leonav_runtime.gnss.ephemeris import NO_EPHEMERIS, OK, STALE, UNHEALTHY, Ephemerides
from leonav_runtime.gnss.observations import ObservationTable
from leonav_runtime.orbits.broadcast import group_delay_s, satellite_states, transmit_time

NO_PSEUDORANGE = 4
REASONS = {NO_EPHEMERIS: "no_ephemeris", STALE: "stale_ephemeris", UNHEALTHY: "unhealthy",
           NO_PSEUDORANGE: "no_pseudorange"}


@dataclass
class ObservedSatStates:
    """Per observation row (n,): ephemeris index, status, transmit time (GPS s), r/v ECEF at
    transmit time, satellite clock of the row's signal (s) and its drift (s/s)."""

    index: np.ndarray
    status: np.ndarray
    t_tx_gps_s: np.ndarray
    r_ecef_m: np.ndarray
    v_ecef_mps: np.ndarray
    clock_s: np.ndarray
    clock_drift_sps: np.ndarray
    counts: Counter

    @property
    def ok(self) -> np.ndarray:
        return self.status == OK


def states_for_observations(obs: ObservationTable, eph: Ephemerides, *, max_age_s: float | None = None,
                            allow_unhealthy: bool = False) -> ObservedSatStates:
    n = len(obs)
    index, status = eph.select(obs.system, obs.prn, obs.t_gps_s, max_age_s=max_age_s,
                               allow_unhealthy=allow_unhealthy)
    status = status.astype(np.int8)
    no_pr = ~np.isfinite(obs.pseudorange_m)
    status[(status == OK) & no_pr] = NO_PSEUDORANGE
    ok = status == OK
    t_tx = np.full(n, np.nan)
    r = np.full((n, 3), np.nan)
    v = np.full((n, 3), np.nan)
    clk = np.full(n, np.nan)
    drift = np.full(n, np.nan)
    if ok.any():
        rows = eph.data[index[ok]]
        t = transmit_time(rows, obs.t_gps_s[ok], obs.pseudorange_m[ok])
        st = satellite_states(rows, t)
        t_tx[ok] = t
        r[ok], v[ok] = st.r_ecef_m, st.v_ecef_mps
        clk[ok] = st.clock_bias_s - group_delay_s(rows, obs.signal[ok])
        drift[ok] = st.clock_drift_sps
    counts = Counter({REASONS[s]: int((status == s).sum()) for s in REASONS if (status == s).any()})
    counts["with_state"] = int(ok.sum())
    return ObservedSatStates(index, status, t_tx, r, v, clk, drift, counts)
