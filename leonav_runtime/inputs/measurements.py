"""Measurement tables -> measurement records (z, R, aux) of the generated observables.

- GNSS fixes: three records per epoch, POS_E, POS_N, POS_U (m, ENU at the origin),
  R = sigma^2 per axis.
- GNSS velocity: three records per epoch, VEL_E, VEL_N, VEL_U (m/s, the antenna's), R =
  sigma^2; aux: the averaged specific force and the latest body rate (`velocity_records`).
- Satellite observables: aux = the satellite's ECEF state r, v, a (and the reference
  satellite's for a differenced observable) plus the receiver's specific force f_b
  (m/s^2, body) averaged over `imu.F_B_AVERAGE_S` up to the latest IMU sample at or
  before the measurement (`imu.averaged_specific_force`); R = sigma^2, except the
  Doppler-rate, whose model uses that measured f_b: R = sigma^2 plus the average's
  accelerometer noise at the carrier (generated `leonav_doppler_rate_variance`); with an
  `OrbitConsider`, R also gets the satellite orbit error's J P_sat J^T (`consider.py`).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import model, navfuncs, records
from leonav_runtime.inputs.consider import OrbitConsider
from leonav_runtime.inputs.imu import latest_sample
from leonav_runtime.inputs.tables import (SAT_A_MPS2, SAT_R_M, SAT_V_MPS, FixTable, ImuTable, LocalSensorTable,
                                          SatelliteTable, VelocityTable)

FIX_KINDS = tuple(o.suffix for o in model.stream_observables("fix"))
VEL_KINDS = tuple(o.suffix for o in model.stream_observables("vel"))


def tag_lead(imu: ImuTable | None, t_s: np.ndarray) -> np.ndarray:
    """Time (s, >= 0) from the latest IMU sample at or before each tag to the tag: the aux `dt_tag`
    with which a fix or velocity is placed at its tag, not at the IMU sample it is applied at
    (zeros without an IMU table: a live stream applies a fix when it arrives)."""
    t_s = np.asarray(t_s, float)
    if imu is None or not imu.t.size:
        return np.zeros(t_s.size)
    samples = np.r_[imu.t[0] - imu.dt[0], imu.t]
    k = latest_sample(imu, t_s)
    return np.clip(t_s - samples[np.clip(k, 0, samples.size - 1)], 0.0, None)


def fix_records(fixes: FixTable, nav: navfuncs.NavFunctions, imu: ImuTable | None = None) -> np.ndarray:
    """POS_E, POS_N, POS_U records of every fix (in that order at each epoch); aux `dt_tag` from
    the IMU table when given (`tag_lead`)."""
    if not fixes.t.size:
        return np.zeros(0, records.RECORD_DTYPE)
    aux = np.zeros((fixes.t.size, nav.layout.NAUX))
    aux[:, nav.layout.AUX_DT_TAG] = tag_lead(imu, fixes.t)
    parts = [records.measurement_records(fixes.t, nav.kind_id(k), fixes.p_enu_m[:, i], fixes.sigma_enu_m[:, i] ** 2,
                                         aux) for i, k in enumerate(FIX_KINDS)]
    return records.merge_records(*parts)


def velocity_records(table: VelocityTable, imu: ImuTable, f_b_avg: np.ndarray, nav: navfuncs.NavFunctions,
                     ) -> np.ndarray:
    """VEL_E, VEL_N, VEL_U records of every velocity epoch, R = sigma^2; aux carries the averaged
    specific force f_b (the latency term's acceleration) and the latest body rate w_b (the lever
    arm's rotation), both at the latest IMU sample at or before the epoch."""
    if not table.t.size:
        return np.zeros(0, records.RECORD_DTYPE)
    L = nav.layout
    k = latest_sample(imu, table.t)
    aux = np.zeros((table.t.size, L.NAUX))
    aux[:, L.AUX_F_B_SLICE] = f_b_avg[k]
    w_b = imu.w_b_radps
    aux[:, L.AUX_W_B_SLICE] = w_b[np.clip(k - 1, 0, w_b.shape[0] - 1)]
    aux[:, L.AUX_DT_TAG] = tag_lead(imu, table.t)
    parts = [records.measurement_records(table.t, nav.kind_id(kind), table.v_enu_mps[:, i], table.sigma_mps[:, i] ** 2,
                                         aux) for i, kind in enumerate(VEL_KINDS)]
    return records.merge_records(*parts)


def doppler_rate_variance(sigma, f_b_span_s: float, params: np.ndarray, nav: navfuncs.NavFunctions):
    """R (Hz^2/s^2) of Doppler-rate records of 1-sigma `sigma` (scalar or (n,)): one generated
    call per distinct sigma."""
    if np.ndim(sigma) == 0:
        return nav.doppler_rate_variance(sigma, f_b_span_s, params)
    values, inverse = np.unique(np.asarray(sigma, float), return_inverse=True)
    return nav.doppler_rate_variance(values, f_b_span_s, params)[inverse]


SAT_NAMES = ("R_S_ECEF", "V_S_ECEF", "A_S_ECEF")
REF_NAMES = ("R_REF_ECEF", "V_REF_ECEF", "A_REF_ECEF")
_BLOCKS: dict[int, tuple] = {}


def aux_blocks(layout) -> tuple[slice | None, slice | None, bool]:
    """(aux columns of the satellite's r, v, a, of the reference's, whether aux is exactly
    [satellite | reference | f_b]); a slice is None when the three blocks are not adjacent."""
    key = id(layout)
    if key not in _BLOCKS:
        def block(names):
            sl = [getattr(layout, f"AUX_{n}_SLICE") for n in names]
            ok = all(a.stop == b.start for a, b in zip(sl, sl[1:]))
            return slice(sl[0].start, sl[-1].stop) if ok else None
        sat, ref = block(SAT_NAMES), block(REF_NAMES)
        whole = (sat is not None and ref is not None and sat.start == 0 and ref.start == sat.stop
                 and layout.AUX_F_B_SLICE.start == ref.stop and layout.AUX_F_B_SLICE.stop == layout.NAUX)
        _BLOCKS[key] = (sat, ref, whole)
    return _BLOCKS[key]


def states_from_aux(aux: np.ndarray, layout) -> tuple[np.ndarray, np.ndarray]:
    """The satellite and reference state blocks (n, 9) (`SAT_*` columns) of aux rows (n, NAUX)."""
    out = []
    for names, block in zip((SAT_NAMES, REF_NAMES), aux_blocks(layout)[:2]):
        out.append(aux[:, block] if block is not None else
                   np.hstack([aux[:, getattr(layout, f"AUX_{n}_SLICE")] for n in names]))
    return out[0], out[1]


def satellite_aux(table: SatelliteTable, f_b: np.ndarray, layout) -> np.ndarray:
    """(n, NAUX) aux blocks: satellite states, reference states (zeros if none), f_b (n, 3)."""
    L = layout
    sat_block, ref_block, whole = aux_blocks(L)
    if whole and table.ref_ecef is not None:   # the generated layout [sat r v a | ref r v a | f_b]: one copy
        return np.concatenate([table.sat_ecef, table.ref_ecef, f_b], axis=1)
    aux = np.zeros((table.t.size, L.NAUX))
    for state, names, block in ((table.sat_ecef, SAT_NAMES, sat_block), (table.ref_ecef, REF_NAMES, ref_block)):
        if state is None:
            continue
        if block is not None:
            aux[:, block] = state
        else:
            for name, cols in zip(names, (SAT_R_M, SAT_V_MPS, SAT_A_MPS2)):
                aux[:, getattr(L, f"AUX_{name}_SLICE")] = state[:, cols]
    aux[:, L.AUX_F_B_SLICE] = f_b
    if table.interval_s is not None:
        aux[:, L.AUX_DT_PHASE] = table.interval_s
    if table.sat_prev_r_m is not None:
        aux[:, L.AUX_R_S_PREV_ECEF_SLICE] = table.sat_prev_r_m
    if table.tone_offset_hz is not None:
        aux[:, L.AUX_DF_TONE] = table.tone_offset_hz
    return aux


def satellite_records(table: SatelliteTable, imu: ImuTable, f_b_avg: np.ndarray, f_b_span_s: float,
                      params: np.ndarray, nav: navfuncs.NavFunctions, consider: OrbitConsider | None = None,
                      x_rx: np.ndarray | None = None, corrections=None) -> np.ndarray:
    """Records of a satellite table; f_b_avg, f_b_span_s: `averaged_specific_force` of `imu`;
    consider: the orbit error's consider term added to R (Jacobian at receiver state x_rx);
    corrections: a base's differential corrections (`corrections.DifferentialCorrections`),
    subtracted here, the one place every source's satellite measurements pass."""
    if not table.t.size:
        return np.zeros(0, records.RECORD_DTYPE)
    if corrections is not None:
        table = corrections.apply(table)
    aux = satellite_aux(table, f_b_avg[latest_sample(imu, table.t)], nav.layout)
    if model.observable(table.KIND).input_noise:   # the Doppler-rate's (models/input_noise.py)
        R = doppler_rate_variance(table.sigma, f_b_span_s, params, nav)
    else:
        R = np.asarray(table.sigma) ** 2 if np.ndim(table.sigma) else table.sigma ** 2
    extra = None if consider is None else consider.variance(table, aux, x_rx, params, nav)
    if extra is not None:
        R = R + extra
    return records.measurement_records(table.t, nav.kind_id(table.KIND), table.z, R, aux, table.sat_id)


def local_records(table: LocalSensorTable, imu: ImuTable, f_b_avg: np.ndarray | None, nav: navfuncs.NavFunctions,
                  ) -> np.ndarray:
    """Records of a local sensor table: one per row and observable of its stream, R = sigma^2;
    aux carries the averaged specific force f_b (the rest zero: a local sensor has no satellite)."""
    if not table.t.size:
        return np.zeros(0, records.RECORD_DTYPE)
    aux = np.zeros((table.t.size, nav.layout.NAUX))
    if f_b_avg is not None:
        aux[:, nav.layout.AUX_F_B_SLICE] = f_b_avg[latest_sample(imu, table.t)]
    sig = table.sigma_columns()
    parts = [records.measurement_records(table.t, nav.kind_id(o.suffix), table.z[:, i], sig[:, i] ** 2, aux)
             for i, o in enumerate(table.observables)]
    return records.merge_records(*parts)
