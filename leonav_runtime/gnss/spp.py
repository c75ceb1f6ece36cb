"""Snapshot single-point positioning: weighted least squares on the generated GNSS model.

Per epoch the unknowns are the position (ENU of a fixed origin), the GPS receiver clock
(c_dt) and the inter-system biases of the other constellations present; they are the
error-state components dp, dc_dt, disb of the one state layout, and every prediction and
Jacobian row comes from the generated `leonav_h_gnss_pseudorange` (the function the EKF
uses), elevation / azimuth / atmosphere delays from `leonav_gnss_terms`, the state update
from the generated boxplus, all through `navfuncs` (one driver call per batch). All epochs
are iterated together (Gauss-Newton, each epoch its own 4-6 unknowns, the normal equations
stacked), which keeps Python out of the per-satellite loop.

Per iteration, as RTKLIB's `pntpos` does: elevation mask at the current position, weights
1 / pseudorange_variance (RTKLIB's default error model, `signals.pseudorange_variance`), an
inter-system bias without satellites held at 0 by a pseudo-observation of variance
0.01 m^2, stop when |dx| < 1e-4 m (at most `max_iterations`). The iteration starts at the
RINEX header position when there is one, else at the point on the ellipsoid below the mean
satellite position of the first epoch, and runs in two stages: without mask and atmosphere
until it is within metres, then with them (RTKLIB starts at the Earth's centre, where it
can apply neither; the converged solutions are the same).

Validation and RAIM: chi-square test of the weighted residuals, sum(v^2 / var) against the
upper 1 - alpha quantile with n - (4 + number of inter-system biases) degrees of freedom
(alpha = SPP_CHI2_ALPHA, the 0.001 of RTKLIB's table), and GDOP <= SPP_MAX_GDOP. An epoch that
fails the test with at least 2 degrees of freedom loses the satellite with the largest
standardised residual |v_i| / sqrt(var_i - a_i N^-1 a_i^T) and is solved again, until it
passes or the redundancy is 1 (then the epoch has no solution). DOPs: from elevation and
azimuth of the used satellites (E, N, U, one clock), as RTKLIB computes them.

Gross errors first (`implausible_pseudoranges`): one pseudorange tens of thousands of km off
would pull the whole epoch away (every row then looks below the mask), so before the
least squares each row's pseudorange plus the satellite clock, less the epoch's common
receiver clock, must be a possible geometric range to its satellite; rows that are not get
the status `implausible_pseudorange`. Rows of an epoch that did not converge, or whose
elevation is not a number, count as `epoch_without_solution` (their elevation says nothing).
"""
from __future__ import annotations

import dataclasses
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gnss.chi2 import chi2_upper
from leonav_runtime.gnss.signals import (BELOW_MASK, EPOCH_UNSOLVED, IMPLAUSIBLE, ISB_INDEX, RAIM_EXCLUDED, REASONS,
                                         GnssRows, pseudorange_variance)
from leonav_runtime.core.navfuncs import NavFunctions
from leonav_runtime.core.params import params_array

# epoch status
SOLVED, SOLVED_RAIM, TOO_FEW, CHI2_FAILED, GDOP_FAILED, NOT_CONVERGED = 0, 1, 2, 3, 4, 5
EPOCH_STATUS = {SOLVED: "ok", SOLVED_RAIM: "ok_after_exclusion", TOO_FEW: "too_few_satellites",
                CHI2_FAILED: "chi2_failed", GDOP_FAILED: "gdop_too_large", NOT_CONVERGED: "not_converged"}
ISB_PSEUDO_VAR_M2 = 0.01
"""Variance (m^2) of the pseudo-observation isb = 0 for a constellation absent from an epoch."""
CONVERGED_M = 1e-4
COARSE_M = 10.0
COLS = np.r_[L.DX_DP_SLICE, L.DX_DC_DT, L.DX_DISB_SLICE]   # unknowns: dp (3), dc_dt, disb (2)
NK = COLS.size
RX_RADIUS_M = (6.35e6, 6.40e6)
"""Geocentric radius (m) a receiver can have: the polar radius less the lowest land, to the
equatorial radius plus 20 km of altitude (aircraft, balloons). With a satellite at radius r_s
its geometric range lies in [r_s - 6.40e6, sqrt(r_s^2 - 6.35e6^2)] (zenith .. horizon), e.g.
20.2e6 .. 25.8e6 m for GPS, 35.8e6 .. 41.7e6 m for a BeiDou GEO."""


@dataclass
class SppOptions:
    """Single-point options: elevation mask (deg), atmosphere switches, RAIM, thresholds."""

    elevation_mask_deg: float = K.GNSS_MASK_DEG
    raim: bool = True
    chi2_alpha: float = K.SPP_CHI2_ALPHA
    max_gdop: float = K.SPP_MAX_GDOP
    max_iterations: int = 10


@dataclass
class SppResult:
    """Per epoch (E,): t_gps_s, status (EPOCH_STATUS), r_ecef_m (E, 3), lat_rad, lon_rad,
    height_m, clock_m (c_dt, GPS), isb_m (E, 2) [Galileo, BeiDou] - GPS (NaN where absent),
    ns (satellites used), dop (E, 4) GDOP PDOP HDOP VDOP, cov_enu_m2 (E, 3, 3) position
    covariance in the local ENU frame, chi2, dof, n_excluded; per row of `rows`: el_rad,
    az_rad, iono_m, tropo_m, residual_m, sigma_m, row_status (0 used, else a REASONS code),
    epoch_index; counts (rows by reason, epochs by status); origin (lat, lon, h) of the ENU
    frame the unknowns lived in."""

    t_gps_s: np.ndarray
    status: np.ndarray
    r_ecef_m: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    height_m: np.ndarray
    clock_m: np.ndarray
    isb_m: np.ndarray
    ns: np.ndarray
    dop: np.ndarray
    cov_enu_m2: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    n_excluded: np.ndarray
    rows: GnssRows
    el_rad: np.ndarray
    az_rad: np.ndarray
    iono_m: np.ndarray
    tropo_m: np.ndarray
    residual_m: np.ndarray
    sigma_m: np.ndarray
    row_status: np.ndarray
    epoch_index: np.ndarray
    x: np.ndarray
    params: np.ndarray
    counts: Counter = field(default_factory=Counter)

    @property
    def solved(self) -> np.ndarray:
        return (self.status == SOLVED) | (self.status == SOLVED_RAIM)

    def used_sats(self, e: int) -> list[str]:
        """Satellites used in epoch e ('G07', ...)."""
        return self.used_sats_per_epoch()[e]

    def used_sats_per_epoch(self) -> list[list[str]]:
        """Satellites used in every epoch (computed once)."""
        cached = getattr(self, "_used_cache", None)
        if cached is None:
            k = np.flatnonzero(self.row_status == 0)
            sats = self.rows.sat[k].tolist()
            cached = [[] for _ in range(self.t_gps_s.size)]
            for e, s in zip(self.epoch_index[k].tolist(), sats):
                cached[e].append(s)
            for lst in cached:
                lst.sort()
            self._used_cache = cached
        return cached


def implausible_pseudoranges(rows: GnssRows) -> np.ndarray:
    """Mask of the usable rows (status 0) whose pseudorange cannot be a range to their satellite.

    Per row, pseudorange + satellite clock (m) = geometric range + receiver clock, the range
    within [lo, hi] of `RX_RADIUS_M`. The epoch's common receiver clock is the median of
    (pseudorange + satellite clock - (lo + hi) / 2) over its rows: with most rows sound it is
    off the true clock by at most the largest half-width (hi - lo) / 2 of the epoch, so a row
    is implausible when it is off the middle of its band by more than its own half-width plus
    that one (about 5.6e6 m for GPS: catches a sign error, a wrapped or zero code, not metres)."""
    bad = np.zeros(len(rows), bool)
    k = np.flatnonzero(rows.status == 0)
    if not k.size:
        return bad
    r_s = np.linalg.norm(rows.aux[k][:, L.AUX_R_S_ECEF_SLICE], axis=1)
    lo = r_s - RX_RADIUS_M[1]
    hi = np.sqrt(np.maximum(r_s**2 - RX_RADIUS_M[0] ** 2, 0.0))
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    off = rows.pseudorange_m[k] + rows.aux[k, L.AUX_SAT_CLOCK] - mid
    epochs, inv = np.unique(rows.t_gps_s[k], return_inverse=True)
    clock, widest = np.zeros(epochs.size), np.zeros(epochs.size)
    finite = np.isfinite(off)
    for e in range(epochs.size):
        m = (inv == e) & finite
        if m.any():
            clock[e], widest[e] = np.median(off[m]), half[m].max()
    with np.errstate(invalid="ignore"):
        bad[k] = ~(np.abs(off - clock[inv]) <= half + widest[inv])
    return bad


def _start_position(rows: GnssRows, approx_ecef_m) -> np.ndarray:
    if approx_ecef_m is not None and 6.0e6 < np.linalg.norm(approx_ecef_m) < 7.0e6:
        return np.asarray(approx_ecef_m, dtype=float)
    t0 = rows.t_gps_s[0]
    mean = rows.aux[rows.t_gps_s == t0][:, L.AUX_R_S_ECEF_SLICE].mean(axis=0)
    lat, lon, _ = geometry.ecef_to_geodetic(mean)
    return np.asarray(geometry.geodetic_to_ecef(lat, lon, 0.0), float)


class _Batch:
    """The epochs' stacked least-squares problem (see the module doc)."""

    def __init__(self, rows: GnssRows, nav: NavFunctions, params: np.ndarray, opts: SppOptions):
        self.rows, self.nav, self.p, self.opts = rows, nav, params, opts
        cand = np.flatnonzero(rows.status == 0)
        # epochs are contiguous runs of time-sorted rows (reduceat below); a table out of time
        # order would mix epochs into singular normal equations
        self.cand = cand[np.argsort(rows.t_gps_s[cand], kind="stable")]
        t = rows.t_gps_s[self.cand]
        self.epochs, self.starts, self.counts_per_epoch = np.unique(t, return_index=True, return_counts=True)
        self.ep = np.repeat(np.arange(self.epochs.size), self.counts_per_epoch)
        self.z = rows.pseudorange_m[self.cand]
        self.ura = rows.ura_m[self.cand]
        self.aux_full = np.ascontiguousarray(rows.aux[self.cand])
        self.aux_plain = self.aux_full.copy()
        self.aux_plain[:, L.AUX_IONO_SCALE] = 0.0
        self.aux_plain[:, L.AUX_TROPO_SCALE] = 0.0
        self.sel = np.c_[np.ones(self.cand.size), self.aux_full[:, L.AUX_ISB_SELECT_SLICE]]  # [GPS-clock, E, C]
        self.excluded = np.zeros(self.cand.size, bool)
        E = self.epochs.size
        self.X = np.zeros((E, L.NX))
        self.X[:, L.X_Q_NB] = 1.0
        self.mask_rad = np.radians(opts.elevation_mask_deg)

    def _sum(self, values: np.ndarray) -> np.ndarray:
        return np.add.reduceat(values, self.starts, axis=0)

    def evaluate(self, full: bool):
        """(terms, h, A, used, var) at the current states; full: atmosphere, mask and the
        elevation-dependent weights on (else terms is None and every satellite weighs as at
        zenith)."""
        aux = self.aux_full if full else self.aux_plain
        xr = self.X[self.ep]
        h, H = self.nav.h_many("gnss_pseudorange", xr, aux, self.p)
        used = np.isfinite(h) & ~self.excluded
        if not full:
            return None, h, H[:, COLS], used, pseudorange_variance(np.pi / 2, self.ura, 0.0, False, False)
        terms = self.nav.gnss_terms(xr, aux, self.p)
        el = terms[:, 0]
        used &= np.isfinite(el) & (el >= self.mask_rad)
        var = pseudorange_variance(el, self.ura, terms[:, 2], self.rows.iono_on, self.rows.tropo_on)
        return terms, h, H[:, COLS], used, var

    def normal_equations(self, A, v, used, var):
        w = np.where(used, 1.0 / var, 0.0)
        N = self._sum(w[:, None, None] * A[:, :, None] * A[:, None, :])
        b = self._sum((w * np.where(used, v, 0.0))[:, None] * A)
        n_used = self._sum(used.astype(int))
        present = self._sum(used[:, None] & (self.sel[:, 1:] > 0)) > 0   # (E, 2) ISB columns with satellites
        for k in range(2):
            j = 4 + k
            N[~present[:, k], j, j] += 1.0 / ISB_PSEUDO_VAR_M2
        n_unknown = 4 + present.sum(axis=1)
        return N, b, n_used, n_unknown, present

    def iterate(self, full: bool, tol_m: float, active: np.ndarray) -> np.ndarray:
        """Gauss-Newton on the active epochs; returns the epochs that converged."""
        E = self.epochs.size
        converged = np.zeros(E, bool)
        for _ in range(self.opts.max_iterations):
            _, h, A, used, var = self.evaluate(full)
            N, b, n_used, n_unknown, _ = self.normal_equations(A, self.z - h, used, var)
            ok = active & (n_used >= n_unknown) & ~converged
            if not ok.any():
                break
            dx = np.zeros((E, NK))
            dx[ok] = np.linalg.solve(N[ok], b[ok][..., None])[..., 0]
            DX = np.zeros((E, L.NDX))
            DX[:, COLS] = dx
            self.X = self.nav.boxplus_many(self.X, DX)
            converged |= ok & (np.linalg.norm(dx, axis=1) < tol_m)
            if not (active & (n_used >= n_unknown) & ~converged).any():
                break
        return converged


def solve(rows: GnssRows, opts: SppOptions | None = None, *, approx_ecef_m=None,
          nav: NavFunctions | None = None) -> SppResult:
    """Single-point solutions of every epoch of `rows` (see the module doc)."""
    opts = opts or SppOptions()
    nav = nav or NavFunctions()
    gross = implausible_pseudoranges(rows)
    if gross.any():   # the rows keep their place, with their reason
        rows = dataclasses.replace(rows, status=np.where(gross, IMPLAUSIBLE, rows.status).astype(rows.status.dtype),
                                   counts=Counter(rows.counts))
        rows.counts[REASONS[IMPLAUSIBLE]] = int(gross.sum())
        rows.counts["usable"] -= int(gross.sum())
    counts = Counter(rows.counts)
    start = _start_position(rows, approx_ecef_m) if len(rows) else np.array([K.WGS84_A_M, 0.0, 0.0])
    lat0, lon0, h0 = (float(v) for v in geometry.ecef_to_geodetic(start))
    params = params_array(lat0, lon0, h0)
    batch = _Batch(rows, nav, params, opts)
    E = batch.epochs.size
    active = np.ones(E, bool)
    batch.iterate(False, COARSE_M, active)
    converged = batch.iterate(True, CONVERGED_M, active)

    status = np.full(E, SOLVED, np.int8)
    for _round in range(41):  # RAIM: at most one exclusion per epoch and round
        terms, h, A, used, var = batch.evaluate(True)
        v = batch.z - h
        N, b, n_used, n_unknown, present = batch.normal_equations(A, v, used, var)
        dof = n_used - n_unknown
        chi2 = batch._sum(np.where(used, v * v / var, 0.0))
        limit = np.array([chi2_upper(int(d), opts.chi2_alpha) if d >= 1 else np.inf for d in dof])
        failing = (dof >= 1) & (chi2 > limit) & (n_used >= n_unknown)
        retry = failing & (dof >= 2) if opts.raim else np.zeros(E, bool)
        if not retry.any() or _round == 40:
            break
        Ninv = np.linalg.inv(N)
        q = np.einsum("ni,nij,nj->n", A, Ninv[batch.ep], A)
        with np.errstate(invalid="ignore", divide="ignore"):
            std_res = np.where(used, np.abs(v) / np.sqrt(np.maximum(var - q, 1e-12)), -1.0)
        for e in np.flatnonzero(retry):
            seg = slice(batch.starts[e], batch.starts[e] + batch.counts_per_epoch[e])
            worst = seg.start + int(np.argmax(std_res[seg]))
            batch.excluded[worst] = True
        status[retry] = SOLVED_RAIM
        again = batch.iterate(True, CONVERGED_M, retry)
        converged[retry] = again[retry]

    # (terms, h, A, used, var, v, N, n_used, dof, chi2, limit: at the final states, from the last round)
    # DOP from elevation and azimuth (E, N, U, one clock), used satellites only
    el, az = terms[:, 0], terms[:, 1]
    G = np.c_[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el), np.ones(el.size)]
    Gu = np.where(used[:, None], G, 0.0)
    GG = batch._sum(Gu[:, :, None] * Gu[:, None, :])
    enough = n_used >= n_unknown
    dop = np.full((E, 4), np.nan)
    cov_origin = np.full((E, 3, 3), np.nan)
    good_geom = enough & (batch._sum(used.astype(int)) >= 4)
    if good_geom.any():
        Q = np.linalg.inv(GG[good_geom])
        d = np.einsum("nii->ni", Q)
        dop[good_geom] = np.c_[np.sqrt(d.sum(1)), np.sqrt(d[:, :3].sum(1)), np.sqrt(d[:, :2].sum(1)), np.sqrt(d[:, 2])]
    if enough.any():
        cov_origin[enough] = np.linalg.inv(N[enough])[:, :3, :3]
    status[~enough] = TOO_FEW
    status[enough & ~converged] = NOT_CONVERGED
    status[enough & converged & (dof >= 1) & (chi2 > limit)] = CHI2_FAILED
    status[enough & converged & ~(dop[:, 0] <= opts.max_gdop)] = GDOP_FAILED
    solved = (status == SOLVED) | (status == SOLVED_RAIM)

    # results per epoch: ECEF (r0 + C_n_e p_enu, geometry.py's twin of the generated
    # leonav_receiver_ecef, vectorized), local-ENU covariance
    r = geometry.enu_to_ecef(batch.X[:, L.X_P_ENU_SLICE], start_r0(lat0, lon0, h0), lat0, lon0)
    lat, lon, hgt = geometry.ecef_to_geodetic(r)
    C0 = geometry.C_enu_ecef(lat0, lon0)
    C1 = geometry.C_enu_ecef(lat, lon)
    R = C1 @ C0.T
    cov_enu = R @ cov_origin @ np.swapaxes(R, 1, 2)
    isb = batch.X[:, L.X_ISB_SLICE].copy()
    isb[~present] = np.nan

    # per-row outputs over the whole table
    n = len(rows)
    out = {k: np.full(n, np.nan) for k in ("el", "az", "iono", "tropo", "res", "sigma")}
    for k, vals in (("el", el), ("az", az), ("iono", terms[:, 2]), ("tropo", terms[:, 3]), ("res", v),
                    ("sigma", np.sqrt(var))):
        out[k][batch.cand] = vals
    row_status = rows.status.copy()
    epoch_index = np.full(n, -1)
    epoch_index[batch.cand] = batch.ep
    cand_status = np.zeros(batch.cand.size, np.int16)
    cand_status[terms[:, 0] < batch.mask_rad] = BELOW_MASK
    cand_status[batch.excluded] = RAIM_EXCLUDED
    # no elevation to judge by: the state of a non-converged epoch, or none at all
    cand_status[(status[batch.ep] == NOT_CONVERGED) | ~np.isfinite(terms[:, 0])] = EPOCH_UNSOLVED
    cand_status[(cand_status == 0) & ~solved[batch.ep]] = EPOCH_UNSOLVED
    row_status[batch.cand] = cand_status
    for code in (BELOW_MASK, RAIM_EXCLUDED, EPOCH_UNSOLVED):
        c = int((cand_status == code).sum())
        if c:
            counts[REASONS[code]] = c
    counts["used"] = int((cand_status == 0).sum())
    for code, name in EPOCH_STATUS.items():
        counts[f"epochs_{name}"] = int((status == code).sum())
    ns = batch._sum((cand_status == 0).astype(int)) if batch.cand.size else np.zeros(0, int)
    n_excl = batch._sum(batch.excluded.astype(int)) if batch.cand.size else np.zeros(0, int)
    return SppResult(batch.epochs, status, r, lat, lon, hgt, batch.X[:, L.X_C_DT].copy(), isb, ns, dop, cov_enu,
                     chi2, dof, n_excl, rows, out["el"], out["az"], out["iono"], out["tropo"], out["res"],
                     out["sigma"], row_status, epoch_index, batch.X, params, counts)


def start_r0(lat0: float, lon0: float, h0: float) -> np.ndarray:
    """ECEF of the ENU origin (m)."""
    return np.asarray(geometry.geodetic_to_ecef(lat0, lon0, h0), float)


__all__ = ["SppOptions", "SppResult", "solve", "EPOCH_STATUS", "ISB_INDEX"]
