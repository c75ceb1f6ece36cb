"""Motion-constraint records: non-holonomic (NHC_Y, NHC_Z) and zero-velocity (ZUPT_E/N/U).

Pseudo-measurements z = 0 of the generated observables (models/measurements/
motion_constraints.py), each with its own R (`[constraints]` of the dataset file):
- "nhc": lateral and vertical body velocity at `nhc_rate_hz` over the whole run, sigma
  `nhc_sigma_mps` = [lateral, vertical] (wheel slip in turns, the IMU's offset from the axle);
- "zupt": the ENU velocity at `zupt_rate_hz` on the IMU samples detected at rest
  (`align.standstill`), sigma `zupt_sigma_mps`.
Records sit on IMU sample times, so a constraint applies to the state of that instant.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import navfuncs, records
from leonav_runtime.dataset.load import ImuSamples


def _grid(imu_t: np.ndarray, t_start: float, t_end: float, rate_hz: float, mask: np.ndarray | None = None):
    """IMU sample times inside (t_start, t_end] thinned to about rate_hz (and inside mask)."""
    sel = (imu_t > t_start) & (imu_t <= t_end)
    if mask is not None:
        sel &= mask
    t = imu_t[sel]
    if t.size == 0:
        return t
    bins = np.floor((t - t_start) * rate_hz + 1e-9)
    return t[np.r_[True, bins[1:] != bins[:-1]]]


def records_for(imu: ImuSamples, still: np.ndarray, t_start: float, t_end: float, con: dict,
                nav: navfuncs.NavFunctions) -> dict[str, np.ndarray]:
    """{"nhc": records, "zupt": records} (module doc)."""
    t_nhc = _grid(imu.t, t_start, t_end, con["nhc_rate_hz"])
    s_lat, s_vert = con["nhc_sigma_mps"]
    nhc = records.merge_records(
        records.measurement_records(t_nhc, nav.kind_id("NHC_Y"), 0.0, s_lat**2),
        records.measurement_records(t_nhc, nav.kind_id("NHC_Z"), 0.0, s_vert**2))
    t_z = _grid(imu.t, t_start, t_end, con["zupt_rate_hz"], still)
    r = con["zupt_sigma_mps"] ** 2
    zupt = records.merge_records(*(records.measurement_records(t_z, nav.kind_id(k), 0.0, r)
                                   for k in ("ZUPT_E", "ZUPT_N", "ZUPT_U")))
    return {"nhc": nhc, "zupt": zupt}
