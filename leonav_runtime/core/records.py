"""Time-ordered record streams for the C filter loop.

`RECORD_DTYPE` is the NumPy twin of the C struct `leonav_record` (csrc/leonav_driver.h):
`t` (s since the scenario epoch), `kind` (-1 IMU, -2 constant-velocity predict, else a
LEONAV_MEAS_* id), `sat_id` (-1 if none), `z` (unit of the observable), `R` (unit^2), `dt`
(s, IMU or constant-velocity interval),
`u` (dtheta_b rad x3, dvel_b m/s x3, body FLU), `aux` (NAUX, see docs/design.md).

An IMU record at `t` carries the increments integrated over `(t - dt, t]`; a
constant-velocity (CV) record at `t` predicts a receiver without IMU over `(t - dt, t]`.

Tie rule of `merge_records`: at equal `t`, predict records (IMU, CV) come before
measurements (the predict brings the state to `t`, where the measurement is then applied);
records of the same class keep their input order (arrays in argument order, then index).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core.compiled import GEN_DIR, load_layout

_LAYOUT = load_layout(GEN_DIR)  # the generated layout the library is built from
KIND_IMU = int(_LAYOUT.MEAS_IMU)  # record kind of an IMU interval (LEONAV_MEAS_IMU)
KIND_CV = int(_LAYOUT.KIND_CV)  # record kind of a constant-velocity predict (LEONAV_KIND_CV)
NU = int(_LAYOUT.NU)
NAUX = int(_LAYOUT.NAUX)


def record_dtype(naux: int) -> np.dtype:
    """Record dtype for an aux block of `naux` doubles (aligned like the C struct)."""
    return np.dtype(
        [("t", "<f8"), ("kind", "<i4"), ("sat_id", "<i4"), ("z", "<f8"), ("R", "<f8"),
         ("dt", "<f8"), ("u", "<f8", (NU,)), ("aux", "<f8", (naux,))],
        align=True,
    )


RECORD_DTYPE = record_dtype(NAUX)


def _column(name: str, values, n: int, dtype) -> np.ndarray:
    arr = np.asarray(values, dtype=dtype)
    if arr.ndim == 0:
        return np.full(n, arr, dtype=dtype)
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got shape {arr.shape}")
    return arr


def imu_records(t_s, dtheta_b, dvel_b, dt_s=None) -> np.ndarray:
    """IMU records from increments.

    t_s (N,) s: end of each integration interval. dtheta_b (N, 3) rad and dvel_b (N, 3)
    m/s: body-frame (FLU) angle and velocity increments over the interval. dt_s: interval
    lengths (N,) s; default `diff(t_s)` with the first interval taken equal to the second.
    """
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    n = t.size
    dtheta = np.asarray(dtheta_b, dtype=np.float64)
    dvel = np.asarray(dvel_b, dtype=np.float64)
    for name, arr, size in (("dtheta_b", dtheta, _LAYOUT.U_DTHETA_B_SIZE), ("dvel_b", dvel, _LAYOUT.U_DVEL_B_SIZE)):
        if arr.shape != (n, size):
            raise ValueError(f"{name}: expected shape ({n}, {size}) to match t_s, got {arr.shape}")
    if dt_s is None:
        if n < 2:
            raise ValueError("imu_records: give dt_s when there are fewer than 2 samples")
        dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    else:
        dt = _column("dt_s", dt_s, n, np.float64)
    rec = np.zeros(n, dtype=RECORD_DTYPE)
    rec["t"], rec["kind"], rec["sat_id"], rec["dt"] = t, KIND_IMU, -1, dt
    rec["z"], rec["R"] = np.nan, np.nan
    rec["u"][:, _LAYOUT.U_DTHETA_B_SLICE], rec["u"][:, _LAYOUT.U_DVEL_B_SLICE] = dtheta, dvel
    return rec


def cv_records(t_s, dt_s) -> np.ndarray:
    """Constant-velocity predict records (a receiver without IMU): each brings the state from
    t - dt to t (s). t_s (N,), dt_s scalar or (N,) (s, >= 0)."""
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    rec = np.zeros(t.size, dtype=RECORD_DTYPE)
    rec["t"], rec["kind"], rec["sat_id"] = t, KIND_CV, -1
    rec["dt"] = _column("dt_s", dt_s, t.size, np.float64)
    rec["z"], rec["R"] = np.nan, np.nan
    return rec


def measurement_records(t_s, kind: int, z, R, aux=None, sat_id=-1) -> np.ndarray:
    """Measurement records of one observable `kind` (a LEONAV_MEAS_* id).

    t_s (N,) s; z (N,) in the observable's unit; R variance (scalar or (N,)); aux
    (NAUX,) or (N, NAUX), zeros if None; sat_id scalar or (N,).
    """
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    n = t.size
    rec = np.zeros(n, dtype=RECORD_DTYPE)
    rec["t"] = t
    rec["kind"] = int(kind)
    if int(kind) < 0:
        raise ValueError(f"kind: expected a LEONAV_MEAS_* id >= 0, got {kind}")
    rec["z"] = _column("z", z, n, np.float64)
    rec["R"] = _column("R", R, n, np.float64)
    rec["sat_id"] = _column("sat_id", sat_id, n, np.int32)
    if aux is not None:
        a = np.asarray(aux, dtype=np.float64)
        if a.shape not in ((NAUX,), (n, NAUX)):
            raise ValueError(f"aux: expected shape ({NAUX},) or ({n}, {NAUX}), got {a.shape}")
        rec["aux"] = a
    rec["dt"] = 0.0
    return rec


def merge_records(*arrays: np.ndarray) -> np.ndarray:
    """One time-ordered stream from several record arrays (tie rule in the module doc)."""
    for i, a in enumerate(arrays):
        if a.dtype != RECORD_DTYPE:
            raise ValueError(f"merge_records: argument {i} has dtype {a.dtype}, expected RECORD_DTYPE")
    if not arrays:
        return np.zeros(0, dtype=RECORD_DTYPE)
    rec = np.concatenate(arrays)
    order = np.argsort(rec["kind"] >= 0, kind="stable")          # IMU / CV predicts first ...
    order = order[np.argsort(rec["t"][order], kind="stable")]     # ... within equal t
    return rec[order]


def check_records(rec: np.ndarray, n_meas: int) -> None:
    """Raise ValueError naming the first bad record (dtype, kind, time order)."""
    if rec.dtype != RECORD_DTYPE:
        raise ValueError(f"records: dtype {rec.dtype}, expected RECORD_DTYPE")
    kinds = rec["kind"]
    bad = np.flatnonzero((kinds < KIND_CV) | (kinds >= n_meas))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"record {i}: kind {int(kinds[i])}, expected -1 (IMU), -2 (CV) or 0..{n_meas - 1}")
    t = rec["t"]
    if not np.all(np.isfinite(t)):
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"record {i}: t is not finite")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise ValueError(f"record {i}: t={float(t[i])!r} s is earlier than the previous record; merge_records() orders a stream")

