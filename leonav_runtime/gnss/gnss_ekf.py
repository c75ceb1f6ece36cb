"""GNSS-only EKF for receivers without an IMU: the one generated filter, fed differently.

The state layout, the scalar Joseph update of `GNSS_PSEUDORANGE` (and `GNSS_RANGE_RATE`
when the receiver gives Doppler) and the C loop are those of the IMU filter. Between epochs
a constant-velocity record (kind LEONAV_KIND_CV, generated `leonav_predict_cv`) replaces the
IMU predict: p += v dt with white acceleration of PSD q_acc (m^2/s^3, passed as the
parameter vrw = sqrt(q_acc)), the two-state clock random walk (q_cdt, q_cddt), inter-system
biases constant. Attitude and IMU biases stay in the state with zero covariance and no
process noise, untouched (nothing observes them and the CV model does not read them).

Records per epoch k: CV(t_k, dt = t_k - t_{k-1}) for k > 0, then one pseudorange record per
satellite that the single-point solution kept above the masks (its variance from the same
error model, at the single-point elevation), then the range rates. RAIM-excluded satellites
are given to the filter too: its NIS gate (chi-square 1 dof, 99.9 %) decides. Initial state:
the first single-point solution (position, clock, inter-system biases), zero velocity, clock
drift from the first two single-point clocks.

Why one filter and not a second, smaller one: a second generated filter would duplicate the
update code and the driver, and drift from the IMU filter the first time either changes; a
record kind costs one generated function and a branch in the driver, and the same filter
runs with or without IMU (an IMU record and a CV record are both "predict to t").
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from leonav_runtime.core import records
from leonav_runtime.orbits import geometry
from leonav_runtime.core.filter import EKF, STATUS_APPLIED, STATUS_GATED, RunResult
from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gen.profiles import ClockProfile, ImuProfile
from leonav_runtime.gnss.signals import EPOCH_UNSOLVED, RAIM_EXCLUDED, filter_pseudorange_variance
from leonav_runtime.gnss.spp import NOT_CONVERGED, SppResult
from leonav_runtime.inputs.gnss_obs import nearest_finite
from leonav_runtime.core.navfuncs import NavFunctions
from leonav_runtime.core.params import params_array

DEFAULT_Q_ACC_M2PS3 = 1e-10
"""m^2/s^3: white-acceleration PSD of a static receiver (velocity sigma grows 0.6 mm/s per hour; a car: ~1)."""
DEFAULT_Q_CDT_M2PS = 1e4
"""m^2/s: clock white-frequency PSD (loose: the receiver clock is re-estimated every epoch)."""
DEFAULT_Q_CDDT_M2PS3 = 1.0
"""m^2/s^3: clock random-walk-frequency PSD (drift changes of receiver TCXOs)."""
P0_POSITION_M, P0_VELOCITY_MPS, P0_CLOCK_M, P0_DRIFT_MPS, P0_ISB_M = 30.0, 0.01, 1e3, 100.0, 100.0


@dataclass
class EkfSolution:
    """Per epoch (E,) of the single-point result it was started from: t_gps_s, r_ecef_m,
    cov_enu_m2 (E, 3, 3) (origin ENU axes), clock_m, ns (pseudoranges applied), gated; and
    the raw RunResult of the C loop, the records, x0, P0, params."""

    t_gps_s: np.ndarray
    r_ecef_m: np.ndarray
    v_enu_mps: np.ndarray
    cov_enu_m2: np.ndarray
    clock_m: np.ndarray
    ns: np.ndarray
    gated: np.ndarray
    run: RunResult
    records: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    params: np.ndarray


MS_M = K.C_LIGHT_MPS * 1e-3
"""One millisecond of receiver clock as range (m)."""
CLOCK_JUMP_TOLERANCE_M = 1000.0
"""A clock change is a jump of whole milliseconds when it is within this of one (m)."""


def clock_jumps_m(spp: SppResult) -> np.ndarray:
    """Receiver clock steps of whole milliseconds accumulated up to each epoch (E,) (m).

    Receivers that keep their clock within +-1 ms (u-blox without clock steering, many
    geodetic receivers) jump by 1 ms = 299.79 km at once; a filter with a loose clock model
    would gate every satellite after it, and never recover. Between consecutive solved
    single-point epochs the clock change less the drift of the interval before is a jump
    when it lies within CLOCK_JUMP_TOLERANCE_M of a non-zero number of milliseconds (the drift
    before the first pair from `start_drift_mps`); the filters subtract the accumulated jumps from the pseudoranges (and the clock start), so
    their clock runs on continuously. Unsolved epochs take the value of the solved one before."""
    E = spp.t_gps_s.size
    out = np.zeros(E)
    ok = np.flatnonzero(spp.solved)
    jump, drift = 0.0, start_drift_mps(spp.t_gps_s[ok], spp.clock_m[ok])
    for a, b in zip(ok[:-1], ok[1:]):
        dt = spp.t_gps_s[b] - spp.t_gps_s[a]
        r = spp.clock_m[b] - jump - (spp.clock_m[a] - out[a]) - drift * dt
        k = round(r / MS_M)
        if k and abs(r - k * MS_M) < CLOCK_JUMP_TOLERANCE_M:
            jump += k * MS_M
        out[a + 1:b] = out[a]   # unsolved epochs of a gap: the step is placed at the next solved one
        out[b] = jump
        if dt > 0:
            drift = (spp.clock_m[b] - jump - (spp.clock_m[a] - out[a])) / dt
    if ok.size:
        out[ok[-1]:] = jump
    return out


def start_drift_mps(t_s: np.ndarray, clock_m: np.ndarray) -> float:
    """Receiver clock drift (m/s) to test the first pair of solved epochs with: the median over
    all pairs of the clock change less its whole milliseconds, per second. With 0 instead, a
    jump between the first two solutions of a drifting clock was missed (GEONET 0759 drifts
    418 m/s: 12.5 km in 30 s, beyond the tolerance) and a step of the opposite sign put at the
    next pair, leaving the jump in the pseudoranges."""
    if t_s.size < 2:
        return 0.0
    dt, dc = np.diff(t_s), np.diff(clock_m)
    frac = dc - np.round(dc / MS_M) * MS_M
    good = (dt > 0) & np.isfinite(frac)
    return float(np.median(frac[good] / dt[good])) if good.any() else 0.0


def filter_rows(spp: SppResult) -> np.ndarray:
    """Rows of a single-point result that a filter is given: above the masks at the single-point
    state with a variance, used or RAIM-excluded or of an unsolved but converged epoch (the
    filter's NIS gate decides on them).

    Rows of those statuses that a filter cannot take (a pseudorange that is not a positive
    number, a non-finite elevation, ionosphere delay or satellite state) are left out here,
    so one bad row cannot stop a run (`inputs.GnssObservationTable.check` would refuse it),
    and counted in `spp.counts["unfit_for_filter"]`."""
    candidate = (spp.epoch_index >= 0) & np.isin(spp.row_status, (0, RAIM_EXCLUDED, EPOCH_UNSOLVED))
    # a non-converged epoch's elevations (hence masks and variances) are of a meaningless state
    candidate &= spp.status[np.maximum(spp.epoch_index, 0)] != NOT_CONVERGED
    rows = spp.rows
    with np.errstate(invalid="ignore"):
        fit = (np.isfinite(spp.sigma_m) & np.isfinite(spp.el_rad) & np.isfinite(spp.iono_m)
               & (rows.pseudorange_m > 0.0) & np.isfinite(rows.pseudorange_m) & np.all(np.isfinite(rows.aux), axis=1))
    keep = candidate & fit & (spp.el_rad >= 0.0)   # below-mask rows already carry their own status
    unfit = int((candidate & ~fit).sum())
    if unfit:
        spp.counts["unfit_for_filter"] = unfit
    return np.flatnonzero(keep)


ERROR_MODELS = ("filter", "snapshot")
"""R of the pseudoranges: "filter" (`signals.filter_pseudorange_variance`, the default) or
"snapshot" (the single-point solution's RTKLIB model with URA and code bias, for comparison)."""


def filter_sigma_m(spp: SppResult, idx: np.ndarray, error_model: str = "filter") -> np.ndarray:
    """1-sigma (m) of the pseudorange rows `idx` in a filter (`ERROR_MODELS`), at the
    single-point elevation and ionosphere delay."""
    if error_model == "snapshot":
        return spp.sigma_m[idx].copy()
    if error_model != "filter":
        raise ValueError(f"error_model {error_model!r}: expected one of {ERROR_MODELS}")
    rows = spp.rows
    return np.sqrt(filter_pseudorange_variance(spp.el_rad[idx], spp.iono_m[idx], rows.iono_on, rows.tropo_on))


def build_records(spp: SppResult, *, use_range_rate: bool = True,
                  error_model: str = "filter") -> tuple[np.ndarray, np.ndarray]:
    """(records, epoch index per record) of the GNSS-only run; times in s since the first epoch."""
    rows = spp.rows
    t0 = spp.t_gps_s[0]
    idx = filter_rows(spp)
    kind_pr = L.MEAS_GNSS_PSEUDORANGE
    parts, epochs = [], []
    t_ep = spp.t_gps_s - t0
    cv = records.cv_records(t_ep[1:], np.diff(t_ep))
    parts.append(cv)
    epochs.append(np.arange(1, t_ep.size))
    jumps = clock_jumps_m(spp)
    pr = records.measurement_records(rows.t_gps_s[idx] - t0, kind_pr,
                                     rows.pseudorange_m[idx] - jumps[spp.epoch_index[idx]],
                                     filter_sigma_m(spp, idx, error_model) ** 2,
                                     rows.aux[idx], sat_id=sat_ids(rows, idx))
    parts.append(pr)
    epochs.append(spp.epoch_index[idx])
    if use_range_rate:
        rr = idx[np.isfinite(rows.range_rate_mps[idx])]
        if rr.size:
            parts.append(records.measurement_records(rows.t_gps_s[rr] - t0, L.MEAS_GNSS_RANGE_RATE,
                                                     rows.range_rate_mps[rr], K.RANGE_RATE_SIGMA_MPS**2,
                                                     rows.aux[rr], sat_id=sat_ids(rows, rr)))
            epochs.append(spp.epoch_index[rr])
    recs = np.concatenate(parts)
    ep = np.concatenate(epochs)
    order = np.argsort(recs["kind"] >= 0, kind="stable")
    order = order[np.argsort(recs["t"][order], kind="stable")]
    return recs[order], ep[order]


def sat_ids(rows, idx) -> np.ndarray:
    """sat_id of a record: ord(system letter) * 1000 + PRN (e.g. G07 -> 71007)."""
    return np.array([ord(s) * 1000 + int(p) for s, p in zip(rows.system[idx], rows.prn[idx])], dtype=np.int32)


def run(spp: SppResult, *, q_acc_m2ps3: float = DEFAULT_Q_ACC_M2PS3, q_cdt_m2ps: float = DEFAULT_Q_CDT_M2PS,
        q_cddt_m2ps3: float = DEFAULT_Q_CDDT_M2PS3, gate: float = K.CHI2_1DOF_999,
        nav: NavFunctions | None = None, error_model: str = "filter") -> EkfSolution:
    """GNSS-only EKF over the epochs of a single-point result (see the module doc)."""
    ok = np.flatnonzero(spp.solved)
    if ok.size == 0:
        raise ValueError("no single-point solution to start the GNSS-only EKF from")
    nav = nav or NavFunctions()
    e0 = int(ok[0])
    lat0, lon0, h0 = (float(v) for v in geometry.ecef_to_geodetic(spp.r_ecef_m[e0]))
    imu = ImuProfile("constant-velocity", math.sqrt(q_acc_m2ps3), 0.0, 0.0, 0.0, 0.0, 0.0,
                     "GNSS-only: vrw is the white-acceleration PSD of the constant-velocity model")
    clock = ClockProfile("gnss-only", q_cdt_m2ps, q_cddt_m2ps3, "GNSS-only EKF defaults (gnss_ekf.py)")
    p = params_array(lat0, lon0, h0, imu=imu, clock=clock)
    x0 = np.zeros(L.NX)
    x0[L.X_Q_NB] = 1.0
    clock = spp.clock_m - clock_jumps_m(spp)
    x0[L.X_C_DT] = clock[e0]
    if ok.size > 1:
        e1 = int(ok[1])
        x0[L.X_C_DDT] = (clock[e1] - clock[e0]) / (spp.t_gps_s[e1] - spp.t_gps_s[e0])
    x0[L.X_ISB_SLICE] = nearest_finite(spp.t_gps_s[ok], spp.isb_m[ok], spp.t_gps_s[e0])
    sd = np.zeros(L.NDX)
    sd[L.DX_DP_SLICE] = P0_POSITION_M
    sd[L.DX_DV_SLICE] = P0_VELOCITY_MPS
    sd[L.DX_DC_DT], sd[L.DX_DC_DDT] = P0_CLOCK_M, P0_DRIFT_MPS
    sd[L.DX_DISB_SLICE] = P0_ISB_M  # an inter-system bias first seen later needs room too
    P0 = np.diag(sd**2)
    recs, ep = build_records(spp, error_model=error_model)
    # records before the first solved epoch are dropped (nothing to start from there)
    first_t = spp.t_gps_s[e0] - spp.t_gps_s[0]
    recs, ep = recs[recs["t"] >= first_t], ep[recs["t"] >= first_t]
    if recs.size and recs["kind"][0] == records.KIND_CV:
        recs, ep = recs[1:], ep[1:]
    ekf = EKF(x0, P0, p, gate={"gnss_pseudorange": gate, "gnss_range_rate": gate}, library=nav.library)
    res = ekf.run(recs)
    E = spp.t_gps_s.size
    last = np.full(E, -1)
    last[ep] = np.arange(ep.size)  # ep is non-decreasing: the last record of each epoch wins
    have = last >= 0
    r = np.full((E, 3), np.nan)
    v = np.full((E, 3), np.nan)
    cov = np.full((E, 3, 3), np.nan)
    clk = np.full(E, np.nan)
    ns = np.zeros(E, int)
    gated = np.zeros(E, int)
    is_pr = recs["kind"] == L.MEAS_GNSS_PSEUDORANGE
    np.add.at(ns, ep[is_pr & (res.status == STATUS_APPLIED)], 1)
    np.add.at(gated, ep[is_pr & (res.status == STATUS_GATED)], 1)
    for e in np.flatnonzero(have):
        x = res.x[last[e]]
        r[e] = nav.receiver_ecef(x, p)[0]
        v[e] = x[L.X_V_ENU_SLICE]
        cov[e] = np.diag(res.P_diag[last[e], L.DX_DP_SLICE])
        clk[e] = x[L.X_C_DT]
    return EkfSolution(spp.t_gps_s, r, v, cov, clk, ns, gated, res, recs, x0, P0, p)


def scatter_rms_m(r_ecef_m: np.ndarray) -> float:
    """RMS of the 3-D distances of the positions (n, 3) from their mean (m)."""
    r = r_ecef_m[np.all(np.isfinite(r_ecef_m), axis=1)]
    return float(np.sqrt(np.mean(np.sum((r - r.mean(axis=0)) ** 2, axis=1)))) if len(r) else math.nan
