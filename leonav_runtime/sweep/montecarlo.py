"""Monte Carlo sweep: RMSE, NEES, NIS and the PCRB per mode and Starlink satellite count.

Work unit: a *task* is (scenario, mode, count, a block of trial indices). Each worker
process prepares the scenario once (truth, satellites; cached per process), builds the block's
records at once (simulation/trial_block.py) and runs each trial through the compiled C filter
loop. Trial i draws from the stream
`SeedSequence(seed).spawn(n)[i]` whatever mode, count or executor runs it, so the
modes are compared on common random numbers and results do not depend on the executor.

Errors are evaluated on the output grid (`EVAL_RATE_HZ`), after every record at that
time (so after the updates of that epoch), as `x_est [-] x_true` with the generated
boxminus: position and velocity in ENU (m, m/s), attitude as the body-frame rotation
vector (rad). NEES uses the 9 x 9 navigation block of P.
"""
from __future__ import annotations

import ctypes
import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import special

from leonav_runtime.core import compiled, records
from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, orbit_states
from leonav_runtime.simulation import simulate, trial_block
from leonav_runtime.sweep import consistency
from leonav_runtime.gen import state_layout as L
from leonav_runtime.scenarios.load import Scenario, scenario_from_dict
from leonav_runtime.simulation.orbit_truth import starlink_sigma_rac

EVAL_RATE_HZ = 10.0
NAV = L.DX_NAV9_SLICE  # the 9D error (dp, dv, dtheta): the leading NNAV entries of dx
# blocks of the 9D error (and of the PCRB's B_nav, whose rows are those of dx[NAV])
BLOCKS = {"position": L.DX_DP_SLICE, "velocity": L.DX_DV_SLICE, "attitude": L.DX_DTHETA_SLICE,
          "vertical": slice(L.DX_DP_SLICE.start + 2, L.DX_DP_SLICE.start + 3)}   # the Up component of dp

BLOCK_SAMPLES = 250_000   # trials x IMU samples drawn at once (a 20 s run at 100 Hz: 124 trials)
_SETUPS: dict[str, simulate.Setup] = {}
MAX_SETUPS = 4   # prepared scenarios kept per process (bounded memory over a study's cells)
_NAV: dict[str, navfuncs.NavFunctions] = {}


def scenario_key(scn: Scenario) -> str:
    """Identity of a scenario's content and element files (caches its preparation per process)."""
    ident = [scn.raw, [str(f) for f in scn.element_files]]
    return hashlib.sha256(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()[:16]


def setup_for(scn: Scenario) -> tuple[simulate.Setup, navfuncs.NavFunctions]:
    """The prepared scenario for this process (prepared on first use)."""
    key = scenario_key(scn)
    if key not in _SETUPS:
        while len(_SETUPS) >= MAX_SETUPS:   # a study's cells come one after another: keep the latest
            oldest = next(iter(_SETUPS))
            del _SETUPS[oldest], _NAV[oldest]
        nav = navfuncs.NavFunctions()
        _SETUPS[key] = simulate.prepare(scn, nav)
        nav.params = _SETUPS[key].params
        _NAV[key] = nav
    return _SETUPS[key], _NAV[key]


def trial_rng(seed: int, index: int) -> np.random.Generator:
    """Random stream of trial `index`: child `index` of SeedSequence(seed), i.e. the same
    stream as `SeedSequence(seed).spawn(n)[index]` for any n > index."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))


def eval_grid(t_imu: np.ndarray, imu_rate_hz: float, rate_hz: float = EVAL_RATE_HZ) -> np.ndarray:
    """IMU sample indices of the output grid (every 1/rate_hz s after the start)."""
    step = max(1, int(round(imu_rate_hz / rate_hz)))
    return np.arange(step, t_imu.size, step)


def eval_rows(recs: np.ndarray, t_imu: np.ndarray, rate_hz: float, imu_rate_hz: float):
    """Indices of the last record at each output time, and the truth sample of that time."""
    k = eval_grid(t_imu, imu_rate_hz, rate_hz)
    t = t_imu[k]
    last = np.searchsorted(recs["t"], t + 1e-9, side="left") - 1
    return last, k


@dataclass
class TrialResult:
    """One trial: errors (nt, NNAV) of the 9D on the output grid, NEES (nt,), NIS sums per kind.

    p_est: estimated ENU position on the output grid (kept for trial 0 only, for plots);
    c_seconds: CPU time (s) of the C filter loop; seconds: CPU time of the whole trial (the
    worker thread's own clock, `time.thread_time`: under load a wall clock counts the waits);
    wall_seconds: the trial's wall time. In a block (`run_block`) the trials share their
    draws and evaluation: seconds and wall_seconds are NaN there, the block carries them.
    """

    index: int
    err: np.ndarray
    nees: np.ndarray
    nis_sum: dict[int, float]
    nis_count: dict[int, int]
    gated: int
    failed: int
    p_est: np.ndarray | None
    c_seconds: float
    seconds: float
    wall_seconds: float = 0.0
    counts: dict = field(default_factory=dict)   # the front end's (simulate.Trial.counts)
    orbit: dict = field(default_factory=dict)    # the orbit-offset states' slot counts (compensate = "states")


def run_trial(scn: Scenario, mode: str, count: int, index: int) -> TrialResult:
    """Run trial `index` of (mode, count) through the C filter loop."""
    t0, w0 = time.thread_time(), time.perf_counter()
    setup, nav = setup_for(scn)
    rng = trial_rng(scn.seed, index)
    trial = simulate.trial_records(setup, mode, count, rng, nav)
    return trial_result(scn, setup, nav, trial, index, t0, w0)


def orbit_states_for(scn: Scenario, kinds: np.ndarray, nav: navfuncs.NavFunctions) -> orbit_states.OrbitStates | None:
    """Fresh orbit-offset states for one trial whose records have these `kinds` when the scenario
    estimates them (`[ephemeris_error] compensate = "states"`, ephemeris method 1) and a kind reads
    its satellite's offsets (a differenced range keeps the consider term: `realism.orbit_consider`);
    their prior is the Starlink sigmas at the element age. None otherwise."""
    eph = scn.realism.get("ephemeris", {})
    if eph.get("compensate") != "states" or not np.isin(kinds, sorted(orbit_states.offset_kinds())).any():
        return None
    return orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), eph["orbit_state_slots"],
                                    starlink_sigma_rac(eph), [eph["orbit_state_walk_m2_s"]] * 3,
                                    eph["orbit_state_free_after_s"])


def trial_result(scn: Scenario, setup: simulate.Setup, nav: navfuncs.NavFunctions, trial: simulate.Trial,
                 index: int, t0: float, w0: float) -> TrialResult:
    """Run one drawn trial through the C filter loop; t0, w0: its start on the thread's CPU
    clock and the wall clock."""
    gate = scn.filter["gate_nis"] or None
    params = setup.params if trial.params is None else trial.params   # realism compensation may differ
    ekf = lfilter.EKF(trial.x0, setup.P0, params, gate=gate, library=nav.library)
    rows, k = eval_rows(trial.records, setup.t_imu, EVAL_RATE_HZ, scn.imu_rate_hz)
    orbit = orbit_states_for(scn, trial.records["kind"], nav)
    t_c = time.thread_time()
    res = ekf.run(trial.records, P_rows=rows, orbit=orbit,   # the 9D block only on the output grid, for NEES
                  covariance_interval_s=scn.filter["covariance_interval_s"], P_lead=L.NNAV)
    t_c = time.thread_time() - t_c
    err = nav.boxminus(res.x[rows], trial.x_true[k])[:, NAV]
    nees = consistency.nees(err, res.P)
    nis_sum, nis_count = consistency.nis_sums(*consistency.kind_index(res.kind), res.nis, res.status)
    p_est = res.x[rows, L.X_P_ENU_SLICE].copy() if index == 0 else None
    return TrialResult(index, err, nees, nis_sum, nis_count, res.n_gated, res.n_failed, p_est,
                       t_c, time.thread_time() - t0, time.perf_counter() - w0, trial.counts,
                       orbit.counts if orbit else {})


@dataclass
class BlockResult:
    """What an executor task returns: its trials, the PCRB curve (block with trial 0)."""

    results: list[TrialResult]
    pcrb: dict[str, np.ndarray] | None
    p_est_trial0: np.ndarray | None
    c_seconds: float        # CPU s (TrialResult)
    seconds: float          # CPU s
    wall_seconds: float = 0.0


def run_block(task: tuple) -> BlockResult:
    """Executor entry point: (scenario dict, source, base dir, mode, count, trial indices).

    The block's records are built at once (simulation/trial_block.py, the same as `run_trial`'s)
    and each trial runs the C loop in turn; its errors, NEES and NIS are evaluated for the whole
    block. Timing: the worker thread's CPU clock (the block's, and each C loop's), wall beside it.
    """
    t0, w0 = time.thread_time(), time.perf_counter()
    raw, source, base_dir, mode, count, indices = task
    scn = scenario_from_dict(raw, source=source, base_dir=Path(base_dir))
    setup, nav = setup_for(scn)
    # a long run draws fewer trials at once: a block's draws stay below one trial's records
    step = max(1, BLOCK_SAMPLES // setup.t_imu.size)
    parts = [_run_trials(scn, setup, nav, mode, count, indices[i:i + step]) for i in range(0, len(indices), step)]
    results = [r for part in parts for r in part[0]]
    bound = pcrb_curve(scn, mode, count) if 0 in indices else None
    p0 = next((r.p_est for r in results if r.p_est is not None), None)
    return BlockResult(results, bound, p0, sum(part[1] for part in parts), time.thread_time() - t0,
                       time.perf_counter() - w0)


def _run_trials(scn: Scenario, setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int,
                indices: list[int]) -> tuple[list[TrialResult], float]:
    """The trials `indices` of (mode, count) from one block of records: (results, C loop CPU s)."""
    block = trial_block.trial_block(setup, mode, count, [trial_rng(scn.seed, i) for i in indices], nav)
    if block.trials is not None:   # streams of different lengths (a realism switch dropped records)
        results = [trial_result(scn, setup, nav, t, i, time.thread_time(), time.perf_counter())
                   for t, i in zip(block.trials, indices)]
        return results, sum(r.c_seconds for r in results)
    gate = scn.filter["gate_nis"] or None
    buf = block.buffer()
    rows, k = eval_rows(buf, setup.t_imu, EVAL_RATE_HZ, scn.imu_rate_hz)
    B, nt = len(indices), rows.size
    x_est = np.empty((B, nt, L.NX))
    P9 = np.empty((L.NNAV, L.NNAV, B, nt))    # batch last: the layout the NEES works in
    c_seconds, runs, orbits = [], [], []
    nis, status = np.empty((B, buf.size)), np.empty((B, buf.size), dtype=np.int32)
    loop = _CLoop(nav.library, buf, rows, lfilter.EKF(block.x0[0], setup.P0, block.params.reshape(-1, L.NP)[0],
                                                      gate=gate, library=nav.library).gate,
                  scn.filter["covariance_interval_s"])
    kinds = consistency.kind_index(buf["kind"])   # the same for every trial of the block
    present = np.unique(buf["kind"])               # so are the kinds the orbit states look for
    for j in range(B):
        params = block.params if block.params.ndim == 1 else block.params[j]
        orbit = orbit_states_for(scn, present, nav)
        c_seconds.append(loop.run(block.x0[j], setup.P0, params, block.fill(j, buf), orbit))
        orbits.append(orbit.counts if orbit else {})
        x_est[j] = loop.x[rows]
        P9[:, :, j] = np.moveaxis(loop.P_rows, 0, -1)
        nis[j], status[j] = loop.nis, loop.status
        runs.append((int(loop.out.n_gated), int(loop.out.n_failed)))
    err = nav.boxminus(x_est.reshape(B * nt, L.NX), block.truth(k).reshape(B * nt, L.NX))[:, NAV]
    nees = consistency.nees_batch_last(err.T, P9.reshape(L.NNAV, L.NNAV, B * nt)).reshape(B, nt)
    err = err.reshape(B, nt, L.NNAV)
    results = []
    nis_per_trial = consistency.nis_sums_many(*kinds, nis, status)
    for j, (index, (nis_sum, nis_count), (gated, failed)) in enumerate(zip(indices, nis_per_trial, runs)):
        p_est = x_est[j, :, L.X_P_ENU_SLICE].copy() if index == 0 else None
        results.append(TrialResult(index, err[j], nees[j], nis_sum, nis_count, gated, failed, p_est, c_seconds[j],
                                   math.nan, math.nan, block.counts[j] if block.counts else {}, orbits[j]))
    return results, sum(c_seconds)


class _CLoop:
    """The C filter loop (`leonav_run`, what `EKF.run` calls, with the same outputs) for the trials
    of one block: their streams share times and kinds, so they are checked once, and the outputs
    are allocated once; `run` times the C call alone (the worker thread's CPU clock)."""

    def __init__(self, library, recs: np.ndarray, rows: np.ndarray, gates: np.ndarray,
                 covariance_interval_s: float = 0.0) -> None:
        records.check_records(recs, len(library.meas_ids))
        self.covariance_interval_s = float(covariance_interval_s)
        n, self.lib, self.n = recs.size, library, recs.size
        self.gates = np.ascontiguousarray(gates, dtype=np.float64)
        self.work = library.new_workspace()
        self.x, self.P_diag = np.empty((n, L.NX)), np.empty((n, L.NDX))
        self.mask = np.zeros(n, dtype=np.uint8)
        self.mask[rows] = 1
        # only the 9D navigation block at the output rows: the NEES reads no more, and P whole
        # would be 6.5x the bytes for C to write and for the copy after it to fetch
        self.P_blocks = np.empty((rows.size, L.NNAV, L.NNAV))
        self.P_rows = self.P_blocks.transpose(0, 2, 1)   # each block is written column-major
        self.y, self.S, self.nis = np.empty(n), np.empty(n), np.empty(n)
        self.status = np.empty(n, dtype=np.int32)
        self.out = compiled.RunOut(
            x=_ptr(self.x), P_diag=_ptr(self.P_diag), P=_ptr(self.P_blocks),
            P_mask=self.mask.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8)), y=_ptr(self.y), S=_ptr(self.S),
            nis=_ptr(self.nis), status=self.status.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), P_lead=L.NNAV)

    def run(self, x0: np.ndarray, P0: np.ndarray, params: np.ndarray, recs: np.ndarray,
            orbit: orbit_states.OrbitStates | None = None) -> float:
        """Run one trial's stream (the block's layout) from x0, P0, with `orbit`'s offset states
        beside it when given; returns the C call's CPU s."""
        x = np.array(x0, dtype=np.float64)
        P = np.array(P0, dtype=np.float64, order="F")   # leonav_run(_orbit) symmetrizes it
        p = np.ascontiguousarray(params, dtype=np.float64)
        if recs.size != self.n or not recs.flags.c_contiguous:
            raise ValueError(f"records: expected the block's {self.n} contiguous records, got {recs.size}")
        t_c = time.thread_time()
        if orbit is None:
            rc = self.lib.lib.leonav_run(_ptr(x), _ptr(P), _ptr(p), recs.ctypes.data, self.n, _ptr(self.gates),
                                         self.covariance_interval_s, ctypes.byref(self.out), self.work.ctypes.data)
        else:
            rc = self.lib.lib.leonav_run_orbit(_ptr(x), _ptr(P), _ptr(p), recs.ctypes.data, self.n, _ptr(self.gates),
                                               ctypes.byref(orbit.c), ctypes.byref(self.out), self.work.ctypes.data)
        t_c = time.thread_time() - t_c
        if rc != L.OK:
            raise RuntimeError(f"leonav_run returned {compiled.code_name(rc)} at record {self.out.n_done}")
        return t_c


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def pcrb_records(setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int) -> np.ndarray:
    """The noise-free record stream the PCRB of (mode, count) runs on.

    Where the trials are built from the block template (no realism switch active), it is the
    template's records: a noise-free trial's stream in every field the bound reads (kinds, times,
    increments, R, aux); only z, which the bound does not read, holds each value's index instead
    (tests/test_pcrb_records.py). That spares drawing the noise-free trial and taking it down the
    road again, ~3 ms of a point's 13 ms. It is a read-only view: the trials' streams are copied
    from the template, which must not change. With a realism switch the trials take the road one
    by one and build no template; building one only for the bound would be slower than the
    noise-free trial and would stay in memory with the setup (61 MB per point in a passive-phase
    scenario), so the noise-free trial is drawn as before.
    """
    if not trial_block.uses_template(setup.scn):
        return simulate.trial_records(setup, mode, count, np.random.default_rng(0), nav, noise_free=True).records
    rec = trial_block.template(setup, nav, mode, count).rec.view()
    rec.flags.writeable = False
    return rec


def pcrb_on_truth(setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int,
                  B0: np.ndarray | None = None, params: np.ndarray | None = None):
    """PCRB of (mode, count) along the scenario's truth, on its noise-free record stream.

    Each record is linearised where it acts: an IMU record at the start of its interval,
    a measurement at its time. B0 and params default to the filter's prior and parameters.
    Returns (records, PcrbResult); the records may be a read-only view (`pcrb_records`): copy
    them to edit.
    """
    recs = pcrb_records(setup, nav, mode, count)
    k_of = np.rint(recs["t"] * setup.scn.imu_rate_hz).astype(int)
    k_lin = np.where(recs["kind"] < 0, k_of - 1, k_of)
    res = lfilter.pcrb(recs, setup.x_true[k_lin], setup.P0 if B0 is None else B0,
                       setup.params if params is None else params, library=nav.library)
    return recs, res


def pcrb_curve(scn: Scenario, mode: str, count: int) -> dict[str, np.ndarray]:
    """PCRB on the output grid: sqrt(trace) of the position, velocity, attitude blocks."""
    setup, nav = setup_for(scn)
    recs, res = pcrb_on_truth(setup, nav, mode, count)
    rows, _ = eval_rows(recs, setup.t_imu, EVAL_RATE_HZ, scn.imu_rate_hz)
    B = res.B_nav[rows]
    return {name: np.sqrt(np.trace(B[:, s, s], axis1=1, axis2=2)) for name, s in BLOCKS.items()}


def _chi2_quantiles(dof: int) -> np.ndarray:
    """The 2.5 % and 97.5 % quantiles of a chi-square(dof): scipy.stats.chi2.ppf's own formula,
    the same numbers, without importing scipy.stats (~0.5 s, paid by every sweep)."""
    return 2.0 * special.gammaincinv(dof / 2.0, np.array([0.025, 0.975]))


def summarize(results: list[TrialResult], bound: dict[str, np.ndarray], n_err: int = L.NNAV) -> dict:
    """RMSE over trials (per time and overall), PCRB, efficiency, NEES and NIS statistics."""
    err = np.stack([r.err for r in results])               # (trials, nt, NNAV)
    n = err.shape[0]
    out: dict = {"trials": n}
    for name, s in BLOCKS.items():
        sq = np.sum(err[:, :, s] ** 2, axis=2)              # (trials, nt)
        rmse_t = np.sqrt(sq.mean(axis=0))
        rmse = float(np.sqrt(sq.mean()))
        crb = float(np.sqrt(np.mean(bound[name] ** 2)))
        out[name] = {"rmse": rmse, "pcrb": crb, "ratio": rmse / crb if crb > 0 else math.nan,
                     "final_rmse": float(rmse_t[-1]), "final_pcrb": float(bound[name][-1]),
                     "rmse_t": rmse_t, "pcrb_t": bound[name]}
    nees = np.stack([r.nees for r in results]).mean(axis=0)  # average over trials, per time
    lo, hi = _chi2_quantiles(n_err * n) / n
    out["nees"] = {"mean": float(nees.mean()), "band95": [float(lo), float(hi)], "dof": n_err,
                   "fraction_inside": float(np.mean((nees >= lo) & (nees <= hi))), "nees_t": nees}
    nis = {}
    kinds = sorted({k for r in results for k in r.nis_count})
    for kind in kinds:
        total = sum(r.nis_sum.get(kind, 0.0) for r in results)
        count = sum(r.nis_count.get(kind, 0) for r in results)
        lo1, hi1 = _chi2_quantiles(count) / count if count else (math.nan, math.nan)
        nis[kind] = {"mean": total / count if count else math.nan, "count": count,
                     "band95": [float(lo1), float(hi1)]}
    out["nis"] = nis
    out["gated"] = int(sum(r.gated for r in results))
    out["failed"] = int(sum(r.failed for r in results))
    out["front_end"] = {k: int(sum(r.counts.get(k, 0) for r in results)) for k in sorted({k for r in results for k in r.counts})}
    if any(r.orbit for r in results):
        out["orbit_states"] = {k: int(sum(r.orbit.get(k, 0) for r in results)) for k in ("slots_taken", "slots_reused",
                                                                                        "no_slot")}
    return out
