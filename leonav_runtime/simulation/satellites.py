"""The simulated satellite measurements of a scenario: which satellites are tracked at every
epoch of each constellation, and the noise-free measurements of every simulated satellite
observable (registry `table = "satellite"`) at the truth, with their Jacobians.

Rows of a constellation are (IMU sample k, t, NORAD id, satellite state (9,), reference state
(9,) or None, elevation rank); GPS states are at transmit time (the pseudorange model's
light-time solution), Starlink states at reception with the epoch's highest satellite as the
reference of a differenced observable (one that reads a reference satellite uses the rows of
rank > 0 only).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.gen import state_layout
from leonav_runtime.inputs import SATELLITE_TABLES, satellite_aux, states_from_aux
from leonav_runtime.scenarios.load import Scenario
from leonav_runtime.simulation import carrier_truth
from leonav_runtime.simulation.visibility import _receiver_ecef, _visible_ranked


@dataclass
class SatSeries:
    """Measurements of one observable over the run (one row per measurement).

    t_s, sat_id (NORAD id), aux (n, NAUX), z_true (noise-free, measurement-sensor states at
    zero; a differenced observable's is exact, its h at the truth in h_true), H (n, NDX) at the truth, rank (elevation rank at its epoch, 0 = highest); sat_ecef,
    ref_ecef: the satellite's and the reference's r, v, a of aux as contiguous (n, 9) blocks
    (`inputs.SAT_*` columns), what the trials' satellite tables are cut from.
    """

    kind: int
    t_s: np.ndarray
    sat_id: np.ndarray
    aux: np.ndarray
    z_true: np.ndarray
    H: np.ndarray
    rank: np.ndarray
    has_ref: bool = False   # rows carry a reference satellite (Starlink's: the epoch's highest)
    interval_s: np.ndarray | None = None   # a time-differenced observable's span per row (s)
    k_prev: np.ndarray | None = None       # the IMU sample its span starts at
    sat_prev_r_m: np.ndarray | None = None  # and the satellite's ECEF position there (m)
    h_true: np.ndarray | None = None       # the model's h at the truth where z_true is not it
    sat_ecef: np.ndarray = field(init=False, repr=False)
    ref_ecef: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.sat_ecef, self.ref_ecef = (np.ascontiguousarray(b) for b in states_from_aux(self.aux, state_layout))

    @property
    def model_at_truth(self) -> np.ndarray:
        """The generated h at the truth (z_true itself, except for an exact differenced truth):
        what a change of the aux satellite states is measured against through the model."""
        return self.z_true if self.h_true is None else self.h_true


def epochs(scn: Scenario, rate_hz: float, t_imu: np.ndarray) -> np.ndarray:
    """Measurement epochs on IMU sample times, from the first sample after 0."""
    step = int(round(scn.imu_rate_hz / rate_hz))
    if step < 1 or abs(scn.imu_rate_hz / rate_hz - step) > 1e-9:
        raise UserInputError(
            f"{scn.source}: measurement rate {rate_hz} Hz must divide the IMU rate "
            f"{scn.imu_rate_hz} Hz (measurements are tagged on IMU sample times)"
        )
    return np.arange(step, t_imu.size, step)


def series(nav, kind_name, rows, x_true, f_b, scn: Scenario | None = None) -> SatSeries:
    """Rows (module doc) as a series: aux as the road builds it (`inputs.satellite_aux`, f_b of
    sample k), h and H at the truth. A time-differenced observable (registry `reads_interval`)
    keeps the rows whose satellite was tracked at the previous epoch too, and its noise-free
    value is the exact phase change (carrier_truth.py), not its h."""
    differenced = model.observable(kind_name).reads_interval
    if differenced:
        rows, k_prev, sat_prev = carrier_truth.differenced_rows(rows)
    n, L = len(rows), nav.layout
    k = np.array([r[0] for r in rows], int)
    sat = np.array([r[3] for r in rows]).reshape(n, 9)
    ref = np.array([r[4] for r in rows]).reshape(n, 9) if n and rows[0][4] is not None else None
    interval = (k - k_prev) / scn.imu_rate_hz if differenced else None
    table = SATELLITE_TABLES[kind_name](np.array([r[1] for r in rows], float), np.array([r[2] for r in rows],
                                        np.int32), np.zeros(n), 1.0, sat, ref, interval,
                                        sat_prev[:, 0:3] if differenced else None)
    aux = satellite_aux(table, f_b[k], L)
    kind = nav.kind_id(kind_name)
    z, H = nav.h_many(kind, x_true[k], aux) if n else (np.empty(0), np.empty((0, L.NDX)))
    h_true = None
    if differenced:
        h_true, p_enu = z, x_true[:, L.X_P_ENU_SLICE]
        z = carrier_truth.geometric_cycles(nav.params[L.P_F_C_HZ], sat, sat_prev, _receiver_ecef(scn, p_enu[k]),
                                           _receiver_ecef(scn, p_enu[k_prev]))
    return SatSeries(kind, table.t, table.sat_id, aux, z, H, np.array([r[5] for r in rows], np.int32), ref is not None,
                     interval, k_prev if differenced else None, sat_prev[:, 0:3] if differenced else None, h_true)


def gps_rows(scn, nav, es, t_imu, x_true, notes):
    """(rows, fewest satellites visible at an epoch) of the GPS constellation."""
    idx = epochs(scn, scn.gps["rate_hz"], t_imu)
    t = t_imu[idx]
    p_enu = x_true[idx, nav.layout.X_P_ENU_SLICE]
    states, ranked, _, es = _visible_ranked(scn, es, t, p_enu, scn.gps["elevation_mask_rad"], notes)
    r_rx = _receiver_ecef(scn, p_enu)
    rows = []
    for j, k in enumerate(idx):
        use = ranked[j][: scn.gps["max_satellites"]]
        for rank, s in enumerate(use):
            # Satellite at transmit time (generated light-time solution), in the ECEF frame
            # of the transmit epoch, as the pseudorange model (with Sagnac) expects.
            a = states.a_ecef_mps2[s, j]
            r_tx, v_tx, _ = nav.transmit_state(states.r_ecef_m[s, j], states.v_ecef_mps[s, j], a, r_rx[j])
            rows.append((k, t[j], int(es.norad_ids[s]), np.concatenate([r_tx, v_tx, a]), None, rank))
    vis = [len(r) for r in ranked]
    return rows, min(vis) if vis else 0


def starlink_rows(scn, nav, es, t_imu, x_true, notes):
    """(rows, fewest satellites visible at an epoch) of the Starlink constellation; every row
    carries the epoch's highest satellite as its reference."""
    idx = epochs(scn, scn.starlink["rate_hz"], t_imu)
    t = t_imu[idx]
    p_enu = x_true[idx, nav.layout.X_P_ENU_SLICE]
    # Only satellites that can be above the mask need states at every epoch (`_candidates`).
    priority = None
    if scn.starlink["selection"] == "random":   # one draw per run: the tracked subset persists
        priority = np.random.default_rng(scn.starlink["selection_seed"]).random(len(es.norad_ids))
    states, ranked, _, es = _visible_ranked(scn, es, t, p_enu, scn.starlink["elevation_mask_rad"], notes,
                                            priority=priority)
    n_max = max(scn.starlink["counts"])
    rows = []
    for j, k in enumerate(idx):
        use = ranked[j][:n_max]
        if use.size == 0:
            continue
        sat = np.concatenate([states.r_ecef_m[use, j], states.v_ecef_mps[use, j], states.a_ecef_mps2[use, j]],
                             axis=1)
        rows += [(k, t[j], int(es.norad_ids[s]), sat[rank], sat[0], rank) for rank, s in enumerate(use)]
    vis = [len(r) for r in ranked]
    return rows, min(vis) if vis else 0


CONSTELLATION_ROWS = {"gps": gps_rows, "starlink": starlink_rows}


def observable_rows(o, rows: list) -> list:
    """The rows of observable `o` among its constellation's: a differenced one (reads a
    reference satellite) has none at rank 0, the reference itself; GPS rows carry no reference."""
    if o.reads_ref:
        return [r for r in rows if r[5] > 0]
    return rows


def satellite_observables() -> tuple:
    """The simulated satellite observables, in kind-id order (the trial's noise draw order)."""
    return tuple(o for o in model.OBSERVABLES if o.table == "satellite")
