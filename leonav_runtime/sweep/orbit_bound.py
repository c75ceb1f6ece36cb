"""Ephemeris method 1's bound: the PCRB with each Starlink satellite's orbit offset as a state.

What estimating the orbit errors with the navigation state (issue 22, method 1) can reach at
best, before a filter is built for it: the posterior Cramer-Rao bound of the navigation error
when every Starlink satellite the mode measures carries its radial, along-track and
cross-track offset (m) from its element orbit as three more states, random constants (as the
simulator's truth draws them: orbit_truth.py) with the element age's prior sigmas, and
independent of everything else until the satellite is first measured (its columns join then);
after its last measurement its columns leave (deleting a state no later record reads is its exact
marginal), so the matrix holds the satellites in view, not every satellite of the run.

The recursion is the covariance form of the PCRB along the truth on the noise-free record
stream of `simulate.trial_records` (what the sweep's `pcrb_on_truth` reads): per IMU record the
generated predict's F and Qd (P_nn = F P_nn F' + Qd, P_no = F P_no; the offsets do not move),
per measurement epoch one Kalman update with H = [H_nav | H_orbit], H_nav the
generated Jacobian and H_orbit (per m of offset) central differences of the generated h over
the records' aux with the satellite moved (`orbit_truth.move_aux`: an along-track offset is a
time shift, and a time difference's both ends move with it). Without offset states it is the
filter's own PCRB (`filter.pcrb`, information form in C); tests/test_orbit_bound.py holds the
two together.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.core.orbit_states import offset_kinds
from leonav_runtime.simulation import simulate
from leonav_runtime.simulation.orbit_truth import move_aux


@dataclasses.dataclass
class OrbitStateBound:
    """The bound after every record: position_m (n,) sqrt(trace) of the ENU position block (m),
    velocity_mps (n,) of the velocity block; sat_id (k,) the satellites whose offsets are states
    and orbit_sigma_m (k, 3) their radial, along, cross bound after their last measurement (m);
    measurements, how many records were applied."""

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    sat_id: np.ndarray
    orbit_sigma_m: np.ndarray
    measurements: int


def offset_jacobian(nav: navfuncs.NavFunctions, kind: int, x_rows: np.ndarray, aux: np.ndarray, params: np.ndarray,
                    step_m: float = 1.0) -> np.ndarray:
    """(n, 3) derivative of each record's h per m of its satellite's radial, along, cross offset:
    central differences over the moved aux, all six moves in one call."""
    n = aux.shape[0]
    moves = np.concatenate([step_m * np.eye(3), -step_m * np.eye(3)])
    aux_all = np.concatenate([move_aux(aux, np.broadcast_to(d, (n, 3)), nav.layout) for d in moves])
    h = nav.h_many(kind, np.tile(x_rows, (6, 1)), aux_all, params=params, jacobian=False)[0].reshape(6, n)
    return ((h[:3] - h[3:]) / (2.0 * step_m)).T


def bound(recs: np.ndarray, x_lin: np.ndarray, P0: np.ndarray, params: np.ndarray, nav: navfuncs.NavFunctions,
          prior_sigma_rac_m: np.ndarray | None) -> OrbitStateBound:
    """The bound along `recs` (time-ordered records; x_lin (n, NX) the truth where each record
    is linearised, as for `filter.pcrb`), prior P0 (NDX, NDX); prior_sigma_rac_m (3,) m: the
    offsets' prior sigmas, None for no offset states (the filter's own PCRB)."""
    L = nav.layout
    ndx, n = int(L.NDX), recs.size
    kind, t, sat = recs["kind"], recs["t"], recs["sat_id"]
    if np.any(kind == L.KIND_CV):
        raise ValueError("orbit-state bound: constant-velocity records are not handled (a mode with the IMU is)")
    estimate = prior_sigma_rac_m is not None
    H_nav, H_orb = np.zeros((n, ndx)), np.zeros((n, 3))
    with_offsets = np.zeros(n, bool)
    for k in np.unique(kind[kind >= 0]):
        idx = np.flatnonzero(kind == k)
        H_nav[idx] = nav.h_many(int(k), x_lin[idx], recs["aux"][idx], params=params)[1]
        if estimate and int(k) in offset_kinds():
            H_orb[idx] = offset_jacobian(nav, int(k), x_lin[idx], recs["aux"][idx], params)
            with_offsets[idx] = True
    predict = navfuncs.GeneratedFunction(nav.library.lib, "leonav_predict")
    P_dummy = np.zeros((ndx, ndx))
    P = np.array(P0, dtype=float)
    column: dict[int, int] = {}                      # satellite -> its first offset column in P
    last = {int(s): int(np.flatnonzero(with_offsets & (sat == s))[-1]) for s in np.unique(sat[with_offsets])}
    final: dict[int, np.ndarray] = {}                # satellite -> its offsets' sigmas when it left
    pos, vel = np.empty(n), np.empty(n)
    sl_p, sl_v = slice(L.DX_DP, L.DX_DP + 3), slice(L.DX_DV, L.DX_DV + 3)
    i, applied = 0, 0
    while i < n:
        if kind[i] < 0:
            F, Qd = predict(x_lin[i], P_dummy, recs["u"][i], float(recs["dt"][i]), params)[2:4]
            P[:ndx, :ndx] = F @ P[:ndx, :ndx] @ F.T + Qd
            P[:ndx, ndx:] = F @ P[:ndx, ndx:]
            P[ndx:, :ndx] = P[:ndx, ndx:].T
            j = i + 1
        else:
            j = i + 1
            while j < n and kind[j] >= 0 and t[j] == t[i]:
                j += 1
            rows = np.arange(i, j)
            for s in np.unique(sat[rows[with_offsets[rows]]]).tolist():
                if s not in column:    # a satellite's offsets join at its first measurement
                    column[s] = P.shape[0]
                    P = np.pad(P, ((0, 3), (0, 3)))
                    P[-3:, -3:] = np.diag(np.asarray(prior_sigma_rac_m, float) ** 2)
            H = np.zeros((rows.size, P.shape[0]))
            H[:, :ndx] = H_nav[rows]
            for r, row in enumerate(rows):
                if with_offsets[row]:
                    c = column[int(sat[row])]
                    H[r, c:c + 3] = H_orb[row]
            PHt = P @ H.T
            K = np.linalg.solve(H @ PHt + np.diag(recs["R"][rows]), PHt.T).T
            P -= K @ PHt.T
            P = 0.5 * (P + P.T)
            applied += rows.size
            gone = [s for s in column if last[s] < j]
            if gone:    # never measured again: dropping its rows and columns is its exact marginal
                keep = np.ones(P.shape[0], bool)
                for s in gone:
                    c = column.pop(s)
                    keep[c:c + 3] = False
                    final[s] = np.sqrt(np.diag(P)[c:c + 3])
                P = P[np.ix_(keep, keep)]
                order = sorted(column, key=column.get)
                column = {s: ndx + 3 * m for m, s in enumerate(order)}
        pos[i:j] = np.sqrt(np.trace(P[sl_p, sl_p]))
        vel[i:j] = np.sqrt(np.trace(P[sl_v, sl_v]))
        i = j
    for s, c in column.items():
        final[s] = np.sqrt(np.diag(P)[c:c + 3])
    ids = np.array(sorted(final), dtype=np.int64)
    sig = np.array([final[s] for s in ids.tolist()]).reshape(-1, 3)
    return OrbitStateBound(t.copy(), pos, vel, ids, sig, applied)


def records_on_truth(setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int):
    """(records, x_lin) of the mode's noise-free stream, linearised as `pcrb_on_truth` does."""
    recs = simulate.trial_records(setup, mode, count, np.random.default_rng(0), nav, noise_free=True).records
    k_of = np.rint(recs["t"] * setup.scn.imu_rate_hz).astype(int)
    k_lin = np.where(recs["kind"] < 0, k_of - 1, k_of)
    return recs, setup.x_true[k_lin]
