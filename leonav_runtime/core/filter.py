"""The error-state EKF as a Python object over the compiled generated C.

Vocabulary follows filterpy: `x` (nominal state, NX), `P` (error-state covariance,
NDX x NDX), `F`, `Q` (discrete process noise of the last predict), `y`, `S`, `nis`
(innovation, its variance, y^2/S of the last update), `x_prior`/`P_prior` (before the
last update, or after the last predict), `x_post`/`P_post` (after the last update).

Every step is one ctypes call into the same driver functions that `run()` loops over in
C, so the step-by-step and the whole-stream results agree to rounding.

Gating: a threshold on nis per observable; `gate` is None (off), a number (all
observables) or a mapping {observable name or id: threshold}; a threshold <= 0 disables.
The default is the chi-square 1-dof 99.9 % quantile, 10.83.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from typing import Mapping, Union

import numpy as np

from leonav_runtime.core import compiled, records
from leonav_runtime.gen import state_layout as _codes
from leonav_runtime.gen.constants import CHI2_1DOF_999

# Per-record statuses (RunResult.status, EKF.status; generated, docs/design.md "Records"):
# -1 IMU predicted, 0 applied, 1 gated, 2 numerical failure. The C step functions return
# the driver's return codes instead (0 success, 1 gated, 2 failed, < 0 error).
STATUS_IMU, STATUS_APPLIED = _codes.STATUS_IMU, _codes.STATUS_APPLIED
STATUS_GATED, STATUS_FAILED = _codes.STATUS_GATED, _codes.STATUS_FAILED

GateSpec = Union[None, float, Mapping[Union[str, int], float]]

_dp = ctypes.POINTER(ctypes.c_double)


def _ptr(a: np.ndarray | None):
    return None if a is None else a.ctypes.data_as(_dp)


@dataclass
class RunResult:
    """Per-record results of `EKF.run` (row i belongs to record i).

    t (s), kind, sat_id, x (n, NX), P_diag (n, NDX), P (n, NDX, NDX) or None, y, S,
    nis (NaN on predict records and where not computed), status (per-record: STATUS_IMU -1
    IMU or constant-velocity record predicted, STATUS_APPLIED 0, STATUS_GATED 1,
    STATUS_FAILED 2 numerical failure), and counts (n_cv: constant-velocity predicts).
    """

    t: np.ndarray
    kind: np.ndarray
    sat_id: np.ndarray
    x: np.ndarray
    P_diag: np.ndarray
    P: np.ndarray | None
    y: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    status: np.ndarray
    n_imu: int
    n_applied: int
    n_gated: int
    n_failed: int
    n_cv: int = 0
    orbit_states: dict | None = None   # with `run(orbit=...)`: its counts and per-satellite offsets (m)


class EKF:
    """Error-state EKF on the compiled generated C (see the module doc for names).

    x0: nominal state (NX,) with the layout of gen/state_layout.py; P0: (NDX, NDX)
    error covariance, symmetrized on entry; params: parameter vector (NP,) (LEONAV_P_* offsets).
    The steps read `P`'s upper triangle only and write it exactly symmetric; a P assigned
    later should be symmetric (`symmetrized`).
    """

    def __init__(self, x0, P0, params, gate: GateSpec = CHI2_1DOF_999,
                 library: compiled.Library | None = None) -> None:
        self.lib = library if library is not None else compiled.load()
        lay = self.lib.layout
        self.nx, self.ndx = int(lay.NX), int(lay.NDX)
        self.x = self._vector("x0", x0, self.nx)
        self.P = self._symmetric("P0", P0)
        self.params = self._vector("params", params, int(lay.NP))
        self.gate = self.gate_vector(gate)
        self._work = self.lib.new_workspace()
        self.F = np.full((self.ndx, self.ndx), np.nan, order="F")
        self.Q = np.full((self.ndx, self.ndx), np.nan, order="F")
        self.y = self.S = self.nis = float("nan")
        self.status: int | None = None
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy(order="F")
        self.x_post, self.P_post = self.x.copy(), self.P.copy(order="F")

    # -- helpers ----------------------------------------------------------------
    @staticmethod
    def _vector(name: str, v, n: int) -> np.ndarray:
        arr = np.array(v, dtype=np.float64).reshape(-1)
        if arr.size != n:
            raise ValueError(f"{name}: expected {n} values, got {arr.size}")
        return arr

    def _matrix(self, name: str, m) -> np.ndarray:
        arr = np.array(m, dtype=np.float64, order="F")  # column-major, as the C expects
        if arr.shape != (self.ndx, self.ndx):
            raise ValueError(f"{name}: expected shape ({self.ndx}, {self.ndx}), got {arr.shape}")
        return arr

    def _symmetric(self, name: str, m) -> np.ndarray:
        """(m + m^T) / 2: the generated steps read P's upper triangle only (models.ekf.upper_mirrored)
        and keep it exactly symmetric, so a caller's P enters symmetrized, as each step once did."""
        return symmetrized(self._matrix(name, m))

    def gate_vector(self, gate: GateSpec) -> np.ndarray:
        """Per-kind NIS thresholds (LEONAV_N_MEAS,) from a gate spec (<= 0 = off)."""
        n = len(self.lib.meas_ids)
        if gate is None:
            return np.zeros(n)
        if isinstance(gate, Mapping):
            vec = np.zeros(n)
            for kind, value in gate.items():
                vec[self.lib.kind_id(kind)] = float(value)
            return vec
        return np.full(n, float(gate))

    # -- steps ------------------------------------------------------------------
    def predict(self, u, dt: float) -> int:
        """Propagate over one IMU interval dt (s) with u = [dtheta_b (rad), dvel_b (m/s)].

        Returns the record status STATUS_IMU (-1, predicted) or STATUS_FAILED (2, numerical
        failure: x, P unchanged), as `run` reports the record.
        """
        u = self._vector("u", u, records.NU)
        rc = self.lib.lib.leonav_predict_step(
            _ptr(self.x), _ptr(self.P), _ptr(u), float(dt), _ptr(self.params),
            _ptr(self.F), _ptr(self.Q), self._work.ctypes.data)
        if rc < 0:
            raise RuntimeError(f"leonav_predict_step returned {compiled.code_name(rc)}")
        self.status = STATUS_IMU if rc == _codes.OK else STATUS_FAILED
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy(order="F")
        return self.status

    def predict_cv(self, dt: float) -> int:
        """Constant-velocity predict over dt (s), for a receiver without IMU (record kind
        LEONAV_KIND_CV): p += v dt, c_dt += c_ddt dt, white acceleration of PSD vrw^2.

        Returns STATUS_IMU (-1, predicted) or STATUS_FAILED (2: x, P unchanged).
        """
        rc = self.lib.lib.leonav_predict_cv_step(
            _ptr(self.x), _ptr(self.P), float(dt), _ptr(self.params), _ptr(self.F), _ptr(self.Q),
            self._work.ctypes.data)
        if rc < 0:
            raise RuntimeError(f"leonav_predict_cv_step returned {compiled.code_name(rc)}")
        self.status = STATUS_IMU if rc == _codes.OK else STATUS_FAILED
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy(order="F")
        return self.status

    def update(self, kind: int | str, z: float, R: float, aux=None) -> bool:
        """Scalar update with observable `kind`; returns True when applied.

        z in the observable's unit, R its variance, aux (NAUX,) (zeros if None).
        After the call: y, S, nis, status (record status: 0 applied, 1 gated, 2 failure), x_prior/P_prior
        (before), x_post/P_post (after; equal to the prior when not applied).
        """
        k = self.lib.kind_id(kind)
        aux_v = np.zeros(records.NAUX) if aux is None else self._vector("aux", aux, records.NAUX)
        ysn = np.full(3, np.nan)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy(order="F")
        rc = self.lib.lib.leonav_update_step(
            _ptr(self.x), _ptr(self.P), k, float(z), float(R), _ptr(aux_v), _ptr(self.params),
            float(self.gate[k]), _ptr(ysn), self._work.ctypes.data)
        if rc < 0:
            raise RuntimeError(f"leonav_update_step returned {compiled.code_name(rc)}")
        self.y, self.S, self.nis = (float(v) for v in ysn)
        self.status = {_codes.OK: STATUS_APPLIED, _codes.GATED: STATUS_GATED}.get(int(rc), STATUS_FAILED)
        self.x_post, self.P_post = self.x.copy(), self.P.copy(order="F")
        return self.status == STATUS_APPLIED

    def h(self, kind: int | str, aux=None, x=None) -> tuple[float, np.ndarray]:
        """Predicted measurement h and its Jacobian H (NDX,) w.r.t. the error state."""
        k = self.lib.kind_id(kind)
        aux_v = np.zeros(records.NAUX) if aux is None else self._vector("aux", aux, records.NAUX)
        x_v = self.x if x is None else self._vector("x", x, self.nx)
        h, H = np.zeros(1), np.zeros(self.ndx)
        rc = self.lib.lib.leonav_h_step(k, _ptr(x_v), _ptr(aux_v), _ptr(self.params), _ptr(h), _ptr(H),
                                        self._work.ctypes.data)
        if rc != _codes.OK:
            raise RuntimeError(f"leonav_h_step returned {compiled.code_name(rc)}")
        return float(h[0]), H

    # -- whole streams ----------------------------------------------------------
    def run(self, recs: np.ndarray, gate: GateSpec | str = "filter", full_P: bool = False,
            P_rows: np.ndarray | None = None, orbit=None, covariance_interval_s: float = 0.0,
            P_lead: int = 0) -> RunResult:
        """Run a time-ordered RECORD_DTYPE stream in the C loop; x and P end at its end.

        gate: "filter" uses this filter's gate, else a gate spec (see module doc).
        full_P: also return P after every record (n * NDX^2 doubles).
        P_rows: record indices (increasing) after which to return P instead; `RunResult.P`
        then has one block per index, in that order.
        P_lead: with full_P or P_rows, return only the leading P_lead x P_lead block of each P
        (`state_layout.NNAV`: the 9D navigation error's); 0 returns P whole.
        orbit: an `orbit_states.OrbitStates`: its satellites' orbit offsets are estimated beside
        the state (`leonav_run_orbit`, ephemeris method 1) and left in it; P stays NDX x NDX.
        covariance_interval_s: 0 propagates P at every IMU record; > 0 mechanizes x at every
        IMU record and propagates P once per run of IMU records, over their summed increments; a
        run ends where its summed dt reaches this (s), before every other record and at every
        P_rows record (leonav_driver.h, docs/design.md "Covariance interval"), and `P_diag` is
        NaN inside a run; a run whose covariance step fails fails whole (each of its records a
        failed predict, x back at the run's first state).
        """
        interval = float(covariance_interval_s)
        if not (math.isfinite(interval) and interval >= 0.0):
            raise ValueError(f"covariance_interval_s = {covariance_interval_s!r}: expected a finite number of "
                             "seconds >= 0 (0: the covariance at every IMU record)")
        if interval > 0.0 and orbit is not None:
            raise ValueError("covariance_interval_s > 0 with orbit states: leonav_run_orbit propagates the "
                             "covariance at every IMU record; use covariance_interval_s = 0")
        if isinstance(P_lead, bool) or not isinstance(P_lead, (int, np.integer)) or not 0 <= P_lead <= self.ndx:
            raise ValueError(f"P_lead = {P_lead!r}: expected a whole number in [0, {self.ndx}] (0: P whole)")
        m = int(P_lead) or self.ndx
        recs = np.ascontiguousarray(recs)
        records.check_records(recs, len(self.lib.meas_ids))
        n = recs.size
        gates = self.gate if isinstance(gate, str) and gate == "filter" else self.gate_vector(gate)
        gates = np.ascontiguousarray(gates, dtype=np.float64)
        x_hist = np.empty((n, self.nx))
        pd_hist = np.empty((n, self.ndx))
        mask = None
        if P_rows is not None:
            rows = np.asarray(P_rows, dtype=np.int64)
            if rows.size and (np.any(np.diff(rows) <= 0) or rows[0] < 0 or rows[-1] >= n):
                raise ValueError(f"P_rows: expected increasing record indices in [0, {n})")
            mask = np.zeros(n, dtype=np.uint8)
            mask[rows] = 1
            p_hist = np.empty((rows.size, m, m))
        else:
            p_hist = np.empty((n, m, m)) if full_P else None
        y, S, nis = np.empty(n), np.empty(n), np.empty(n)
        status = np.empty(n, dtype=np.int32)
        out = compiled.RunOut(
            x=_ptr(x_hist), P_diag=_ptr(pd_hist), P=_ptr(p_hist),
            P_mask=None if mask is None else mask.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8)),
            y=_ptr(y), S=_ptr(S), nis=_ptr(nis),
            status=status.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), P_lead=int(P_lead))
        if orbit is None:
            rc = self.lib.lib.leonav_run(_ptr(self.x), _ptr(self.P), _ptr(self.params), recs.ctypes.data, n,
                                         _ptr(gates), interval, ctypes.byref(out), self._work.ctypes.data)
        else:
            rc = self.lib.lib.leonav_run_orbit(_ptr(self.x), _ptr(self.P), _ptr(self.params), recs.ctypes.data, n,
                                               _ptr(gates), ctypes.byref(orbit.c), ctypes.byref(out),
                                               self._work.ctypes.data)
        if rc != _codes.OK:
            name = "leonav_run" if orbit is None else "leonav_run_orbit"
            raise RuntimeError(f"{name} returned {compiled.code_name(rc)} at record {out.n_done}")
        if p_hist is not None:
            p_hist = p_hist.transpose(0, 2, 1)  # each block was written column-major
        return RunResult(recs["t"].copy(), recs["kind"].copy(), recs["sat_id"].copy(), x_hist, pd_hist, p_hist,
                         y, S, nis, status, int(out.n_imu), int(out.n_applied), int(out.n_gated),
                         int(out.n_failed), int(out.n_cv), None if orbit is None else orbit.summary())


@dataclass
class PcrbResult:
    """PCRB history: B_diag (n, NDX), B_nav (n, NNAV, NNAV) block of dp dv dtheta (the 9D), B final."""

    t: np.ndarray
    B_diag: np.ndarray
    B_nav: np.ndarray
    B: np.ndarray


def pcrb(recs: np.ndarray, x_lin: np.ndarray, B0, params, library: compiled.Library | None = None) -> PcrbResult:
    """Posterior Cramer-Rao bound along a true trajectory (see leonav_pcrb_run).

    x_lin (n, NX): per record, the true state where it is linearised: the start of the
    interval (t - dt) for an IMU record, the time t for a measurement. B0: prior
    covariance (NDX, NDX). Measurement R must be > 0.
    """
    lib = library if library is not None else compiled.load()
    ndx, nx, nnav = int(lib.layout.NDX), int(lib.layout.NX), int(lib.layout.NNAV)
    recs = np.ascontiguousarray(recs)
    records.check_records(recs, len(lib.meas_ids))
    n = recs.size
    x_lin = np.ascontiguousarray(x_lin, dtype=np.float64)
    if x_lin.shape != (n, nx):
        raise ValueError(f"x_lin: expected shape ({n}, {nx}), got {x_lin.shape}")
    B = np.array(B0, dtype=np.float64, order="F")
    if B.shape != (ndx, ndx):
        raise ValueError(f"B0: expected shape ({ndx}, {ndx}), got {B.shape}")
    p = np.ascontiguousarray(params, dtype=np.float64)
    B_diag, B_nav = np.empty((n, ndx)), np.empty((n, nnav, nnav))
    done = ctypes.c_long(0)
    work = lib.new_workspace()
    rc = lib.lib.leonav_pcrb_run(_ptr(B), _ptr(p), recs.ctypes.data, n, _ptr(x_lin), _ptr(B_diag), _ptr(B_nav),
                                 None, ctypes.byref(done), work.ctypes.data)
    if rc != _codes.OK:
        raise RuntimeError(f"leonav_pcrb_run returned {compiled.code_name(rc)} at record {done.value}")
    return PcrbResult(recs["t"].copy(), B_diag, B_nav.transpose(0, 2, 1), B)


def symmetrized(M: np.ndarray) -> np.ndarray:
    """(M + M^T) / 2, column-major (the C's order); an exactly symmetric M comes back unchanged."""
    return np.asfortranarray((M + M.T) / 2)


def stationary_imu(x, dt: float, params, library: compiled.Library | None = None) -> np.ndarray:
    """IMU increments u (6,) that keep the nominal state x at rest over an interval dt (s).

    Solved on the generated mechanization itself (`NavFunctions.imu_increments` towards x:
    velocity change and body-frame attitude change both zero), so a simulated static
    receiver is exactly static for the filter's model (gravity, Earth rate, Coriolis).
    """
    from leonav_runtime.core.navfuncs import NavFunctions

    nav = NavFunctions(params=np.asarray(params, dtype=np.float64), library=library)
    x = np.asarray(x, dtype=np.float64)
    u, _ = nav.imu_increments(x, x, float(dt), tol=1e-16)
    return u
