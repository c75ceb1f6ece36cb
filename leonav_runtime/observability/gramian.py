"""Information (observability Gramian) along a record stream, its analysis, scenario runs and
the PCRB agreement (see the package docstring)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType
from typing import Mapping, Sequence

import numpy as np

from leonav_runtime.core import compiled, navfuncs, records
from leonav_runtime.core import filter as lfilter
from leonav_runtime.observability.naming import *  # noqa: F401,F403
from leonav_runtime.observability.naming import REL_TOL, VAGUE, Naming, name_subspace, name_vector

# --- accumulation ----------------------------------------------------------------------------

@dataclass
class Accumulated:
    """Square-root information along a record stream, sampled at output times.

    t_s (n,); R (n, NDX, NDX) upper-triangular with R^T R = W (Gramian of the initial error);
    Phi (n, NDX, NDX) transition from the stream's start; n_meas (n,) measurements used so far.
    """

    t_s: np.ndarray
    R: np.ndarray
    Phi: np.ndarray
    n_meas: np.ndarray


def accumulate(recs: np.ndarray, x_lin: np.ndarray, params: np.ndarray, t_out: np.ndarray | None = None,
               library: compiled.Library | None = None) -> Accumulated:
    """Accumulate Phi and the square-root Gramian along `recs` (RECORD_DTYPE, time-ordered).

    x_lin (n, NX): linearisation state per record (IMU record: start of its interval;
    measurement: its time). t_out: output times (s, increasing; default: every distinct record
    time that ends a measurement epoch, plus the end); the state after every record with
    t <= t_out[j] is stored. Measurements with R <= 0 or non-finite inputs are skipped.
    """
    lib = library if library is not None else compiled.load()
    L = lib.layout
    ndx = int(L.NDX)
    recs = np.ascontiguousarray(recs)
    records.check_records(recs, len(lib.meas_ids))
    x_lin = np.asarray(x_lin, dtype=np.float64)
    if x_lin.shape != (recs.size, int(L.NX)):
        raise ValueError(f"x_lin: expected shape ({recs.size}, {int(L.NX)}), got {x_lin.shape}")
    params = np.asarray(params, dtype=np.float64)
    if t_out is None:
        meas_t = recs["t"][recs["kind"] >= 0]
        t_out = np.unique(np.r_[meas_t, recs["t"][-1:]]) if recs.size else np.zeros(0)
    t_out = np.asarray(t_out, dtype=np.float64)
    predict = navfuncs.GeneratedFunction(lib.lib, "leonav_predict")
    h_fn = {kid: navfuncs.GeneratedFunction(lib.lib, f"leonav_h_{name}") for name, kid in lib.meas_ids.items()}
    P_dummy = np.zeros((ndx, ndx))
    Phi = np.eye(ndx)
    R = np.zeros((ndx, ndx))
    rows: list[np.ndarray] = []
    n_meas = 0
    out_R, out_Phi, out_n = [], [], []
    j = 0

    def flush():
        nonlocal R
        if rows:
            R = np.linalg.qr(np.vstack([R, *rows]), mode="r")[:ndx]
            rows.clear()

    def emit_until(t):
        nonlocal j
        while j < t_out.size and t_out[j] < t:
            flush()
            out_R.append(R.copy())
            out_Phi.append(Phi.copy())
            out_n.append(n_meas)
            j += 1

    for i, rec in enumerate(recs):
        emit_until(rec["t"] - 1e-12)
        kind = int(rec["kind"])
        if kind < 0:
            if not (np.all(np.isfinite(rec["u"])) and rec["dt"] >= 0):
                continue
            flush()
            F = predict(x_lin[i], P_dummy, rec["u"], float(rec["dt"]), params)[2]
            Phi = F @ Phi
        else:
            var = float(rec["R"])
            if not (var > 0 and math.isfinite(var) and np.all(np.isfinite(rec["aux"]))):
                continue
            H = h_fn[kind](x_lin[i], rec["aux"], params)[1][0]
            rows.append((H @ Phi / math.sqrt(var))[None, :])
            n_meas += 1
    emit_until(math.inf)
    shape = (len(out_R), ndx, ndx)
    return Accumulated(t_out[: len(out_R)], np.array(out_R).reshape(shape), np.array(out_Phi).reshape(shape),
                       np.array(out_n, dtype=int))


# --- analysis -------------------------------------------------------------------------------

def _sigma_info(Vt: np.ndarray, sv: np.ndarray, vague: float) -> np.ndarray:
    """Per-component sigma (scaled units) from the SVD of A with a vague prior of `vague` units."""
    return np.sqrt(np.sum(Vt**2 / (sv[:, None] ** 2 + vague**-2), axis=0))


def analyze_information(acc: Accumulated, scales: np.ndarray, names: Sequence[str], units: Sequence[str] | None = None,
                        targets: np.ndarray | None = None, n_weakest: int = 3, rel_tol: float = REL_TOL,
                        vague: float = VAGUE, labels: Sequence[str] | None = None) -> dict:
    """Eigen-analysis of the current-state information along the run.

    scales (NDX,): unit of each component (e.g. prior sigmas); targets (NDX,): target sigma in
    physical units for `time_to_target_s` (default: the scales). Returns a dict of arrays over
    the output times (keys with units in their names): t_s, singular_values (n, NDX) of
    A = R Phi^-1 S descending (sqrt of the scaled information; 1 = the information of one
    unit), rank, condition (inf when rank-deficient), condition_observable (over the counted
    ones), sigma_info (n, NDX) physical units, index (n, NDX) 1 - posterior / prior variance
    with prior S^2, time_to_target_s per component (inf when never reached), and weakest_final:
    at the final time every unobservable direction and the `n_weakest` weakest observable ones,
    named (with `labels` when given) and with their information in units of S^-2.
    """
    # a component without a prior (sigma 0: a state the scenario leaves out) is scaled by its unit
    scales = np.asarray(scales, dtype=float)
    scales = np.where(np.isfinite(scales) & (scales > 0), scales, 1.0)
    targets = scales if targets is None else np.asarray(targets, dtype=float)
    n, ndx = acc.R.shape[0], scales.size
    sv_all = np.zeros((n, ndx))
    sig = np.full((n, ndx), np.inf)
    index = np.zeros((n, ndx))
    rank = np.zeros(n, dtype=int)
    cond = np.full(n, np.inf)
    cond_obs = np.full(n, np.inf)
    last_Vt = np.eye(ndx)
    for k in range(n):
        A = np.linalg.solve(acc.Phi[k].T, acc.R[k].T).T * scales[None, :]  # R Phi^-1 S
        _, sv, Vt = np.linalg.svd(A)
        sv_all[k] = sv
        r = int(np.sum(sv > rel_tol * sv[0])) if sv[0] > 0 else 0
        rank[k] = r
        if r == ndx:
            cond[k] = sv[0] / sv[-1]
        if r > 0:
            cond_obs[k] = sv[0] / sv[r - 1]
        sig[k] = _sigma_info(Vt, sv, vague) * scales
        index[k] = 1.0 - np.sum(Vt**2 / (1.0 + sv[:, None] ** 2), axis=0)
        last_Vt = Vt
    reached = sig <= targets[None, :]
    first = np.where(reached.any(axis=0), np.argmax(reached, axis=0), -1)
    time_to = np.array([acc.t_s[f] if f >= 0 else np.inf for f in first])
    weakest = []
    if n:
        sv = sv_all[-1]
        nm = Naming(tuple(names), tuple(labels or names), tuple(units or [""] * ndx), scales)
        r = int(rank[-1])
        for d in name_subspace(last_Vt[r:].T, nm):  # the unobservable subspace, canonical basis
            weakest.append({"information": 0.0, "unobservable": True, **d})
        for i in range(r - 1, max(r - 1 - n_weakest, -1), -1):
            weakest.append({"information": float(sv[i] ** 2), "unobservable": False, **name_vector(last_Vt[i], nm)})
    return {"t_s": acc.t_s, "n_meas": acc.n_meas, "singular_values": sv_all, "rank": rank, "condition": cond,
            "condition_observable": cond_obs, "sigma_info": sig, "index": index, "targets": targets,
            "time_to_target_s": time_to, "weakest_final": weakest, "names": list(names)}


def run_information(recs: np.ndarray, x_lin: np.ndarray, params: np.ndarray, scales: np.ndarray,
                    t_out: np.ndarray | None = None, targets: Mapping[str, float] | None = None,
                    library: compiled.Library | None = None) -> dict:
    """Information along any record stream (simulated, replayed session, dataset): `accumulate`
    then `analyze_information`, components named from the generated layout.

    recs (RECORD_DTYPE), x_lin (n, NX) linearisation states (IMU record: start of its interval;
    measurement: its time), params (NP,), scales (NDX,) unit per component (e.g. the filter's
    prior sigmas: sqrt(diag(P0))); targets {component or block name: sigma (SI)} (others: the
    scales). Returns `analyze_information`'s dict plus components, labels, units, scales.
    """
    lib = library if library is not None else compiled.load()
    blocks = layout_blocks(lib.layout)
    comps = component_names(blocks)
    names = [c[0] for c in comps]
    units = [b.unit for b in blocks for _ in range(b.size)]
    block_of = [b.name for b in blocks for _ in range(b.size)]
    scales = np.asarray(scales, dtype=float)
    tgt = scales.copy()
    for key, value in (targets or {}).items():
        hit = [i for i, (n, b) in enumerate(zip(names, block_of)) if key in (n, b)]
        if not hit:
            raise ValueError(f"target {key!r}: no such component or block; known: {', '.join(names)}")
        tgt[hit] = float(value)
    acc = accumulate(recs, x_lin, params, t_out, lib)
    out = analyze_information(acc, scales, names, units, tgt, labels=[c[1] for c in comps])
    out.update({"components": names, "labels": [c[1] for c in comps], "units": units, "scales": scales,
                "records": int(np.asarray(recs).size)})
    return out


# --- scenario runs ---------------------------------------------------------------------------

def linearisation_states(recs: np.ndarray, t_imu: np.ndarray, x_true: np.ndarray, imu_rate_hz: float) -> np.ndarray:
    """x_lin per record of a simulated stream (IMU: start of its interval; measurement: its time),
    from the truth sampled at the IMU times (as `montecarlo.pcrb_on_truth` linearises)."""
    k = np.rint(recs["t"] * imu_rate_hz).astype(int)
    k = np.where(recs["kind"] < 0, k - 1, k)
    return x_true[np.clip(k, 0, t_imu.size - 1)]


def scenario_run(scn, mode: str, count: int | None = None, rate_hz: float = 1.0,
                 targets: Mapping[str, float] | None = None, setup=None, nav=None) -> dict:
    """Information along the scenario's truth for one mode (noise-free records, truth linearisation).

    count: Starlink satellites (default: the smallest of the scenario's counts); rate_hz: output
    grid; targets: {component or block name: target sigma (SI)}, others default to the prior
    sigma. Returns `run_information`'s dict plus mode, count, prior_sigma, and the PCRB beside it:
    pcrb_over_prior (per component, final PCRB variance / the prior propagated without
    measurements, with the scenario's process noise) and pcrb_prior_ratios (`pcrb_prior_ratios`).
    """
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep import montecarlo

    if setup is None:
        setup, nav = montecarlo.setup_for(scn)
    count = int(count if count is not None else min(scn.starlink["counts"]))
    trial = simulate.trial_records(setup, mode, count, np.random.default_rng(0), nav, noise_free=True)
    recs = trial.records
    x_lin = linearisation_states(recs, setup.t_imu, setup.x_true, scn.imu_rate_hz)
    t_end = float(setup.t_imu[-1])
    t_out = np.unique(np.r_[np.arange(1, int(t_end * rate_hz) + 1) / rate_hz, t_end])
    prior = np.sqrt(np.diag(setup.P0))
    out = run_information(recs, x_lin, setup.params, prior, t_out, targets, nav.library)
    # the stochastic view beside it: PCRB (process noise, prior P0) against the prior propagated alone
    pr = pcrb_prior_ratios(recs, x_lin, setup.params, setup.P0, nav.library)
    out.update({"mode": mode, "count": count, "prior_sigma": prior,
                # nan for a state held known (zero prior): nothing to improve on
                "pcrb_over_prior": _ratio_or_nan(np.diag(pr["B"]), np.diag(pr["B_prior"])),
                "pcrb_prior_ratios": pr["ratio"]})
    return out


def _ratio_or_nan(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.full(a.shape, np.nan)
    np.divide(a, b, out=out, where=b > 0)
    return out


# --- PCRB agreement --------------------------------------------------------------------------

def without_process_noise(params: np.ndarray, layout: ModuleType | None = None) -> np.ndarray:
    """A copy of params with every noise density at zero: the parameters named vrw, arw, *_rw and
    q_* in the layout's P_NAMES (IMU white noise, bias random walks, clock and LO PSDs)."""
    layout = layout or compiled.load_layout(compiled.GEN_DIR)
    p = np.array(params, dtype=np.float64)
    for i, name in enumerate(layout.P_NAMES):
        if name in ("vrw", "arw") or name.endswith("_rw") or name.startswith("q_"):
            p[i] = 0.0
    return p


def pcrb_prior_ratios(recs: np.ndarray, x_lin: np.ndarray, params: np.ndarray, B0: np.ndarray,
                      library: compiled.Library | None = None) -> dict:
    """How far the PCRB falls below the prior, direction by direction, at the end of `recs`.

    Runs `filter.pcrb` on the stream (B) and on its IMU records only (B_prior: the prior
    propagated without measurements) and solves B d = ratio B_prior d. ratio = 1: the bound of
    the functional d^T dx did not improve on the prior (an unobservable direction); ratio < 1:
    the measurements reduced it. States held known (zero prior variance and no process noise) are
    left out. Returns {"ratio" (ascending, one per free state), "directions" (NDX, n_free) columns
    d, "B", "B_prior"}.
    """
    imu = recs["kind"] < 0
    B = lfilter.pcrb(recs, x_lin, B0, params, library=library).B
    Bp = lfilter.pcrb(recs[imu], x_lin[imu], B0, params, library=library).B
    B, Bp = (B + B.T) / 2, (Bp + Bp.T) / 2
    # a state with a zero prior and no process noise is held known (e.g. a fix latency the run does
    # not estimate): it has no direction to compare, so the eigenproblem is over the others
    free = np.diag(Bp) > 0
    # generalized symmetric eigenproblem via the Cholesky factor of B_prior
    C = np.linalg.cholesky(Bp[np.ix_(free, free)])
    M = np.linalg.solve(C, np.linalg.solve(C, B[np.ix_(free, free)]).T).T
    ratio, Y = np.linalg.eigh((M + M.T) / 2)
    D = np.zeros((B.shape[0], ratio.size))
    D[free] = np.linalg.solve(C.T, Y)
    return {"ratio": ratio, "directions": D, "B": B, "B_prior": Bp}


def trajectory_records(t_s: np.ndarray, x: np.ndarray, u: np.ndarray, dt_s: float, kinds: Sequence[int],
                       steps: Sequence[int], aux: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(records, x_lin) of a nominal trajectory: IMU records for the steps (increments u[k] over
    (t_k, t_k+1]) and one measurement record per (kind, step, aux, R); z is 0 (not used by the
    PCRB or the Gramian). x (N+1, NX) states at t_s."""
    imu = records.imu_records(t_s[1:], u[:, :3], u[:, 3:], dt_s=dt_s)
    steps = np.asarray(steps, dtype=int)
    kinds = np.asarray(kinds, dtype=int)
    parts = [imu]
    for kind in dict.fromkeys(kinds.tolist()):
        sel = kinds == kind
        parts.append(records.measurement_records(t_s[steps[sel]], kind, 0.0, np.asarray(R)[sel], aux[sel]))
    recs = records.merge_records(*parts)
    k = np.searchsorted(t_s, recs["t"])  # exact: record times are taken from t_s
    return recs, x[np.where(recs["kind"] < 0, k - 1, k)]


