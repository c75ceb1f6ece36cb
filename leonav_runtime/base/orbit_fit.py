"""A base station's orbit corrections: each satellite's radial / along-track / cross-track offset
(m) estimated from the base's own measurements at its known position (ephemeris method 3 in the
orbit domain).

Measurement-domain corrections (compute.py, `[base] corrections = "measurement"`) hand the rover
the orbit error's effect at the base. That effect depends on the geometry: 20 km away a time-
differenced carrier phase keeps ~10-20 % of it, tens of cycles with element sets hours old.
An orbit offset is the same for every receiver, so a base that estimates it hands over
something that does not decay with the baseline; what the rover keeps is the estimate's error.

Model, per measurement row j of satellite i at epoch g:

    r_j = z_base_j - h(base, element orbit)_j = dh_j(d_i) + B_j c + e_g + n_j,   n_j ~ N(0, sigma_j^2)

with d_i (3,) the satellite's offsets (the realism model's: along-track as a time shift), dh_j the
model's change with the satellite moved by them (the caller's `linearize`: its value and
derivative A_j at a given offset), c the base's own constant receiver states that the rows
read (the sample-clock scale; columns B_j = the generated H at the base), and e_g a term common to
an epoch's rows of one kind (the LO's random walk, the clock): it is eliminated exactly by
removing each epoch's weighted mean from the rows and the columns. A Gaussian prior (the
element-age sigmas, the receiver states' priors) keeps the system regular while a satellite has
few rows.

Satellites out of view leave the solve (marginalized, their information about c kept), so its
size is that of the satellites in view, not of every satellite of a long run.

The estimate is causal: at each serving time t_k the base solves with every row of t <= t_k, so
a rover applying the correction served at or before its epoch uses no future data. Linear least
squares, relinearized: the offsets are small against the ranges (~1 km against 500+ km), yet
a kilometre's along-track shift changes a 0.1 s phase difference by tens of cycles and the
model's departure from its tangent is ~1e-3 of that, a few noise sigmas: each serving time's
new rows are linearized about the current estimate, `iterations` times (an iterated sequential
fit), not once about the element orbit.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OrbitFit:
    """Served orbit corrections: at serving time `t_serve[k]` (s) satellite `sat_ids[i]` has the
    radial, along-track, cross-track offset `offsets_rac_m[k, i]` (m; true orbit minus element
    orbit) with covariance `cov_rac_m2[k, i]` (m^2). Before the first serving time: no
    correction (zeros) with the prior covariance."""

    sat_ids: np.ndarray          # (N,) NORAD ids
    t_serve: np.ndarray          # (K,) s
    offsets_rac_m: np.ndarray    # (K, N, 3) m
    cov_rac_m2: np.ndarray       # (K, N, 3, 3) m^2
    prior_cov_rac_m2: np.ndarray  # (3, 3) m^2, every satellite's before it is served

    def at(self, sat_id: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) offsets (m) and (n, 3, 3) covariances (m^2) a rover holds at times t (s) for
        satellites sat_id: the latest correction served at or before t (age >= 0)."""
        i = np.searchsorted(self.sat_ids, sat_id)
        if np.any(i >= self.sat_ids.size) or np.any(self.sat_ids[np.minimum(i, self.sat_ids.size - 1)] != sat_id):
            raise ValueError("OrbitFit.at: a satellite the base never measured")
        k = np.searchsorted(self.t_serve, t, side="right") - 1
        off = np.zeros((i.size, 3))
        cov = np.broadcast_to(self.prior_cov_rac_m2, (i.size, 3, 3)).copy()
        served = k >= 0
        off[served] = self.offsets_rac_m[k[served], i[served]]
        cov[served] = self.cov_rac_m2[k[served], i[served]]
        return off, cov


def _group_means(group: np.ndarray, w: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Weighted mean per group of each column of cols (n, m) -> (n_groups, m)."""
    sw = np.bincount(group, w)
    out = np.zeros((sw.size, cols.shape[1]))
    np.add.at(out, group, w[:, None] * cols)
    return out / sw[:, None]


Linearize = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _retire(info: np.ndarray, rhs: np.ndarray, active: list[int], last_t: np.ndarray, before_s: float,
            m: int) -> tuple[np.ndarray, np.ndarray]:
    """Marginalize out of (info, rhs) the active satellites last measured before `before_s`
    (Schur complement: exact for the linear problem); `active` is updated in place."""
    gone = [j for j, i in enumerate(active) if last_t[i] < before_s]
    if not gone:
        return info, rhs
    out = np.concatenate([m + 3 * j + np.arange(3) for j in gone])
    keep = np.setdiff1d(np.arange(info.shape[0]), out)
    gain = info[np.ix_(keep, out)] @ np.linalg.inv(info[np.ix_(out, out)])
    info_kept = info[np.ix_(keep, keep)] - gain @ info[np.ix_(out, keep)]
    rhs_kept = rhs[keep] - gain @ rhs[out]
    for j in reversed(gone):
        del active[j]
    return info_kept, rhs_kept


def _enter(info: np.ndarray, rhs: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(info, rhs) with a satellite's 3 unknowns appended, its Gaussian prior (mean, cov)."""
    n = info.shape[0]
    prior_info = np.linalg.inv(cov)
    grown = np.zeros((n + 3, n + 3))
    grown[:n, :n] = info
    grown[n:, n:] = prior_info
    return grown, np.concatenate([rhs, prior_info @ mean])


def fit_orbit_offsets(sat_id: np.ndarray, t: np.ndarray, group: np.ndarray, residual: np.ndarray,
                      sigma: np.ndarray, B: np.ndarray, linearize: Linearize, prior_sigma_rac_m: np.ndarray,
                      prior_sigma_common: np.ndarray, t_serve: np.ndarray, iterations: int = 3,
                      tolerance_m: float = 30.0, retire_after_s: float = 30.0) -> OrbitFit:
    """Causal least-squares orbit offsets (module doc).

    sat_id (n,) NORAD ids, t (n,) s, group (n,) int label of each row's epoch and kind (its
    common term), residual (n,) z_base - h(base, element orbit), sigma (n,) its 1-sigma, B (n, m)
    d residual / d the base's constant receiver states, linearize(rows, d) -> (dh (r,), A (r, 3)):
    the model's change at those rows with their satellites moved by offsets d (r, 3) m and its
    derivative there (per m), prior_sigma_rac_m (3,) m, prior_sigma_common (m,), t_serve (K,)
    increasing serving times (s); each serving time's new rows are relinearized about the new
    estimate until it moves their satellites by less than tolerance_m (m), at most `iterations`
    times (an iterated sequential fit: a row keeps the linearization it entered with). A
    satellite without rows for retire_after_s (s) leaves the solve, its information about the
    common states kept (marginalized out); its offsets stay served as last fitted, and if it
    comes back it enters with them as its prior. So the solve holds the satellites in view,
    not every satellite of the run."""
    sat_id, t, residual, sigma = (np.asarray(a) for a in (sat_id, t, residual, sigma))
    if not (sat_id.shape == t.shape == residual.shape == sigma.shape == group.shape) or B.shape[0] != t.size:
        raise ValueError("fit_orbit_offsets: rows of sat_id, t, group, residual, sigma, B must agree")
    if not np.all(np.isfinite(residual)) or not np.all(sigma > 0):
        raise ValueError("fit_orbit_offsets: residuals must be finite and sigmas > 0")
    if np.any(np.diff(t_serve) <= 0) or iterations < 1:
        raise ValueError("fit_orbit_offsets: t_serve must increase and iterations be >= 1")
    ids, slot = np.unique(sat_id, return_inverse=True)
    w = 1.0 / sigma**2
    _, g = np.unique(group, return_inverse=True)
    prior_sigma_common = np.asarray(prior_sigma_common, float)
    if B.shape[1]:   # a column the epoch's mean removes entirely is the common term itself: no unknown
        left = np.max(np.abs(B - _group_means(g, w, B)[g]), axis=0)
        keep = left > 1e-9 * np.maximum(np.max(np.abs(B), axis=0), 1e-300)
        B, prior_sigma_common = B[:, keep], prior_sigma_common[keep]
    N, m = ids.size, B.shape[1]
    prior_cov = np.diag(np.asarray(prior_sigma_rac_m, float) ** 2)
    est, est_cov = np.zeros((N, 3)), np.broadcast_to(prior_cov, (N, 3, 3)).copy()   # latest per satellite
    last_t = np.full(N, -np.inf)
    # the solve's unknowns: the common states, then 3 per satellite in view (`active`, in order)
    active: list[int] = []
    info = np.diag(1.0 / prior_sigma_common**2)
    rhs = np.zeros(m)
    order = np.argsort(t, kind="stable")
    K = len(t_serve)
    offsets, covs = np.zeros((K, N, 3)), np.zeros((K, N, 3, 3))
    ends = np.searchsorted(t[order], t_serve, side="right")   # an epoch's rows share t: epochs enter whole
    start = 0
    for k, end in enumerate(ends):
        rows = order[start:end]
        start = end
        if rows.size:
            info, rhs = _retire(info, rhs, active, last_t, t_serve[k] - retire_after_s, m)
            sats = np.unique(slot[rows])
            for i in sats[~np.isin(sats, active)]:   # in view: enters with what is known of it (prior or last fit)
                info, rhs = _enter(info, rhs, est[i], est_cov[i])
                active.append(int(i))
            last_t[sats] = t_serve[k]
            position = {s_: j for j, s_ in enumerate(active)}
            col = m + 3 * np.array([position[i] for i in slot[rows]])[:, None] + np.arange(3)
            _, gi = np.unique(g[rows], return_inverse=True)
            d_new = est[slot[rows]]
            for _ in range(iterations):
                d = d_new
                dh, A = linearize(rows, d)
                y = residual[rows] - dh + np.einsum("ni,ni->n", A, d)   # a measurement of A d
                # the design with the epoch's common term eliminated: each column minus its group's weighted mean
                X = np.zeros((rows.size, info.shape[0]))
                X[np.arange(rows.size)[:, None], col] = A
                X[:, :m] = B[rows]
                X -= _group_means(gi, w[rows], X)[gi]
                y = y - _group_means(gi, w[rows], y[:, None])[gi, 0]
                info_k = info + X.T @ (w[rows, None] * X)
                rhs_k = rhs + X.T @ (w[rows] * y)
                cov = np.linalg.inv(info_k)
                theta = cov @ rhs_k
                est[active] = theta[m:].reshape(-1, 3)
                d_new = est[slot[rows]]
                if np.max(np.abs(d_new - d)) < tolerance_m:
                    break
            info, rhs = info_k, rhs_k
            j = np.arange(len(active))
            est_cov[active] = cov[m:, m:].reshape(len(active), 3, len(active), 3)[j, :, j, :]
        offsets[k], covs[k] = est, est_cov
    return OrbitFit(ids, np.asarray(t_serve, float), offsets, covs, prior_cov)
