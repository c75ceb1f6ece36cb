"""Observability along a run: the information the measurements carry about the error state.

Numeric counterpart of `codegen.observability` (the structural, symbolic analysis). This
module never imports casadi or `models/`: every F and H comes from the compiled generated
functions (`leonav_predict` gives F, `leonav_h_<k>` gives H), so it runs wherever the filter
runs, on any record stream (simulated scenario, replayed session, dataset).

Along a record stream with linearisation states x_lin (as for `filter.pcrb`: the start of the
interval for an IMU record, the record time for a measurement) it accumulates, without process
noise and without a prior,

    Phi(t) = F_k ... F_0                         (error-state transition from the start)
    W(t)   = sum_i Phi_i^T H_i^T H_i Phi_i / R_i  (observability Gramian of the initial error)

in square-root form (W = R^T R, R updated by QR, so singular values far below sqrt(eps) of the
largest stay accurate), and reports the information about the *current* error state,
J(t) = Phi^-T W Phi^-1, through A(t) = R Phi^-1 S, where S scales each component by a unit
(default: its prior sigma, so an information of 1 equals the prior's):

- singular values of A (sqrt of the eigenvalues of the scaled information) over time, the
  rank (relative threshold `REL_TOL`), the condition number, the weakest directions named;
- per component sigma_info(t): the standard deviation the measurements alone give (a vague
  prior of `VAGUE` units keeps unobservable components finite: they stay near VAGUE units),
  and the time at which it first falls below a target sigma;
- the observability index 1 - posterior / prior variance (prior = S^2, no process noise).

`pcrb_prior_ratios` compares the PCRB (`filter.pcrb`, the driver's `leonav_pcrb_run`) with the
prior propagated without measurements: directions whose bound does not fall below the prior
are the unobservable ones (see docs/observability.md).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Mapping, Sequence

import numpy as np

from leonav_runtime import compiled, navfuncs, records
from leonav_runtime import filter as lfilter

GNSS_FIX_MODE = "gnss-fix+imu"
REL_TOL = 1e-12
"""A singular value of A(t) counts towards the rank when above REL_TOL * the largest. Looser
than the structural analysis' 1e-14 (codegen.observability.REL_TOL): a run multiplies thousands
of transitions, and the roundoff floor of the paper's 20 s static run reaches 1e-13.8."""
VAGUE = 1e6
"""sigma_info uses a vague prior of VAGUE units per component (units: S, by default prior sigmas)."""

_AXES_ENU, _AXES_BODY = ("e", "n", "u"), ("x", "y", "z")
_ROTATION_NAMES = ("roll", "pitch", "yaw")


# --- names ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class BlockInfo:
    """One error-state block: name, offset, size, unit and description."""

    name: str
    offset: int
    size: int
    unit: str
    doc: str


def component_names(blocks: Sequence[BlockInfo]) -> list[tuple[str, str]]:
    """(name, label) of every scalar component of the error-state blocks, in order.

    The one naming rule of both analyses: a 3-vector block gets suffixes e/n/u when its doc says
    ENU, else x/y/z; a 3-vector in rad (a rotation vector) gets the hints roll/pitch/yaw; other
    sizes are numbered.
    """
    out = []
    for b in blocks:
        if b.size == 1:
            out.append((b.name, b.name))
            continue
        axes = (_AXES_ENU if "ENU" in b.doc else _AXES_BODY) if b.size == 3 else tuple(map(str, range(b.size)))
        for i, a in enumerate(axes):
            name = f"{b.name}_{a}"
            hint = b.unit == "rad" and b.size == 3
            out.append((name, f"{name} ({_ROTATION_NAMES[i]})" if hint else name))
    return out


_LAYOUT_LINE = re.compile(r"^DX_([A-Z0-9_]+) = (\d+)\s*#\s*([^:]*):\s*(.*)$")


def layout_blocks(layout: ModuleType | None = None) -> list[BlockInfo]:
    """Error-state blocks of the generated layout (gen/state_layout.py, the twin of models/state.py).

    Offsets and sizes come from the module's DX_<NAME> / DX_<NAME>_SIZE constants; unit and
    description from the generated comment of each DX_<NAME> line (empty when absent).
    """
    layout = layout or compiled.load_layout(compiled.GEN_DIR)
    notes = {}
    path = getattr(layout, "__file__", None)
    if path and Path(path).exists():
        for line in Path(path).read_text().splitlines():
            m = _LAYOUT_LINE.match(line)
            if m:
                notes[m.group(1)] = (m.group(3).strip(), m.group(4).strip())
    blocks = []
    for attr in dir(layout):
        if attr.startswith("DX_") and not attr.endswith("_SIZE") and hasattr(layout, f"{attr}_SIZE"):
            key = attr[3:]
            unit, doc = notes.get(key, ("", ""))
            blocks.append(BlockInfo(key.lower(), int(getattr(layout, attr)), int(getattr(layout, f"{attr}_SIZE")),
                                    unit, doc))
    return sorted(blocks, key=lambda b: b.offset)


def analysis_modes(layout: ModuleType | None = None) -> dict[str, tuple[str, ...]]:
    """Modes analysed: the filter's `scenario.MODE_OBSERVABLES` plus a GNSS position-fix mode
    (`GNSS_FIX_MODE`: every observable named pos_*)."""
    from leonav_runtime.scenario import MODE_OBSERVABLES

    layout = layout or compiled.load_layout(compiled.GEN_DIR)
    modes = {k: tuple(v) for k, v in MODE_OBSERVABLES.items()}
    modes[GNSS_FIX_MODE] = tuple(m.suffix for m in layout.MEAS_TABLE if m.suffix.startswith("pos_"))
    return modes


@dataclass(frozen=True)
class Naming:
    """How to name directions: per component name, label (name with a hint), unit and scale
    (the unit a direction's scaled coordinates are expressed in)."""

    names: tuple[str, ...]
    labels: tuple[str, ...]
    units: tuple[str, ...]
    scales: np.ndarray


MAJOR_TERM = 0.05
"""Terms with at least this share of the largest (scaled) name a direction in its short label."""
PIVOT_SHARE = 0.05
"""Canonical basis of a subspace: the leading component of each direction is the earliest one with
at least this share of the largest remaining column norm (see `name_subspace`)."""
TERM_TOL = 1e-4
"""Terms below this (scaled, leading term 1) are not listed in a direction of a canonical basis."""


def _direction(row: np.ndarray, lead: int, nm: Naming, term_tol: float) -> dict:
    """A direction (scaled coordinates, `row[lead]` = 1) as named terms in physical units."""
    order = [lead] + [i for i in np.argsort(-np.abs(row)) if i != lead and abs(row[i]) >= term_tol]
    terms = [{"component": nm.names[i], "label": nm.labels[i],
              "coefficient": float(row[i] * nm.scales[i] / nm.scales[lead]), "unit": nm.units[i],
              "scaled": float(row[i])} for i in order]
    biggest = max(abs(t["scaled"]) for t in terms)
    major = [t["label"] for t in terms if abs(t["scaled"]) >= MAJOR_TERM * biggest]
    text = " ".join((f"1 {t['unit']} {t['label']}" if k == 0 else f"{t['coefficient']:+.3g} {t['unit']} {t['label']}")
                    .replace("  ", " ") for k, t in enumerate(terms))
    return {"leading": nm.names[lead], "label": " and ".join(major), "text": text, "terms": terms}


def name_subspace(N: np.ndarray, nm: Naming, term_tol: float = TERM_TOL) -> list[dict]:
    """Named canonical basis of the subspace spanned by the columns of N (scaled coordinates).

    The basis is made readable by Gauss-Jordan elimination on N^T: each basis vector has a
    leading component (coefficient 1) absent from the others. Pivots go to the earliest
    component (dx order: navigation states before biases and clock) that carries at least
    `PIVOT_SHARE` of the largest remaining column norm, so a tilt / accelerometer-bias pair
    reads '1 rad dtheta_y (pitch) +9.8 m/s^2 db_a_x'. Each direction is returned as
    {"leading", "label" (its major terms), "text" (the combination in physical units:
    '1 rad dtheta_z (yaw) -5.3e-05 rad/s db_g_x' means 1 rad of yaw error together with
    -5.3e-05 rad/s of x gyro bias error), "terms"}.
    """
    d = N.shape[1]
    if d == 0:
        return []
    B = np.array(N.T, dtype=float)
    lead: list[int] = []
    for k in range(d):
        norms = np.linalg.norm(B[k:], axis=0)
        norms[lead] = 0.0
        j = int(np.flatnonzero(norms >= PIVOT_SHARE * norms.max())[0])
        p = k + int(np.argmax(np.abs(B[k:, j])))
        B[[k, p]] = B[[p, k]]
        B[k] /= B[k, j]
        for r in range(d):
            if r != k:
                B[r] -= B[r, j] * B[k]
        lead.append(j)
    return [_direction(B[i], lead[i], nm, term_tol) for i in np.argsort(lead)]


def name_vector(v: np.ndarray, nm: Naming, term_tol: float = 1e-2) -> dict:
    """One direction (scaled coordinates) named with its largest component leading; terms below
    `term_tol` of it are left out."""
    v = np.asarray(v, dtype=float)
    lead = int(np.argmax(np.abs(v)))
    return _direction(v / v[lead], lead, nm, term_tol)


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
    scales = np.asarray(scales, dtype=float)
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
    from leonav_runtime import montecarlo, simulate

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
                "pcrb_over_prior": np.diag(pr["B"]) / np.diag(pr["B_prior"]),
                "pcrb_prior_ratios": pr["ratio"]})
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
    the measurements reduced it. Returns {"ratio" (ascending), "directions" (NDX, NDX) columns
    d, "B", "B_prior"}.
    """
    imu = recs["kind"] < 0
    B = lfilter.pcrb(recs, x_lin, B0, params, library=library).B
    Bp = lfilter.pcrb(recs[imu], x_lin[imu], B0, params, library=library).B
    B, Bp = (B + B.T) / 2, (Bp + Bp.T) / 2
    # generalized symmetric eigenproblem via the Cholesky factor of B_prior
    C = np.linalg.cholesky(Bp)
    M = np.linalg.solve(C, np.linalg.solve(C, B).T).T
    ratio, Y = np.linalg.eigh((M + M.T) / 2)
    D = np.linalg.solve(C.T, Y)
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


# --- figures -----------------------------------------------------------------------------------

def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_singular_values(runs: Sequence[dict], path, title: str = "") -> Path:
    """Singular values of the scaled current-state information vs time, one panel per mode.

    runs: `scenario_run` results. A singular value s means the measurements so far give the
    information of a prior of sigma = (unit) / s along that direction (1 = the prior's).
    """
    plt = _pyplot()
    n = max(len(runs), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.8 * rows), squeeze=False, sharey=True)
    lows = []
    for ax, run in zip(axes.flat, runs):
        raw = run["singular_values"]
        floor = REL_TOL * raw[:, :1]  # numerically zero below this: not drawn
        sv = np.where(raw > floor, raw, np.nan)
        if np.any(np.isfinite(sv)):
            lows.append(np.nanmin(sv))
        ax.semilogy(run["t_s"], sv, lw=1)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_title(f"{run['mode']} (rank {int(run['rank'][-1])}/{sv.shape[1]} at the end)", fontsize=9)
        ax.set_xlabel("time since start (s)")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("singular value (prior units)")
    if lows:
        axes[0, 0].set_ylim(bottom=max(min(lows) / 3, 1e-30))
    for ax in list(axes.flat)[len(runs):]:
        ax.axis("off")
    fig.suptitle((title or "information along the run: singular values of R Phi^-1 S")
                 + f"\n(dashed: the prior's information; values below {REL_TOL:g} x the largest are numerically 0, "
                   "not drawn)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_index(mode: str, components: Sequence[str], by_motion: Mapping[str, np.ndarray], path,
               run_index: np.ndarray | None = None, run_label: str = "scenario") -> Path:
    """Per-component observability index of one mode: one bar per motion class (structural
    analysis, unit prior) and, when given, the index at the end of a scenario run (prior P0)."""
    plt = _pyplot()
    series = dict(by_motion)
    if run_index is not None:
        series[run_label] = np.asarray(run_index)
    x = np.arange(len(components))
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(max(8.0, 0.55 * len(components)), 3.8))
    for i, (label, idx) in enumerate(series.items()):
        ax.bar(x + (i - (len(series) - 1) / 2) * width, np.clip(idx, 0, 1), width, label=label)
    ax.set_xticks(x)
    ax.set_xticklabels(components, rotation=60, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("index: 1 - posterior/prior variance")
    ax.set_title(f"{mode}: observability index per state (0 = no information)", fontsize=10)
    ax.legend(fontsize=7, ncol=min(len(series), 5))
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


# --- tables ------------------------------------------------------------------------------------

STRUCTURAL_HEADER = ("mode", "motion", "rank", "n_states", "weak", "nullity", "steps_to_saturate", "gap",
                     "gap_clear", "draws_agree", "unobservable_directions", "weak_directions",
                     "weakest_observable", "weakest_sigma", "weakest_sigma_unit")


def structural_rows(summaries: Sequence[dict]) -> list[list]:
    """CSV rows (STRUCTURAL_HEADER) of structural-analysis summaries (`CaseResult.summary()`)."""
    rows = []
    for s in summaries:
        w = s.get("weakest_observable") or {}
        rows.append([s["mode"], s["motion"], s["rank"], s["n_states"], s["weak"], s["nullity"],
                     s["steps_to_saturate"], s["gap"], s["gap_clear"], s["draws_agree"],
                     " | ".join(d["text"] for d in s["unobservable_directions"]),
                     " | ".join(f"{d['text']} (sigma {d['sigma']:.2g} {d['sigma_unit']})" for d in s["weak_directions"]),
                     w.get("text", ""), w.get("sigma", math.nan), w.get("sigma_unit", "")])
    return rows


def format_structural_table(summaries: Sequence[dict]) -> str:
    """The mode x motion table as printed by `leonav observability`.

    rank: observable directions of the error state (structural, numerical rank of O); +w: of
    which w weak; steps: measurement epochs until the rank saturates; gap: sigma_r/sigma_r+1.
    Unobservable directions are named by their major terms (full combinations in the CSV/JSON).
    """
    lines = [f"{'mode':22s} {'motion':17s} {'rank':>9s} {'steps':>5s} {'gap':>7s}  unobservable directions "
             "(null space)  [weak directions]"]
    for s in summaries:
        rank = f"{s['rank']}/{s['n_states']}" + (f"+{s['weak']}w" if s["weak"] else "")
        gap = "inf" if not math.isfinite(s["gap"]) else f"{s['gap']:.0e}"
        flags = ("" if s["gap_clear"] else " (gap not clear)") + ("" if s["draws_agree"] else " (draws disagree)")
        null = "; ".join(d["label"] for d in s["unobservable_directions"]) or "none"
        weak = "; ".join(f"{d['label']}: sigma {d['sigma']:.0e} {d['sigma_unit']}" for d in s["weak_directions"])
        lines.append(f"{s['mode']:22s} {s['motion']:17s} {rank:>9s} {s['steps_to_saturate']:5d} {gap:>7s}  "
                     f"{null}{' [' + weak + ']' if weak else ''}{flags}")
    return "\n".join(lines)


def format_time_to_target(runs: Sequence[dict]) -> str:
    """Per mode and component: seconds until the measurements alone give sigma <= target ('-': never)."""
    if not runs:
        return ""
    names = runs[0]["components"]
    width = max(6, max(len(n) for n in names) + 1)
    lines = [f"{'mode':22s} " + "".join(f"{n:>{width}s}" for n in names)]
    for r in runs:
        cells = "".join(f"{(f'{v:.0f}' if math.isfinite(v) else '-'):>{width}s}" for v in r["time_to_target_s"])
        lines.append(f"{r['mode']:22s} {cells}")
    return "\n".join(lines)
